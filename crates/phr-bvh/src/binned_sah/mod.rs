//! Binned SAH builder (Wald 2007; what Embree, pbrt-v4 and tinybvh use by default): at every
//! node the centroids are sorted into a fixed number of bins per axis and only the bin
//! boundaries are evaluated. Much faster than the full sweep, slightly worse trees.
//!
//! Laid out as Embree's builders are: the primitives travel as 32-byte references (box and
//! index in two SIMD vectors, `PrimRef`) that are binned and partitioned in place, so every
//! pass reads memory in order instead of through an index array; a node's box and centroid
//! box are gathered while its parent partitions, not in a pass of their own; the three axes
//! are binned at once, one SIMD vector per reference. Binning is parallel at the top levels,
//! where nodes are large, and subtrees below `PARALLEL_GRAIN` are built by one task each.

use crate::aabb::Aabb;
use crate::node::Bvh;
use crate::sah::{LeafPolicy, MEDIAN_SPLIT_DEPTH};
use crate::topdown::{assemble, Built, Piece};
use glam::{Vec3, Vec4};
use rayon::prelude::*;

mod wide;
pub use wide::build_binned_sah_wide;

/// Above this many primitives a node's children are built as separate rayon tasks.
const PARALLEL_GRAIN: usize = 1 << 12;
/// Above this many primitives a node's binning itself runs in parallel.
const PARALLEL_BINNING: usize = 1 << 16;
pub const MAX_BINS: usize = 32;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BinnedSahOptions {
    /// Bins per axis at most (2 to 32; 16 to 32 is the usual choice). A node of `n`
    /// primitives uses `4 + n / 20` bins if that is fewer, Embree's rule: small nodes bin
    /// and sweep far less for nearly the same trees (dragon: 13 % faster, SAH cost +0.5 %;
    /// Sponza −1.2 %, Conference +0.5 %; it was one bin per primitive below 32).
    pub bins: usize,
    pub leaf: LeafPolicy,
}

impl Default for BinnedSahOptions {
    fn default() -> Self {
        Self { bins: 32, leaf: LeafPolicy::default() }
    }
}

/// A primitive's box with its index in the `w` lane of `lo`, as the bits of a normal float
/// (`INDEX_TAG | index`: the SIMD arithmetic on the unused lane never meets a denormal,
/// which some CPUs handle in slow microcode).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
struct PrimRef {
    lo: Vec4,
    hi: Vec4,
}

/// Sets the exponent bits of the `w` lane: for indices below [`MAX_PRIMS`] it is a normal
/// float (or infinity or NaN, which are as fast).
const INDEX_TAG: u32 = 0x4000_0000;
/// The builder's limit: indices must fit below the tag bit.
pub const MAX_PRIMS: usize = 1 << 30;

impl PrimRef {
    fn new(i: usize, b: &Aabb) -> Self {
        PrimRef { lo: b.min.extend(f32::from_bits(INDEX_TAG | i as u32)), hi: b.max.extend(1.0) }
    }

    #[inline(always)]
    fn index(&self) -> u32 {
        self.lo.w.to_bits() & !INDEX_TAG
    }

    /// Twice the box's centre (the `w` lane is meaningless).
    #[inline(always)]
    fn centre2(&self) -> Vec4 {
        self.lo + self.hi
    }
}

/// A box and a centroid box, accumulated as SIMD vectors (`w` lanes meaningless).
#[derive(Clone, Copy)]
struct Bounds {
    lo: Vec4,
    hi: Vec4,
    /// Twice the smallest and largest centre.
    c_lo: Vec4,
    c_hi: Vec4,
}

impl Bounds {
    const EMPTY: Bounds =
        Bounds { lo: Vec4::INFINITY, hi: Vec4::NEG_INFINITY, c_lo: Vec4::INFINITY, c_hi: Vec4::NEG_INFINITY };

    #[inline(always)]
    fn add(&mut self, r: &PrimRef) {
        let c = r.centre2();
        self.lo = self.lo.min(r.lo);
        self.hi = self.hi.max(r.hi);
        self.c_lo = self.c_lo.min(c);
        self.c_hi = self.c_hi.max(c);
    }

    /// Adds `r` if `yes`, without a branch. (Each bound's `min` or `max`, then a select of it
    /// or the old bound: one masked instruction each where AVX-512 is compiled in.)
    #[inline(always)]
    fn add_if(&mut self, r: &PrimRef, yes: bool) {
        let mask = glam::BVec4A::splat(yes);
        let c = r.centre2();
        self.lo = Vec4::select(mask, self.lo.min(r.lo), self.lo);
        self.hi = Vec4::select(mask, self.hi.max(r.hi), self.hi);
        self.c_lo = Vec4::select(mask, self.c_lo.min(c), self.c_lo);
        self.c_hi = Vec4::select(mask, self.c_hi.max(c), self.c_hi);
    }

    fn merge(mut self, o: Bounds) -> Bounds {
        self.lo = self.lo.min(o.lo);
        self.hi = self.hi.max(o.hi);
        self.c_lo = self.c_lo.min(o.c_lo);
        self.c_hi = self.c_hi.max(o.c_hi);
        self
    }

    fn of(refs: &[PrimRef]) -> Bounds {
        let fold = |chunk: &[PrimRef]| {
            let mut b = Bounds::EMPTY;
            chunk.iter().for_each(|r| b.add(r));
            b
        };
        if refs.len() > PARALLEL_BINNING {
            refs.par_chunks(PARALLEL_BINNING / 4).map(fold).reduce(|| Bounds::EMPTY, Bounds::merge)
        } else {
            fold(refs)
        }
    }

    fn aabb(&self) -> Aabb {
        Aabb::new(self.lo.truncate(), self.hi.truncate())
    }

    /// Extent of the doubled centres.
    fn centre_extent(&self) -> Vec3 {
        (self.c_hi - self.c_lo).truncate()
    }
}

/// One bin: the box of the primitives whose centre falls in it, and their number.
#[derive(Clone, Copy)]
struct Bin {
    lo: Vec4,
    hi: Vec4,
    count: u32,
}

impl Bin {
    const EMPTY: Bin = Bin { lo: Vec4::INFINITY, hi: Vec4::NEG_INFINITY, count: 0 };

    #[inline(always)]
    fn add(&mut self, r: &PrimRef) {
        self.lo = self.lo.min(r.lo);
        self.hi = self.hi.max(r.hi);
        self.count += 1;
    }

    /// Surface area of a non-empty box (no emptiness test: the sweep only asks for sides
    /// that hold primitives).
    #[inline(always)]
    fn area(lo: Vec4, hi: Vec4) -> f32 {
        let e = hi - lo;
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }
}

/// Per-axis bins of one node.
#[derive(Clone)]
struct Bins([[Bin; MAX_BINS]; 3]);

impl Bins {
    fn boxed() -> Box<Bins> {
        Box::new(Bins([[Bin::EMPTY; MAX_BINS]; 3]))
    }

    fn merge(&mut self, o: &Bins) {
        for (mine, theirs) in self.0.iter_mut().flatten().zip(o.0.iter().flatten()) {
            mine.lo = mine.lo.min(theirs.lo);
            mine.hi = mine.hi.max(theirs.hi);
            mine.count += theirs.count;
        }
    }
}

/// Maps a doubled centre to its bin on each axis at once.
#[derive(Clone, Copy)]
struct Binner {
    origin: Vec4,
    scale: Vec4,
    /// The last bin, as a float.
    last: f32,
}

impl Binner {
    #[inline(always)]
    fn bins(&self, r: &PrimRef) -> [usize; 3] {
        // Clamped as floats (the `w` lane may be anything), then truncated in one
        // instruction: glam's `as_ivec4` casts lane by lane with saturation checks, which
        // took 15 % of the build.
        let v = ((r.centre2() - self.origin) * self.scale).max(Vec4::ZERO).min(Vec4::splat(self.last));
        #[cfg(target_arch = "x86_64")]
        let b: [i32; 4] = {
            use std::arch::x86_64::{__m128, _mm_cvttps_epi32};
            // SAFETY: SSE2 is part of x86_64; the conversion reads and writes registers only.
            unsafe { std::mem::transmute(_mm_cvttps_epi32(__m128::from(v))) }
        };
        #[cfg(not(target_arch = "x86_64"))]
        let b = [v.x as i32, v.y as i32, v.z as i32, 0];
        [b[0] as usize, b[1] as usize, b[2] as usize]
    }

    /// Bins `refs` into the first `nb` bins of each axis of `bins` (reset first). Large
    /// nodes bin in parallel chunks, merged in order.
    #[inline(always)]
    fn fill(&self, refs: &[PrimRef], nb: usize, bins: &mut Bins) {
        let fill = |chunk: &[PrimRef], bins: &mut Bins| {
            for axis in &mut bins.0 {
                axis[..nb].fill(Bin::EMPTY);
            }
            for r in chunk {
                let [x, y, z] = self.bins(r);
                bins.0[0][x].add(r);
                bins.0[1][y].add(r);
                bins.0[2][z].add(r);
            }
        };
        if refs.len() > PARALLEL_BINNING {
            let empty = Bins::boxed;
            let merged = refs
                .par_chunks(PARALLEL_BINNING / 4)
                .map(|chunk| {
                    let mut b = empty();
                    fill(chunk, &mut b);
                    b
                })
                .reduce(empty, |mut a, b| {
                    a.merge(&b);
                    a
                });
            *bins = *merged;
        } else {
            fill(refs, bins);
        }
    }
}

struct Ctx {
    bins: usize,
    leaf: LeafPolicy,
    /// Whether [`Ctx::decide`] runs its AVX2 compilation (the same arithmetic, so the same
    /// tree; the test below builds with both).
    avx2: bool,
    /// Whether it runs its AVX-512 compilation instead (masked `min` and `max` in the
    /// partition; the same tree again).
    avx512: bool,
}

impl Ctx {
    fn new(options: &BinnedSahOptions) -> Ctx {
        Ctx {
            bins: options.bins.clamp(2, MAX_BINS),
            leaf: options.leaf,
            avx2: crate::wide::SimdLevel::detect() == crate::wide::SimdLevel::Avx2,
            avx512: has_avx512(),
        }
    }
}

pub fn build_binned_sah(boxes: &[Aabb], options: &BinnedSahOptions) -> Bvh {
    if boxes.is_empty() {
        return Bvh::default();
    }
    assert!(boxes.len() < MAX_PRIMS, "the binned SAH builder takes fewer than 2^30 primitives");
    let mut refs: Vec<PrimRef> = boxes.par_iter().enumerate().map(|(i, b)| PrimRef::new(i, b)).collect();
    let ctx = Ctx::new(options);
    let bounds = Bounds::of(&refs);
    assemble(ctx.build(&mut refs, bounds, 0))
}

/// Whether the CPU has AVX-512 F and VL.
fn has_avx512() -> bool {
    #[cfg(target_arch = "x86_64")]
    return std::arch::is_x86_feature_detected!("avx512f") && std::arch::is_x86_feature_detected!("avx512vl");
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// A node's decision: a leaf, or the number of references moved to the front (left) with
/// the two sides' bounds.
enum Decision {
    Leaf,
    Split(usize, Bounds, Bounds),
}

impl Ctx {
    /// Bins `refs`, picks the cheapest plane and partitions them: compiled for AVX-512 (F and
    /// VL: masked `min`/`max` for the sides' bounds in the partition) or AVX2 (blends instead
    /// of and/or masks, three-operand forms) where the CPU has it.
    fn decide(&self, refs: &mut [PrimRef], bounds: &Bounds, depth: u32, bins: &mut Bins) -> Decision {
        #[cfg(target_arch = "x86_64")]
        if self.avx512 {
            // SAFETY: the CPU has AVX-512 F and VL (checked by `Ctx::new`).
            return unsafe { self.decide_avx512(refs, bounds, depth, bins) };
        }
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: the CPU has AVX2 (checked by `Ctx::new`).
            return unsafe { self.decide_avx2(refs, bounds, depth, bins) };
        }
        self.decide_inline(refs, bounds, depth, bins)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn decide_avx2(&self, refs: &mut [PrimRef], bounds: &Bounds, depth: u32, bins: &mut Bins) -> Decision {
        self.decide_inline(refs, bounds, depth, bins)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,avx512f,avx512vl")]
    fn decide_avx512(&self, refs: &mut [PrimRef], bounds: &Bounds, depth: u32, bins: &mut Bins) -> Decision {
        self.decide_inline(refs, bounds, depth, bins)
    }

    #[inline(always)]
    fn decide_inline(&self, refs: &mut [PrimRef], bounds: &Bounds, depth: u32, bins: &mut Bins) -> Decision {
        let n = refs.len();
        if n <= 1 {
            return Decision::Leaf;
        }
        let extent = bounds.centre_extent();
        if depth >= MEDIAN_SPLIT_DEPTH || extent.max_element() <= 0.0 {
            // Past the depth cap, or all centroids coincide (no plane separates them): split
            // by count if we must.
            return if self.leaf.must_split(n as u32) { self.median_split(refs, extent) } else { Decision::Leaf };
        }
        let nb = self.bins.min(4 + n / 20);
        let scale = Vec3::select(extent.cmpgt(Vec3::ZERO), Vec3::splat(nb as f32) / extent, Vec3::ZERO);
        let binner = Binner { origin: bounds.c_lo, scale: scale.extend(0.0), last: (nb - 1) as f32 };
        binner.fill(refs, nb, bins);
        let mut best = (f32::INFINITY, 0usize, 0usize);
        for axis in 0..3 {
            if extent[axis] <= 0.0 {
                continue;
            }
            let axis_bins = &bins.0[axis][..nb];
            let mut right_cost = [0.0f32; MAX_BINS];
            let (mut lo, mut hi, mut count) = (Vec4::INFINITY, Vec4::NEG_INFINITY, 0u32);
            for b in (1..nb).rev() {
                (lo, hi, count) = (lo.min(axis_bins[b].lo), hi.max(axis_bins[b].hi), count + axis_bins[b].count);
                right_cost[b] = Bin::area(lo, hi) * count as f32;
            }
            let (mut lo, mut hi, mut count) = (Vec4::INFINITY, Vec4::NEG_INFINITY, 0u32);
            for b in 1..nb {
                let l = &axis_bins[b - 1];
                (lo, hi, count) = (lo.min(l.lo), hi.max(l.hi), count + l.count);
                let cost = Bin::area(lo, hi) * count as f32 + right_cost[b];
                if count > 0 && (count as usize) < n && cost < best.0 {
                    best = (cost, axis, b);
                }
            }
        }
        if best.0 == f32::INFINITY {
            return if self.leaf.must_split(n as u32) { self.median_split(refs, extent) } else { Decision::Leaf };
        }
        if !self.leaf.must_split(n as u32) && self.leaf.prefers_leaf(n as u32, bounds.aabb().surface_area(), best.0) {
            return Decision::Leaf;
        }
        let (_, axis, split_bin) = best;
        partition(refs, |r| binner.bins(r)[axis] < split_bin)
    }

    /// The object median along the axis of largest centroid extent (ties by index).
    fn median_split(&self, refs: &mut [PrimRef], extent: Vec3) -> Decision {
        let axis = Aabb::new(Vec3::ZERO, extent).longest_axis();
        let k = refs.len() / 2;
        refs.select_nth_unstable_by(k, |a, b| {
            a.centre2()[axis].total_cmp(&b.centre2()[axis]).then(a.index().cmp(&b.index()))
        });
        let (l, r) = refs.split_at(k);
        Decision::Split(k, Bounds::of(l), Bounds::of(r))
    }

    fn build(&self, refs: &mut [PrimRef], bounds: Bounds, depth: u32) -> Built {
        if refs.len() <= PARALLEL_GRAIN {
            let mut piece = Piece::new();
            self.build_piece(&mut piece, refs, bounds, depth);
            return Built::Piece(piece);
        }
        let mut bins = Bins::boxed();
        match self.decide(refs, &bounds, depth, &mut bins) {
            Decision::Leaf => {
                let mut piece = Piece::new();
                piece.set_leaf(0, bounds.aabb(), refs.iter().map(PrimRef::index));
                Built::Piece(piece)
            }
            Decision::Split(k, lb, rb) => {
                let (l, r) = refs.split_at_mut(k);
                let (left, right) = rayon::join(|| self.build(l, lb, depth + 1), || self.build(r, rb, depth + 1));
                Built::Split { bounds: bounds.aabb(), children: vec![left, right] }
            }
        }
    }

    fn build_piece(&self, piece: &mut Piece, refs: &mut [PrimRef], bounds: Bounds, depth: u32) {
        let mut bins = Bins::boxed();
        let mut stack = vec![(refs, bounds, 0u32, depth)];
        while let Some((refs, bounds, slot, depth)) = stack.pop() {
            match self.decide(refs, &bounds, depth, &mut bins) {
                Decision::Leaf => piece.set_leaf(slot, bounds.aabb(), refs.iter().map(PrimRef::index)),
                Decision::Split(k, lb, rb) => {
                    let first = piece.alloc_children(2);
                    piece.set_interior(slot, bounds.aabb(), first, 2);
                    let (l, r) = refs.split_at_mut(k);
                    stack.push((r, rb, first + 1, depth + 1));
                    stack.push((l, lb, first, depth + 1));
                }
            }
        }
    }
}

/// Moves the references for which `left` holds to the front, in place (order within the
/// sides does not matter for the tree), gathering both sides' bounds on the way.
///
/// Branch-free (Lomuto's scheme with the swap always made): the sides of consecutive
/// references are close to random, and the branchy two-pointer scan mispredicted on most
/// of them; it was 28 % of the dragon's build.
#[inline(always)]
fn partition(refs: &mut [PrimRef], left: impl Fn(&PrimRef) -> bool) -> Decision {
    let (mut lb, mut rb) = (Bounds::EMPTY, Bounds::EMPTY);
    let mut k = 0usize;
    for i in 0..refs.len() {
        let r = refs[i];
        let is_left = left(&r);
        // A swap of whole references: the next step often reads back `refs[k]`, and a
        // 32-byte load of what two 16-byte stores wrote (`refs[k] = r` from the two halves'
        // registers) cannot be forwarded from the store buffer.
        refs.swap(i, k);
        k += is_left as usize;
        lb.add_if(&r, is_left);
        rb.add_if(&r, !is_left);
    }
    Decision::Split(k, lb, rb)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The AVX2 and AVX-512 compilations of the builder's hot loop make the portable one's
    /// tree, node for node (on a CPU without them those builds take the portable path).
    #[test]
    fn simd_and_portable_builds_make_the_same_tree() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let boxes: Vec<Aabb> = (0..20_000)
            .map(|_| {
                let c = Vec3::new(next(), next(), next()) * 100.0;
                let e = Vec3::new(next(), next(), next()) * 2.0;
                Aabb::new(c - e, c + e)
            })
            .collect();
        let build = |avx2: bool, avx512: bool| {
            let mut refs: Vec<PrimRef> = boxes.iter().enumerate().map(|(i, b)| PrimRef::new(i, b)).collect();
            let ctx = Ctx {
                avx2: avx2 && Ctx::new(&BinnedSahOptions::default()).avx2,
                avx512: avx512 && has_avx512(),
                ..Ctx::new(&BinnedSahOptions::default())
            };
            let bounds = Bounds::of(&refs);
            assemble(ctx.build(&mut refs, bounds, 0))
        };
        let portable = build(false, false);
        for fast in [build(true, false), build(false, true)] {
            assert_eq!(portable.nodes, fast.nodes);
            assert_eq!(portable.prim_indices, fast.prim_indices);
        }
    }
}
