//! Binned SAH builder (Wald 2007; what Embree, pbrt-v4 and tinybvh use by default): at every
//! node the centroids are sorted into a fixed number of bins per axis and only the bin
//! boundaries are evaluated. Much faster than the full sweep, slightly worse trees. Binning
//! is itself parallel at the top levels, where nodes are large.

use crate::aabb::Aabb;
use crate::node::Bvh;
use crate::sah::{LeafPolicy, MEDIAN_SPLIT_DEPTH};
use crate::topdown::{assemble, Built, Piece};
use glam::Vec3;
use rayon::prelude::*;

/// Above this many primitives a node's children are built as separate rayon tasks.
const PARALLEL_GRAIN: usize = 1 << 12;
/// Above this many primitives a node's binning itself runs in parallel.
const PARALLEL_BINNING: usize = 1 << 16;
pub const MAX_BINS: usize = 32;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BinnedSahOptions {
    /// Bins per axis (2 to 32; 16 to 32 is the usual choice). Nodes with fewer primitives
    /// than bins use one bin per primitive (at least 4): as good, and much cheaper.
    pub bins: usize,
    pub leaf: LeafPolicy,
}

impl Default for BinnedSahOptions {
    fn default() -> Self {
        Self { bins: 32, leaf: LeafPolicy::default() }
    }
}

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: u32,
}

/// Per-axis bins of one node.
#[derive(Clone)]
struct Bins([[Bin; MAX_BINS]; 3]);

impl Bins {
    fn empty() -> Self {
        Bins([[Bin { bounds: Aabb::EMPTY, count: 0 }; MAX_BINS]; 3])
    }

    fn merge(mut self, o: &Bins) -> Self {
        for a in 0..3 {
            for b in 0..MAX_BINS {
                self.0[a][b].bounds = self.0[a][b].bounds.union(o.0[a][b].bounds);
                self.0[a][b].count += o.0[a][b].count;
            }
        }
        self
    }
}

struct Ctx<'a> {
    boxes: &'a [Aabb],
    centers: Vec<Vec3>,
    bins: usize,
    leaf: LeafPolicy,
}

pub fn build_binned_sah(boxes: &[Aabb], options: &BinnedSahOptions) -> Bvh {
    if boxes.is_empty() {
        return Bvh::default();
    }
    let centers = boxes.par_iter().map(Aabb::center).collect();
    let ctx = Ctx { boxes, centers, bins: options.bins.clamp(2, MAX_BINS), leaf: options.leaf };
    let mut prims: Vec<u32> = (0..boxes.len() as u32).collect();
    assemble(ctx.build(&mut prims, 0))
}

/// Maps a centroid coordinate to its bin on one axis.
#[derive(Clone, Copy)]
struct Binner {
    min: Vec3,
    scale: Vec3,
    bins: usize,
}

impl Binner {
    #[inline]
    fn bin(&self, c: Vec3, axis: usize) -> usize {
        (((c[axis] - self.min[axis]) * self.scale[axis]) as usize).min(self.bins - 1)
    }
}

impl Ctx<'_> {
    fn bounds_and_centroids(&self, prims: &[u32]) -> (Aabb, Aabb) {
        let f = |(b, c): (Aabb, Aabb), &p: &u32| (b.union(self.boxes[p as usize]), c.grown(self.centers[p as usize]));
        if prims.len() > PARALLEL_BINNING {
            prims
                .par_chunks(PARALLEL_BINNING / 4)
                .map(|c| c.iter().fold((Aabb::EMPTY, Aabb::EMPTY), f))
                .reduce(|| (Aabb::EMPTY, Aabb::EMPTY), |a, b| (a.0.union(b.0), a.1.union(b.1)))
        } else {
            prims.iter().fold((Aabb::EMPTY, Aabb::EMPTY), f)
        }
    }

    fn bin_prims(&self, prims: &[u32], binner: &Binner) -> Bins {
        let fill = |mut bins: Bins, chunk: &[u32]| {
            for &p in chunk {
                let c = self.centers[p as usize];
                let b = self.boxes[p as usize];
                for axis in 0..3 {
                    let bin = &mut bins.0[axis][binner.bin(c, axis)];
                    bin.bounds = bin.bounds.union(b);
                    bin.count += 1;
                }
            }
            bins
        };
        if prims.len() > PARALLEL_BINNING {
            prims
                .par_chunks(PARALLEL_BINNING / 4)
                .map(|c| fill(Bins::empty(), c))
                .reduce(Bins::empty, |a, b| a.merge(&b))
        } else {
            fill(Bins::empty(), prims)
        }
    }

    /// Leaf (`None`) or the number of primitives moved to the front (left) of `prims`, for
    /// a node at `depth`.
    fn decide(&self, prims: &mut [u32], bounds: &Aabb, centroids: &Aabb, depth: u32) -> Option<usize> {
        let n = prims.len();
        if n <= 1 {
            return None;
        }
        let extent = centroids.extent();
        if depth >= MEDIAN_SPLIT_DEPTH {
            return self.leaf.must_split(n as u32).then(|| self.median_partition(prims, centroids.longest_axis()));
        }
        if extent.max_element() <= 0.0 {
            // All centroids coincide: no plane separates them; split by count if we must.
            return if self.leaf.must_split(n as u32) { Some(n / 2) } else { None };
        }
        let nb = self.bins.min(n.max(4));
        let scale = Vec3::select(extent.cmpgt(Vec3::ZERO), Vec3::splat(nb as f32) / extent, Vec3::ZERO);
        let binner = Binner { min: centroids.min, scale, bins: nb };
        let bins = self.bin_prims(prims, &binner);
        let mut best = (f32::INFINITY, 0usize, 0usize);
        for axis in 0..3 {
            if extent[axis] <= 0.0 {
                continue;
            }
            let axis_bins = &bins.0[axis][..nb];
            let mut right_cost = [0.0f32; MAX_BINS];
            let (mut acc, mut count) = (Aabb::EMPTY, 0u32);
            for b in (1..nb).rev() {
                acc = acc.union(axis_bins[b].bounds);
                count += axis_bins[b].count;
                right_cost[b] = acc.surface_area() * count as f32;
            }
            let (mut acc, mut count) = (Aabb::EMPTY, 0u32);
            for b in 1..nb {
                acc = acc.union(axis_bins[b - 1].bounds);
                count += axis_bins[b - 1].count;
                let cost = acc.surface_area() * count as f32 + right_cost[b];
                if count > 0 && (count as usize) < n && cost < best.0 {
                    best = (cost, axis, b);
                }
            }
        }
        if best.0 == f32::INFINITY {
            return if self.leaf.must_split(n as u32) { Some(n / 2) } else { None };
        }
        if !self.leaf.must_split(n as u32) && self.leaf.prefers_leaf(n as u32, bounds.surface_area(), best.0) {
            return None;
        }
        let (_, axis, split_bin) = best;
        // In-place partition (order within halves does not matter for the tree).
        let (mut i, mut j) = (0usize, n);
        while i < j {
            if binner.bin(self.centers[prims[i] as usize], axis) < split_bin {
                i += 1;
            } else {
                j -= 1;
                prims.swap(i, j);
            }
        }
        Some(i)
    }

    /// Moves the half of `prims` with the smaller centroids along `axis` to the front: the
    /// object median of [`MEDIAN_SPLIT_DEPTH`].
    fn median_partition(&self, prims: &mut [u32], axis: usize) -> usize {
        let k = prims.len() / 2;
        prims.select_nth_unstable_by(k, |&a, &b| {
            self.centers[a as usize][axis].total_cmp(&self.centers[b as usize][axis]).then(a.cmp(&b))
        });
        k
    }

    fn build(&self, prims: &mut [u32], depth: u32) -> Built {
        if prims.len() <= PARALLEL_GRAIN {
            let mut piece = Piece::new();
            self.build_piece(&mut piece, prims, depth);
            return Built::Piece(piece);
        }
        let (bounds, centroids) = self.bounds_and_centroids(prims);
        match self.decide(prims, &bounds, &centroids, depth) {
            None => {
                let mut piece = Piece::new();
                piece.set_leaf(0, bounds, prims.iter().copied());
                Built::Piece(piece)
            }
            Some(k) => {
                let (l, r) = prims.split_at_mut(k);
                let (left, right) = rayon::join(|| self.build(l, depth + 1), || self.build(r, depth + 1));
                Built::Split { bounds, children: vec![left, right] }
            }
        }
    }

    fn build_piece(&self, piece: &mut Piece, prims: &mut [u32], depth: u32) {
        let mut stack = vec![(prims, 0u32, depth)];
        while let Some((prims, slot, depth)) = stack.pop() {
            let (bounds, centroids) = self.bounds_and_centroids(prims);
            match self.decide(prims, &bounds, &centroids, depth) {
                None => piece.set_leaf(slot, bounds, prims.iter().copied()),
                Some(k) => {
                    let first = piece.alloc_children(2);
                    piece.set_interior(slot, bounds, first, 2);
                    let (l, r) = prims.split_at_mut(k);
                    stack.push((r, first + 1, depth + 1));
                    stack.push((l, first, depth + 1));
                }
            }
        }
    }
}
