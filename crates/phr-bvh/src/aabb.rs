//! Axis-aligned bounding boxes and the slab test.

use crate::ray::Ray;
use glam::Vec3;

/// An axis-aligned box. The empty box has `min = +inf`, `max = -inf`, so that growing it by
/// any point or box gives exactly that point or box.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

impl Default for Aabb {
    fn default() -> Self {
        Self::EMPTY
    }
}

/// Per-component minimum by plain comparison: one instruction per component, where
/// `Vec3::min` also handles NaN. Boxes never hold NaN (loaders reject non-finite input), and
/// the builders spend much of their time in unions.
#[inline(always)]
fn fast_min(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(if a.x < b.x { a.x } else { b.x }, if a.y < b.y { a.y } else { b.y }, if a.z < b.z { a.z } else { b.z })
}

#[inline(always)]
fn fast_max(a: Vec3, b: Vec3) -> Vec3 {
    Vec3::new(if a.x > b.x { a.x } else { b.x }, if a.y > b.y { a.y } else { b.y }, if a.z > b.z { a.z } else { b.z })
}

/// `1 + 2γ₃`: the relative slack of the robust slab test (see [`Aabb::intersect`]).
pub const ROBUST_SLAB: f32 = 1.0 + 2.0 * 3.0 * f32::EPSILON;

impl Aabb {
    pub const EMPTY: Aabb = Aabb { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };

    pub fn new(min: Vec3, max: Vec3) -> Self {
        Self { min, max }
    }

    #[inline]
    pub fn from_points(points: &[Vec3]) -> Self {
        points.iter().fold(Self::EMPTY, |b, &p| b.grown(p))
    }

    #[inline]
    pub fn grown(self, p: Vec3) -> Self {
        Self { min: fast_min(self.min, p), max: fast_max(self.max, p) }
    }

    #[inline]
    pub fn union(self, o: Aabb) -> Self {
        Self { min: fast_min(self.min, o.min), max: fast_max(self.max, o.max) }
    }

    #[inline]
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    #[inline]
    pub fn extent(&self) -> Vec3 {
        self.max - self.min
    }

    /// The axis (0, 1, 2) along which the box is longest (the first of equals).
    pub fn longest_axis(&self) -> usize {
        let e = self.extent();
        if e.x >= e.y && e.x >= e.z {
            0
        } else if e.y >= e.z {
            1
        } else {
            2
        }
    }

    #[inline]
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// Surface area; 0 for the empty box, so empty children cost nothing in the SAH.
    #[inline]
    pub fn surface_area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// The box both enclose (empty if they are disjoint).
    #[inline]
    pub fn overlap(self, o: Aabb) -> Self {
        Self { min: fast_max(self.min, o.min), max: fast_min(self.max, o.max) }
    }

    /// True if `o` lies inside `self` (inclusive); the empty box is inside everything.
    pub fn contains(&self, o: &Aabb) -> bool {
        o.is_empty() || (self.min.cmple(o.min).all() && self.max.cmpge(o.max).all())
    }

    /// Slab test with the ray's precomputed inverse direction (Kay & Kajiya; Williams et al.
    /// 2005). Returns the entry distance if the box is hit within `[ray.tmin, ray.tmax]`,
    /// otherwise `f32::INFINITY`. A ray lying in a slab's plane counts as inside that
    /// slab (see [`crate::ray::safe_recip`]).
    ///
    /// The exit distance, clipped to `ray.tmax`, is enlarged by `1 + 2γ₃` (Ize 2013, "Robust
    /// BVH Ray Traversal"), so that rounding never makes a ray miss a box that it touches, nor
    /// prune a box whose entry distance rounds to just beyond a hit found elsewhere: without
    /// it, rays grazing flat boxes (axis-aligned triangles) lose hits.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray) -> f32 {
        // Plain comparisons compile to single min/max instructions; NaN cannot occur here
        // because `Ray` never holds an infinite inverse direction (see `safe_recip`).
        #[inline(always)]
        fn min(a: f32, b: f32) -> f32 {
            if a < b {
                a
            } else {
                b
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
        let (o, inv) = (ray.origin, ray.inv_dir);
        let (tx0, tx1) = ((self.min.x - o.x) * inv.x, (self.max.x - o.x) * inv.x);
        let (ty0, ty1) = ((self.min.y - o.y) * inv.y, (self.max.y - o.y) * inv.y);
        let (tz0, tz1) = ((self.min.z - o.z) * inv.z, (self.max.z - o.z) * inv.z);
        let tnear = max(max(min(tx0, tx1), min(ty0, ty1)), max(min(tz0, tz1), ray.tmin));
        let tfar = min(min(max(tx0, tx1), max(ty0, ty1)), min(max(tz0, tz1), ray.tmax)) * ROBUST_SLAB;
        if tnear <= tfar {
            tnear
        } else {
            f32::INFINITY
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slab_hits_and_misses() {
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        let hit = Ray::new(Vec3::new(0.5, 0.5, -1.0), Vec3::Z);
        assert_eq!(b.intersect(&hit), 1.0);
        let miss = Ray::new(Vec3::new(1.5, 0.5, -1.0), Vec3::Z);
        assert_eq!(b.intersect(&miss), f32::INFINITY);
        let behind = Ray::new(Vec3::new(0.5, 0.5, 2.0), Vec3::Z);
        assert_eq!(b.intersect(&behind), f32::INFINITY);
        let inside = Ray::new(Vec3::splat(0.5), Vec3::X);
        assert_eq!(b.intersect(&inside), 0.0);
    }

    #[test]
    fn slab_ray_in_face_plane_and_flat_box() {
        // Ray parallel to x, lying in the box's min-y plane: counts as a hit (inclusive).
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        let r = Ray::new(Vec3::new(-1.0, 0.0, 0.5), Vec3::X);
        assert_eq!(b.intersect(&r), 1.0);
        // A flat box (a triangle in the z = 0 plane) is still hit head-on.
        let flat = Aabb::new(Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.0));
        let r = Ray::new(Vec3::new(0.5, 0.5, -1.0), Vec3::Z);
        assert_eq!(flat.intersect(&r), 1.0);
    }

    #[test]
    fn empty_box_properties() {
        assert_eq!(Aabb::EMPTY.surface_area(), 0.0);
        let b = Aabb::new(Vec3::ZERO, Vec3::ONE);
        assert_eq!(Aabb::EMPTY.union(b), b);
        assert!(b.contains(&Aabb::EMPTY));
        assert_eq!(b.surface_area(), 6.0);
    }
}
