//! Wide BVHs (4 or 8 children per node) traced one ray at a time with SIMD box tests (or, for
//! coherent rays of an 8-wide tree, 16 at a time: [`packet`]): the fast path for rendering,
//! made from any [`Bvh`] of this crate.
//!
//! # Why
//!
//! The binary traversal of [`crate::traverse`] tests two boxes per node visit, each with
//! scalar code, and pays a dependent load, a branch and a stack operation for every one of
//! them. On incoherent rays that is where the time goes. A node with `N` children stored
//! structure-of-arrays (`min_x[N], max_x[N], ..., max_z[N]`) lets one SIMD instruction
//! compute one slab plane for all `N` children, so a node visit costs about what one binary
//! box test did, and a tree with branching 4 or 8 has a half or a third of the depth. This is
//! the layout of Embree's `BVH4`/`BVH8` and tinybvh's `BVH4_CPU`/`BVH8_CPU`, written here from
//! the published descriptions (Wald et al. 2008, "Getting rid of packets"; Dammertz et al.
//! 2008, "Shallow bounding volume hierarchies for fast SIMD ray tracing of incoherent rays").
//!
//! # Pieces
//!
//! - [`WideNode`]: the node, `bounds[6][N]` (rows `min_x, max_x, min_y, max_y, min_z, max_z`)
//!   plus per child slot a reference and a primitive count (0 for interior children). Empty
//!   slots hold the inverted box `min = +inf, max = -inf`, which the ordered slab test below
//!   never hits, so the kernels need no per-lane validity mask.
//! - [`collapse`]: [`WideBvh::from_bvh`] turns a binary or k-ary tree into a wide one by the
//!   greedy rule of Embree's and tinybvh's converters: start from a node's children and
//!   repeatedly replace the interior child with the **largest surface area** by its children
//!   while they fit in `N` slots. (Not the SAH-optimal dynamic-programming collapse; the
//!   greedy one is linear-time and within a few per cent of it in the literature.) Nodes with
//!   more than two children (PHR's multi-BVHs) are first regrouped into binary subtrees by a
//!   small SAH sweep over their children, so every builder's tree can be collapsed. Subtrees
//!   of at most 4 primitives become one leaf ([`CollapseOptions`]); primitives are renumbered
//!   in leaf order ([`WideBvh::prim_indices`]) so that each leaf is one contiguous range
//!   starting at a multiple of 4, which lets [`PackedTriangles`] store a leaf's triangles as
//!   one 4-lane block.
//! - [`simd`]: the ray-versus-`N`-boxes kernels: scalar (any target), SSE (4 lanes; two halves
//!   for 8) and AVX2 (8 lanes), chosen by [`SimdLevel`] once per tree (runtime feature
//!   detection in [`SimdLevel::detect`]), not per ray.
//! - [`child_order`] (x86_64): the branch-free order of three or more hit children, a
//!   bitonic sorting network in one AVX2 register.
//! - `traverse`: the ordered stack traversal, the same algorithm as the binary reference:
//!   hit children sorted by entry distance, nearest visited first, the others pushed with
//!   their entry distance and skipped when popped if that distance exceeds the closest hit
//!   (with the same `ROBUST_SLAB` slack as the binary traversal). Any-hit stops at the first
//!   hit. [`WideBvh::closest_hit_interleaved`] walks several rays at once, one node or leaf
//!   visit of each in turn (the same visit as the single-ray loop): a single ray waits for
//!   each node before it knows the next, and interleaved rays fill that wait with each
//!   other's work, which pays most where the tree does not fit the cache (the dragon's 65 MB:
//!   1.7–1.8× the single ray's rate with 4 rays at once).
//! - [`packet`] (x86_64 with AVX-512): 16 coherent rays traced together through an 8-wide
//!   tree, one per lane, with the single-ray answers.
//! - [`PackedTriangles`]: triangles in leaf order with `v0, e1 = v1 - v0, e2 = v2 - v0`
//!   precomputed, structure-of-arrays in blocks of 4, tested 4 at a time by an SSE
//!   Möller–Trumbore that performs [`crate::triangle::intersect_triangle`]'s operations in
//!   the same order (no FMA), so `t`, `u`, `v` are bit-identical to the reference; a scalar
//!   path ([`crate::triangle::intersect_triangle_edges`]) serves other targets and tests.
//!   The primitive test stays pluggable: [`WideBvh::closest_hit_leaves`] takes any leaf
//!   closure (the renderer uses the packed test for triangles and its own for spheres), and
//!   [`WideBvh::closest_hit`] a per-primitive one like the binary traversal.
//!
//! # Exactness
//!
//! The slab test is the robust one of [`crate::aabb::Aabb::intersect`] (Ize 2013): per axis
//! `(plane - origin) * inv_dir` with [`crate::ray::safe_recip`]'d inverse directions, the far
//! distance (clipped to `tmax`) enlarged by `ROBUST_SLAB`. Instead of `min`/`max` of the two
//! plane distances, the near and far plane of each axis are picked once per ray from the sign
//! of the direction, which gives the same values for every non-empty box (rounding is
//! monotonic) and never hits the inverted empty box. The kernels use no FMA, so all three
//! levels compute the same bits. With the primitive tests' tie rule (equal `t`: lowest
//! primitive index), closest hits do not depend on the tree or the visit order; the tests in
//! `tests/wide.rs` compare every level and width with the binary traversal and brute force.
//!
//! # Speed
//!
//! Measured with `phr bench-rays` against the binary traversal and Embree on the same rays:
//! wide-8 beats wide-4 on every shared scene, so the renderer traces wide-8. The numbers,
//! and what was tried and did not pay, are in `docs/bench-rays/` (`bench-rays.md`, the latest
//! run, and `history.md`).

#[cfg(target_arch = "x86_64")]
pub mod child_order;
pub mod collapse;
pub mod interleave;
pub mod packet;
pub(crate) mod pieces;
mod refit;
pub mod simd;
mod traverse;
pub mod triangles;

pub use refit::RefitAreas;
pub use traverse::LeafVisitor;
pub use triangles::PackedTriangles;

pub use collapse::CollapseOptions;

use crate::node::Bvh;
use crate::ray::Ray;

/// The filler of [`WideBvh::prim_indices`] between leaves (see [`CollapseOptions::leaf_align`]).
pub const PAD: u32 = u32::MAX;

/// Which box-test kernel a [`WideBvh`] uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum SimdLevel {
    /// Plain Rust, one child after the other; every target.
    Scalar,
    /// 128-bit SSE (x86_64 baseline): 4 children per instruction.
    Sse,
    /// 256-bit AVX2: 8 children per instruction (4-wide trees use the SSE kernel).
    Avx2,
}

impl SimdLevel {
    /// The best level this CPU supports (detected once, then cached).
    pub fn detect() -> SimdLevel {
        use std::sync::OnceLock;
        static LEVEL: OnceLock<SimdLevel> = OnceLock::new();
        *LEVEL.get_or_init(|| {
            #[cfg(target_arch = "x86_64")]
            {
                if std::arch::is_x86_feature_detected!("avx2") {
                    return SimdLevel::Avx2;
                }
                SimdLevel::Sse
            }
            #[cfg(not(target_arch = "x86_64"))]
            {
                SimdLevel::Scalar
            }
        })
    }

    /// Every level this CPU supports, lowest first.
    pub fn supported() -> Vec<SimdLevel> {
        [SimdLevel::Scalar, SimdLevel::Sse, SimdLevel::Avx2].into_iter().filter(|l| *l <= Self::detect()).collect()
    }

    pub fn name(self) -> &'static str {
        match self {
            SimdLevel::Scalar => "scalar",
            SimdLevel::Sse => "sse",
            SimdLevel::Avx2 => "avx2",
        }
    }
}

/// One node of a [`WideBvh`]: `N` child slots, boxes structure-of-arrays.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct WideNode<const N: usize> {
    /// Rows [`MIN_X`], [`MAX_X`], [`MIN_Y`], [`MAX_Y`], [`MIN_Z`], [`MAX_Z`], one lane per
    /// child: row `2 * axis` holds the minima along `axis`, row `2 * axis + 1` the maxima.
    pub bounds: [[f32; N]; 6],
    /// Interior child: its node index. Leaf child: the first of its primitives in
    /// [`WideBvh::prim_indices`]. Empty slot: 0.
    pub child: [u32; N],
    /// Leaf child: its number of primitives (at least 1). Interior child and empty slot: 0.
    pub count: [u32; N],
}

pub const MIN_X: usize = 0;
pub const MAX_X: usize = 1;
pub const MIN_Y: usize = 2;
pub const MAX_Y: usize = 3;
pub const MIN_Z: usize = 4;
pub const MAX_Z: usize = 5;

impl<const N: usize> WideNode<N> {
    /// A node whose slots are all empty (inverted boxes that no ray hits).
    pub const EMPTY: Self = {
        let inf = [f32::INFINITY; N];
        let ninf = [f32::NEG_INFINITY; N];
        Self { bounds: [inf, ninf, inf, ninf, inf, ninf], child: [0; N], count: [0; N] }
    };

    /// The box of slot `i` (empty slots give the empty box).
    pub fn child_bounds(&self, i: usize) -> crate::Aabb {
        let b = &self.bounds;
        crate::Aabb::new(
            glam::Vec3::new(b[MIN_X][i], b[MIN_Y][i], b[MIN_Z][i]),
            glam::Vec3::new(b[MAX_X][i], b[MAX_Y][i], b[MAX_Z][i]),
        )
    }

    pub(crate) fn set_child_bounds(&mut self, i: usize, a: crate::Aabb) {
        let b = &mut self.bounds;
        (b[MIN_X][i], b[MIN_Y][i], b[MIN_Z][i]) = (a.min.x, a.min.y, a.min.z);
        (b[MAX_X][i], b[MAX_Y][i], b[MAX_Z][i]) = (a.max.x, a.max.y, a.max.z);
    }

    /// The union of its slots' boxes: each row reduced (empty slots hold +∞ minima and −∞
    /// maxima, so they drop out).
    pub fn bounds(&self) -> crate::Aabb {
        let min = |row: &[f32; N]| row.iter().fold(f32::INFINITY, |a, &b| a.min(b));
        let max = |row: &[f32; N]| row.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b));
        let b = &self.bounds;
        crate::Aabb::new(
            glam::Vec3::new(min(&b[MIN_X]), min(&b[MIN_Y]), min(&b[MIN_Z])),
            glam::Vec3::new(max(&b[MAX_X]), max(&b[MAX_Y]), max(&b[MAX_Z])),
        )
    }

    /// True if slot `i` holds a child (a non-empty box).
    pub fn is_used(&self, i: usize) -> bool {
        !self.child_bounds(i).is_empty()
    }
}

/// A wide BVH: `nodes[0]` is the root (unless the tree is empty); leaves are child slots.
#[derive(Clone, Debug)]
pub struct WideBvh<const N: usize> {
    pub nodes: Vec<WideNode<N>>,
    /// The caller's primitive indices in leaf order: a leaf child `(first, count)` holds
    /// `prim_indices[first..first + count]`. Between leaves there may be [`PAD`] entries.
    pub prim_indices: Vec<u32>,
    /// An upper bound of the traversal stack's depth (computed by the collapse).
    pub(crate) stack_bound: usize,
    simd: SimdLevel,
}

impl<const N: usize> Default for WideBvh<N> {
    fn default() -> Self {
        Self { nodes: Vec::new(), prim_indices: Vec::new(), stack_bound: 0, simd: SimdLevel::detect() }
    }
}

/// Per-ray work counters of the wide traversal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WideStats {
    /// Wide nodes visited (each one SIMD box test of all its children).
    pub nodes: u32,
    /// Leaves visited.
    pub leaves: u32,
    /// Primitives tested.
    pub prims: u32,
}

/// The widths with SIMD kernels: 4 and 8. (Sealed: implemented here only.)
pub trait Width<const N: usize>: traverse::sealed::Sealed<N> {}

/// Marker type carrying a width, so that [`WideBvh`]'s methods exist for `N = 4` and `N = 8`.
pub struct Lanes<const N: usize>;

impl<const N: usize> WideBvh<N>
where
    Lanes<N>: Width<N>,
{
    /// Collapses `bvh` (binary or k-ary, any builder) into a wide tree with the default
    /// [`CollapseOptions`] (leaves of up to 4 primitives); see [`collapse`]. Uses the best
    /// [`SimdLevel`] of this CPU.
    pub fn from_bvh(bvh: &Bvh) -> Self {
        Self::from_bvh_with(bvh, CollapseOptions::default())
    }

    /// [`WideBvh::from_bvh`] with explicit options.
    pub fn from_bvh_with(bvh: &Bvh, options: CollapseOptions) -> Self {
        let (nodes, prim_indices, stack_bound) = collapse::collapse::<N>(bvh, options, Vec::new(), Vec::new());
        Self { nodes, prim_indices, stack_bound, simd: SimdLevel::detect() }
    }

    /// Collapses `bvh` (default options) into this tree's memory: the per-frame update of a
    /// dynamic scene, without fresh allocations.
    pub fn rebuild(&mut self, bvh: &Bvh) {
        let nodes = std::mem::take(&mut self.nodes);
        let prims = std::mem::take(&mut self.prim_indices);
        let (nodes, prim_indices, stack_bound) = collapse::collapse::<N>(bvh, CollapseOptions::default(), nodes, prims);
        (self.nodes, self.prim_indices, self.stack_bound) = (nodes, prim_indices, stack_bound);
    }

    /// The bound of the traversal stack's depth the builder computed (along any root-to-node
    /// path, the sum of `children - 1`).
    pub fn stack_bound(&self) -> usize {
        self.stack_bound
    }

    /// The kernel in use.
    pub fn simd(&self) -> SimdLevel {
        self.simd
    }

    /// Chooses the kernel (for tests and benchmarks); a level the CPU lacks is lowered to the
    /// best one it has, so the SIMD code never runs on a CPU without the instructions.
    pub fn set_simd(&mut self, level: SimdLevel) {
        self.simd = level.min(SimdLevel::detect());
    }

    /// [`WideBvh::set_simd`] by value.
    pub fn with_simd(mut self, level: SimdLevel) -> Self {
        self.set_simd(level);
        self
    }

    /// Primitives referenced (without padding).
    pub fn prim_count(&self) -> usize {
        self.prim_indices.iter().filter(|&&p| p != PAD).count()
    }

    /// Closest hit, the primitive test called per leaf: `leaf(first, count, ray)` must test
    /// the primitives `prim_indices[first..first + count]` and, on hits, shrink `ray.tmax`;
    /// it returns whether it did. Returns true if any primitive was hit.
    #[inline]
    pub fn closest_hit_leaves(&self, ray: &mut Ray, leaf: impl FnMut(u32, u32, &mut Ray) -> bool) -> bool {
        let mut stats = WideStats::default();
        <Lanes<N> as traverse::sealed::Sealed<N>>::run::<false, false, _>(
            self,
            ray,
            &mut traverse::FnLeaves(leaf, |_| {}),
            &mut stats,
        )
    }

    /// [`WideBvh::closest_hit_leaves`] with a prefetch hint: `prefetch(first)` is called when
    /// a leaf is pushed on the stack (to be tested later), so the caller can ask for its
    /// primitive data to be loaded meanwhile.
    #[inline]
    pub fn closest_hit_leaves_prefetch(
        &self,
        ray: &mut Ray,
        prefetch: impl Fn(u32),
        leaf: impl FnMut(u32, u32, &mut Ray) -> bool,
    ) -> bool {
        let mut stats = WideStats::default();
        <Lanes<N> as traverse::sealed::Sealed<N>>::run::<false, false, _>(
            self,
            ray,
            &mut traverse::FnLeaves(leaf, prefetch),
            &mut stats,
        )
    }

    /// [`WideBvh::closest_hit_leaves`], also counting nodes, leaves and primitives.
    #[inline]
    pub fn closest_hit_leaves_counted(
        &self,
        ray: &mut Ray,
        leaf: impl FnMut(u32, u32, &mut Ray) -> bool,
        stats: &mut WideStats,
    ) -> bool {
        <Lanes<N> as traverse::sealed::Sealed<N>>::run::<false, true, _>(
            self,
            ray,
            &mut traverse::FnLeaves(leaf, |_| {}),
            stats,
        )
    }

    /// Closest hit with a per-primitive test, like [`crate::traverse::closest_hit`]:
    /// `intersect(prim, ray)` gets the caller's primitive index.
    #[inline]
    pub fn closest_hit(&self, ray: &mut Ray, mut intersect: impl FnMut(u32, &mut Ray) -> bool) -> bool {
        let prims = &self.prim_indices;
        self.closest_hit_leaves(ray, |first, count, r| {
            let mut hit = false;
            for &p in &prims[first as usize..(first + count) as usize] {
                hit |= intersect(p, r);
            }
            hit
        })
    }

    /// Any hit (shadow rays), per leaf: stops at the first leaf for which `leaf` returns true.
    #[inline]
    pub fn any_hit_leaves(&self, ray: &Ray, mut leaf: impl FnMut(u32, u32, &Ray) -> bool) -> bool {
        let mut r = *ray;
        let mut stats = WideStats::default();
        <Lanes<N> as traverse::sealed::Sealed<N>>::run::<true, false, _>(
            self,
            &mut r,
            &mut traverse::FnLeaves(|first, count, r: &mut Ray| leaf(first, count, r), |_| {}),
            &mut stats,
        )
    }

    /// Closest hit with a [`LeafVisitor`] (the leaf test compiled into the loop; see there).
    /// Returns true if any primitive was hit.
    #[inline]
    pub fn closest_hit_visit(&self, ray: &mut Ray, leaves: &mut impl LeafVisitor) -> bool {
        let mut stats = WideStats::default();
        <Lanes<N> as traverse::sealed::Sealed<N>>::run::<false, false, _>(self, ray, leaves, &mut stats)
    }

    /// Closest hits of `count` rays with `M` of them traversed at once, interleaved: each
    /// round visits one node or leaf of every ray in flight, so that one ray's dependent node
    /// loads overlap the others' work, and a finished ray's place goes to the next.
    /// `start(i)` gives ray `i` and its leaf visitor; `finish(i, ray, visitor, hit)` returns
    /// them when its traversal ends (`hit`: a visit reported a hit), in any order. Each ray
    /// gets exactly what [`WideBvh::closest_hit_visit`] would give it.
    #[inline]
    pub fn closest_hit_interleaved<const M: usize, V: LeafVisitor>(
        &self,
        count: usize,
        start: impl FnMut(usize) -> (Ray, V),
        finish: impl FnMut(usize, Ray, V, bool),
    ) {
        <Lanes<N> as traverse::sealed::Sealed<N>>::run_interleaved::<M, false, V>(self, count, start, finish)
    }

    /// Any-hit queries of `count` rays, `M` of them traversed at once: as
    /// [`WideBvh::closest_hit_interleaved`], each walk stopping at the first leaf whose visit
    /// returns true (`hit` in `finish`), as [`WideBvh::any_hit_visit`] does.
    #[inline]
    pub fn any_hit_interleaved<const M: usize, V: LeafVisitor>(
        &self,
        count: usize,
        start: impl FnMut(usize) -> (Ray, V),
        finish: impl FnMut(usize, Ray, V, bool),
    ) {
        <Lanes<N> as traverse::sealed::Sealed<N>>::run_interleaved::<M, true, V>(self, count, start, finish)
    }

    /// [`WideBvh::closest_hit_interleaved`] with as many rays in flight as the traced data
    /// calls for: `traced_bytes` (this tree's nodes and its primitive data, e.g.
    /// [`WideBvh::traced_bytes`]) against the last-level cache ([`interleave`]).
    #[inline]
    pub fn closest_hit_batch<V: LeafVisitor>(
        &self,
        traced_bytes: usize,
        count: usize,
        start: impl FnMut(usize) -> (Ray, V),
        finish: impl FnMut(usize, Ray, V, bool),
    ) {
        self.batch::<false, V>(traced_bytes, count, start, finish)
    }

    /// [`WideBvh::any_hit_interleaved`] with as many rays in flight as
    /// [`WideBvh::closest_hit_batch`] takes.
    #[inline]
    pub fn any_hit_batch<V: LeafVisitor>(
        &self,
        traced_bytes: usize,
        count: usize,
        start: impl FnMut(usize) -> (Ray, V),
        finish: impl FnMut(usize, Ray, V, bool),
    ) {
        self.batch::<true, V>(traced_bytes, count, start, finish)
    }

    /// The one place the rays-in-flight rule of [`interleave`] is applied.
    #[inline(always)]
    fn batch<const ANY: bool, V: LeafVisitor>(
        &self,
        traced_bytes: usize,
        count: usize,
        start: impl FnMut(usize) -> (Ray, V),
        finish: impl FnMut(usize, Ray, V, bool),
    ) {
        if interleave::fits_cache(traced_bytes) {
            <Lanes<N> as traverse::sealed::Sealed<N>>::run_interleaved::<{ interleave::FROM_CACHE }, ANY, V>(
                self, count, start, finish,
            )
        } else {
            <Lanes<N> as traverse::sealed::Sealed<N>>::run_interleaved::<{ interleave::FROM_MEMORY }, ANY, V>(
                self, count, start, finish,
            )
        }
    }

    /// Any hit with a [`LeafVisitor`]: stops at the first leaf whose visit returns true.
    #[inline]
    pub fn any_hit_visit(&self, ray: &Ray, leaves: &mut impl LeafVisitor) -> bool {
        let mut r = *ray;
        let mut stats = WideStats::default();
        <Lanes<N> as traverse::sealed::Sealed<N>>::run::<true, false, _>(self, &mut r, leaves, &mut stats)
    }

    /// Any hit with a per-primitive test, like [`crate::traverse::any_hit`].
    #[inline]
    pub fn any_hit(&self, ray: &Ray, mut intersect: impl FnMut(u32, &Ray) -> bool) -> bool {
        let prims = &self.prim_indices;
        self.any_hit_leaves(ray, |first, count, r| {
            prims[first as usize..(first + count) as usize].iter().any(|&p| intersect(p, r))
        })
    }
}

impl<const N: usize> WideBvh<N> {
    /// Checks the structure: every node reachable once, every primitive of `0..prim_count`
    /// in exactly one leaf, every interior slot's box enclosing its child's slots, leaf ranges
    /// in bounds, empty slots empty, and the stack bound large enough. `boxes` (the
    /// primitives' boxes, by the caller's index) are checked to lie inside their leaf's box.
    pub fn validate(&self, boxes: &[crate::Aabb]) -> Result<(), String> {
        self.check(boxes, false)
    }

    /// [`WideBvh::validate`] for a tree collapsed from one with spatial splits
    /// ([`crate::validate::validate_split`]): a primitive may be in several leaves (not
    /// twice in one), and a leaf's box need only meet its primitives' boxes.
    pub fn validate_split(&self, boxes: &[crate::Aabb]) -> Result<(), String> {
        self.check(boxes, true)
    }

    fn check(&self, boxes: &[crate::Aabb], split: bool) -> Result<(), String> {
        if self.nodes.is_empty() {
            return if boxes.is_empty() { Ok(()) } else { Err(format!("{} primitives but no nodes", boxes.len())) };
        }
        let refs = self.prim_indices.iter().filter(|&&p| p != PAD).count();
        if if split { refs < boxes.len() } else { refs != boxes.len() } {
            return Err(format!("{refs} primitive references for {} primitives", boxes.len()));
        }
        let mut seen_node = vec![false; self.nodes.len()];
        let mut seen_ref = vec![false; self.prim_indices.len()];
        let mut seen_prim = vec![false; boxes.len()];
        // (node, pushes on the path so far)
        let mut stack = vec![(0usize, 0usize)];
        while let Some((i, depth)) = stack.pop() {
            if std::mem::replace(&mut seen_node[i], true) {
                return Err(format!("node {i} reached twice"));
            }
            let node = &self.nodes[i];
            let used = (0..N).filter(|&s| node.is_used(s)).count();
            if used == 0 {
                return Err(format!("node {i} has no children"));
            }
            let depth = depth + used - 1;
            if depth > self.stack_bound {
                return Err(format!("node {i}: stack depth {depth} above the bound {}", self.stack_bound));
            }
            for s in 0..N {
                let b = node.child_bounds(s);
                if b.is_empty() {
                    if node.count[s] != 0 || node.child[s] != 0 {
                        return Err(format!("node {i} slot {s}: empty box but a child"));
                    }
                    continue;
                }
                if node.count[s] == 0 {
                    let c = node.child[s] as usize;
                    if c <= i || c >= self.nodes.len() {
                        return Err(format!("node {i} slot {s}: child {c} invalid"));
                    }
                    let cn = &self.nodes[c];
                    for t in 0..N {
                        if !b.contains(&cn.child_bounds(t)) {
                            return Err(format!("node {i} slot {s} does not enclose slot {t} of node {c}"));
                        }
                    }
                    stack.push((c, depth));
                } else {
                    let (first, count) = (node.child[s] as usize, node.count[s] as usize);
                    let refs = first..first + count;
                    if refs.end > self.prim_indices.len() {
                        return Err(format!("node {i} slot {s}: leaf range {refs:?} out of bounds"));
                    }
                    for r in refs {
                        if std::mem::replace(&mut seen_ref[r], true) {
                            return Err(format!("primitive reference {r} in two leaves"));
                        }
                        let p = self.prim_indices[r];
                        if p == PAD {
                            return Err(format!("node {i} slot {s}: padding inside a leaf"));
                        }
                        if split && self.prim_indices[first..r].contains(&p) {
                            return Err(format!("node {i} slot {s} holds primitive {p} twice"));
                        }
                        let p = p as usize;
                        let seen = seen_prim.get_mut(p).ok_or(format!("primitive {p} out of range"))?;
                        if std::mem::replace(seen, true) && !split {
                            return Err(format!("primitive {p} in more than one leaf"));
                        }
                        if split && !boxes[p].is_empty() && b.overlap(boxes[p]).is_empty() {
                            return Err(format!("node {i} slot {s} does not meet primitive {p}"));
                        }
                        if !split && !b.contains(&boxes[p]) {
                            return Err(format!("node {i} slot {s} does not enclose primitive {p}"));
                        }
                    }
                }
            }
        }
        if let Some(p) = seen_prim.iter().position(|s| !s) {
            return Err(format!("primitive {p} in no leaf"));
        }
        if let Some(n) = seen_node.iter().position(|s| !s) {
            return Err(format!("node {n} unreachable"));
        }
        Ok(())
    }

    /// Number of leaves (leaf child slots).
    pub fn leaf_count(&self) -> usize {
        self.nodes.iter().map(|n| n.count.iter().filter(|&&c| c > 0).count()).sum()
    }

    /// Mean number of used slots per node.
    pub fn mean_fill(&self) -> f64 {
        let used: usize = self.nodes.iter().map(|n| (0..N).filter(|&s| n.is_used(s)).count()).sum();
        used as f64 / self.nodes.len().max(1) as f64
    }
}
