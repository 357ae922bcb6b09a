//! Full-sweep SAH builder (MacDonald & Booth 1990; Wald 2007, "On fast Construction of
//! SAH-based Bounding Volume Hierarchies"): at every node, every position between
//! consecutive primitives along each axis is evaluated exactly. The quality reference that
//! PHR approximates; slow (the evaluation is exact, not binned) but O(n log n) overall: the
//! primitives are sorted by centroid once per axis, and each split partitions the three
//! orders stably, so no node sorts again.

use crate::aabb::Aabb;
use crate::node::Bvh;
use crate::sah::{LeafPolicy, MEDIAN_SPLIT_DEPTH};
use crate::topdown::{assemble, Built, Piece};
use glam::Vec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

/// Above this many primitives a node's children are built as separate rayon tasks.
const PARALLEL_GRAIN: usize = 1 << 12;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SweepSahOptions {
    pub leaf: LeafPolicy,
}

struct Ctx<'a> {
    boxes: &'a [Aabb],
    /// Per primitive: goes left in the split being applied (each task owns its primitives).
    goes_left: Vec<AtomicBool>,
    leaf: LeafPolicy,
}

/// A node's primitives in three orders, one per axis (the same set in each).
struct Orders<'a> {
    axes: [&'a mut [u32]; 3],
}

pub fn build_sweep_sah(boxes: &[Aabb], options: &SweepSahOptions) -> Bvh {
    if boxes.is_empty() {
        return Bvh::default();
    }
    let centers: Vec<Vec3> = boxes.par_iter().map(Aabb::center).collect();
    let sorted = |axis: usize| {
        let mut v: Vec<u32> = (0..boxes.len() as u32).collect();
        v.par_sort_unstable_by(|&a, &b| {
            centers[a as usize][axis].total_cmp(&centers[b as usize][axis]).then(a.cmp(&b))
        });
        v
    };
    let (mut x, mut y, mut z) = (sorted(0), sorted(1), sorted(2));
    let goes_left = (0..boxes.len()).map(|_| AtomicBool::new(false)).collect();
    let ctx = Ctx { boxes, goes_left, leaf: options.leaf };
    let built = ctx.build(Orders { axes: [&mut x, &mut y, &mut z] }, 0);
    assemble(built)
}

/// The best split of one node: its axis, the number of primitives going left, and
/// `Σ A_child · N_child`.
struct Split {
    axis: usize,
    left_count: usize,
    area_count: f32,
}

impl Ctx<'_> {
    fn bounds(&self, prims: &[u32]) -> Aabb {
        prims.iter().fold(Aabb::EMPTY, |b, &p| b.union(self.boxes[p as usize]))
    }

    fn best_split(&self, orders: &Orders, right_area: &mut Vec<f32>) -> Split {
        let n = orders.axes[0].len();
        let mut best = Split { axis: 0, left_count: n / 2, area_count: f32::INFINITY };
        right_area.resize(n, 0.0);
        for (axis, order) in orders.axes.iter().enumerate() {
            let mut acc = Aabb::EMPTY;
            for k in (1..n).rev() {
                acc = acc.union(self.boxes[order[k] as usize]);
                right_area[k] = acc.surface_area();
            }
            let mut left = Aabb::EMPTY;
            for k in 1..n {
                left = left.union(self.boxes[order[k - 1] as usize]);
                let cost = left.surface_area() * k as f32 + right_area[k] * (n - k) as f32;
                if cost < best.area_count {
                    best = Split { axis, left_count: k, area_count: cost };
                }
            }
        }
        best
    }

    /// The object median along the axis where the centroids spread most: what a node gets
    /// when its centroids coincide (no plane separates them) or it lies past
    /// [`MEDIAN_SPLIT_DEPTH`].
    fn median_split(&self, orders: &Orders) -> Split {
        let n = orders.axes[0].len();
        let spread = |axis: usize| {
            let order = &orders.axes[axis];
            self.centroid(order[n - 1], axis) - self.centroid(order[0], axis)
        };
        let axis = (0..3).max_by(|&a, &b| spread(a).total_cmp(&spread(b))).unwrap_or(0);
        let k = n / 2;
        let (l, r) = orders.axes[axis].split_at(k);
        Split {
            axis,
            left_count: k,
            area_count: self.bounds(l).surface_area() * k as f32 + self.bounds(r).surface_area() * (n - k) as f32,
        }
    }

    /// Twice the centroid of primitive `p` along `axis` (the sort key of the orders).
    fn centroid(&self, p: u32, axis: usize) -> f32 {
        let b = &self.boxes[p as usize];
        b.min[axis] + b.max[axis]
    }

    /// Whether every primitive's centroid is the same point (the orders' ends agree on every
    /// axis).
    fn centroids_coincide(&self, orders: &Orders) -> bool {
        (0..3).all(|axis| {
            let order = &orders.axes[axis];
            self.centroid(order[0], axis) == self.centroid(order[order.len() - 1], axis)
        })
    }

    /// Applies `split`: marks the left primitives, partitions the other two orders stably.
    fn partition(&self, orders: &mut Orders, split: &Split, scratch: &mut Vec<u32>) {
        let order = &orders.axes[split.axis];
        for (k, &p) in order.iter().enumerate() {
            self.goes_left[p as usize].store(k < split.left_count, Ordering::Relaxed);
        }
        for axis in (0..3).filter(|&a| a != split.axis) {
            let slice = &mut *orders.axes[axis];
            scratch.clear();
            let mut write = 0;
            for k in 0..slice.len() {
                let p = slice[k];
                if self.goes_left[p as usize].load(Ordering::Relaxed) {
                    slice[write] = p;
                    write += 1;
                } else {
                    scratch.push(p);
                }
            }
            slice[write..].copy_from_slice(scratch);
        }
    }

    /// Leaf or split for a node at `depth`; on a split the orders are partitioned.
    fn decide(
        &self,
        orders: &mut Orders,
        bounds: &Aabb,
        depth: u32,
        right_area: &mut Vec<f32>,
        scratch: &mut Vec<u32>,
    ) -> Option<usize> {
        let n = orders.axes[0].len();
        if n <= 1 {
            return None;
        }
        let split = if depth >= MEDIAN_SPLIT_DEPTH || self.centroids_coincide(orders) {
            self.median_split(orders)
        } else {
            self.best_split(orders, right_area)
        };
        if !self.leaf.must_split(n as u32) && self.leaf.prefers_leaf(n as u32, bounds.surface_area(), split.area_count)
        {
            return None;
        }
        self.partition(orders, &split, scratch);
        Some(split.left_count)
    }

    fn build(&self, mut orders: Orders, depth: u32) -> Built {
        let n = orders.axes[0].len();
        if n <= PARALLEL_GRAIN {
            let mut piece = Piece::new();
            self.build_piece(&mut piece, orders, depth);
            return Built::Piece(piece);
        }
        let bounds = self.bounds(orders.axes[0]);
        let Some(k) = self.decide(&mut orders, &bounds, depth, &mut Vec::new(), &mut Vec::new()) else {
            let mut piece = Piece::new();
            piece.set_leaf(0, bounds, orders.axes[0].iter().copied());
            return Built::Piece(piece);
        };
        let [x, y, z] = orders.axes;
        let (xl, xr) = x.split_at_mut(k);
        let (yl, yr) = y.split_at_mut(k);
        let (zl, zr) = z.split_at_mut(k);
        let (left, right) = rayon::join(
            || self.build(Orders { axes: [xl, yl, zl] }, depth + 1),
            || self.build(Orders { axes: [xr, yr, zr] }, depth + 1),
        );
        Built::Split { bounds, children: vec![left, right] }
    }

    fn build_piece(&self, piece: &mut Piece, orders: Orders, depth: u32) {
        let (mut right_area, mut scratch) = (Vec::new(), Vec::new());
        let mut stack = vec![(orders, 0u32, depth)];
        while let Some((mut orders, slot, depth)) = stack.pop() {
            let bounds = self.bounds(orders.axes[0]);
            match self.decide(&mut orders, &bounds, depth, &mut right_area, &mut scratch) {
                None => piece.set_leaf(slot, bounds, orders.axes[0].iter().copied()),
                Some(k) => {
                    let first = piece.alloc_children(2);
                    piece.set_interior(slot, bounds, first, 2);
                    let [x, y, z] = orders.axes;
                    let (xl, xr) = x.split_at_mut(k);
                    let (yl, yr) = y.split_at_mut(k);
                    let (zl, zr) = z.split_at_mut(k);
                    stack.push((Orders { axes: [xr, yr, zr] }, first + 1, depth + 1));
                    stack.push((Orders { axes: [xl, yl, zl] }, first, depth + 1));
                }
            }
        }
    }
}
