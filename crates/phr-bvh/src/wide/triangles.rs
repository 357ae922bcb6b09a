//! Triangles laid out for intersection: in the leaf order of a [`super::WideBvh`], with the
//! edges precomputed, in blocks of 4 (structure of arrays) tested 4 at a time.

use super::{Lanes, LeafVisitor, SimdLevel, WideBvh, Width};
use crate::aabb::Aabb;
use crate::ray::Ray;
use crate::triangle::{intersect_triangle_edges, TriangleHit, EDGE_TOLERANCE, MAX_EDGE_SLACK};
use glam::Vec3;
use std::ops::Range;
use std::sync::atomic::{AtomicU32, Ordering};

/// Triangles per block (one SSE register per coordinate).
pub const LANES: usize = 4;

/// 4 triangles: rows `v0.x, v0.y, v0.z, e1.x, e1.y, e1.z, e2.x, e2.y, e2.z`, one lane each.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(16))]
pub struct TriangleBlock {
    pub rows: [[f32; LANES]; 9],
}

/// `[v0, e1 = v1 - v0, e2 = v2 - v0]` per entry of a wide tree's `prim_indices`, 4 entries
/// per [`TriangleBlock`]. A leaf of up to 4 triangles lies within one block (the builders place
/// it so), so it is one block: 144 bytes, read with 9 aligned loads and tested
/// with one 4-lane Möller–Trumbore, instead of up to 4 dependent scalar tests through an
/// index indirection.
///
/// The edges are computed as [`crate::triangle::intersect_triangle`] computes them and the
/// 4-lane test performs the scalar test's operations in the same order (no FMA), so
/// `t`, `u` and `v` are bit-identical to the scalar test; the tests check it.
///
/// Entries that are not triangles (padding, and the renderer's spheres, numbered after its
/// triangles) are zero, which no ray hits (zero determinant); callers test spheres their own
/// way.
#[derive(Clone, Debug, Default)]
pub struct PackedTriangles {
    pub blocks: Vec<TriangleBlock>,
    simd: Option<SimdLevel>,
}

impl PackedTriangles {
    /// Packs `triangles` (by the caller's primitive index) in the order of `prim_indices`;
    /// indices `>= triangles.len()` (padding, non-triangles) get a never-hit entry.
    pub fn new(prim_indices: &[u32], triangles: &[[Vec3; 3]]) -> Self {
        let mut packed = Self { blocks: Vec::new(), simd: None };
        packed.repack(prim_indices, triangles);
        packed
    }

    /// Packs again (the triangles moved, or the tree changed) into the same memory.
    pub fn repack(&mut self, prim_indices: &[u32], triangles: &[[Vec3; 3]]) {
        use rayon::prelude::*;
        // Detected once here, not per leaf: the detection is a call through the dynamic
        // linker's table, which showed up at 4 % of a render's time.
        self.simd.get_or_insert_with(SimdLevel::detect);
        self.blocks.resize(prim_indices.len().div_ceil(LANES), TriangleBlock::default());
        // Tasks of PACK_GRAIN blocks; within one, the triangles of the block PREFETCH_AHEAD
        // blocks on are asked for while this one is filled: the triangles are read in leaf
        // order, scattered over the scene's array, and the loads otherwise wait one by one.
        // The dragon (871k triangles, 2 threads): 9.5 ms without the prefetch, 5.3 with 8
        // blocks ahead, 3.3 with 32, 5.2 with 64 (medians of 31; docs/bench-build/history.md).
        const PACK_GRAIN: usize = 512;
        const PREFETCH_AHEAD: usize = 32;
        self.blocks.par_chunks_mut(PACK_GRAIN).enumerate().for_each(|(chunk, blocks)| {
            let first = chunk * PACK_GRAIN;
            let lanes_of = |b: usize| {
                let start = (b * LANES).min(prim_indices.len());
                &prim_indices[start..(start + LANES).min(prim_indices.len())]
            };
            for (k, block) in blocks.iter_mut().enumerate() {
                for &p in lanes_of(first + k + PREFETCH_AHEAD) {
                    prefetch_read(triangles.as_ptr().wrapping_add(p as usize));
                }
                let mut rows = [[0.0f32; LANES]; 9];
                for (l, &p) in lanes_of(first + k).iter().enumerate() {
                    if let Some(&[v0, v1, v2]) = triangles.get(p as usize) {
                        let (e1, e2) = (v1 - v0, v2 - v0);
                        let values = [v0.x, v0.y, v0.z, e1.x, e1.y, e1.z, e2.x, e2.y, e2.z];
                        for (row, value) in rows.iter_mut().zip(values) {
                            row[l] = value;
                        }
                    }
                }
                block.rows = rows;
            }
        });
    }

    /// Forces the scalar (or another) leaf test; by default the best of this CPU.
    pub fn set_simd(&mut self, level: SimdLevel) {
        self.simd = Some(level.min(SimdLevel::detect()));
    }

    /// The leaf test in use (set when packing; an empty, never packed set has nothing to
    /// test).
    #[inline(always)]
    fn simd(&self) -> SimdLevel {
        self.simd.unwrap_or(SimdLevel::Scalar)
    }

    /// Entry `i` (a position in the tree's `prim_indices`) as `[v0, e1, e2]`.
    #[inline(always)]
    pub fn get(&self, i: u32) -> [Vec3; 3] {
        let b = &self.blocks[i as usize / LANES].rows;
        let l = i as usize % LANES;
        [
            Vec3::new(b[0][l], b[1][l], b[2][l]),
            Vec3::new(b[3][l], b[4][l], b[5][l]),
            Vec3::new(b[6][l], b[7][l], b[8][l]),
        ]
    }

    /// Asks for the block holding entry `i` to be loaded into the cache (a hint).
    #[inline(always)]
    pub fn prefetch(&self, i: u32) {
        prefetch_block(self.blocks.as_ptr().wrapping_add(i as usize / LANES));
    }

    /// Möller–Trumbore on entry `i`, scalar.
    #[inline(always)]
    pub fn intersect(&self, i: u32, ray: &Ray) -> Option<TriangleHit> {
        let [v0, e1, e2] = self.get(i);
        intersect_triangle_edges(ray, v0, e1, e2)
    }

    /// Tests the entries `first..first + count` (a leaf; fastest when `first` is a multiple of
    /// [`LANES`], as the default collapse makes it) and
    /// calls `on_hit(i, hit, ray)` for each hit in index order, skipping hits beyond the
    /// current `ray.tmax`: exactly the hits, with the same `ray.tmax` at each call, that the
    /// scalar loop `for i in first..first + count { if let Some(h) = intersect(i, ray) ... }`
    /// would see. `on_hit` applies the caller's rule (shrinking `ray.tmax`) and returns
    /// whether it kept the hit. Returns whether any `on_hit` did.
    #[inline(always)]
    pub fn leaf_hits(
        &self,
        first: u32,
        count: u32,
        ray: &mut Ray,
        mut on_hit: impl FnMut(u32, TriangleHit, &mut Ray) -> bool,
    ) -> bool {
        let mut kept = false;
        #[cfg(target_arch = "x86_64")]
        if self.simd() >= SimdLevel::Sse {
            let end = first + count;
            // Blocks from the one holding `first`; lanes outside `first..end` are masked.
            let mut base = first - first % LANES as u32;
            while base < end {
                let lo = first.saturating_sub(base);
                let hi = (end - base).min(LANES as u32);
                let block = &self.blocks[base as usize / LANES];
                // SAFETY: SSE is part of the x86_64 baseline.
                let (mut mask, t, u, v) = unsafe { sse::block(block, ray) };
                mask &= ((1 << hi) - 1) & !((1 << lo) - 1);
                while mask != 0 {
                    let l = mask.trailing_zeros() as usize;
                    mask &= mask - 1;
                    if t[l] <= ray.tmax {
                        kept |= on_hit(base + l as u32, TriangleHit { t: t[l], u: u[l], v: v[l] }, ray);
                    }
                }
                base += LANES as u32;
            }
            return kept;
        }
        for i in first..first + count {
            if let Some(h) = self.intersect(i, ray) {
                kept |= on_hit(i, h, ray);
            }
        }
        kept
    }
}

/// Asks for the cache lines of the 36-byte triangle at `p` (a hint; never faults).
#[inline(always)]
pub(crate) fn prefetch_read(p: *const [Vec3; 3]) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = p.cast::<i8>();
        // SAFETY: prefetching is a hint and never faults, whatever the address.
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p);
            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(35));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

#[cfg(target_arch = "x86_64")]
mod sse {
    use super::*;
    use std::arch::x86_64::*;

    /// The 4-lane Möller–Trumbore: [`intersect_triangle_edges`] lane by lane, same
    /// operations in the same order. Returns the hit mask (`tmin < t <= tmax` and inside with
    /// the edge tolerance) and `t`, `u`, `v` of every lane.
    ///
    /// # Safety
    /// Needs SSE (x86_64 baseline).
    #[inline(always)]
    pub unsafe fn block(b: &TriangleBlock, ray: &Ray) -> (u32, [f32; 4], [f32; 4], [f32; 4]) {
        // SAFETY: the block is 16-byte aligned (repr align(16), rows of 16 bytes) and SSE is
        // baseline; stores go to local arrays of 4 floats.
        unsafe {
            let row = |k: usize| _mm_load_ps(b.rows[k].as_ptr());
            let (v0x, v0y, v0z) = (row(0), row(1), row(2));
            let (e1x, e1y, e1z) = (row(3), row(4), row(5));
            let (e2x, e2y, e2z) = (row(6), row(7), row(8));
            let (dx, dy, dz) = (_mm_set1_ps(ray.dir.x), _mm_set1_ps(ray.dir.y), _mm_set1_ps(ray.dir.z));
            let (ox, oy, oz) = (_mm_set1_ps(ray.origin.x), _mm_set1_ps(ray.origin.y), _mm_set1_ps(ray.origin.z));
            let mul = |a, b| _mm_mul_ps(a, b);
            let sub = |a, b| _mm_sub_ps(a, b);
            let add = |a, b| _mm_add_ps(a, b);
            let sign = _mm_set1_ps(-0.0);
            let abs = |a| _mm_andnot_ps(sign, a);
            // (a.x * b.x + a.y * b.y) + a.z * b.z, as glam's `dot`.
            let dot = |ax, ay, az, bx, by, bz| add(add(mul(ax, bx), mul(ay, by)), mul(az, bz));
            // p = dir × e2 (glam's `cross`: y * rhs.z - rhs.y * z, ...).
            let px = sub(mul(dy, e2z), mul(e2y, dz));
            let py = sub(mul(dz, e2x), mul(e2z, dx));
            let pz = sub(mul(dx, e2y), mul(e2x, dy));
            let det = dot(e1x, e1y, e1z, px, py, pz);
            // det != 0 and finite (`cmplt` with +inf is false for NaN and ±inf).
            let valid =
                _mm_and_ps(_mm_cmpneq_ps(det, _mm_setzero_ps()), _mm_cmplt_ps(abs(det), _mm_set1_ps(f32::INFINITY)));
            let inv_det = _mm_div_ps(_mm_set1_ps(1.0), det);
            let (sx, sy, sz) = (sub(ox, v0x), sub(oy, v0y), sub(oz, v0z));
            // q = s × e1
            let qx = sub(mul(sy, e1z), mul(e1y, sz));
            let qy = sub(mul(sz, e1x), mul(e1z, sx));
            let qz = sub(mul(sx, e1y), mul(e1x, sy));
            let u = mul(dot(sx, sy, sz, px, py, pz), inv_det);
            let v = mul(dot(dx, dy, dz, qx, qy, qz), inv_det);
            let t = mul(dot(e2x, e2y, e2z, qx, qy, qz), inv_det);
            let in_range = _mm_and_ps(
                _mm_and_ps(_mm_cmpgt_ps(t, _mm_set1_ps(ray.tmin)), _mm_cmple_ps(t, _mm_set1_ps(ray.tmax))),
                _mm_cmplt_ps(t, _mm_set1_ps(f32::INFINITY)),
            );
            let candidate = _mm_and_ps(valid, in_range);
            let one = _mm_set1_ps(1.0);
            let slack = _mm_set1_ps(MAX_EDGE_SLACK);
            let neg = |a| _mm_xor_ps(sign, a);
            let uv = add(u, v);
            // The edge tolerances lie in [0, MAX_EDGE_SLACK] (`minps` gives the second operand
            // for NaN), so a lane clearly inside (u, v >= 0, u + v <= 1) or clearly outside
            // (beyond the largest slack) gets the same answer without them; only lanes in
            // between (or NaN) need them, and most blocks have none.
            let clear_in = _mm_and_ps(
                _mm_and_ps(_mm_cmpge_ps(u, _mm_setzero_ps()), _mm_cmpge_ps(v, _mm_setzero_ps())),
                _mm_cmple_ps(uv, one),
            );
            let clear_out = _mm_or_ps(
                _mm_or_ps(_mm_cmplt_ps(u, neg(slack)), _mm_cmplt_ps(v, neg(slack))),
                _mm_cmpgt_ps(uv, add(add(one, slack), slack)),
            );
            let unsure = _mm_andnot_ps(_mm_or_ps(clear_in, clear_out), candidate);
            let outside = if _mm_movemask_ps(unsure) == 0 {
                clear_out
            } else {
                let abs_inv_det = abs(inv_det);
                let edge = _mm_set1_ps(EDGE_TOLERANCE);
                // `x.min(S)` is S for NaN x, as `minps(x, S)`.
                let tol_u = _mm_min_ps(
                    mul(mul(edge, dot(abs(sx), abs(sy), abs(sz), abs(px), abs(py), abs(pz))), abs_inv_det),
                    slack,
                );
                let tol_v = _mm_min_ps(
                    mul(mul(edge, dot(abs(dx), abs(dy), abs(dz), abs(qx), abs(qy), abs(qz))), abs_inv_det),
                    slack,
                );
                _mm_or_ps(
                    _mm_or_ps(_mm_cmplt_ps(u, neg(tol_u)), _mm_cmplt_ps(v, neg(tol_v))),
                    _mm_cmpgt_ps(uv, add(add(one, tol_u), tol_v)),
                )
            };
            let hit = _mm_andnot_ps(outside, candidate);
            let (mut ta, mut ua, mut va) = ([0.0f32; 4], [0.0f32; 4], [0.0f32; 4]);
            _mm_storeu_ps(ta.as_mut_ptr(), t);
            _mm_storeu_ps(ua.as_mut_ptr(), u);
            _mm_storeu_ps(va.as_mut_ptr(), v);
            (_mm_movemask_ps(hit) as u32, ta, ua, va)
        }
    }
}

/// A closest triangle hit with where it was found: `slot`, the entry in the tree's leaf order
/// (for [`PackedTriangles::get`], whose data the hit has just brought into the cache), and
/// `prim`, the caller's primitive index.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlotHit {
    pub slot: u32,
    pub prim: u32,
    pub hit: TriangleHit,
}

/// The closest-hit leaf test over packed triangles, as a [`LeafVisitor`] (compiled into the
/// traversal loop). Ties (equal `t`) go to the lowest primitive index, whatever the visit
/// order, so the result equals brute force's.
pub struct ClosestTriangle<'a> {
    tris: &'a PackedTriangles,
    prims: &'a [u32],
    /// The best hit so far.
    pub best: Option<SlotHit>,
}

impl<'a> ClosestTriangle<'a> {
    pub fn new<const N: usize>(bvh: &'a WideBvh<N>, tris: &'a PackedTriangles) -> Self {
        Self { tris, prims: &bvh.prim_indices, best: None }
    }
}

impl LeafVisitor for ClosestTriangle<'_> {
    #[inline(always)]
    fn visit(&mut self, first: u32, count: u32, ray: &mut Ray) -> bool {
        let (prims, best) = (self.prims, &mut self.best);
        self.tris.leaf_hits(first, count, ray, |slot, hit, r| {
            let prim = prims[slot as usize];
            // Hits at exactly tmax are reported too; they win if their index is lower.
            if hit.t < r.tmax || best.is_none_or(|b| prim < b.prim) {
                r.tmax = hit.t;
                *best = Some(SlotHit { slot, prim, hit });
                true
            } else {
                false
            }
        })
    }

    #[inline(always)]
    fn prefetch(&self, first: u32) {
        self.tris.prefetch(first);
    }
}

/// The any-hit leaf test over packed triangles, as a [`LeafVisitor`].
pub struct AnyTriangle<'a>(pub &'a PackedTriangles);

impl LeafVisitor for AnyTriangle<'_> {
    #[inline(always)]
    fn visit(&mut self, first: u32, count: u32, ray: &mut Ray) -> bool {
        let mut r = *ray;
        self.0.leaf_hits(first, count, &mut r, |_, _, _| true)
    }

    /// As [`ClosestTriangle`]'s: a pushed leaf's block is asked for when it is pushed.
    #[inline(always)]
    fn prefetch(&self, first: u32) {
        self.0.prefetch(first);
    }
}

impl<const N: usize> WideBvh<N>
where
    Lanes<N>: Width<N>,
{
    /// Closest hit over triangles only (`tris` packed from this tree): the caller's primitive
    /// index and the hit. Ties (equal `t`) go to the lowest primitive index, whatever the
    /// visit order, so the result equals brute force's.
    #[inline]
    pub fn closest_triangle(&self, tris: &PackedTriangles, ray: &Ray) -> Option<(u32, TriangleHit)> {
        self.closest_triangle_slot(tris, ray).map(|h| (h.prim, h.hit))
    }

    /// [`WideBvh::closest_triangle`] with the hit's slot in leaf order.
    #[inline]
    pub fn closest_triangle_slot(&self, tris: &PackedTriangles, ray: &Ray) -> Option<SlotHit> {
        let mut r = *ray;
        let mut visitor = ClosestTriangle::new(self, tris);
        self.closest_hit_visit(&mut r, &mut visitor);
        visitor.best
    }

    /// [`WideBvh::closest_triangle_slot`] of each of `rays`, into `hits`, with `M` rays
    /// traversed at once (interleaved: see [`WideBvh::closest_hit_interleaved`]).
    #[inline]
    pub fn closest_triangles_interleaved<const M: usize>(
        &self,
        tris: &PackedTriangles,
        rays: &[Ray],
        hits: &mut [Option<SlotHit>],
    ) {
        assert_eq!(rays.len(), hits.len(), "one hit per ray");
        self.closest_hit_interleaved::<M, _>(
            rays.len(),
            |i| (rays[i], ClosestTriangle::new(self, tris)),
            |i, _, visitor, _| hits[i] = visitor.best,
        );
    }

    /// [`WideBvh::any_triangle`] of each of `rays`, into `occluded`, with `M` rays traversed
    /// at once.
    #[inline]
    pub fn any_triangles_interleaved<const M: usize>(
        &self,
        tris: &PackedTriangles,
        rays: &[Ray],
        occluded: &mut [bool],
    ) {
        assert_eq!(rays.len(), occluded.len(), "one answer per ray");
        self.any_hit_interleaved::<M, _>(
            rays.len(),
            |i| (rays[i], AnyTriangle(tris)),
            |i, _, _, hit| occluded[i] = hit,
        );
    }

    /// [`WideBvh::closest_triangle_slot`] of each of `rays`, into `hits`, interleaved with as
    /// many rays in flight as the tree and the triangles call for
    /// ([`WideBvh::closest_hit_batch`]).
    pub fn closest_triangles_batch(&self, tris: &PackedTriangles, rays: &[Ray], hits: &mut [Option<SlotHit>]) {
        assert_eq!(rays.len(), hits.len(), "one hit per ray");
        self.closest_hit_batch(
            self.traced_bytes(tris),
            rays.len(),
            |i| (rays[i], ClosestTriangle::new(self, tris)),
            |i, _, visitor, _| hits[i] = visitor.best,
        );
    }

    /// [`WideBvh::any_triangle`] of each of `rays`, into `occluded`, interleaved as
    /// [`WideBvh::closest_triangles_batch`].
    pub fn any_triangles_batch(&self, tris: &PackedTriangles, rays: &[Ray], occluded: &mut [bool]) {
        assert_eq!(rays.len(), occluded.len(), "one answer per ray");
        self.any_hit_batch(
            self.traced_bytes(tris),
            rays.len(),
            |i| (rays[i], AnyTriangle(tris)),
            |i, _, _, hit| occluded[i] = hit,
        );
    }

    /// Bytes a traversal reads from: the nodes and the packed triangles.
    pub fn traced_bytes(&self, tris: &PackedTriangles) -> usize {
        self.nodes.len() * std::mem::size_of::<super::WideNode<N>>()
            + tris.blocks.len() * std::mem::size_of::<TriangleBlock>()
    }

    /// Whether any triangle is hit within the ray's interval.
    #[inline]
    pub fn any_triangle(&self, tris: &PackedTriangles, ray: &Ray) -> bool {
        self.any_hit_visit(ray, &mut AnyTriangle(tris))
    }
}

impl PackedTriangles {
    /// The box of the triangles of `entries` (a range of the tree's leaf order) as the
    /// packed test sees them: `v0`, `v0 + e1` and `v0 + e2`, each sum rounded to the nearest
    /// float, so the box is widened by a relative `2⁻²³` (at least one unit in the last place
    /// of each bound) to hold the exact sums. Computed 4 lanes at a time, a block after the
    /// other, lanes outside `entries` masked out. (Read entry by entry, as `Vec3`s, the
    /// lanes went through the stack and every load waited for a failed store forwarding:
    /// twice the time of gathering the primitives' boxes.)
    pub fn bounds(&self, entries: Range<usize>) -> Aabb {
        use glam::Vec4;
        const LANE: Vec4 = Vec4::new(0.0, 1.0, 2.0, 3.0);
        let (mut lo, mut hi) = ([Vec4::INFINITY; 3], [Vec4::NEG_INFINITY; 3]);
        if entries.is_empty() {
            return Aabb::EMPTY;
        }
        for b in entries.start / LANES..=(entries.end - 1) / LANES {
            let rows = &self.blocks[b].rows;
            // Lane l holds entry b·4 + l (differences taken in integers: exact in f32).
            let base = (b * LANES) as isize;
            let inside = LANE.cmpge(Vec4::splat((entries.start as isize - base) as f32))
                & LANE.cmplt(Vec4::splat((entries.end as isize - base) as f32));
            for axis in 0..3 {
                let v0 = Vec4::from_array(rows[axis]);
                let (v1, v2) = (v0 + Vec4::from_array(rows[3 + axis]), v0 + Vec4::from_array(rows[6 + axis]));
                lo[axis] = Vec4::select(inside, lo[axis].min(v0.min(v1).min(v2)), lo[axis]);
                hi[axis] = Vec4::select(inside, hi[axis].max(v0.max(v1).max(v2)), hi[axis]);
            }
        }
        let min = glam::Vec3::new(lo[0].min_element(), lo[1].min_element(), lo[2].min_element());
        let max = glam::Vec3::new(hi[0].max_element(), hi[1].max_element(), hi[2].max_element());
        widened(min, max)
    }
}

/// The box `min..max` of packed entries' corners, widened by a relative 2⁻²³ per side: the
/// packed test's `v0 + e1` and `v0 + e2` may round past the corners the box was taken from.
#[inline(always)]
pub(crate) fn widened(min: Vec3, max: Vec3) -> Aabb {
    const ULP: f32 = f32::EPSILON;
    Aabb::new(min - min.abs() * ULP, max + max.abs() * ULP)
}

/// Entries of a [`PackedTriangles`] written from several threads through a shared
/// reference ([`WideBvh::refit_repacking`] packs leaf by leaf in parallel, and small leaves
/// share blocks, so the blocks cannot be split into disjoint `&mut` pieces by leaf). Each
/// float is a relaxed atomic store, a plain store on x86.
pub(crate) struct SharedEntries<'a> {
    floats: &'a [AtomicU32],
}

/// Floats per block.
const BLOCK_FLOATS: usize = 9 * LANES;

impl<'a> SharedEntries<'a> {
    pub(crate) fn new(packed: &'a mut PackedTriangles) -> Self {
        let blocks = packed.blocks.as_mut_slice();
        // SAFETY: a block is 36 f32 with no padding, an `AtomicU32` has the size and bit
        // validity of a `u32` and an alignment (4) the blocks' (16) satisfies, and the
        // exclusive borrow of the blocks lasts as long as the view.
        let floats =
            unsafe { std::slice::from_raw_parts(blocks.as_mut_ptr().cast::<AtomicU32>(), blocks.len() * BLOCK_FLOATS) };
        Self { floats }
    }

    /// Stores triangle `[v0, v1, v2]` as entry `i` (as [`PackedTriangles::repack`] does) and
    /// returns its corners as the packed test sees them: `v0`, `v0 + e1`, `v0 + e2`.
    #[inline(always)]
    pub(crate) fn store(&self, i: usize, [v0, v1, v2]: [Vec3; 3]) -> [Vec3; 3] {
        let (e1, e2) = (v1 - v0, v2 - v0);
        let values = [v0.x, v0.y, v0.z, e1.x, e1.y, e1.z, e2.x, e2.y, e2.z];
        let first = i / LANES * BLOCK_FLOATS + i % LANES;
        for (row, value) in values.into_iter().enumerate() {
            self.floats[first + row * LANES].store(value.to_bits(), Ordering::Relaxed);
        }
        [v0, v0 + e1, v0 + e2]
    }

    /// Asks for the block of entry `i` to be brought into the cache (a hint).
    #[inline(always)]
    pub(crate) fn prefetch(&self, i: usize) {
        prefetch_block(self.floats.as_ptr().wrapping_add(i / LANES * BLOCK_FLOATS).cast());
    }
}

/// Asks for the three cache lines of the 144-byte block at `p` (a hint; never faults).
#[inline(always)]
fn prefetch_block(p: *const TriangleBlock) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = p.cast::<i8>();
        // SAFETY: prefetching is a hint and never faults, whatever the address.
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p);
            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64));
            _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(143));
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}
