//! PHR's auxiliary tree: a full radix tree (one primitive per leaf), every box tight, the
//! same for any thread count, and exact again after a refit to moved primitives.

mod common;

use common::*;
use glam::Vec3;
use phr_bvh::phr::{build_phr, AuxTree, PhrOptions};
use phr_bvh::{validate, Aabb, Bvh};

/// Every node's box equals the union of its primitives' boxes, bit for bit.
fn assert_tight(bvh: &Bvh, boxes: &[Aabb], what: &str) {
    // Children follow their parents in `to_bvh`'s layout: one backward pass.
    let mut expected = vec![Aabb::EMPTY; bvh.nodes.len()];
    for i in (0..bvh.nodes.len()).rev() {
        let n = &bvh.nodes[i];
        expected[i] = if n.is_leaf() {
            bvh.leaf_prims(n).iter().fold(Aabb::EMPTY, |b, &p| b.union(boxes[p as usize]))
        } else {
            n.children().fold(Aabb::EMPTY, |b, c| b.union(expected[c as usize]))
        };
        assert_eq!(n.bounds, expected[i], "{what}: node {i}");
    }
}

fn meshes() -> Vec<(&'static str, Vec<[Vec3; 3]>)> {
    let mut rng = Rng::new(40);
    let mut meshes = adversarial_meshes();
    // Larger than one build task (4096 primitives), so the parallel top is exercised too.
    meshes.push(("large soup", random_soup(20_000, 1.0, &mut rng)));
    meshes.push(("many identical", (0..10_000).map(|_| [Vec3::ZERO, Vec3::X, Vec3::Y]).collect()));
    meshes
}

#[test]
fn every_primitive_in_one_leaf_and_every_box_tight() {
    for (name, tris) in meshes() {
        let boxes = triangle_boxes(&tris);
        let aux = AuxTree::build(&boxes);
        assert_eq!(aux.prim_count(), boxes.len(), "{name}");
        assert_eq!(aux.node_count(), 2 * boxes.len() - 1, "{name}");
        let bvh = aux.to_bvh();
        assert_eq!(bvh.nodes.len(), aux.node_count(), "{name}");
        validate(&bvh, &boxes, 1).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_tight(&bvh, &boxes, name);
        let root = aux.root().expect("non-empty");
        assert_eq!(root.prims as usize, boxes.len(), "{name}");
    }
}

#[test]
fn refit_to_moved_primitives_is_exact() {
    let mut rng = Rng::new(41);
    for (name, tris) in meshes() {
        let mut aux = AuxTree::build(&triangle_boxes(&tris));
        let topology = |aux: &AuxTree| aux.to_bvh().nodes.iter().map(|n| (n.first, n.count)).collect::<Vec<_>>();
        let before = topology(&aux);
        let offset = rng.vec3(Vec3::splat(-1.0), Vec3::splat(1.0));
        let moved: Vec<[Vec3; 3]> =
            tris.iter().enumerate().map(|(i, t)| t.map(|v| v * (1.0 + (i % 7) as f32) + offset)).collect();
        let boxes = triangle_boxes(&moved);
        aux.refit(&boxes);
        assert_eq!(topology(&aux), before, "{name}: a refit keeps the topology");
        let bvh = aux.to_bvh();
        validate(&bvh, &boxes, 1).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_tight(&bvh, &boxes, name);
    }
}

#[test]
fn same_tree_for_any_thread_count() {
    let mut rng = Rng::new(42);
    let boxes = triangle_boxes(&random_soup(30_000, 1.0, &mut rng));
    let build = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| AuxTree::build(&boxes).to_bvh())
    };
    let (a, b) = (build(1), build(2));
    assert_eq!(a.nodes, b.nodes);
    assert_eq!(a.prim_indices, b.prim_indices);
}

#[test]
fn empty_input_gives_empty_trees() {
    let aux = AuxTree::build(&[]);
    assert!(aux.root().is_none());
    assert_eq!((aux.prim_count(), aux.node_count()), (0, 0));
    assert!(aux.to_bvh().nodes.is_empty());
    let (bvh, stats) = build_phr(&aux, &PhrOptions::FAST);
    assert!(bvh.nodes.is_empty());
    assert_eq!(stats.build_cost, 0);
}
