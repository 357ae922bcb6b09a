//! The binned SAH's direct wide output (`binned_sah::build_binned_sah_wide`) against what it
//! replaces: the collapse of the binary builder's tree (`WideBvh::from_bvh(build_binned_sah(..))`).
//! Both must give the same wide nodes with the same boxes and the same leaves (node order in
//! memory and primitive order within a leaf may differ), on the adversarial meshes (duplicates,
//! coincident centroids, the depth cap), with several bin counts and leaf sizes, on a mesh large
//! enough for the parallel top (1 and 2 threads); and the direct trees must pass the wide
//! invariants and give brute force's hits.

mod common;

use common::*;
use phr_bvh::binned_sah::{build_binned_sah, build_binned_sah_wide, BinnedSahOptions};
use phr_bvh::sah::LeafPolicy;
use phr_bvh::wide::{Lanes, Width};
use phr_bvh::WideBvh;

fn options() -> Vec<(String, BinnedSahOptions)> {
    let mut all = vec![("default".to_string(), BinnedSahOptions::default())];
    for bins in [2, 8] {
        all.push((format!("{bins} bins"), BinnedSahOptions { bins, ..BinnedSahOptions::default() }));
    }
    for max_leaf_size in [1, 4, 16] {
        let leaf = LeafPolicy { max_leaf_size, ..LeafPolicy::default() };
        all.push((format!("leaves ≤ {max_leaf_size}"), BinnedSahOptions { leaf, ..BinnedSahOptions::default() }));
    }
    all
}

/// Checks the direct tree of `tris` against the collapse for width `N`; returns its leaf count.
fn check<const N: usize>(
    name: &str,
    tris: &[[glam::Vec3; 3]],
    options: &BinnedSahOptions,
    what: &str,
    into: &mut WideBvh<N>,
) -> usize
where
    Lanes<N>: Width<N>,
{
    let boxes = triangle_boxes(tris);
    let expected = WideBvh::<N>::from_bvh(&build_binned_sah(&boxes, options));
    build_binned_sah_wide(&boxes, options, into);
    let what = format!("{name}, {what}, wide-{N}");
    assert_eq!(canonical_wide(into), canonical_wide(&expected), "{what}: the direct tree differs from the collapse");
    assert_eq!(into.stack_bound(), expected.stack_bound(), "{what}: stack bound");
    assert_wide_tree_sound(into, &boxes, tris, &what)
}

#[test]
fn direct_wide_output_equals_the_collapse_of_the_binary_tree() {
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
    // Large enough for several levels of parallel wide nodes (above 4096 primitives).
    let mut rng = Rng::new(12);
    let tris = random_soup(60_000, 10.0, &mut rng);
    assert_same_on_1_and_2_threads(|threads| {
        let mut wide = WideBvh::<8>::default();
        check::<8>("soup 60k", &tris, &BinnedSahOptions::default(), &format!("{threads} threads"), &mut wide);
        wide
    });
}

#[test]
fn direct_wide_output_of_nothing_is_empty() {
    let mut wide = WideBvh::<8>::default();
    build_binned_sah_wide(&[], &BinnedSahOptions::default(), &mut wide);
    assert!(wide.nodes.is_empty() && wide.prim_indices.is_empty());
}
