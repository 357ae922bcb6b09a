//! The renderer's geometry (`geometry.rs`) against brute force and against what its
//! documentation and `shared/reference/README.md` promise.
//!
//! Random scenes of triangles and spheres (of both radius signs), every primitive present
//! twice at unrelated indices so that every hit is a tie: `Geometry::intersect`, the counting
//! query and the shadow-ray query equal a brute-force loop over all primitives in index order
//! (closest hit, ties to the lower index) for every builder, with and without spheres (the two
//! traversal paths). Each hit's `surface_point` lies on the primitive at the ray's `t`, has
//! the unit normal the README defines (`(v1 − v0) × (v2 − v0)` for triangles, outward, inward
//! for a negative radius, for spheres), is `front` exactly when the ray arrives from the side
//! the normal points to (judged from a point just before the hit: outside or inside the
//! sphere, above or below the plane), and carries the README's secondary-ray offset; a ray
//! leaving from `spawn_origin` does not hit its own surface again.

use glam::Vec3;
use phr_bvh::sphere::Sphere;
use phr_bvh::triangle::intersect_triangle;
use phr_bvh::{Builder, Ray, TraversalStats};
use phr_render::geometry::{Geometry, Hit, NO_SLOT};
use phr_render::material::Material;
use phr_render::sampler::Pcg32;
use phr_render::scene::{Mesh, Scene, SphereObject};

fn uniform(rng: &mut Pcg32, lo: f32, hi: f32) -> f32 {
    lo + (hi - lo) * rng.next_f32()
}

fn point(rng: &mut Pcg32, half: f32) -> Vec3 {
    Vec3::new(uniform(rng, -half, half), uniform(rng, -half, half), uniform(rng, -half, half))
}

/// `triangles` random triangles and `spheres` random spheres (every other one with a negative
/// radius), each followed later by a copy at a shuffled index.
fn scene(triangles: usize, spheres: usize, seed: u64) -> Scene {
    let mut rng = Pcg32::new(seed, 1);
    let mut scene = Scene::default();
    scene.add_material("a", Material::Lambertian { albedo: Vec3::ONE });
    scene.add_material("b", Material::Lambertian { albedo: Vec3::ONE });
    let mut tris: Vec<[Vec3; 3]> = (0..triangles)
        .map(|_| {
            let c = point(&mut rng, 10.0);
            [c + point(&mut rng, 2.0), c + point(&mut rng, 2.0), c + point(&mut rng, 2.0)]
        })
        .collect();
    let mut balls: Vec<Sphere> = (0..spheres)
        .map(|i| {
            let r = uniform(&mut rng, 0.3, 1.5);
            Sphere { center: point(&mut rng, 10.0), radius: if i % 2 == 0 { r } else { -r } }
        })
        .collect();
    let shuffled = |n: usize, rng: &mut Pcg32| {
        let mut order: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            order.swap(i, rng.next_u32() as usize % (i + 1));
        }
        order
    };
    let copies: Vec<[Vec3; 3]> = shuffled(triangles, &mut rng).into_iter().map(|i| tris[i]).collect();
    tris.extend(copies);
    let copies: Vec<Sphere> = shuffled(spheres, &mut rng).into_iter().map(|i| balls[i]).collect();
    balls.extend(copies);
    scene.meshes.push(Mesh {
        name: "random".into(),
        positions: tris.iter().flatten().copied().collect(),
        triangles: (0..tris.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect(),
        triangle_material: (0..tris.len() as u32).map(|i| i % 2).collect(),
        uvs: Vec::new(),
    });
    scene.spheres =
        balls.into_iter().enumerate().map(|(i, sphere)| SphereObject { sphere, material: i as u32 % 2 }).collect();
    scene
}

/// Closest hit by testing every primitive in index order; a later one must be strictly
/// closer, so ties go to the lower index. Returns (t, primitive, how many primitives were hit
/// at exactly that t).
fn brute_force(triangles: &[[Vec3; 3]], spheres: &[SphereObject], ray: &Ray) -> Option<(f32, u32, usize)> {
    let ts = triangles
        .iter()
        .map(|t| intersect_triangle(ray, t[0], t[1], t[2]).map(|h| h.t))
        .chain(spheres.iter().map(|s| s.sphere.intersect(ray)));
    let mut best: Option<(f32, u32, usize)> = None;
    for (i, t) in ts.enumerate() {
        let Some(t) = t else { continue };
        match best {
            Some((bt, _, ref mut ties)) if t == bt => *ties += 1,
            Some((bt, _, _)) if t > bt => {}
            _ => best = Some((t, i as u32, 1)),
        }
    }
    best
}

/// Random rays through the scene: some with a finite interval, some starting past 0.
fn rays(count: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Pcg32::new(seed, 2);
    (0..count)
        .map(|i| {
            let origin = point(&mut rng, 12.0);
            let dir = (point(&mut rng, 10.0) - origin).normalize_or(Vec3::X);
            match i % 4 {
                0 => Ray::with_interval(origin, dir, 0.0, uniform(&mut rng, 1.0, 25.0)),
                1 => Ray::with_interval(origin, dir, uniform(&mut rng, 0.5, 5.0), f32::INFINITY),
                _ => Ray::new(origin, dir),
            }
        })
        .collect()
}

fn builders() -> Vec<Builder> {
    let mut builders: Vec<Builder> =
        ["lbvh", "phr-fast", "phr-hq", "sweep-sah", "binned-sah"].iter().map(|s| s.parse().unwrap()).collect();
    builders.push(Builder::PHR_HQ.with_branching(4).unwrap());
    builders
}

/// Checks every query against brute force for every builder; returns (hits, ties) over all rays.
fn check_against_brute_force(scene: &Scene, rays: &[Ray]) -> (usize, usize) {
    let mut geometry = Geometry::new(scene);
    let (mut hits, mut ties) = (0, 0);
    for builder in builders() {
        geometry.build(&builder);
        for (i, ray) in rays.iter().enumerate() {
            let expected = brute_force(&geometry.triangles, &geometry.spheres, ray);
            let got = geometry.intersect(ray);
            assert_eq!(
                got.map(|h| (h.t, h.prim)),
                expected.map(|e| (e.0, e.1)),
                "{builder}: intersect, ray {i} {ray:?}"
            );
            let counted = geometry.intersect_counted(ray, &mut TraversalStats::default());
            assert_eq!(
                counted.map(|h| (h.t, h.prim)),
                expected.map(|e| (e.0, e.1)),
                "{builder}: intersect_counted, ray {i}"
            );
            assert_eq!(geometry.occluded(ray), expected.is_some(), "{builder}: occluded, ray {i} {ray:?}");
            if let (Some(fast), Some(reference)) = (got, counted) {
                // The wide query says where its triangle is packed; shading from there gives
                // the same bits as from the scene-order triangle the counting query names.
                let is_triangle = (fast.prim as usize) < geometry.triangles.len();
                assert_eq!(fast.slot != NO_SLOT, is_triangle, "{builder}: slot of ray {i}");
                assert_eq!(reference.slot, NO_SLOT);
                let (a, b) = (geometry.surface_point(ray, &fast), geometry.surface_point(ray, &reference));
                assert_eq!(
                    (a.position, a.normal, a.front, a.material, a.offset),
                    (b.position, b.normal, b.front, b.material, b.offset),
                    "{builder}: surface point, ray {i}"
                );
            }
            if let Some((_, _, n)) = expected {
                hits += 1;
                ties += (n > 1) as usize;
            }
        }
    }
    (hits, ties)
}

#[test]
fn closest_hit_equals_brute_force_with_ties_to_the_lower_index() {
    let rays = rays(3000, 5);
    // Triangles only (the renderer's 4-wide leaf path), then triangles and spheres together.
    for (triangles, spheres) in [(150, 0), (100, 40)] {
        let (hits, ties) = check_against_brute_force(&scene(triangles, spheres, 9), &rays);
        // Not vacuous: most hits are on a duplicated primitive, at exactly the same t.
        assert!(
            hits > 3000 && ties > hits * 9 / 10,
            "{triangles} triangles, {spheres} spheres: {hits} hits, {ties} ties"
        );
    }
}

#[test]
fn spheres_alone_match_brute_force() {
    let (hits, ties) = check_against_brute_force(&scene(0, 60, 4), &rays(2000, 6));
    assert!(hits > 1000 && ties > hits * 9 / 10, "{hits} hits, {ties} ties");
}

/// Whether `p` is on the side the primitive's normal points to: above a triangle's plane, or
/// outside a sphere of positive radius (inside one of negative radius).
fn on_normal_side(geometry: &Geometry, prim: usize, p: Vec3) -> bool {
    if let Some(t) = geometry.triangles.get(prim) {
        (p - t[0]).dot((t[1] - t[0]).cross(t[2] - t[0])) > 0.0
    } else {
        let s = geometry.spheres[prim - geometry.triangles.len()].sphere;
        ((p - s.center).length() > s.radius.abs()) == (s.radius > 0.0)
    }
}

/// Whether primitives `a` and `b` are the same surface (the same one or its copy).
fn same_surface(geometry: &Geometry, a: usize, b: usize) -> bool {
    let n = geometry.triangles.len();
    match (a < n, b < n) {
        (true, true) => geometry.triangles[a] == geometry.triangles[b],
        (false, false) => geometry.spheres[a - n].sphere == geometry.spheres[b - n].sphere,
        _ => false,
    }
}

#[test]
fn surface_points_lie_on_the_primitive_with_the_documented_normal_side_and_offset() {
    let scene = scene(100, 40, 2);
    let mut geometry = Geometry::new(&scene);
    geometry.build(&Builder::default());
    let n_tris = geometry.triangles.len();
    let (mut checked, mut fronts, mut backs) = (0, 0, 0);
    for ray in rays(4000, 8) {
        let Some(hit): Option<Hit> = geometry.intersect(&ray) else { continue };
        let sp = geometry.surface_point(&ray, &hit);
        let prim = hit.prim as usize;
        let at = ray.at(hit.t);
        assert!((sp.position - at).length() < 1e-4 * (1.0 + at.length()), "position {} vs o + t d = {at}", sp.position);
        assert!((sp.normal.length() - 1.0).abs() < 1e-5, "normal {} not unit", sp.normal);
        let (expected_normal, rel) = if let Some(t) = geometry.triangles.get(prim) {
            assert_eq!(sp.material, scene.meshes[0].triangle_material[prim]);
            ((t[1] - t[0]).cross(t[2] - t[0]).normalize(), 1.0e-6)
        } else {
            let s = &geometry.spheres[prim - n_tris];
            assert_eq!(sp.material, s.material);
            let radial = sp.position - s.sphere.center;
            assert!((radial.length() - s.sphere.radius.abs()).abs() < 1e-5 * (1.0 + at.length()), "off sphere {prim}");
            (radial.normalize() * s.sphere.radius.signum(), 1500.0 / 16_777_216.0)
        };
        assert!(
            sp.normal.dot(expected_normal) > 1.0 - 1e-5,
            "primitive {prim}: normal {} vs {expected_normal}",
            sp.normal
        );
        // README: secondary rays start rel · (1 + max|p|) off the surface.
        let offset = rel * (1.0 + sp.position.abs().max_element());
        assert!((sp.offset / offset - 1.0).abs() < 1e-5, "primitive {prim}: offset {} vs {offset}", sp.offset);
        // The side the ray came from, away from grazing hits where "just before" is ambiguous.
        let dir = ray.dir.normalize();
        if dir.dot(sp.normal).abs() < 0.05 {
            continue;
        }
        let before = ray.at(hit.t - 0.01);
        assert_eq!(sp.front, on_normal_side(&geometry, prim, before), "primitive {prim}: front, ray {ray:?}");
        (fronts, backs) = if sp.front { (fronts + 1, backs) } else { (fronts, backs + 1) };
        // Leaving by reflection or straight on: not stuck on the surface it left.
        for out in [dir - 2.0 * dir.dot(sp.normal) * sp.normal, dir] {
            let origin = sp.spawn_origin(out);
            // By the offset, up to the rounding of the position (a tenth of the offset at |p| = 20).
            let moved = (origin - sp.position).length() / sp.offset;
            assert!((moved - 1.0).abs() < 0.3, "spawn origin moved by {moved} offsets");
            assert!((origin - sp.position).dot(out) > 0.0, "spawn origin on the side the ray leaves to");
            if let Some(again) = geometry.intersect(&Ray::new(origin, out)) {
                let same = same_surface(&geometry, prim, again.prim as usize);
                assert!(
                    !(same && again.t < 1e-3),
                    "primitive {prim}: leaving towards {out} hits it again at t = {}",
                    again.t
                );
            }
        }
        checked += 1;
    }
    assert!(checked > 1000 && fronts > 300 && backs > 300, "{checked} hits checked, {fronts} front, {backs} back");
}

/// A part's boxes, recomputed after its triangles moved, land in the scene's box array at the
/// part's primitives and nowhere else (the parallel scatter, on a part large enough to split).
#[test]
fn part_boxes_go_back_to_their_primitives() {
    use phr_bvh::triangle::triangle_bounds;
    let scene = scene(60_000, 4, 31);
    let mut geometry = Geometry::new(&scene);
    let n = geometry.prim_count() as u32;
    // Every third primitive in the second part, the rest in the first.
    let (a, b): (Vec<u32>, Vec<u32>) = (0..n).partition(|p| p % 3 != 1);
    geometry.split(vec![a, b.clone()], &Builder::PHR_FAST);
    let before = geometry.boxes.clone();
    for &p in &b {
        if let Some(t) = geometry.triangles.get_mut(p as usize) {
            *t = t.map(|v| v * 1.5 + Vec3::new(0.25, -1.0, 2.0));
        }
    }
    let part = geometry.part_boxes(1);
    assert_eq!(part.len(), b.len());
    for (p, (&old, &now)) in before.iter().zip(&geometry.boxes).enumerate() {
        let want = match geometry.triangles.get(p) {
            Some(&[v0, v1, v2]) if p % 3 == 1 => triangle_bounds(v0, v1, v2),
            _ => old,
        };
        assert_eq!(now, want, "primitive {p}");
    }
    assert_eq!(geometry.boxes.len(), n as usize);
    for (i, &p) in b.iter().enumerate() {
        assert_eq!(part[i], geometry.boxes[p as usize], "part entry {i}");
    }
}
