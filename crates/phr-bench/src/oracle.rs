//! What every traversal's hits are checked against: brute force over all triangles, and the
//! binary ordered traversal with the scalar Möller–Trumbore test (the reference). Ties (equal
//! `t`) go to the lowest primitive index in both, as in the wide traversal.

use glam::Vec3;
use phr_bvh::triangle::intersect_triangle;
use phr_bvh::wide::{Lanes, Width};
use phr_bvh::{any_hit, closest_hit, closest_hit_counted, Bvh, PackedTriangles, Ray, TraversalStats, WideBvh};

/// A closest hit: primitive index and distance.
pub type Hit = Option<(u32, f32)>;

/// Closest hit over every triangle.
pub fn brute_force(tris: &[[Vec3; 3]], ray: &Ray) -> Hit {
    let mut best: Hit = None;
    for (i, [a, b, c]) in tris.iter().enumerate() {
        if let Some(h) = intersect_triangle(ray, *a, *b, *c) {
            if best.is_none_or(|(_, t)| h.t < t) {
                best = Some((i as u32, h.t));
            }
        }
    }
    best
}

/// The reference: binary ordered traversal, scalar Möller–Trumbore.
#[inline]
pub fn binary_hit(bvh: &Bvh, tris: &[[Vec3; 3]], ray: &Ray) -> Hit {
    let mut r = *ray;
    let mut best: Hit = None;
    closest_hit(bvh, &mut r, |p, r| binary_test(tris, p, r, &mut best));
    best
}

/// [`binary_hit`]'s nodes visited and triangles tested.
pub fn binary_work(bvh: &Bvh, tris: &[[Vec3; 3]], ray: &Ray) -> [u64; 2] {
    let mut s = TraversalStats::default();
    let (mut r, mut best) = (*ray, None);
    closest_hit_counted(bvh, &mut r, |p, r| binary_test(tris, p, r, &mut best), &mut s);
    [s.nodes as u64, s.prims as u64]
}

#[inline(always)]
fn binary_test(tris: &[[Vec3; 3]], p: u32, r: &mut Ray, best: &mut Hit) -> bool {
    let [a, b, c] = tris[p as usize];
    match intersect_triangle(r, a, b, c) {
        Some(h) if h.t < r.tmax || best.is_none_or(|(bp, _)| p < bp) => {
            r.tmax = h.t;
            *best = Some((p, h.t));
            true
        }
        _ => false,
    }
}

/// Any hit by the binary reference traversal.
#[inline]
pub fn binary_occluded(bvh: &Bvh, tris: &[[Vec3; 3]], ray: &Ray) -> bool {
    any_hit(bvh, ray, |p, r| {
        let [a, b, c] = tris[p as usize];
        intersect_triangle(r, a, b, c).is_some()
    })
}

/// The wide traversal's closest hit, in the reference's form.
#[inline]
pub fn wide_hit<const N: usize>(wide: &WideBvh<N>, packed: &PackedTriangles, ray: &Ray) -> Hit
where
    Lanes<N>: Width<N>,
{
    wide.closest_triangle(packed, ray).map(|(p, h)| (p, h.t))
}

/// Whether `got` is right for `ray` where the reference found `reference`: equal, or equal to
/// brute force. (A hit accepted by the triangle test's edge tolerance just outside the
/// triangle's box can be missed by the binary reference and found in a merged leaf's larger
/// box.) `Err` carries the brute-force hit when `got` is neither.
pub fn agrees(got: Hit, reference: Hit, tris: &[[Vec3; 3]], ray: &Ray) -> Result<(), Hit> {
    if got == reference {
        return Ok(());
    }
    let brute = brute_force(tris, ray);
    if got == brute {
        Ok(())
    } else {
        Err(brute)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use phr_bvh::{Aabb, Builder};

    #[test]
    fn the_reference_and_the_wide_traversal_equal_brute_force() {
        let mut tris = Vec::new();
        for i in 0..200 {
            let c = Vec3::new((i % 10) as f32, ((i / 10) % 5) as f32, (i / 50) as f32);
            tris.push([c, c + Vec3::new(0.9, 0.1, 0.0), c + Vec3::new(0.2, 0.8, 0.3)]);
        }
        let boxes: Vec<Aabb> = tris.iter().map(|t| Aabb::from_points(t)).collect();
        let bvh = Builder::default().build(&boxes);
        let wide = WideBvh::<8>::from_bvh(&bvh);
        let packed = PackedTriangles::new(&wide.prim_indices, &tris);
        let mut hits = 0;
        for i in 0..400 {
            let o = Vec3::new((i % 20) as f32 * 0.5 + 0.1, (i / 20) as f32 * 0.25 + 0.05, 10.0);
            let ray = Ray::new(o, Vec3::new(0.03, 0.02, -1.0).normalize());
            let brute = brute_force(&tris, &ray);
            hits += brute.is_some() as usize;
            assert_eq!(binary_hit(&bvh, &tris, &ray), brute);
            assert_eq!(agrees(wide_hit(&wide, &packed, &ray), brute, &tris, &ray), Ok(()));
            assert_eq!(binary_occluded(&bvh, &tris, &ray), brute.is_some());
        }
        assert!(hits > 100, "{hits} hits");
        assert_eq!(agrees(Some((0, 1e9)), None, &tris, &Ray::new(Vec3::splat(-5.0), -Vec3::X)), Err(None));
    }
}
