//! The BVH over real scanned and modelled meshes (the Stanford bunny, the Cornell box): the tree
//! passes `validate`, and closest hits through it, both with phr-bvh's traversal directly and
//! through the renderer's `Geometry::intersect`, equal brute force over every triangle.

use glam::Vec3;
use phr_bvh::triangle::intersect_triangle;
use phr_bvh::{closest_hit, validate, Aabb, Builder, Bvh, Ray};
use phr_render::geometry::Geometry;
use phr_render::load::load_mesh;
use phr_render::scene::{Mesh, Scene};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

fn scenes() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/scenes"))
}

// The helpers below are copied from crates/phr-bvh/tests/common/mod.rs (private to that crate's
// tests): same RNG, same ray distribution, same tie rule.

struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1)
    }
    fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    fn vec3(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        lo + (hi - lo) * Vec3::new(self.f32(), self.f32(), self.f32())
    }
    fn unit_vector(&mut self) -> Vec3 {
        loop {
            let v = self.vec3(Vec3::splat(-1.0), Vec3::ONE);
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
}

/// Closest hit (t, primitive) by testing every triangle; ties go to the lower index.
fn brute_force(tris: &[[Vec3; 3]], ray: &Ray) -> Option<(f32, u32)> {
    let mut best: Option<(f32, u32)> = None;
    for (i, t) in tris.iter().enumerate() {
        if let Some(h) = intersect_triangle(ray, t[0], t[1], t[2]) {
            if best.is_none_or(|(bt, _)| h.t < bt) {
                best = Some((h.t, i as u32));
            }
        }
    }
    best
}

/// Closest hit through the BVH, with the same tie rule as [`brute_force`].
fn bvh_hit(bvh: &Bvh, tris: &[[Vec3; 3]], ray: &Ray) -> Option<(f32, u32)> {
    let mut r = *ray;
    let mut best: Option<(f32, u32)> = None;
    closest_hit(bvh, &mut r, |p, r| {
        let t = &tris[p as usize];
        match intersect_triangle(r, t[0], t[1], t[2]) {
            Some(h) if h.t < r.tmax || (h.t == r.tmax && best.is_some_and(|(_, bp)| p < bp)) => {
                r.tmax = h.t;
                best = Some((h.t, p));
                true
            }
            _ => false,
        }
    });
    best
}

/// Random rays: from random points around the scene box towards random points inside it
/// (even indices), and in fully random directions (odd indices).
fn random_rays(bounds: Aabb, count: usize, rng: &mut Rng) -> Vec<Ray> {
    let c = bounds.center();
    let e = bounds.extent().max(Vec3::splat(1e-6));
    (0..count)
        .map(|i| {
            let origin = rng.vec3(c - e, c + e);
            let dir = if i % 2 == 0 { rng.vec3(bounds.min, bounds.max) - origin } else { rng.unit_vector() };
            let dir = if dir.length_squared() > 0.0 { dir.normalize() } else { Vec3::X };
            Ray::new(origin, dir)
        })
        .collect()
}

/// Loads `file`, builds the default BVH, validates it and checks `rays` random rays against
/// brute force. Returns (triangles, hits).
fn check_scene(file: &Path, rays: usize, seed: u64) -> (usize, usize) {
    assert!(file.is_file(), "missing {} (shared/ must sit next to the repository)", file.display());
    let data = load_mesh(file).unwrap_or_else(|e| panic!("{e}"));
    let name = file.display().to_string();

    // phr-bvh on its own: triangle boxes in, tree out.
    let tris: Vec<[Vec3; 3]> = data.triangles.iter().map(|t| t.map(|i| data.positions[i as usize])).collect();
    let boxes: Vec<Aabb> = tris.iter().map(|t| Aabb::from_points(t)).collect();
    let builder = Builder::default();
    let bvh = builder.build(&boxes);
    validate(&bvh, &boxes, builder.max_leaf_size()).unwrap_or_else(|e| panic!("{name}: invalid tree: {e}"));

    // The renderer's geometry over the same triangles, in the same order.
    let n = data.triangles.len();
    let mut scene = Scene::default();
    scene.meshes.push(Mesh {
        name: name.clone(),
        positions: data.positions.clone(),
        triangles: data.triangles.clone(),
        triangle_material: vec![0; n],
        uvs: Vec::new(),
    });
    let mut geometry = Geometry::new(&scene);
    assert_eq!(geometry.triangles, tris);
    geometry.build(&builder);
    validate(geometry.bvh(), &geometry.boxes, builder.max_leaf_size())
        .unwrap_or_else(|e| panic!("{name}: invalid geometry tree: {e}"));

    let bounds = boxes.iter().fold(Aabb::EMPTY, |b, x| b.union(*x));
    let rays = random_rays(bounds, rays, &mut Rng::new(seed));
    let hits: usize = rays
        .par_iter()
        .enumerate()
        .map(|(i, ray)| {
            let expected = brute_force(&tris, ray);
            assert_eq!(bvh_hit(&bvh, &tris, ray), expected, "{name}: phr-bvh traversal, ray {i} {ray:?}");
            let got = geometry.intersect(ray).map(|h| (h.t, h.prim));
            assert_eq!(got, expected, "{name}: Geometry::intersect, ray {i} {ray:?}");
            expected.is_some() as usize
        })
        .sum();
    (n, hits)
}

#[test]
fn bunny_matches_brute_force() {
    let (triangles, hits) = check_scene(&scenes().join("bunny/bun_zipper.ply"), 3000, 1);
    assert_eq!(triangles, 69_451);
    // Rays aimed inside the bounds hit the bunny often; the check must not be vacuous.
    assert!(hits > 600, "only {hits} of 3000 rays hit the bunny");
}

#[test]
fn cornell_box_matches_brute_force() {
    let (triangles, hits) = check_scene(&scenes().join("cornell_box/CornellBox-Original.obj"), 20_000, 2);
    assert!(triangles > 10, "{triangles} triangles");
    // Origins inside the closed box mostly hit a wall.
    assert!(hits > 10_000, "only {hits} of 20000 rays hit the Cornell box");
}
