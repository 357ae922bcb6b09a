//! Every builder, every PHR preset and branching factor, and random (α, δ): tree invariants and
//! closest hits against brute force on the adversarial meshes.

mod common;

use common::*;
use phr_bvh::phr::{build_phr, CutWeight, PhrOptions};
use phr_bvh::{build_lbvh, sah_cost, validate, Builder, LbvhOptions, SahConstants};

fn all_builders() -> Vec<Builder> {
    let mut builders: Vec<Builder> =
        ["lbvh", "phr-fast", "phr-hq", "sweep-sah", "binned-sah"].iter().map(|s| s.parse().unwrap()).collect();
    for k in [4, 8, 16] {
        builders.push(Builder::PHR_FAST.with_branching(k).unwrap());
        builders.push(Builder::PHR_HQ.with_branching(k).unwrap());
    }
    let mut rng = Rng::new(99);
    for _ in 0..4 {
        let (alpha, delta) = (0.3 + 0.4 * rng.f32(), 4.0 + 8.0 * rng.f32());
        builders.push(Builder::Phr(PhrOptions::with(alpha, delta)));
    }
    builders.push(Builder::Phr(PhrOptions { weight: CutWeight::AuxNodes, ..PhrOptions::HQ }));
    builders.push(Builder::Phr(PhrOptions { max_initial_cut: Some(16), ..PhrOptions::HQ }));
    builders.push(Builder::Phr(PhrOptions::thesis(0.5, 6.0)));
    builders
}

#[test]
fn every_builder_matches_brute_force_on_adversarial_meshes() {
    for (name, tris) in adversarial_meshes() {
        let boxes = triangle_boxes(&tris);
        let mut rng = Rng::new(tris.len() as u64);
        for builder in all_builders() {
            let bvh = builder.build(&boxes);
            validate(&bvh, &boxes, builder.max_leaf_size()).unwrap_or_else(|e| panic!("{name}, {builder}: {e}"));
            let rays = random_rays(bvh.root_bounds(), 400, &mut rng);
            assert_matches_brute_force(&bvh, &tris, &rays, &format!("{name}, {builder}"));
        }
    }
}

#[test]
fn phr_branching_factor_is_respected() {
    let mut rng = Rng::new(1);
    let tris = random_soup(20_000, 1.0, &mut rng);
    let boxes = triangle_boxes(&tris);
    for k in [2, 4, 8, 16] {
        let bvh = Builder::PHR_HQ.with_branching(k).unwrap().build(&boxes);
        assert!(bvh.max_branching() <= k && bvh.max_branching() >= 2, "k = {k}: {}", bvh.max_branching());
        if k > 2 {
            assert!(bvh.max_branching() > 2, "a {k}-ary build should make some wide nodes");
        }
    }
}

#[test]
fn single_node_cuts_never_become_giant_leaves() {
    // δ = 0 puts the whole scene in the root's cut as one node: the thesis code would have
    // made one leaf of everything. The leaf bound must hold anyway.
    let mut rng = Rng::new(2);
    let tris = random_soup(5000, 1.0, &mut rng);
    let boxes = triangle_boxes(&tris);
    for (alpha, delta) in [(0.0, 0.0), (0.1, 0.0), (0.5, 1.0)] {
        let options = PhrOptions::with(alpha, delta);
        let aux = build_lbvh(&boxes, LbvhOptions { max_leaf_size: 1 });
        let (bvh, stats) = build_phr(&aux, &options);
        validate(&bvh, &boxes, options.leaf.max_leaf_size).unwrap();
        assert!(stats.initial_cut >= 1 && stats.build_cost > 0);
    }
}

#[test]
fn phr_quality_approaches_the_full_sweep() {
    let mut rng = Rng::new(3);
    let tris = random_soup(30_000, 1.0, &mut rng);
    let boxes = triangle_boxes(&tris);
    let cost = |b: Builder| sah_cost(&b.build(&boxes), SahConstants::UNIT);
    let sweep = cost("sweep-sah".parse().unwrap());
    let hq = cost(Builder::PHR_HQ);
    let fast = cost(Builder::PHR_FAST);
    let lbvh = cost(Builder::default());
    assert!(sweep <= hq * 1.001 && hq <= fast * 1.02, "sweep {sweep}, hq {hq}, fast {fast}");
    assert!(hq < lbvh, "PHR-HQ ({hq}) should beat the LBVH ({lbvh})");
    assert!(hq <= sweep * 1.10, "PHR-HQ {hq} vs sweep {sweep}");
}

#[test]
fn build_cost_grows_with_refinement() {
    let mut rng = Rng::new(4);
    let tris = random_soup(30_000, 1.0, &mut rng);
    let aux = build_lbvh(&triangle_boxes(&tris), LbvhOptions { max_leaf_size: 1 });
    let b = |alpha, delta| build_phr(&aux, &PhrOptions::with(alpha, delta)).1.build_cost;
    assert!(b(0.5, 6.0) < b(0.5, 9.0));
    assert!(b(0.4, 8.0) < b(0.6, 8.0));
}

#[test]
fn builders_are_deterministic_across_thread_counts() {
    let mut rng = Rng::new(5);
    let tris = random_soup(40_000, 1.0, &mut rng);
    let boxes = triangle_boxes(&tris);
    for builder in ["phr-hq", "sweep-sah", "binned-sah"].map(|s| s.parse::<Builder>().unwrap()) {
        let build = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| builder.build(&boxes))
        };
        let (a, b) = (build(1), build(2));
        assert_eq!(a.nodes, b.nodes, "{builder}");
        assert_eq!(a.prim_indices, b.prim_indices, "{builder}");
    }
}

#[test]
fn builder_names_parse() {
    assert_eq!("phr:0.4,7".parse::<Builder>().unwrap(), Builder::Phr(PhrOptions::with(0.4, 7.0)));
    assert!("phr:0.4".parse::<Builder>().is_err());
    assert!("phr:x,7".parse::<Builder>().is_err());
    assert!("octree".parse::<Builder>().is_err());
    assert!(Builder::default().with_branching(4).is_err());
    assert_eq!(Builder::PHR_HQ.to_string(), "phr-hq");
    let thesis: Builder = "phr-thesis:0.5,6".parse().unwrap();
    assert_eq!(thesis, Builder::Phr(PhrOptions::thesis(0.5, 6.0)));
    assert_eq!(thesis.to_string(), "phr-thesis:0.5,6");
}
