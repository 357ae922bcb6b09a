//! PHR's direct wide output (`phr::build_phr_wide`) against what it replaces: the collapse of
//! binary PHR's tree (`WideBvh::from_bvh(build_phr(..))`). Both must give the same wide nodes
//! with the same boxes and the same leaves (node order in memory and primitive order within a
//! leaf may differ), on the adversarial meshes, on meshes large enough for the parallel top
//! (1 and 2 threads), for several α, δ and branching factors; and the direct trees must pass
//! the wide invariants and give brute force's hits.

mod common;

use common::*;
use phr_bvh::phr::{build_phr, build_phr_wide, AuxTree, PhrOptions};
use phr_bvh::wide::{Lanes, Width};
use phr_bvh::WideBvh;

fn options() -> Vec<(String, PhrOptions)> {
    let mut all = vec![
        ("phr-fast".to_string(), PhrOptions::FAST),
        ("phr-hq".to_string(), PhrOptions::HQ),
        ("thesis 0.3/5".to_string(), PhrOptions::thesis(0.3, 5.0)),
        ("α 0.8 δ 12".to_string(), PhrOptions::with(0.8, 12.0)),
    ];
    for k in [3, 4, 8] {
        all.push((format!("phr-hq k={k}"), PhrOptions { branching: k, ..PhrOptions::HQ }));
    }
    all
}

/// Checks the direct tree of `tris` against the collapse for width `N`; returns its leaf count.
fn check<const N: usize>(
    name: &str,
    tris: &[[glam::Vec3; 3]],
    options: &PhrOptions,
    what: &str,
    into: &mut WideBvh<N>,
) -> usize
where
    Lanes<N>: Width<N>,
{
    let boxes = triangle_boxes(tris);
    let aux = AuxTree::build(&boxes);
    let (bvh, binary_stats) = build_phr(&aux, options);
    let expected = WideBvh::<N>::from_bvh(&bvh);
    let stats = build_phr_wide(&aux, options, into);
    let what = format!("{name}, {what}, wide-{N}");
    // A branching factor above N is built as N, where the collapse regroups PHR's nodes.
    if options.branching as usize <= N {
        assert_eq!(
            canonical_wide(into),
            canonical_wide(&expected),
            "{what}: the direct tree differs from the collapse"
        );
        assert_eq!(into.stack_bound(), expected.stack_bound(), "{what}: stack bound");
        assert!(
            stats.build_cost <= binary_stats.build_cost,
            "{what}: Σ|cut| {} > {}",
            stats.build_cost,
            binary_stats.build_cost
        );
    }
    assert_eq!(stats.initial_cut, binary_stats.initial_cut, "{what}: initial cut");
    assert_wide_tree_sound(into, &boxes, tris, &what)
}

#[test]
fn direct_wide_output_equals_the_collapse_of_binary_phr() {
    let mut leaves = 0;
    // One tree reused throughout, as a dynamic scene reuses its memory.
    let (mut wide4, mut wide8) = (WideBvh::<4>::default(), WideBvh::<8>::default());
    for (name, tris) in adversarial_meshes() {
        for (what, o) in options() {
            leaves += check::<4>(name, &tris, &o, &what, &mut wide4);
            leaves += check::<8>(name, &tris, &o, &what, &mut wide8);
        }
    }
    assert!(leaves > 1000, "only {leaves} leaves: the meshes are too small to test anything");
}

#[test]
fn direct_wide_output_is_the_same_in_parallel() {
    // Large enough for several levels of parallel wide nodes (above 8192 primitives).
    let mut rng = Rng::new(11);
    let tris = random_soup(60_000, 10.0, &mut rng);
    assert_same_on_1_and_2_threads(|threads| {
        let mut wide = WideBvh::<8>::default();
        check::<8>("soup 60k", &tris, &PhrOptions::FAST, &format!("{threads} threads"), &mut wide);
        wide
    });
}

#[test]
fn direct_wide_output_of_nothing_is_empty() {
    let aux = AuxTree::build(&[]);
    let mut wide = WideBvh::<8>::default();
    let stats = build_phr_wide(&aux, &PhrOptions::FAST, &mut wide);
    assert!(wide.nodes.is_empty() && wide.prim_indices.is_empty());
    assert_eq!(stats.build_cost, 0);
}
