//! Full-sweep SAH builder (MacDonald & Booth 1990; Wald 2007, "On fast Construction of
//! SAH-based Bounding Volume Hierarchies"): at every node, every position between
//! consecutive primitives along each axis is evaluated exactly. The quality reference that
//! PHR approximates; slow (the evaluation is exact, not binned) but O(n log n) overall: the
//! primitives are sorted by centroid once per axis, and each split partitions the three
//! orders stably, so no node sorts again.

use crate::aabb::Aabb;
use crate::node::Bvh;
use crate::sah::LeafPolicy;
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
    let built = ctx.build(Orders { axes: [&mut x, &mut y, &mut z] });
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

    /// Leaf or split for a node; on a split the orders are partitioned.
    fn decide(
        &self,
        orders: &mut Orders,
        bounds: &Aabb,
        right_area: &mut Vec<f32>,
        scratch: &mut Vec<u32>,
    ) -> Option<usize> {
        let n = orders.axes[0].len();
        if n <= 1 {
            return None;
        }
        let split = self.best_split(orders, right_area);
        if !self.leaf.must_split(n as u32) && self.leaf.prefers_leaf(n as u32, bounds.surface_area(), split.area_count)
        {
            return None;
        }
        self.partition(orders, &split, scratch);
        Some(split.left_count)
    }

    fn build(&self, mut orders: Orders) -> Built {
        let n = orders.axes[0].len();
        if n <= PARALLEL_GRAIN {
            let mut piece = Piece::new();
            self.build_piece(&mut piece, orders);
            return Built::Piece(piece);
        }
        let bounds = self.bounds(orders.axes[0]);
        let Some(k) = self.decide(&mut orders, &bounds, &mut Vec::new(), &mut Vec::new()) else {
            let mut piece = Piece::new();
            piece.set_leaf(0, bounds, orders.axes[0].iter().copied());
            return Built::Piece(piece);
        };
        let [x, y, z] = orders.axes;
        let (xl, xr) = x.split_at_mut(k);
        let (yl, yr) = y.split_at_mut(k);
        let (zl, zr) = z.split_at_mut(k);
        let (left, right) =
            rayon::join(|| self.build(Orders { axes: [xl, yl, zl] }), || self.build(Orders { axes: [xr, yr, zr] }));
        Built::Split { bounds, children: vec![left, right] }
    }

    fn build_piece(&self, piece: &mut Piece, orders: Orders) {
        let (mut right_area, mut scratch) = (Vec::new(), Vec::new());
        let mut stack = vec![(orders, 0u32)];
        while let Some((mut orders, slot)) = stack.pop() {
            let bounds = self.bounds(orders.axes[0]);
            match self.decide(&mut orders, &bounds, &mut right_area, &mut scratch) {
                None => piece.set_leaf(slot, bounds, orders.axes[0].iter().copied()),
                Some(k) => {
                    let first = piece.alloc_children(2);
                    piece.set_interior(slot, bounds, first, 2);
                    let [x, y, z] = orders.axes;
                    let (xl, xr) = x.split_at_mut(k);
                    let (yl, yr) = y.split_at_mut(k);
                    let (zl, zr) = z.split_at_mut(k);
                    stack.push((Orders { axes: [xr, yr, zr] }, first + 1));
                    stack.push((Orders { axes: [xl, yl, zl] }, first));
                }
            }
        }
    }
}
