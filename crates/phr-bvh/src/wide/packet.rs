//! Packets: 16 rays traced together through an 8-wide tree, one ray per lane of a 512-bit
//! register (AVX-512 F).
//!
//! Coherent rays (a camera's, through neighbouring pixels) visit nearly the same nodes, so a
//! packet loads each node and each leaf block once for all of its rays, and tests a child's
//! box, or a triangle, against 16 rays in one pass of the arithmetic a single ray spends on
//! it. The walk is depth first over entries `(node or leaf, rays)`: a node's children that
//! any of those rays hit are pushed with the mask of the rays that hit them, farthest first
//! by the entry distance of the entry's first ray (an order that matters for speed only).
//! Rays that part ways stay in the packet as idle lanes.
//!
//! The results are the single-ray traversal's: the box test is the robust slab test of
//! [`super::simd`] lane by lane (each ray's near plane chosen by its direction's sign, the same
//! operations in the same order), the triangle test the 4-lane Möller–Trumbore of
//! [`super::triangles`] (same operations, same order, edge tolerances where a lane needs
//! them), and ties at equal `t` go to the lowest primitive index as in
//! [`super::triangles::ClosestTriangle`]: the same primitive, `t`, `u` and `v`, bit for bit.
//! (Only the slot may differ where spatial splits put a primitive in several leaves: a packet
//! meets them in another order.)
//!
//! Packets pay only where a packet's rays stay together: on the camera rays of Sponza,
//! Sibenik and Conference they trace twice as fast as the interleaved single rays, but on
//! fine meshes (the bunny, the dragon: triangles smaller than a pixel) and on incoherent rays
//! the rays part ways after a few nodes, most lanes idle, and they are slower
//! (`docs/bench-rays/history.md`, 2026-11-28). The renderer therefore does not use them.

use super::triangles::{PackedTriangles, SlotHit};
use super::WideBvh;
use crate::ray::Ray;

/// Rays per packet.
pub const PACKET: usize = 16;

impl WideBvh<8> {
    /// [`WideBvh::closest_triangle_slot`] of each of `rays`, into `hits`, traced in packets of
    /// [`PACKET`] consecutive rays where the CPU has AVX-512 F (one ray at a time, interleaved,
    /// elsewhere, at the tree's SIMD level): the same hits either way (see the module's notes
    /// on slots). The packets ignore [`WideBvh::set_simd`]. Give it coherent rays: camera
    /// rays through neighbouring pixels.
    pub fn closest_triangles_packets(&self, tris: &PackedTriangles, rays: &[Ray], hits: &mut [Option<SlotHit>]) {
        assert_eq!(rays.len(), hits.len(), "one hit per ray");
        #[cfg(target_arch = "x86_64")]
        if available() {
            let mut stack = Vec::with_capacity(self.stack_bound + 8 + 1);
            for (rays, hits) in rays.chunks(PACKET).zip(hits.chunks_mut(PACKET)) {
                // SAFETY: the CPU has AVX-512 F (checked); the tree comes from a builder
                // (child indices in range) and `tris` was packed from it.
                unsafe { avx512::closest(self, tris, rays, hits, &mut stack) };
            }
            return;
        }
        self.closest_triangles_interleaved::<2>(tris, rays, hits);
    }
}

/// Whether [`WideBvh::closest_triangles_packets`] traces packets on this CPU (else it
/// traces one ray at a time).
pub fn available() -> bool {
    #[cfg(target_arch = "x86_64")]
    return std::arch::is_x86_feature_detected!("avx512f");
    #[cfg(not(target_arch = "x86_64"))]
    false
}

#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::*;
    use crate::aabb::ROBUST_SLAB;
    use crate::triangle::{TriangleHit, EDGE_TOLERANCE, MAX_EDGE_SLACK};
    use crate::wide::traverse::traversable;
    use crate::wide::triangles::LANES;
    use std::arch::x86_64::*;

    /// A stack entry: a node (`count == 0`) or a leaf's entries `child..child + count`, and
    /// the rays (lanes) to take there.
    type Entry = (u32, u32, u16);

    /// The rays of a packet, one per lane.
    struct Packet {
        o: [__m512; 3],
        d: [__m512; 3],
        inv: [__m512; 3],
        /// Lanes whose direction is negative along each axis (their near plane is the box's
        /// maximum).
        neg: [__mmask16; 3],
        tmin: __m512,
    }

    /// The closest hits of up to 16 `rays` into `hits`.
    ///
    /// # Safety
    /// The CPU must have AVX-512 F; `bvh` must come from a builder and `tris` be packed from
    /// it.
    #[target_feature(enable = "avx512f")]
    pub(super) unsafe fn closest(
        bvh: &WideBvh<8>,
        tris: &PackedTriangles,
        rays: &[Ray],
        hits: &mut [Option<SlotHit>],
        stack: &mut Vec<Entry>,
    ) {
        let n = rays.len();
        debug_assert!(n <= PACKET);
        let lane = |f: &dyn Fn(&Ray) -> f32, pad: f32| {
            let mut a = [pad; PACKET];
            for (x, r) in a.iter_mut().zip(rays) {
                *x = f(r);
            }
            // SAFETY: 16 floats.
            unsafe { _mm512_loadu_ps(a.as_ptr()) }
        };
        let o = [lane(&|r| r.origin.x, 0.0), lane(&|r| r.origin.y, 0.0), lane(&|r| r.origin.z, 0.0)];
        let d = [lane(&|r| r.dir.x, 1.0), lane(&|r| r.dir.y, 1.0), lane(&|r| r.dir.z, 1.0)];
        let inv = [lane(&|r| r.inv_dir.x, 1.0), lane(&|r| r.inv_dir.y, 1.0), lane(&|r| r.inv_dir.z, 1.0)];
        let zero = _mm512_setzero_ps();
        let neg = inv.map(|i| _mm512_cmp_ps_mask::<_CMP_LT_OQ>(i, zero));
        let p = Packet { o, d, inv, neg, tmin: lane(&|r| r.tmin, 0.0) };
        let mut tmax = lane(&|r| r.tmax, 0.0);
        // Rays that may be traversed.
        let active = rays.iter().enumerate().fold(0u16, |m, (i, r)| m | (u16::from(traversable(r)) << i));
        // The best hit per lane: prim (u32::MAX while there is none, above every primitive's
        // index, so that a first hit at exactly `tmax` is taken), slot, t (= tmax once found), u, v.
        let mut best_prim = _mm512_set1_epi32(-1);
        let mut best_slot = _mm512_setzero_si512();
        let (mut best_u, mut best_v) = (zero, zero);
        let mut found: u16 = 0;
        stack.clear();
        if active != 0 && !bvh.nodes.is_empty() {
            stack.push((0, 0, active));
        }
        let prims = &bvh.prim_indices;
        while let Some((child, count, mask)) = stack.pop() {
            if count == 0 {
                let node = &bvh.nodes[child as usize];
                // The entry's first ray orders the children.
                let lead = mask.trailing_zeros() as usize;
                // The hit slots: the lead ray's entry distance, the slot, the rays that hit it.
                let mut order: [(f32, usize, u16); 8] = [(0.0, 0, 0); 8];
                let mut k = 0;
                for c in 0..8 {
                    let (m, tnear) = box_test(&p, tmax, mask, node, c);
                    if m != 0 {
                        let mut t = [0.0f32; PACKET];
                        // SAFETY: 16 floats.
                        unsafe { _mm512_storeu_ps(t.as_mut_ptr(), tnear) };
                        let key = if m >> lead & 1 == 1 { t[lead] } else { f32::INFINITY };
                        order[k] = (key, c, m);
                        k += 1;
                    }
                }
                // Farthest pushed first, so the nearest is taken next.
                order[..k].sort_unstable_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
                for &(_, c, m) in &order[..k] {
                    stack.push((node.child[c], node.count[c], m));
                }
            } else {
                for slot in child..child + count {
                    let block = &tris.blocks[slot as usize / LANES];
                    let l = slot as usize % LANES;
                    let row = |k: usize| _mm512_set1_ps(block.rows[k][l]);
                    let v0 = [row(0), row(1), row(2)];
                    let e1 = [row(3), row(4), row(5)];
                    let e2 = [row(6), row(7), row(8)];
                    let (hit, t, u, v) = triangle_test(&p, tmax, mask, v0, e1, e2);
                    if hit == 0 {
                        continue;
                    }
                    // Hits at exactly tmax win if their primitive index is lower (ties go to
                    // the lowest index, as `ClosestTriangle`'s).
                    let prim = prims[slot as usize];
                    let prim_v = _mm512_set1_epi32(prim as i32);
                    let closer = _mm512_mask_cmp_ps_mask::<_CMP_LT_OQ>(hit, t, tmax);
                    let tie = _mm512_mask_cmp_ps_mask::<_CMP_EQ_OQ>(hit, t, tmax)
                        & _mm512_cmp_epu32_mask::<_MM_CMPINT_LT>(prim_v, best_prim);
                    let take = closer | tie;
                    if take == 0 {
                        continue;
                    }
                    tmax = _mm512_mask_blend_ps(take, tmax, t);
                    best_u = _mm512_mask_blend_ps(take, best_u, u);
                    best_v = _mm512_mask_blend_ps(take, best_v, v);
                    best_prim = _mm512_mask_blend_epi32(take, best_prim, prim_v);
                    best_slot = _mm512_mask_blend_epi32(take, best_slot, _mm512_set1_epi32(slot as i32));
                    found |= take;
                }
            }
        }
        let (mut t, mut u, mut v) = ([0.0f32; PACKET], [0.0f32; PACKET], [0.0f32; PACKET]);
        let (mut prim, mut slot) = ([0u32; PACKET], [0u32; PACKET]);
        // SAFETY: 16 lanes each.
        unsafe {
            _mm512_storeu_ps(t.as_mut_ptr(), tmax);
            _mm512_storeu_ps(u.as_mut_ptr(), best_u);
            _mm512_storeu_ps(v.as_mut_ptr(), best_v);
            _mm512_storeu_si512(prim.as_mut_ptr().cast(), best_prim);
            _mm512_storeu_si512(slot.as_mut_ptr().cast(), best_slot);
        }
        for (i, h) in hits.iter_mut().enumerate().take(n) {
            *h = (found >> i & 1 == 1).then(|| SlotHit {
                slot: slot[i],
                prim: prim[i],
                hit: TriangleHit { t: t[i], u: u[i], v: v[i] },
            });
        }
    }

    /// Slot `c` of `node` against the rays of `mask`: the lanes that hit it, and every lane's
    /// entry distance ([`super::super::simd`]'s kernels, lane by lane).
    #[target_feature(enable = "avx512f")]
    #[inline]
    fn box_test(p: &Packet, tmax: __m512, mask: u16, node: &super::super::WideNode<8>, c: usize) -> (u16, __m512) {
        let b = &node.bounds;
        let plane = |axis: usize, near: bool| {
            let (lo, hi) = (_mm512_set1_ps(b[2 * axis][c]), _mm512_set1_ps(b[2 * axis + 1][c]));
            // Near: the minimum for a positive direction, the maximum for a negative one.
            if near {
                _mm512_mask_blend_ps(p.neg[axis], lo, hi)
            } else {
                _mm512_mask_blend_ps(p.neg[axis], hi, lo)
            }
        };
        let dist = |axis: usize, near: bool| _mm512_mul_ps(_mm512_sub_ps(plane(axis, near), p.o[axis]), p.inv[axis]);
        let (nx, ny, nz) = (dist(0, true), dist(1, true), dist(2, true));
        let (fx, fy, fz) = (dist(0, false), dist(1, false), dist(2, false));
        let tnear = _mm512_max_ps(_mm512_max_ps(nx, ny), _mm512_max_ps(nz, p.tmin));
        let tfar =
            _mm512_mul_ps(_mm512_min_ps(_mm512_min_ps(fx, fy), _mm512_min_ps(fz, tmax)), _mm512_set1_ps(ROBUST_SLAB));
        (_mm512_mask_cmp_ps_mask::<_CMP_LE_OQ>(mask, tnear, tfar), tnear)
    }

    /// One triangle (`v0` and its edges, broadcast) against the rays of `mask`: the lanes
    /// hit within `(tmin, tmax]`, and `t`, `u`, `v` of every lane. The operations of
    /// `triangles::sse::block`, in its order.
    #[target_feature(enable = "avx512f")]
    #[inline]
    fn triangle_test(
        p: &Packet,
        tmax: __m512,
        mask: u16,
        v0: [__m512; 3],
        e1: [__m512; 3],
        e2: [__m512; 3],
    ) -> (u16, __m512, __m512, __m512) {
        let [dx, dy, dz] = p.d;
        let [ox, oy, oz] = p.o;
        let mul = |a, b| _mm512_mul_ps(a, b);
        let sub = |a, b| _mm512_sub_ps(a, b);
        let add = |a, b| _mm512_add_ps(a, b);
        let abs = |a| _mm512_abs_ps(a);
        let dot = |ax, ay, az, bx, by, bz| add(add(mul(ax, bx), mul(ay, by)), mul(az, bz));
        let px = sub(mul(dy, e2[2]), mul(e2[1], dz));
        let py = sub(mul(dz, e2[0]), mul(e2[2], dx));
        let pz = sub(mul(dx, e2[1]), mul(e2[0], dy));
        let det = dot(e1[0], e1[1], e1[2], px, py, pz);
        let zero = _mm512_setzero_ps();
        let inf = _mm512_set1_ps(f32::INFINITY);
        let valid =
            _mm512_mask_cmp_ps_mask::<_CMP_NEQ_UQ>(mask, det, zero) & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(abs(det), inf);
        let inv_det = _mm512_div_ps(_mm512_set1_ps(1.0), det);
        let (sx, sy, sz) = (sub(ox, v0[0]), sub(oy, v0[1]), sub(oz, v0[2]));
        let qx = sub(mul(sy, e1[2]), mul(e1[1], sz));
        let qy = sub(mul(sz, e1[0]), mul(e1[2], sx));
        let qz = sub(mul(sx, e1[1]), mul(e1[0], sy));
        let u = mul(dot(sx, sy, sz, px, py, pz), inv_det);
        let v = mul(dot(dx, dy, dz, qx, qy, qz), inv_det);
        let t = mul(dot(e2[0], e2[1], e2[2], qx, qy, qz), inv_det);
        let in_range = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(t, p.tmin)
            & _mm512_cmp_ps_mask::<_CMP_LE_OQ>(t, tmax)
            & _mm512_cmp_ps_mask::<_CMP_LT_OQ>(t, inf);
        let candidate = valid & in_range;
        if candidate == 0 {
            return (0, t, u, v);
        }
        let one = _mm512_set1_ps(1.0);
        let slack = _mm512_set1_ps(MAX_EDGE_SLACK);
        let neg_slack = _mm512_set1_ps(-MAX_EDGE_SLACK);
        let uv = add(u, v);
        let clear_in = _mm512_cmp_ps_mask::<_CMP_GE_OQ>(u, zero)
            & _mm512_cmp_ps_mask::<_CMP_GE_OQ>(v, zero)
            & _mm512_cmp_ps_mask::<_CMP_LE_OQ>(uv, one);
        let clear_out = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(u, neg_slack)
            | _mm512_cmp_ps_mask::<_CMP_LT_OQ>(v, neg_slack)
            | _mm512_cmp_ps_mask::<_CMP_GT_OQ>(uv, add(add(one, slack), slack));
        let unsure = candidate & !(clear_in | clear_out);
        let outside = if unsure == 0 {
            clear_out
        } else {
            let abs_inv_det = abs(inv_det);
            let edge = _mm512_set1_ps(EDGE_TOLERANCE);
            // `minps(x, S)` is S for NaN x, as in the 4-lane test.
            let tol_u = _mm512_min_ps(
                mul(mul(edge, dot(abs(sx), abs(sy), abs(sz), abs(px), abs(py), abs(pz))), abs_inv_det),
                slack,
            );
            let tol_v = _mm512_min_ps(
                mul(mul(edge, dot(abs(dx), abs(dy), abs(dz), abs(qx), abs(qy), abs(qz))), abs_inv_det),
                slack,
            );
            let neg = |a| _mm512_sub_ps(zero, a);
            _mm512_cmp_ps_mask::<_CMP_LT_OQ>(u, neg(tol_u))
                | _mm512_cmp_ps_mask::<_CMP_LT_OQ>(v, neg(tol_v))
                | _mm512_cmp_ps_mask::<_CMP_GT_OQ>(uv, add(add(one, tol_u), tol_v))
        };
        (candidate & !outside, t, u, v)
    }
}
