//! One ray against all `N` child boxes of a [`WideNode`]: the robust slab test of
//! [`crate::aabb::Aabb::intersect`], lane-parallel.
//!
//! Per axis the ray's near plane is the box minimum if the direction is positive and the
//! maximum otherwise ([`RayPre`] picks the rows once per ray), so a lane computes
//! `tnear = max(near_x, near_y, near_z, tmin)` and `tfar = min(far_x, far_y, far_z, tmax) ·
//! ROBUST_SLAB` from six subtractions and six multiplications, and hits if `tnear <= tfar`.
//! For a non-empty box these are exactly the values `Aabb::intersect` computes with
//! `min`/`max` of both planes; for the inverted empty box (`min = +inf`, `max = -inf`) the
//! near distance is `+inf` and the far one `-inf`, a miss. `max`/`min` are written as
//! `if a > b { a } else { b }`, the semantics of `maxps`/`minps`, and nothing is fused, so the
//! scalar, SSE and AVX2 kernels return the same bits.
//!
//! Each kernel writes the entry distances of all lanes to `t` and returns the bit mask of the
//! lanes hit.

use super::WideNode;
use crate::aabb::ROBUST_SLAB;
use crate::ray::Ray;

/// A ray prepared for the node kernels.
#[derive(Clone, Copy, Debug)]
pub struct RayPre {
    pub origin: [f32; 3],
    pub inv_dir: [f32; 3],
    /// Row of [`WideNode::bounds`] holding the near plane per axis (`2 * axis` for a positive
    /// direction, `2 * axis + 1` for a negative one) and the far plane.
    pub near: [usize; 3],
    pub far: [usize; 3],
    pub tmin: f32,
}

impl RayPre {
    #[inline(always)]
    pub fn new(ray: &Ray) -> Self {
        let inv = ray.inv_dir.to_array();
        // `safe_recip` never returns 0, so the sign of `inv` is the direction's.
        let neg = |a: usize| (inv[a] < 0.0) as usize;
        Self {
            origin: ray.origin.to_array(),
            inv_dir: inv,
            near: [neg(0), 2 + neg(1), 4 + neg(2)],
            far: [1 - neg(0), 3 - neg(1), 5 - neg(2)],
            tmin: ray.tmin,
        }
    }
}

#[inline(always)]
fn max(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

#[inline(always)]
fn min(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// The portable kernel, one lane after the other.
#[inline(always)]
pub fn node_scalar<const N: usize>(node: &WideNode<N>, r: &RayPre, tmax: f32, t: &mut [f32; N]) -> u32 {
    let b = &node.bounds;
    let (nx, ny, nz) = (&b[r.near[0]], &b[r.near[1]], &b[r.near[2]]);
    let (fx, fy, fz) = (&b[r.far[0]], &b[r.far[1]], &b[r.far[2]]);
    let [ox, oy, oz] = r.origin;
    let [ix, iy, iz] = r.inv_dir;
    let mut mask = 0;
    for i in 0..N {
        let tnear = max(max((nx[i] - ox) * ix, (ny[i] - oy) * iy), max((nz[i] - oz) * iz, r.tmin));
        let tfar = min(min((fx[i] - ox) * ix, (fy[i] - oy) * iy), min((fz[i] - oz) * iz, tmax)) * ROBUST_SLAB;
        t[i] = tnear;
        mask |= ((tnear <= tfar) as u32) << i;
    }
    mask
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::*;
    use std::arch::x86_64::*;

    /// The SSE kernel on 4 lanes starting at lane `lane` of each row.
    #[inline(always)]
    unsafe fn sse_lanes<const N: usize>(node: &WideNode<N>, r: &RayPre, tmax: f32, lane: usize) -> (__m128, u32) {
        debug_assert!(lane + 4 <= N);
        let row = |k: usize| -> __m128 {
            // SAFETY: `k < 6` (RayPre's rows) and `lane + 4 <= N`, so the four floats lie
            // inside `node.bounds[k]`; unaligned loads have no alignment requirement.
            unsafe { _mm_loadu_ps(node.bounds.as_ptr().cast::<f32>().add(k * N + lane)) }
        };
        let (ox, oy, oz) = (_mm_set1_ps(r.origin[0]), _mm_set1_ps(r.origin[1]), _mm_set1_ps(r.origin[2]));
        let (ix, iy, iz) = (_mm_set1_ps(r.inv_dir[0]), _mm_set1_ps(r.inv_dir[1]), _mm_set1_ps(r.inv_dir[2]));
        let nx = _mm_mul_ps(_mm_sub_ps(row(r.near[0]), ox), ix);
        let ny = _mm_mul_ps(_mm_sub_ps(row(r.near[1]), oy), iy);
        let nz = _mm_mul_ps(_mm_sub_ps(row(r.near[2]), oz), iz);
        let fx = _mm_mul_ps(_mm_sub_ps(row(r.far[0]), ox), ix);
        let fy = _mm_mul_ps(_mm_sub_ps(row(r.far[1]), oy), iy);
        let fz = _mm_mul_ps(_mm_sub_ps(row(r.far[2]), oz), iz);
        let tnear = _mm_max_ps(_mm_max_ps(nx, ny), _mm_max_ps(nz, _mm_set1_ps(r.tmin)));
        let tfar =
            _mm_mul_ps(_mm_min_ps(_mm_min_ps(fx, fy), _mm_min_ps(fz, _mm_set1_ps(tmax))), _mm_set1_ps(ROBUST_SLAB));
        (tnear, _mm_movemask_ps(_mm_cmple_ps(tnear, tfar)) as u32)
    }

    /// SSE on a 4-wide node.
    ///
    /// # Safety
    /// Needs SSE (part of the x86_64 baseline).
    #[inline(always)]
    pub unsafe fn node_sse4(node: &WideNode<4>, r: &RayPre, tmax: f32, t: &mut [f32; 4]) -> u32 {
        // SAFETY: SSE is available on every x86_64 CPU; `t` has room for 4 floats.
        unsafe {
            let (tnear, mask) = sse_lanes(node, r, tmax, 0);
            _mm_storeu_ps(t.as_mut_ptr(), tnear);
            mask
        }
    }

    /// SSE on an 8-wide node: two halves.
    ///
    /// # Safety
    /// Needs SSE (part of the x86_64 baseline).
    #[inline(always)]
    pub unsafe fn node_sse8(node: &WideNode<8>, r: &RayPre, tmax: f32, t: &mut [f32; 8]) -> u32 {
        // SAFETY: as in `node_sse4`; `t` has room for 8 floats.
        unsafe {
            let (lo, mlo) = sse_lanes(node, r, tmax, 0);
            let (hi, mhi) = sse_lanes(node, r, tmax, 4);
            _mm_storeu_ps(t.as_mut_ptr(), lo);
            _mm_storeu_ps(t.as_mut_ptr().add(4), hi);
            mlo | (mhi << 4)
        }
    }

    /// AVX2 on an 8-wide node.
    ///
    /// # Safety
    /// The CPU must support AVX2 (the caller checked with `SimdLevel`).
    #[inline]
    #[target_feature(enable = "avx2")]
    pub unsafe fn node_avx8(node: &WideNode<8>, r: &RayPre, tmax: f32, t: &mut [f32; 8]) -> u32 {
        let row = |k: usize| -> __m256 {
            // SAFETY: `k < 6`, so the 8 floats of row `k` lie inside `node.bounds`; AVX is
            // enabled on this function.
            unsafe { _mm256_loadu_ps(node.bounds.as_ptr().cast::<f32>().add(k * 8)) }
        };
        let (ox, oy, oz) = (_mm256_set1_ps(r.origin[0]), _mm256_set1_ps(r.origin[1]), _mm256_set1_ps(r.origin[2]));
        let (ix, iy, iz) = (_mm256_set1_ps(r.inv_dir[0]), _mm256_set1_ps(r.inv_dir[1]), _mm256_set1_ps(r.inv_dir[2]));
        let nx = _mm256_mul_ps(_mm256_sub_ps(row(r.near[0]), ox), ix);
        let ny = _mm256_mul_ps(_mm256_sub_ps(row(r.near[1]), oy), iy);
        let nz = _mm256_mul_ps(_mm256_sub_ps(row(r.near[2]), oz), iz);
        let fx = _mm256_mul_ps(_mm256_sub_ps(row(r.far[0]), ox), ix);
        let fy = _mm256_mul_ps(_mm256_sub_ps(row(r.far[1]), oy), iy);
        let fz = _mm256_mul_ps(_mm256_sub_ps(row(r.far[2]), oz), iz);
        let tnear = _mm256_max_ps(_mm256_max_ps(nx, ny), _mm256_max_ps(nz, _mm256_set1_ps(r.tmin)));
        let tfar = _mm256_mul_ps(
            _mm256_min_ps(_mm256_min_ps(fx, fy), _mm256_min_ps(fz, _mm256_set1_ps(tmax))),
            _mm256_set1_ps(ROBUST_SLAB),
        );
        // SAFETY: `t` has room for 8 floats.
        unsafe { _mm256_storeu_ps(t.as_mut_ptr(), tnear) };
        _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(tnear, tfar)) as u32
    }
}

#[cfg(target_arch = "x86_64")]
pub use x86::{node_avx8, node_sse4, node_sse8};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::aabb::Aabb;
    use glam::Vec3;

    fn node8() -> WideNode<8> {
        let mut n = WideNode::<8>::EMPTY;
        let boxes = [
            Aabb::new(Vec3::ZERO, Vec3::ONE),
            Aabb::new(Vec3::new(2.0, 0.0, 0.0), Vec3::new(3.0, 1.0, 1.0)),
            Aabb::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0)),
            Aabb::new(Vec3::splat(-5.0), Vec3::splat(-4.0)),
            Aabb::new(Vec3::new(0.25, 0.25, 3.0), Vec3::new(0.75, 0.75, 4.0)),
        ];
        for (i, b) in boxes.iter().enumerate() {
            n.set_child_bounds(i, *b);
        }
        n
    }

    /// Every kernel agrees with `Aabb::intersect` on hit/miss and entry distance, and empty
    /// slots never hit.
    #[test]
    fn kernels_match_aabb_intersect() {
        let node = node8();
        let mut rays = Vec::new();
        let mut s = 1u32;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            (s >> 8) as f32 / (1 << 24) as f32 * 8.0 - 4.0
        };
        for _ in 0..2000 {
            let o = Vec3::new(rnd(), rnd(), rnd());
            let d = Vec3::new(rnd(), rnd(), rnd());
            rays.push(Ray::new(o, d));
        }
        // Axis-parallel rays, rays in face planes.
        rays.push(Ray::new(Vec3::new(-1.0, 0.0, 0.5), Vec3::X));
        rays.push(Ray::new(Vec3::new(0.5, 0.5, -1.0), Vec3::Z));
        rays.push(Ray::new(Vec3::new(0.5, 0.5, 10.0), -Vec3::Z));
        rays.push(Ray::new(Vec3::new(0.5, 0.5, 10.0), Vec3::new(0.0, -0.0, -1.0)));
        for ray in &rays {
            let r = RayPre::new(ray);
            let mut t = [0.0; 8];
            let mask = node_scalar(&node, &r, ray.tmax, &mut t);
            for (i, &ti) in t.iter().enumerate() {
                let expected = node.child_bounds(i).intersect(ray);
                let hit = mask >> i & 1 == 1;
                if i >= 5 {
                    assert!(!hit, "empty slot {i} hit by {ray:?}");
                } else {
                    assert_eq!(hit, expected != f32::INFINITY, "slot {i} {ray:?}");
                    if hit {
                        assert_eq!(ti.to_bits(), expected.to_bits(), "slot {i} {ray:?}");
                    }
                }
            }
            #[cfg(target_arch = "x86_64")]
            {
                let mut t2 = [0.0; 8];
                // SAFETY: SSE is baseline on x86_64.
                let m2 = unsafe { node_sse8(&node, &r, ray.tmax, &mut t2) };
                assert_eq!(m2, mask);
                assert_eq!(t2.map(f32::to_bits), t.map(f32::to_bits));
                if super::super::SimdLevel::detect() >= super::super::SimdLevel::Avx2 {
                    let mut t3 = [0.0; 8];
                    // SAFETY: AVX2 was detected.
                    let m3 = unsafe { node_avx8(&node, &r, ray.tmax, &mut t3) };
                    assert_eq!(m3, mask);
                    assert_eq!(t3.map(f32::to_bits), t.map(f32::to_bits));
                }
            }
        }
    }
}
