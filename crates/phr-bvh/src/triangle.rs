//! Ray–triangle intersection, Möller & Trumbore 1997 ("Fast, minimum storage ray/triangle
//! intersection").
//!
//! Edge robustness: a ray through the shared edge of two triangles must hit at least one of
//! them, or holes ("cracks") appear in watertight meshes. Rounding can push the barycentrics
//! of an edge point slightly negative in *both* triangles. The two barycentric numerators
//! are dot products whose rounding error is bounded by a few ulps of the dot product of the
//! absolute values (Higham, *Accuracy and Stability of Numerical Algorithms*, 3.1), so the
//! inside test accepts that slack ([`EDGE_TOLERANCE`] times that bound, at most
//! [`MAX_EDGE_SLACK`]). A ray then
//! may hit both neighbours at the same `t`, which is harmless for closest-hit queries. The
//! test `no_cracks_on_watertight_meshes` checks this on shared edges and vertices.

use crate::ray::Ray;
use glam::Vec3;

/// Slack of the barycentric inside test, in units of the rounding-error bound of the
/// numerators (see the module documentation).
pub const EDGE_TOLERANCE: f32 = 8.0 * f32::EPSILON;

/// Upper limit of that slack, in barycentric units. For rays grazing the triangle's plane the
/// error bound grows without limit (the determinant goes to 0); capping it keeps every hit
/// within a hair of the triangle, and so inside (the robust slab test of) its bounding box,
/// which the BVH relies on.
pub const MAX_EDGE_SLACK: f32 = 1.0e-5;

/// A hit on a triangle: distance along the ray and barycentrics of v1 (`u`) and v2 (`v`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    pub t: f32,
    pub u: f32,
    pub v: f32,
}

/// Möller–Trumbore. Returns a hit with `ray.tmin < t <= ray.tmax` (inclusive at the far end,
/// so a caller can break ties between hits at equal distance) and `t` finite, both faces
/// counted. Degenerate (zero-area) triangles have a zero determinant and are never hit. (A
/// `t` that overflows to infinity, as with coordinates near f32's limit, is no hit: the
/// builder fuzz test found the trees, rightly, never reaching one.)
#[inline(always)]
pub fn intersect_triangle(ray: &Ray, v0: Vec3, v1: Vec3, v2: Vec3) -> Option<TriangleHit> {
    intersect_triangle_edges(ray, v0, v1 - v0, v2 - v0)
}

/// [`intersect_triangle`] with the edges `e1 = v1 - v0` and `e2 = v2 - v0` precomputed (as
/// [`crate::wide::PackedTriangles`] stores them). Both run this one body, so their hits are
/// bit-identical.
#[inline(always)]
pub fn intersect_triangle_edges(ray: &Ray, v0: Vec3, e1: Vec3, e2: Vec3) -> Option<TriangleHit> {
    let p = ray.dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = ray.origin - v0;
    let q = s.cross(e1);
    // Numerators and their rounding-error bounds, scaled like the barycentrics.
    let u = s.dot(p) * inv_det;
    let v = ray.dir.dot(q) * inv_det;
    let abs_inv_det = inv_det.abs();
    let tol_u = (EDGE_TOLERANCE * s.abs().dot(p.abs()) * abs_inv_det).min(MAX_EDGE_SLACK);
    let tol_v = (EDGE_TOLERANCE * ray.dir.abs().dot(q.abs()) * abs_inv_det).min(MAX_EDGE_SLACK);
    if u < -tol_u || v < -tol_v || u + v > 1.0 + tol_u + tol_v {
        return None;
    }
    let t = e2.dot(q) * inv_det;
    if t > ray.tmin && t <= ray.tmax && t < f32::INFINITY {
        Some(TriangleHit { t, u, v })
    } else {
        None
    }
}

/// The box a BVH should hold a triangle in: its bounds grown by the inside test's largest
/// slack. [`intersect_triangle`] accepts barycentrics down to `-MAX_EDGE_SLACK`, so a hit may
/// lie up to `MAX_EDGE_SLACK · (|e1| + |e2|)` (at most `2√3 · MAX_EDGE_SLACK` times the box's
/// largest extent) outside the triangle, and so outside its exact bounds, where a traversal
/// would never look for it.
#[inline]
pub fn triangle_bounds(v0: Vec3, v1: Vec3, v2: Vec3) -> crate::Aabb {
    let b = crate::Aabb::from_points(&[v0, v1, v2]);
    let pad = Vec3::splat(4.0 * MAX_EDGE_SLACK * b.extent().max_element());
    crate::Aabb { min: b.min - pad, max: b.max + pad }
}

/// The unnormalised geometric normal `(v1 - v0) × (v2 - v0)` (counter-clockwise = front).
#[inline]
pub fn triangle_normal(v0: Vec3, v1: Vec3, v2: Vec3) -> Vec3 {
    (v1 - v0).cross(v2 - v0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> (Vec3, Vec3, Vec3) {
        (Vec3::ZERO, Vec3::X, Vec3::Y)
    }

    #[test]
    fn hits_inside_misses_outside() {
        let (a, b, c) = tri();
        let r = Ray::new(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z);
        let h = intersect_triangle(&r, a, b, c).expect("hit");
        assert!((h.t - 1.0).abs() < 1e-6 && (h.u - 0.25).abs() < 1e-6 && (h.v - 0.25).abs() < 1e-6);
        let r = Ray::new(Vec3::new(0.75, 0.75, 1.0), -Vec3::Z);
        assert!(intersect_triangle(&r, a, b, c).is_none());
        // Behind the origin and beyond tmax.
        let r = Ray::new(Vec3::new(0.25, 0.25, 1.0), Vec3::Z);
        assert!(intersect_triangle(&r, a, b, c).is_none());
        let r = Ray::with_interval(Vec3::new(0.25, 0.25, 1.0), -Vec3::Z, 0.0, 0.5);
        assert!(intersect_triangle(&r, a, b, c).is_none());
    }

    #[test]
    fn degenerate_and_parallel_never_hit() {
        let r = Ray::new(Vec3::new(0.0, 0.0, 1.0), -Vec3::Z);
        assert!(intersect_triangle(&r, Vec3::ZERO, Vec3::X, 2.0 * Vec3::X).is_none());
        assert!(intersect_triangle(&r, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO).is_none());
        let (a, b, c) = tri();
        let r = Ray::new(Vec3::new(-1.0, 0.25, 0.0), Vec3::X);
        assert!(intersect_triangle(&r, a, b, c).is_none());
    }

    #[test]
    fn no_cracks_on_watertight_meshes() {
        // A bumpy grid of 2 triangles per cell; shoot rays exactly at shared edge midpoints and
        // shared vertices from many directions: each must hit something.
        let n = 24;
        let height = |i: usize, j: usize| ((i * 7 + j * 13) % 11) as f32 * 0.037;
        let p = |i: usize, j: usize| Vec3::new(i as f32 * 0.31 + 100.0, height(i, j), j as f32 * 0.29 - 50.0);
        let mut tris = Vec::new();
        for i in 0..n {
            for j in 0..n {
                tris.push([p(i, j), p(i + 1, j), p(i + 1, j + 1)]);
                tris.push([p(i, j), p(i + 1, j + 1), p(i, j + 1)]);
            }
        }
        let mut targets = Vec::new();
        for i in 1..n {
            for j in 1..n {
                targets.push(p(i, j));
                targets.push(0.5 * (p(i, j) + p(i + 1, j + 1)));
                targets.push(0.5 * (p(i, j) + p(i + 1, j)));
            }
        }
        let mut misses = 0;
        let mut rays = 0;
        for (k, target) in targets.iter().enumerate() {
            for d in 0..8 {
                let a = (k * 8 + d) as f32 * 0.618;
                let dir = Vec3::new(a.cos() * 0.6, -1.0, a.sin() * 0.6).normalize();
                let origin = *target - 3.0 * dir;
                let ray = Ray::new(origin, dir);
                rays += 1;
                if !tris.iter().any(|t| intersect_triangle(&ray, t[0], t[1], t[2]).is_some()) {
                    misses += 1;
                }
            }
        }
        assert_eq!(misses, 0, "{misses} of {rays} rays through shared edges fell through");
    }
}
