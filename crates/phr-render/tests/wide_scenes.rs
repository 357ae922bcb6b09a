//! The wide BVH on the shared scenes (bunny, sponza, sibenik, conference, dragon): closest
//! hits of wide-4 and wide-8, with the SIMD kernels and with the forced scalar fallback, and of
//! the renderer's `Geometry::intersect`, equal the binary reference traversal for primary,
//! random and diffuse-bounce rays; a sample is also checked against brute force over every
//! triangle. Any-hit agrees with closest-hit.
//!
//! One exception is allowed and counted: a triangle hit accepted by the edge tolerance of
//! `intersect_triangle` can lie a hair outside the triangle's bounding box; a tree may then
//! miss it (the binary reference does, on a handful of rays per scene), and a wide tree whose
//! merged leaf box happens to contain it finds it. Such a hit is recognised by its point lying
//! outside its triangle's box, and only then may two answers differ.

use glam::Vec3;
use phr_bvh::triangle::intersect_triangle;
use phr_bvh::wide::{Lanes, Width};
use phr_bvh::{closest_hit, Aabb, Builder, Bvh, PackedTriangles, Ray, SimdLevel, WideBvh};
use phr_render::camera::Camera;
use phr_render::geometry::Geometry;
use phr_render::scene::load_scene;
use rayon::prelude::*;
use std::path::{Path, PathBuf};

fn scenes() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/scenes"))
}

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

type Answer = Option<(f32, u32)>;

fn brute_force(tris: &[[Vec3; 3]], ray: &Ray) -> Answer {
    let mut best: Answer = None;
    for (i, t) in tris.iter().enumerate() {
        if let Some(h) = intersect_triangle(ray, t[0], t[1], t[2]) {
            if best.is_none_or(|(bt, _)| h.t < bt) {
                best = Some((h.t, i as u32));
            }
        }
    }
    best
}

fn binary_hit(bvh: &Bvh, tris: &[[Vec3; 3]], ray: &Ray) -> Answer {
    let mut r = *ray;
    let mut best: Answer = None;
    closest_hit(bvh, &mut r, |p, r| {
        let t = &tris[p as usize];
        match intersect_triangle(r, t[0], t[1], t[2]) {
            Some(h) if h.t < r.tmax || best.is_none_or(|(_, bp)| p < bp) => {
                r.tmax = h.t;
                best = Some((h.t, p));
                true
            }
            _ => false,
        }
    });
    best
}

/// True if `answer` is a hit whose point lies outside its triangle's bounding box (an
/// edge-tolerance hit a tree may legitimately miss).
fn outside_its_box(tris: &[[Vec3; 3]], ray: &Ray, answer: Answer) -> bool {
    answer.is_some_and(|(t, p)| {
        let b = Aabb::from_points(&tris[p as usize]);
        let x = ray.at(t);
        x.cmplt(b.min).any() || x.cmpgt(b.max).any()
    })
}

/// Equal, or different only because of an out-of-box tolerance hit.
fn agrees(tris: &[[Vec3; 3]], ray: &Ray, a: Answer, b: Answer) -> bool {
    a == b || outside_its_box(tris, ray, a) || outside_its_box(tris, ray, b)
}

struct Variant<const N: usize> {
    wide: WideBvh<N>,
    packed: PackedTriangles,
}

impl<const N: usize> Variant<N>
where
    Lanes<N>: Width<N>,
{
    fn new(bvh: &Bvh, tris: &[[Vec3; 3]], boxes: &[Aabb], level: SimdLevel, split: bool) -> Self {
        let mut wide = WideBvh::<N>::from_bvh(bvh);
        let valid = if split { wide.validate_split(boxes) } else { wide.validate(boxes) };
        valid.unwrap_or_else(|e| panic!("wide-{N}: {e}"));
        let mut packed = PackedTriangles::new(&wide.prim_indices, tris);
        wide.set_simd(level);
        packed.set_simd(level);
        Self { wide, packed }
    }

    fn hit(&self, ray: &Ray) -> Answer {
        self.wide.closest_triangle(&self.packed, ray).map(|(p, h)| (h.t, p))
    }
}

/// Loads `file`, builds, collapses, and checks `rays` random, primary and diffuse rays;
/// returns (rays checked, hits, tolerated differences).
fn check_scene(file: &Path, builder: Builder, random: usize, brute_sample: usize, seed: u64) -> (usize, usize, usize) {
    assert!(file.is_file(), "missing {} (shared/ must sit next to the repository)", file.display());
    let name = file.display().to_string();
    let scene = load_scene(file).unwrap_or_else(|e| panic!("{name}: {e}"));
    let mut geometry = Geometry::new(&scene);
    assert!(geometry.spheres.is_empty());
    geometry.build(&builder);
    let tris = geometry.triangles.clone();
    let boxes = geometry.boxes.clone();
    let bvh = geometry.bvh().clone();
    builder.validate(&bvh, &boxes).unwrap_or_else(|e| panic!("{name}, {builder}: {e}"));

    // Rays: random, primary (48² of the framing view), one diffuse bounce per primary hit.
    let mut rng = Rng::new(seed);
    let bounds = boxes.iter().fold(Aabb::EMPTY, |b, x| b.union(*x));
    let (c, e) = (bounds.center(), bounds.extent());
    let mut rays: Vec<Ray> = (0..random)
        .map(|i| {
            let origin = rng.vec3(c - e, c + e);
            let dir = if i % 2 == 0 { rng.vec3(bounds.min, bounds.max) - origin } else { rng.unit_vector() };
            Ray::new(origin, dir.normalize_or(Vec3::X))
        })
        .collect();
    let res = 48;
    let camera = Camera::new(&scene.framing_camera(), res, res);
    let primary: Vec<Ray> =
        (0..res * res).map(|i| camera.ray((i % res) as f32 + 0.5, (i / res) as f32 + 0.5)).collect();
    let bounces: Vec<Ray> = primary
        .iter()
        .filter_map(|r| {
            let hit = geometry.intersect(r)?;
            let s = geometry.surface_point(r, &hit);
            let facing = if s.front { s.normal } else { -s.normal };
            let dir = (facing + rng.unit_vector()).normalize_or(facing);
            Some(Ray::new(s.spawn_origin(dir), dir))
        })
        .collect();
    assert!(bounces.len() > 200, "{name}: only {} primary hits", bounces.len());
    rays.extend(primary);
    rays.extend(bounces);

    let (simd, split) = (SimdLevel::detect(), builder.splits_primitives());
    let w4 = Variant::<4>::new(&bvh, &tris, &boxes, simd, split);
    let w8 = Variant::<8>::new(&bvh, &tris, &boxes, simd, split);
    let w4s = Variant::<4>::new(&bvh, &tris, &boxes, SimdLevel::Scalar, split);
    let w8s = Variant::<8>::new(&bvh, &tris, &boxes, SimdLevel::Scalar, split);
    let results: Vec<(usize, usize)> = rays
        .par_iter()
        .enumerate()
        .map(|(i, ray)| {
            let reference = binary_hit(&bvh, &tris, ray);
            let answers = [
                ("wide-4", w4.hit(ray)),
                ("wide-8", w8.hit(ray)),
                ("wide-4 scalar", w4s.hit(ray)),
                ("wide-8 scalar", w8s.hit(ray)),
                ("Geometry::intersect", geometry.intersect(ray).map(|h| (h.t, h.prim))),
            ];
            let mut tolerated = 0;
            for (what, got) in answers {
                if got != reference {
                    assert!(
                        agrees(&tris, ray, got, reference),
                        "{name}: {what} {got:?} vs binary {reference:?}, ray {i} {ray:?}"
                    );
                    tolerated += 1;
                }
            }
            // The SIMD and scalar wide paths agree exactly (same tree, same bits).
            assert_eq!(answers[0].1, answers[2].1, "{name}: wide-4 SIMD vs scalar, ray {i}");
            assert_eq!(answers[1].1, answers[3].1, "{name}: wide-8 SIMD vs scalar, ray {i}");
            assert_eq!(w8.wide.any_triangle(&w8.packed, ray), answers[1].1.is_some(), "{name}: any hit, ray {i}");
            if i % (rays.len() / brute_sample).max(1) == 0 {
                let brute = brute_force(&tris, ray);
                assert!(agrees(&tris, ray, answers[1].1, brute), "{name}: wide-8 vs brute force, ray {i} {ray:?}");
                assert!(agrees(&tris, ray, reference, brute), "{name}: binary vs brute force, ray {i} {ray:?}");
            }
            (reference.is_some() as usize, tolerated)
        })
        .collect();
    let hits = results.iter().map(|r| r.0).sum();
    let tolerated = results.iter().map(|r| r.1).sum();
    eprintln!("{name}: {} rays, {hits} hits, {tolerated} tolerated differences", rays.len());
    (rays.len(), hits, tolerated)
}

fn check(file: &str, builder: Builder, random: usize, brute_sample: usize, seed: u64) {
    let (rays, hits, tolerated) = check_scene(&scenes().join(file), builder, random, brute_sample, seed);
    assert!(hits * 5 > rays, "{file}: only {hits} of {rays} rays hit");
    // Geometry's boxes hold the triangle test's edge slack (`triangle_bounds`), so no tree
    // can miss a hit the test accepts: every answer is the binary reference's, bit for bit.
    assert_eq!(tolerated, 0, "{file}: {tolerated} differences in {rays} rays");
}

#[test]
fn wide_matches_reference_on_bunny() {
    check("bunny/bun_zipper.ply", Builder::PHR_HQ, 2000, 300, 1);
}

#[test]
fn wide_matches_reference_on_sponza() {
    // A 4-ary PHR tree: the collapse regroups its nodes.
    check("sponza/sponza.obj", Builder::PHR_HQ.with_branching(4).unwrap(), 2000, 300, 2);
}

/// Spatial splits: triangles cut into parts in several leaves, each leaf box holding only its
/// part (with the triangle test's margin).
#[test]
fn wide_matches_reference_on_sponza_from_the_sbvh() {
    check("sponza/sponza.obj", "sbvh".parse().unwrap(), 2000, 300, 8);
}

#[test]
fn wide_matches_reference_on_sibenik() {
    check("sibenik/sibenik.obj", Builder::PHR_HQ, 2000, 300, 3);
}

#[test]
fn wide_matches_reference_on_conference() {
    check("conference/conference_geometry.ply", "binned-sah".parse().unwrap(), 2000, 150, 4);
}

#[test]
fn wide_matches_reference_on_dragon() {
    check("dragon/dragon_vrip.ply", Builder::default(), 2000, 60, 5);
}

/// PHR's multi-way trees (k = 8 and 16) on real meshes: the collapse regroups nodes of up to
/// 16 children into 4- and 8-wide ones.
#[test]
fn wide_matches_reference_on_bunny_from_8_ary_phr() {
    check("bunny/bun_zipper.ply", Builder::PHR_HQ.with_branching(8).unwrap(), 1000, 150, 6);
}

#[test]
fn wide_matches_reference_on_sibenik_from_16_ary_phr() {
    check("sibenik/sibenik.obj", Builder::PHR_FAST.with_branching(16).unwrap(), 1000, 150, 7);
}

/// The wide collapse and the triangle packing run in parallel: their output (node layout,
/// leaf order, packed blocks) must not depend on the thread count, or images and benchmark
/// numbers would change with `--threads`.
#[test]
fn wide_collapse_layout_does_not_depend_on_thread_count() {
    let file = scenes().join("sponza/sponza.obj");
    assert!(file.is_file(), "missing {} (shared/ must sit next to the repository)", file.display());
    let scene = load_scene(&file).unwrap();
    let geometry = Geometry::new(&scene);
    let tris = &geometry.triangles;
    for builder in [Builder::PHR_HQ, Builder::PHR_HQ.with_branching(8).unwrap()] {
        let bvh = builder.build(&geometry.boxes);
        let collapse = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| {
                let wide = WideBvh::<8>::from_bvh(&bvh);
                let packed = PackedTriangles::new(&wide.prim_indices, tris);
                (wide, packed)
            })
        };
        let (one, one_packed) = collapse(1);
        for threads in [2, 3] {
            let (other, other_packed) = collapse(threads);
            assert!(one.nodes == other.nodes, "{builder}: wide nodes differ with {threads} threads");
            assert_eq!(one.prim_indices, other.prim_indices, "{builder}: leaf order differs with {threads} threads");
            assert!(one_packed.blocks == other_packed.blocks, "{builder}: packed blocks differ with {threads} threads");
        }
    }
}
