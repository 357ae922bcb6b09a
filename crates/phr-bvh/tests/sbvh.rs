//! The spatial-split BVH: its parts cover every triangle, it splits where object splits
//! overlap and stays within its reference budget, it beats the binned SAH on tilted
//! quads, and `validate_split` catches broken split trees. (Hits against brute force,
//! determinism and the wide collapse are checked with the other builders in `builders.rs`,
//! `wide.rs` and `fuzz_builders.rs`.)

mod common;

use common::*;
use glam::Vec3;
use phr_bvh::sbvh::{build_sbvh, SbvhOptions};
use phr_bvh::validate::validate_split;
use phr_bvh::{sah_cost, Aabb, Builder, Bvh, SahConstants};

/// Large tilted quads across the scene (ramps, roofs, walls at an angle: their boxes cover
/// much of the scene) among small triangles, as in architecture.
fn ramps_and_clutter(rng: &mut Rng) -> Vec<[Vec3; 3]> {
    let mut tris = random_soup(20_000, 1.0, rng);
    for _ in 0..50 {
        let c = rng.vec3(Vec3::splat(-0.5), Vec3::splat(0.5));
        let (u, v) = (rng.unit_vector(), rng.unit_vector());
        let (a, b, d, e) = (c - u - v, c + u - v, c + u + v, c - u + v);
        tris.extend([[a, b, d], [a, d, e]]);
    }
    tris
}

/// For every triangle, points spread over it (vertices, edge points, interior grid) lie in
/// the box of some leaf holding it.
fn assert_parts_cover_triangles(bvh: &Bvh, tris: &[[Vec3; 3]], what: &str) {
    let mut leaf_boxes: Vec<Vec<Aabb>> = vec![Vec::new(); tris.len()];
    for n in bvh.nodes.iter().filter(|n| n.is_leaf()) {
        for &p in bvh.leaf_prims(n) {
            leaf_boxes[p as usize].push(n.bounds);
        }
    }
    const STEPS: u32 = 8;
    for (p, t) in tris.iter().enumerate() {
        for i in 0..=STEPS {
            for j in 0..=STEPS - i {
                let (u, v) = (i as f32 / STEPS as f32, j as f32 / STEPS as f32);
                let x = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
                let covered = leaf_boxes[p].iter().any(|b| {
                    let slack = 1e-6 * (1.0 + x.abs().max_element());
                    x.cmpge(b.min - slack).all() && x.cmple(b.max + slack).all()
                });
                assert!(covered, "{what}: triangle {p} at (u, v) = ({u}, {v}) = {x} is in none of its leaves");
            }
        }
    }
}

#[test]
fn parts_cover_every_triangle_and_stay_within_the_budget() {
    let mut rng = Rng::new(21);
    let mut meshes = adversarial_meshes();
    meshes.push(("ramps and clutter", ramps_and_clutter(&mut rng)));
    for (name, tris) in meshes {
        let boxes = triangle_boxes(&tris);
        for max_references in [1.2, 2.0] {
            let options = SbvhOptions { max_references, ..SbvhOptions::default() };
            let bvh = build_sbvh(&boxes, &tris, &options);
            validate_split(&bvh, &boxes, options.leaf.max_leaf_size).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_parts_cover_triangles(&bvh, &tris, name);
            let budget = (max_references - 1.0) as f64 * tris.len() as f64;
            assert!(bvh.prim_indices.len() as f64 <= tris.len() as f64 + budget, "{name}: over budget");
            let rays = random_rays(bvh.root_bounds(), 300, &mut rng);
            assert_matches_brute_force(&bvh, &tris, &rays, &format!("{name}, up to {max_references}× references"));
        }
    }
}

#[test]
fn spatial_splits_beat_object_splits_on_tilted_quads() {
    let mut rng = Rng::new(22);
    let tris = ramps_and_clutter(&mut rng);
    let boxes = triangle_boxes(&tris);
    let sbvh = build_sbvh(&boxes, &tris, &SbvhOptions::default());
    let binned = "binned-sah".parse::<Builder>().unwrap().build(&boxes);
    let (split_cost, object_cost) = (sah_cost(&sbvh, SahConstants::UNIT), sah_cost(&binned, SahConstants::UNIT));
    let refs = sbvh.prim_indices.len() as f64 / tris.len() as f64;
    eprintln!(
        "ramps and clutter: SBVH SAH {split_cost:.1} with {refs:.3} references a triangle, binned {object_cost:.1}"
    );
    assert!(refs > 1.1 && refs <= 1.2, "{refs} references a triangle");
    assert!(split_cost < 0.8 * object_cost, "SBVH {split_cost} vs binned {object_cost}");
    // Measured: SBVH 68.6 with 1.19 references a triangle, binned 103.9.
    // Without a budget nothing is cut.
    let none = build_sbvh(&boxes, &tris, &SbvhOptions { max_references: 1.0, ..SbvhOptions::default() });
    assert_eq!(none.prim_indices.len(), tris.len());
    phr_bvh::validate(&none, &boxes, 8).unwrap();
}

#[test]
fn primitives_without_triangles_are_never_cut() {
    // Spheres, or a caller without triangles: the tree holds each primitive once, whole.
    let mut rng = Rng::new(23);
    let tris = ramps_and_clutter(&mut rng);
    let boxes = triangle_boxes(&tris);
    let bvh = build_sbvh(&boxes, &[], &SbvhOptions::default());
    phr_bvh::validate(&bvh, &boxes, 8).unwrap();
    let rays = random_rays(bvh.root_bounds(), 300, &mut rng);
    assert_matches_brute_force(&bvh, &tris, &rays, "boxes only");
    // Half of them triangles: only those are cut.
    let half = tris.len() / 2;
    let bvh = build_sbvh(&boxes, &tris[..half], &SbvhOptions::default());
    validate_split(&bvh, &boxes, 8).unwrap();
    let mut count = vec![0u32; tris.len()];
    bvh.prim_indices.iter().for_each(|&p| count[p as usize] += 1);
    assert!(count[..half].iter().any(|&c| c > 1), "no triangle was cut");
    assert!(count[half..].iter().all(|&c| c == 1), "a primitive without its triangle was cut");
    assert_matches_brute_force(&bvh, &tris, &rays, "half triangles");
}

#[test]
fn validate_split_catches_broken_split_trees() {
    let mut rng = Rng::new(24);
    let tris = ramps_and_clutter(&mut rng);
    let boxes = triangle_boxes(&tris);
    let bvh = build_sbvh(&boxes, &tris, &SbvhOptions::default());
    validate_split(&bvh, &boxes, 8).unwrap();
    assert!(phr_bvh::validate(&bvh, &boxes, 8).is_err(), "the strict check refuses split trees");
    let leaf = bvh.nodes.iter().position(|n| n.is_leaf() && n.count >= 2).expect("a leaf of two");
    let first = bvh.nodes[leaf].first as usize;
    // One primitive twice in a leaf.
    let mut broken = bvh.clone();
    broken.prim_indices[first + 1] = broken.prim_indices[first];
    assert!(validate_split(&broken, &boxes, 8).is_err());
    // A leaf box that misses its primitive.
    let mut broken = bvh.clone();
    let far = Vec3::splat(100.0);
    broken.nodes[leaf].bounds = Aabb::new(far, far);
    assert!(validate_split(&broken, &boxes, 8).is_err());
    // A primitive in no leaf.
    let mut broken = bvh.clone();
    let lost = broken.prim_indices[first];
    for p in broken.prim_indices.iter_mut().filter(|p| **p == lost) {
        *p = (lost + 1) % tris.len() as u32;
    }
    assert!(validate_split(&broken, &boxes, 8).is_err());
}
