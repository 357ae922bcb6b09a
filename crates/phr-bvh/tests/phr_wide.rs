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
use phr_bvh::{PackedTriangles, WideBvh};

/// The tree as the builder decided it, independent of where nodes sit in memory: depth
/// first, each slot's box bits, then its sorted primitives (a leaf) or its subtree.
fn canonical<const N: usize>(wide: &WideBvh<N>) -> Vec<u64> {
    let mut out = Vec::new();
    if wide.nodes.is_empty() {
        return out;
    }
    let mut stack = vec![0u32];
    while let Some(n) = stack.pop() {
        let node = &wide.nodes[n as usize];
        let mut interior = Vec::new();
        for i in (0..N).filter(|&i| node.is_used(i)) {
            let b = node.child_bounds(i);
            out.extend([b.min, b.max].iter().flat_map(|v| v.to_array()).map(|x| x.to_bits() as u64));
            if node.count[i] > 0 {
                let (first, count) = (node.child[i] as usize, node.count[i] as usize);
                let mut prims = wide.prim_indices[first..first + count].to_vec();
                prims.sort_unstable();
                out.push(u64::MAX - count as u64);
                out.extend(prims.iter().map(|&p| p as u64));
            } else {
                out.push(u64::MAX);
                interior.push(node.child[i]);
            }
        }
        stack.extend(interior.into_iter().rev());
    }
    out
}

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
        assert_eq!(canonical(into), canonical(&expected), "{what}: the direct tree differs from the collapse");
        assert_eq!(into.stack_bound(), expected.stack_bound(), "{what}: stack bound");
        assert!(
            stats.build_cost <= binary_stats.build_cost,
            "{what}: Σ|cut| {} > {}",
            stats.build_cost,
            binary_stats.build_cost
        );
    }
    assert_eq!(stats.initial_cut, binary_stats.initial_cut, "{what}: initial cut");
    into.validate(&boxes).unwrap_or_else(|e| panic!("{what}: {e}"));
    let packed = PackedTriangles::new(&into.prim_indices, tris);
    let mut rng = Rng::new(tris.len() as u64);
    for (i, ray) in random_rays(aux.root().map_or(phr_bvh::Aabb::EMPTY, |r| r.bounds), 100, &mut rng).iter().enumerate()
    {
        let hit = into.closest_triangle(&packed, ray).map(|(p, h)| (h.t, p));
        assert_eq!(hit, brute_force(tris, ray), "{what}: ray {i} {ray:?}");
    }
    into.leaf_count()
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
    let mut trees = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let mut wide = WideBvh::<8>::default();
        pool.install(|| check::<8>("soup 60k", &tris, &PhrOptions::FAST, &format!("{threads} threads"), &mut wide));
        trees.push(wide);
    }
    assert_eq!(trees[0].nodes, trees[1].nodes, "the layout depends on the thread count");
    assert_eq!(trees[0].prim_indices, trees[1].prim_indices);
}

#[test]
fn direct_wide_output_of_nothing_is_empty() {
    let aux = AuxTree::build(&[]);
    let mut wide = WideBvh::<8>::default();
    let stats = build_phr_wide(&aux, &PhrOptions::FAST, &mut wide);
    assert!(wide.nodes.is_empty() && wide.prim_indices.is_empty());
    assert_eq!(stats.build_cost, 0);
}
