//! The LBVH against brute force and the tree invariants, on adversarial meshes.

mod common;

use common::*;
use glam::Vec3;
use phr_bvh::{build_lbvh, refit, validate, LbvhOptions};

#[test]
fn lbvh_matches_brute_force_on_adversarial_meshes() {
    for (name, tris) in adversarial_meshes() {
        let boxes = triangle_boxes(&tris);
        for leaf in [1, 4, 8] {
            let bvh = build_lbvh(&boxes, LbvhOptions { max_leaf_size: leaf });
            validate(&bvh, &boxes, leaf).unwrap_or_else(|e| panic!("{name}, leaf {leaf}: {e}"));
            let mut rng = Rng::new(leaf as u64);
            let rays = random_rays(bvh.root_bounds(), 2000, &mut rng);
            assert_matches_brute_force(&bvh, &tris, &rays, name);
        }
    }
}

#[test]
fn lbvh_is_the_same_for_any_thread_count() {
    let mut rng = Rng::new(3);
    let tris = random_soup(50_000, 1.0, &mut rng);
    let boxes = triangle_boxes(&tris);
    let build = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| build_lbvh(&boxes, LbvhOptions::default()))
    };
    let (a, b) = (build(1), build(2));
    assert_eq!(a.nodes, b.nodes);
    assert_eq!(a.prim_indices, b.prim_indices);
}

#[test]
fn refit_after_motion_gives_the_same_hits_as_a_fresh_build() {
    let mut rng = Rng::new(11);
    let mut tris = random_soup(20_000, 1.0, &mut rng);
    let mut bvh = build_lbvh(&triangle_boxes(&tris), LbvhOptions::default());
    for frame in 0..5 {
        // A deformation that moves triangles far from where the tree was built.
        let phase = frame as f32 * 0.7;
        for t in tris.iter_mut() {
            for v in t.iter_mut() {
                *v += Vec3::new((v.y * 3.0 + phase).sin(), 0.3 * (v.x * 2.0).cos(), 0.1) * 0.2;
            }
        }
        let boxes = triangle_boxes(&tris);
        refit(&mut bvh, &boxes);
        validate(&bvh, &boxes, 4).unwrap();
        let fresh = build_lbvh(&boxes, LbvhOptions::default());
        let rays = random_rays(fresh.root_bounds(), 2000, &mut rng);
        for ray in &rays {
            assert_eq!(bvh_hit(&bvh, &tris, ray), bvh_hit(&fresh, &tris, ray));
        }
        assert_matches_brute_force(&bvh, &tris, &rays[..300], "refit");
    }
}

#[test]
fn validate_catches_broken_trees() {
    let mut rng = Rng::new(5);
    let tris = random_soup(100, 1.0, &mut rng);
    let boxes = triangle_boxes(&tris);
    let good = build_lbvh(&boxes, LbvhOptions::default());
    validate(&good, &boxes, 4).unwrap();

    let mut shrunk = good.clone();
    let leaf = shrunk.nodes.iter().position(|n| n.is_leaf()).unwrap();
    shrunk.nodes[leaf].bounds.max -= Vec3::splat(0.01);
    assert!(validate(&shrunk, &boxes, 4).is_err());

    let mut duplicated = good.clone();
    duplicated.prim_indices[1] = duplicated.prim_indices[0];
    assert!(validate(&duplicated, &boxes, 4).is_err());

    assert!(validate(&good, &boxes, 1).is_err(), "leaf size bound must be checked");
}
