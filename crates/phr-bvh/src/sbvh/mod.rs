//! Spatial-split BVH (SBVH; Stich, Friedrich & Dietrich 2009, "Spatial Splits in Bounding
//! Volume Hierarchies"): the binned SAH builder's object splits, plus splits that cut the
//! primitives straddling a plane into two references, one per side. Long and large
//! triangles (architecture: Sponza's floors and columns) no longer make siblings overlap,
//! so rays visit fewer nodes; Embree's `RTC_BUILD_QUALITY_HIGH`, which Mitsuba 3 uses, is
//! this builder. A primitive may then sit in several leaves, and a leaf's box may enclose
//! only the part of it that lies in the leaf ([`crate::validate::validate_split`] checks
//! such trees).
//!
//! At every node:
//! 1. **Object split**: the binned SAH over the references' centres (as
//!    [`crate::binned_sah`]).
//! 2. **Spatial split**, tried only where the best object split's two boxes overlap by more
//!    than [`SbvhOptions::min_overlap`] of the root's surface area (Stich's α): each axis is
//!    cut into [`SbvhOptions::spatial_bins`] equal slabs; every reference is clipped into the
//!    slabs it spans ([`split`]: triangles only; other primitives are never cut), counted
//!    where it enters and where it leaves; the SAH is swept over the slab planes.
//! 3. The cheaper of the two wins (or a leaf, by the shared [`LeafPolicy`]). A spatial split
//!    keeps a straddling reference whole on one side when that is cheaper than cutting it
//!    (Stich's reference unsplitting).
//!
//! **Budget.** The references may grow to [`SbvhOptions::max_references`] × the primitives
//! (Embree's default is 1.2). Each node holds part of the budget; a spatial split spends
//! what it duplicates, and the rest is shared between the children by their size, so the
//! tree does not depend on the order or the thread count of the build.

mod split;

use crate::aabb::Aabb;
use crate::node::Bvh;
use crate::sah::{LeafPolicy, MEDIAN_SPLIT_DEPTH};
use crate::topdown::{assemble, Built, Piece};
use glam::Vec3;
use rayon::prelude::*;
use split::{Primitives, Ref};

/// Above this many references a node's children are built as separate rayon tasks.
const PARALLEL_GRAIN: usize = 1 << 12;
/// Above this many references a node's binning and partition run in parallel.
const PARALLEL_BINNING: usize = 1 << 14;
pub const MAX_BINS: usize = 32;
/// The largest [`SbvhOptions::max_references`] honoured.
pub const MAX_REFERENCES: f32 = 4.0;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SbvhOptions {
    /// Bins per axis for object splits (2 to 32).
    pub object_bins: usize,
    /// Slabs per axis for spatial splits (2 to 32).
    pub spatial_bins: usize,
    /// Spatial splits are tried where the best object split's children overlap by more than
    /// this fraction of the root's surface area (Stich et al.'s α; 0: everywhere).
    pub min_overlap: f32,
    /// The references may number up to this many times the primitives (1: no spatial split;
    /// at most [`MAX_REFERENCES`]).
    pub max_references: f32,
    pub leaf: LeafPolicy,
}

impl Default for SbvhOptions {
    fn default() -> Self {
        Self { object_bins: 32, spatial_bins: 16, min_overlap: 1e-4, max_references: 1.2, leaf: LeafPolicy::default() }
    }
}

/// Builds an SBVH over `boxes`. Primitives `0..triangles.len()` are the given triangles (their
/// boxes must be `boxes[..triangles.len()]`, [`crate::triangle::triangle_bounds`] or larger)
/// and may be cut; the others are not. With no triangles at all this is the binned SAH over
/// object splits only.
pub fn build_sbvh(boxes: &[Aabb], triangles: &[[Vec3; 3]], options: &SbvhOptions) -> Bvh {
    assert!(triangles.len() <= boxes.len(), "more triangles than primitive boxes");
    if boxes.is_empty() {
        return Bvh::default();
    }
    // References (up to MAX_REFERENCES × the primitives) are counted in u32.
    assert!(boxes.len() < 1 << 29, "the SBVH builder takes fewer than 2^29 primitives");
    let refs: Vec<Ref> = boxes.par_iter().enumerate().map(|(i, &b)| Ref { bounds: b, prim: i as u32 }).collect();
    let bounds = bounds_of(&refs);
    let ctx = Ctx {
        prims: Primitives::new(triangles),
        object_bins: options.object_bins.clamp(2, MAX_BINS),
        spatial_bins: options.spatial_bins.clamp(2, MAX_BINS),
        min_overlap_area: options.min_overlap * bounds.surface_area(),
        leaf: options.leaf,
    };
    let extra = options.max_references.clamp(1.0, MAX_REFERENCES) - 1.0;
    let budget = (extra as f64 * boxes.len() as f64) as usize;
    assemble(ctx.build(refs, bounds, 0, budget))
}

struct Ctx<'a> {
    prims: Primitives<'a>,
    object_bins: usize,
    spatial_bins: usize,
    min_overlap_area: f32,
    leaf: LeafPolicy,
}

/// A node's children: their references and boxes.
struct Children {
    left: Vec<Ref>,
    left_bounds: Aabb,
    right: Vec<Ref>,
    right_bounds: Aabb,
}

impl Children {
    fn new(left: Vec<Ref>, right: Vec<Ref>) -> Self {
        Children { left_bounds: bounds_of(&left), right_bounds: bounds_of(&right), left, right }
    }
}

/// The best object split of a node.
struct ObjectSplit {
    cost: f32,
    axis: usize,
    bin: usize,
    left: Aabb,
    right: Aabb,
}

/// The best spatial split of a node: the plane, and the sides' boxes and reference counts
/// if every straddling reference were cut.
struct SpatialSplit {
    cost: f32,
    axis: usize,
    /// The slabs of `axis`, and the plane (at `planes.plane(plane)`).
    planes: Planes,
    plane: usize,
    left: Aabb,
    right: Aabb,
    left_count: u32,
    right_count: u32,
}

/// Maps centres to object bins on each axis.
struct CentreBins {
    origin: Vec3,
    scale: Vec3,
    last: usize,
}

impl CentreBins {
    #[inline]
    fn bin(&self, r: &Ref, axis: usize) -> usize {
        let c = r.bounds.center()[axis];
        (((c - self.origin[axis]) * self.scale[axis]) as usize).min(self.last)
    }
}

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

const EMPTY_BIN: Bin = Bin { bounds: Aabb::EMPTY, count: 0 };

/// Spatial bins of one axis: the clipped parts in each slab, and how many references enter
/// and leave in it.
#[derive(Clone, Copy)]
struct Slab {
    bounds: Aabb,
    enter: u32,
    exit: u32,
}

const EMPTY_SLAB: Slab = Slab { bounds: Aabb::EMPTY, enter: 0, exit: 0 };

fn bounds_of(refs: &[Ref]) -> Aabb {
    fold_chunks(refs, |c| c.iter().fold(Aabb::EMPTY, |b, r| b.union(r.bounds)), Aabb::union)
}

/// Runs `f` over chunks of `refs` (in parallel when large) and merges the results in order.
fn fold_chunks<T: Send>(refs: &[Ref], f: impl Fn(&[Ref]) -> T + Sync, merge: impl Fn(T, T) -> T + Sync) -> T {
    if refs.len() > PARALLEL_BINNING {
        refs.par_chunks(PARALLEL_BINNING / 4).map(&f).reduce_with(&merge).expect("non-empty")
    } else {
        f(refs)
    }
}

impl Ctx<'_> {
    fn build(&self, refs: Vec<Ref>, bounds: Aabb, depth: u32, budget: usize) -> Built {
        if refs.len() <= PARALLEL_GRAIN {
            let mut piece = Piece::new();
            self.build_piece(&mut piece, refs, bounds, depth, budget);
            return Built::Piece(piece);
        }
        let n = refs.len();
        match self.decide(refs, bounds, depth, budget) {
            Err(refs) => {
                let mut piece = Piece::new();
                piece.set_leaf(0, bounds, refs.iter().map(|r| r.prim));
                Built::Piece(piece)
            }
            Ok(c) => {
                let (lb, rb) = share_budget(budget, n, c.left.len(), c.right.len());
                let (left, right) = rayon::join(
                    || self.build(c.left, c.left_bounds, depth + 1, lb),
                    || self.build(c.right, c.right_bounds, depth + 1, rb),
                );
                Built::Split { bounds, children: vec![left, right] }
            }
        }
    }

    fn build_piece(&self, piece: &mut Piece, refs: Vec<Ref>, bounds: Aabb, depth: u32, budget: usize) {
        let mut stack = vec![(refs, bounds, 0u32, depth, budget)];
        while let Some((refs, bounds, slot, depth, budget)) = stack.pop() {
            let n = refs.len();
            match self.decide(refs, bounds, depth, budget) {
                Err(refs) => piece.set_leaf(slot, bounds, refs.iter().map(|r| r.prim)),
                Ok(c) => {
                    let first = piece.alloc_children(2);
                    piece.set_interior(slot, bounds, first, 2);
                    let (lb, rb) = share_budget(budget, n, c.left.len(), c.right.len());
                    stack.push((c.right, c.right_bounds, first + 1, depth + 1, rb));
                    stack.push((c.left, c.left_bounds, first, depth + 1, lb));
                }
            }
        }
    }

    /// Splits a node, or hands its references back for a leaf.
    fn decide(&self, mut refs: Vec<Ref>, bounds: Aabb, depth: u32, budget: usize) -> Result<Children, Vec<Ref>> {
        let n = refs.len();
        if n <= 1 {
            return Err(refs);
        }
        let centres =
            fold_chunks(&refs, |c| c.iter().fold(Aabb::EMPTY, |b, r| b.grown(r.bounds.center())), Aabb::union);
        let extent = centres.extent();
        if depth >= MEDIAN_SPLIT_DEPTH || extent.max_element() <= 0.0 {
            // Past the depth cap, or all centres coincide: split by count if we must.
            return if self.leaf.must_split(n as u32) { Ok(median_split(refs, centres)) } else { Err(refs) };
        }
        let nb = self.object_bins.min(n.max(4));
        let binner = CentreBins {
            origin: centres.min,
            scale: Vec3::select(extent.cmpgt(Vec3::ZERO), Vec3::splat(nb as f32) / extent, Vec3::ZERO),
            last: nb - 1,
        };
        let object = self.best_object_split(&refs, &binner, nb);
        let overlapping =
            object.as_ref().is_none_or(|o| o.left.overlap(o.right).surface_area() > self.min_overlap_area);
        let spatial = (budget > 0 && overlapping).then(|| self.best_spatial_split(&refs, bounds, budget)).flatten();
        let object_cost = object.as_ref().map_or(f32::INFINITY, |o| o.cost);
        let spatial_cost = spatial.as_ref().map_or(f32::INFINITY, |s| s.cost);
        let best = object_cost.min(spatial_cost);
        if best == f32::INFINITY {
            return if self.leaf.must_split(n as u32) { Ok(median_split(refs, centres)) } else { Err(refs) };
        }
        if !self.leaf.must_split(n as u32) && self.leaf.prefers_leaf(n as u32, bounds.surface_area(), best) {
            return Err(refs);
        }
        if let Some(s) = spatial.filter(|_| spatial_cost < object_cost) {
            match self.spatial_partition(refs, &s, budget) {
                Ok(c) => return Ok(c),
                // Every straddler went to one side, or the cuts overran the budget: fall back
                // to the object split.
                Err(back) => refs = back,
            }
        }
        Ok(match object {
            Some(o) => partition(refs, |r| binner.bin(r, o.axis) < o.bin),
            None => median_split(refs, centres),
        })
    }

    fn best_object_split(&self, refs: &[Ref], binner: &CentreBins, nb: usize) -> Option<ObjectSplit> {
        let bins = fold_chunks(
            refs,
            |chunk| {
                let mut bins = [[EMPTY_BIN; MAX_BINS]; 3];
                for r in chunk {
                    for (axis, axis_bins) in bins.iter_mut().enumerate() {
                        let b = &mut axis_bins[binner.bin(r, axis)];
                        b.bounds = b.bounds.union(r.bounds);
                        b.count += 1;
                    }
                }
                bins
            },
            |mut a, b| {
                for (x, y) in a.iter_mut().flatten().zip(b.iter().flatten()) {
                    x.bounds = x.bounds.union(y.bounds);
                    x.count += y.count;
                }
                a
            },
        );
        let n = refs.len() as u32;
        let mut best: Option<ObjectSplit> = None;
        for (axis, axis_bins) in bins.iter().enumerate() {
            if binner.scale[axis] == 0.0 {
                continue;
            }
            let axis_bins = &axis_bins[..nb];
            let mut right = [Aabb::EMPTY; MAX_BINS];
            let mut acc = Aabb::EMPTY;
            for b in (1..nb).rev() {
                acc = acc.union(axis_bins[b].bounds);
                right[b] = acc;
            }
            let (mut left, mut count) = (Aabb::EMPTY, 0u32);
            for b in 1..nb {
                left = left.union(axis_bins[b - 1].bounds);
                count += axis_bins[b - 1].count;
                if count == 0 || count == n {
                    continue;
                }
                let cost = left.surface_area() * count as f32 + right[b].surface_area() * (n - count) as f32;
                if best.as_ref().is_none_or(|s| cost < s.cost) {
                    best = Some(ObjectSplit { cost, axis, bin: b, left, right: right[b] });
                }
            }
        }
        best
    }

    fn best_spatial_split(&self, refs: &[Ref], bounds: Aabb, budget: usize) -> Option<SpatialSplit> {
        let nb = self.spatial_bins;
        let n = refs.len() as u32;
        let extent = bounds.extent();
        let mut best: Option<SpatialSplit> = None;
        for axis in 0..3 {
            if extent[axis] <= 0.0 {
                continue;
            }
            let planes = Planes { origin: bounds.min[axis], width: extent[axis] / nb as f32, last: nb - 1 };
            let slabs = fold_chunks(
                refs,
                |chunk| {
                    let mut slabs = [EMPTY_SLAB; MAX_BINS];
                    for r in chunk {
                        self.bin_spatially(r, axis, &planes, &mut slabs);
                    }
                    slabs
                },
                |mut a, b| {
                    for (x, y) in a.iter_mut().zip(&b) {
                        x.bounds = x.bounds.union(y.bounds);
                        x.enter += y.enter;
                        x.exit += y.exit;
                    }
                    a
                },
            );
            let mut right = [(Aabb::EMPTY, 0u32); MAX_BINS];
            let (mut acc, mut exits) = (Aabb::EMPTY, 0u32);
            for b in (1..nb).rev() {
                acc = acc.union(slabs[b].bounds);
                exits += slabs[b].exit;
                right[b] = (acc, exits);
            }
            let (mut left, mut enters) = (Aabb::EMPTY, 0u32);
            for b in 1..nb {
                left = left.union(slabs[b - 1].bounds);
                enters += slabs[b - 1].enter;
                let (right_box, exits) = right[b];
                if enters == 0 || exits == 0 || (enters + exits).saturating_sub(n) as usize > budget {
                    continue;
                }
                let cost = left.surface_area() * enters as f32 + right_box.surface_area() * exits as f32;
                if best.as_ref().is_none_or(|s| cost < s.cost) {
                    best = Some(SpatialSplit {
                        cost,
                        axis,
                        planes,
                        plane: b,
                        left,
                        right: right_box,
                        left_count: enters,
                        right_count: exits,
                    });
                }
            }
        }
        best
    }

    /// Clips `r` into the slabs it spans on `axis`, plane by plane. A reference that may not
    /// be cut goes whole to the slab of its centre (and to that side of the plane, see
    /// [`Ctx::spatial_partition`]).
    fn bin_spatially(&self, r: &Ref, axis: usize, planes: &Planes, slabs: &mut [Slab; MAX_BINS]) {
        if !self.prims.splittable(r) {
            let slab = &mut slabs[planes.slab(r.bounds.center()[axis])];
            slab.bounds = slab.bounds.union(r.bounds);
            slab.enter += 1;
            slab.exit += 1;
            return;
        }
        let first = planes.slab(r.bounds.min[axis]);
        let last = planes.slab(r.bounds.max[axis]);
        slabs[first].enter += 1;
        slabs[last].exit += 1;
        let mut rest = *r;
        for (b, slab) in slabs.iter_mut().enumerate().take(last).skip(first) {
            let (left, right) = self.prims.split(&rest, axis, planes.plane(b + 1));
            slab.bounds = slab.bounds.union(left);
            rest.bounds = right;
        }
        slabs[last].bounds = slabs[last].bounds.union(rest.bounds);
    }

    /// Sends each reference to its side of the plane; a straddling one is cut in two, or kept
    /// whole on the side where that costs less. Fails (handing the references back) when one
    /// side would be empty, or when the cuts exceed `budget` (the slab counts estimate them
    /// from the references' boxes; one rounding into the slab beyond the plane escapes them).
    fn spatial_partition(&self, refs: Vec<Ref>, s: &SpatialSplit, budget: usize) -> Result<Children, Vec<Ref>> {
        let (al, ar) = (s.left.surface_area(), s.right.surface_area());
        let (nl, nr) = (s.left_count as f32, s.right_count as f32);
        let split_cost = al * nl + ar * nr;
        let pos = s.planes.plane(s.plane);
        let place = |r: &Ref| -> (Option<Ref>, Option<Ref>) {
            if r.bounds.max[s.axis] <= pos {
                return (Some(*r), None);
            }
            if r.bounds.min[s.axis] >= pos {
                return (None, Some(*r));
            }
            if !self.prims.splittable(r) {
                let left = s.planes.slab(r.bounds.center()[s.axis]) < s.plane;
                return if left { (Some(*r), None) } else { (None, Some(*r)) };
            }
            let whole_left = s.left.union(r.bounds).surface_area() * nl + ar * (nr - 1.0);
            let whole_right = al * (nl - 1.0) + s.right.union(r.bounds).surface_area() * nr;
            if whole_left < split_cost && whole_left <= whole_right {
                return (Some(*r), None);
            }
            if whole_right < split_cost {
                return (None, Some(*r));
            }
            match self.prims.split(r, s.axis, pos) {
                (l, _) if l.is_empty() => (None, Some(*r)),
                (_, h) if h.is_empty() => (Some(*r), None),
                (l, h) => (Some(Ref { bounds: l, prim: r.prim }), Some(Ref { bounds: h, prim: r.prim })),
            }
        };
        let placed: Vec<(Option<Ref>, Option<Ref>)> = if refs.len() > PARALLEL_BINNING {
            refs.par_iter().with_min_len(PARALLEL_BINNING / 4).map(place).collect()
        } else {
            refs.iter().map(place).collect()
        };
        let left: Vec<Ref> = placed.iter().filter_map(|p| p.0).collect();
        let right: Vec<Ref> = placed.iter().filter_map(|p| p.1).collect();
        if left.is_empty() || right.is_empty() || left.len() + right.len() > refs.len() + budget {
            return Err(refs);
        }
        Ok(Children::new(left, right))
    }
}

/// The slab planes of one axis: `origin + b · width` for `b` in `0..=bins`.
#[derive(Clone, Copy)]
struct Planes {
    origin: f32,
    width: f32,
    last: usize,
}

impl Planes {
    #[inline]
    fn plane(&self, b: usize) -> f32 {
        self.origin + b as f32 * self.width
    }

    /// The slab holding coordinate `x` (clamped to the node).
    #[inline]
    fn slab(&self, x: f32) -> usize {
        (((x - self.origin) / self.width).max(0.0) as usize).min(self.last)
    }
}

/// The budget left after a split of `n` references into `left` and `right`, shared between the
/// children by their size.
fn share_budget(budget: usize, n: usize, left: usize, right: usize) -> (usize, usize) {
    let rest = budget.saturating_sub((left + right).saturating_sub(n));
    let to_left = (rest as u128 * left as u128 / (left + right) as u128) as usize;
    (to_left, rest - to_left)
}

/// Splits by `goes_left` (the order within each side is kept).
fn partition(refs: Vec<Ref>, goes_left: impl Fn(&Ref) -> bool + Sync) -> Children {
    let (left, right): (Vec<Ref>, Vec<Ref>) = if refs.len() > PARALLEL_BINNING {
        refs.into_par_iter().with_min_len(PARALLEL_BINNING / 4).partition(|r| goes_left(r))
    } else {
        refs.into_iter().partition(|r| goes_left(r))
    };
    Children::new(left, right)
}

/// The object median along the axis of largest centre extent (ties by index).
fn median_split(mut refs: Vec<Ref>, centres: Aabb) -> Children {
    let axis = centres.longest_axis();
    let k = refs.len() / 2;
    refs.select_nth_unstable_by(k, |a, b| {
        a.bounds.center()[axis].total_cmp(&b.bounds.center()[axis]).then(a.prim.cmp(&b.prim))
    });
    let right = refs.split_off(k);
    Children::new(refs, right)
}
