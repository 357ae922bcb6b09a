//! Ray–sphere intersection by the quadratic formula, in the numerically careful form of
//! Ray Tracing Gems ch. 7 (Haines et al., "Precision Improvements for Ray/Sphere
//! Intersection"): the discriminant is computed from the distance of the centre to the ray
//! rather than from `b² - 4ac`, which cancels catastrophically for small or distant spheres.

use crate::aabb::Aabb;
use crate::ray::Ray;
use glam::Vec3;

/// A sphere; a negative radius keeps the same surface but flips its normals inwards
/// (the "hollow glass" trick of Ray Tracing in One Weekend).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    pub center: Vec3,
    pub radius: f32,
}

impl Sphere {
    pub fn bounds(&self) -> Aabb {
        let r = Vec3::splat(self.radius.abs());
        Aabb::new(self.center - r, self.center + r)
    }

    /// The nearest `t` in `(ray.tmin, ray.tmax]`, if any.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        let r = self.radius.abs();
        let f = ray.origin - self.center;
        let a = ray.dir.length_squared();
        let b = -f.dot(ray.dir);
        // Distance from the centre to the ray's line: f + (b/a) d.
        let l = f + (b / a) * ray.dir;
        let disc = a * (r * r - l.length_squared());
        if disc < 0.0 {
            return None;
        }
        let sq = disc.sqrt();
        let q = b + b.signum() * sq;
        let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (q / a, (f.length_squared() - r * r) / q) };
        let (near, far) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
        [near, far].into_iter().find(|&t| t > ray.tmin && t <= ray.tmax)
    }

    /// Outward normal at a surface point (inward for a negative radius).
    #[inline]
    pub fn normal(&self, p: Vec3) -> Vec3 {
        (p - self.center) / self.radius
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn front_back_and_inside() {
        let s = Sphere { center: Vec3::new(0.0, 0.0, -5.0), radius: 1.0 };
        let r = Ray::new(Vec3::ZERO, -Vec3::Z);
        assert!((s.intersect(&r).unwrap() - 4.0).abs() < 1e-5);
        let inside = Ray::new(Vec3::new(0.0, 0.0, -5.0), Vec3::X);
        assert!((s.intersect(&inside).unwrap() - 1.0).abs() < 1e-5);
        let miss = Ray::new(Vec3::new(0.0, 1.5, 0.0), -Vec3::Z);
        assert!(s.intersect(&miss).is_none());
        let away = Ray::new(Vec3::ZERO, Vec3::Z);
        assert!(s.intersect(&away).is_none());
    }

    #[test]
    fn small_distant_sphere_is_accurate() {
        let s = Sphere { center: Vec3::new(0.0, 0.0, -1.0e4), radius: 0.01 };
        let r = Ray::new(Vec3::ZERO, -Vec3::Z);
        let t = s.intersect(&r).expect("hit");
        assert!((t - (1.0e4 - 0.01)).abs() < 2e-3, "t = {t}");
    }

    #[test]
    fn negative_radius_flips_normal() {
        let s = Sphere { center: Vec3::ZERO, radius: -2.0 };
        assert_eq!(s.normal(Vec3::new(2.0, 0.0, 0.0)), -Vec3::X);
        assert_eq!(s.bounds().max, Vec3::splat(2.0));
    }
}
