//! The dynamic-scene pipeline of thesis section 5.3: vertices move, the auxiliary LBVH is
//! refit, PHR rebuilds the render tree from it; 100 frames, trees valid and hits right.

mod common;

use common::*;
use glam::Vec3;
use phr_bvh::dynamic::DynamicBvh;
use phr_bvh::phr::PhrOptions;
use phr_bvh::validate;

#[test]
fn hundred_animated_frames_stay_valid_and_exact() {
    let mut rng = Rng::new(21);
    let rest = random_soup(8000, 1.0, &mut rng);
    let mut dynamic = DynamicBvh::new(&triangle_boxes(&rest), PhrOptions::FAST);
    for frame in 0..100 {
        let time = frame as f32 * 0.05;
        // A rotation about y plus a travelling wave: triangles move and deform.
        let (s, c) = time.sin_cos();
        let tris: Vec<[Vec3; 3]> = rest
            .iter()
            .map(|t| {
                t.map(|v| {
                    let r = Vec3::new(c * v.x + s * v.z, v.y, -s * v.x + c * v.z);
                    r + Vec3::new(0.0, 0.3 * (3.0 * r.x + 4.0 * time).sin(), 0.0)
                })
            })
            .collect();
        let boxes = triangle_boxes(&tris);
        let (bvh, timings) = dynamic.update(&boxes);
        assert!(timings.build_cost > 0);
        let bvh = &bvh;
        validate(bvh, &boxes, PhrOptions::FAST.leaf.max_leaf_size).unwrap_or_else(|e| panic!("frame {frame}: {e}"));
        validate(&dynamic.aux().to_bvh(), &boxes, 1).unwrap_or_else(|e| panic!("frame {frame}, aux: {e}"));
        let rays = random_rays(bvh.root_bounds(), 60, &mut rng);
        assert_matches_brute_force(bvh, &tris, &rays, &format!("frame {frame}"));
    }
}

/// `update_wide` gives the tree `update` gives, collapsed: the same SAH cost every frame, the
/// wide invariants, and brute force's hits, while the mesh moves.
#[test]
fn direct_wide_updates_equal_the_collapse() {
    use phr_bvh::{wide_sah_cost, PackedTriangles, SahConstants, WideBvh};
    let mut rng = Rng::new(5);
    let rest = random_soup(6000, 1.0, &mut rng);
    let boxes = triangle_boxes(&rest);
    let (mut binary, mut direct) = (DynamicBvh::new(&boxes, PhrOptions::HQ), DynamicBvh::new(&boxes, PhrOptions::HQ));
    let (mut collapsed, mut wide) = (WideBvh::<8>::default(), WideBvh::<8>::default());
    for frame in 0..20 {
        let shift = |v: Vec3| v + Vec3::new(0.0, 0.2 * (5.0 * v.x + frame as f32 * 0.3).sin(), 0.0);
        let tris: Vec<[Vec3; 3]> = rest.iter().map(|t| t.map(shift)).collect();
        let boxes = triangle_boxes(&tris);
        let (bvh, timings) = binary.update(&boxes);
        collapsed.rebuild(&bvh);
        let direct_timings = direct.update_wide(&boxes, &mut wide);
        wide.validate(&boxes).unwrap_or_else(|e| panic!("frame {frame}: {e}"));
        let (a, b) = (wide_sah_cost(&collapsed, SahConstants::UNIT), wide_sah_cost(&wide, SahConstants::UNIT));
        assert!((a - b).abs() <= 1e-9 * a, "frame {frame}: SAH {a} collapsed, {b} direct");
        assert_eq!(wide.leaf_count(), collapsed.leaf_count(), "frame {frame}");
        assert!(direct_timings.build_cost > 0 && direct_timings.build_cost <= timings.build_cost);
        let packed = PackedTriangles::new(&wide.prim_indices, &tris);
        for ray in random_rays(bvh.root_bounds(), 50, &mut rng) {
            let hit = wide.closest_triangle(&packed, &ray).map(|(p, h)| (h.t, p));
            assert_eq!(hit, brute_force(&tris, &ray), "frame {frame}");
        }
    }
}

/// A refit with the boxes the tree was built over gives the builder's boxes, bit for bit;
/// after the primitives move, the refitted tree is valid over the new boxes and gives brute
/// force's hits (its topology is the old one).
#[test]
fn refitted_wide_trees_enclose_the_moved_primitives() {
    use phr_bvh::{PackedTriangles, WideBvh};
    let mut rng = Rng::new(9);
    let rest = random_soup(5000, 1.0, &mut rng);
    let boxes = triangle_boxes(&rest);
    for (name, mut wide) in [
        ("direct PHR", {
            let mut w = WideBvh::<8>::default();
            DynamicBvh::new(&boxes, PhrOptions::FAST).update_wide(&boxes, &mut w);
            w
        }),
        (
            "collapsed binned SAH",
            WideBvh::<8>::from_bvh(&"binned-sah".parse::<phr_bvh::Builder>().unwrap().build(&boxes)),
        ),
    ] {
        let built = wide.nodes.clone();
        wide.refit(&boxes);
        assert!(wide.nodes == built, "{name}: a refit over the same boxes changed the tree");
        for frame in 1..6 {
            let shift = |v: Vec3| v + Vec3::new(0.0, 0.3 * (4.0 * v.x + frame as f32).sin(), 0.1 * frame as f32);
            let tris: Vec<[Vec3; 3]> = rest.iter().map(|t| t.map(shift)).collect();
            let moved = triangle_boxes(&tris);
            assert!(wide.validate(&moved).is_err(), "{name}: the motion must leave the old boxes");
            wide.refit(&moved);
            wide.validate(&moved).unwrap_or_else(|e| panic!("{name}, frame {frame}: {e}"));
            let packed = PackedTriangles::new(&wide.prim_indices, &tris);
            let bounds = moved.iter().fold(phr_bvh::Aabb::EMPTY, |b, x| b.union(*x));
            for ray in random_rays(bounds, 50, &mut rng) {
                let hit = wide.closest_triangle(&packed, &ray).map(|(p, h)| (h.t, p));
                assert_eq!(hit, brute_force(&tris, &ray), "{name}, frame {frame}");
            }
        }
    }
}

/// The refit a deforming mesh runs every frame ([`phr_bvh::WideBvh::refit_packed`]): the
/// leaves' boxes come from the triangles just packed in leaf order. Each leaf slot's box is
/// exactly its own entries' box (lanes of neighbouring leaves in the same block masked out),
/// widened by a relative 2⁻²³; each interior slot's is its child's union; the tree gives
/// brute force's hits. Entries past `triangle_count` (a renderer's spheres) take the
/// caller's boxes.
#[test]
fn trees_refitted_from_packed_triangles_hold_exactly_their_leaves() {
    use phr_bvh::{Aabb, PackedTriangles, WideBvh};
    let mut rng = Rng::new(10);
    let rest = random_soup(5000, 1.0, &mut rng);
    let others = 120;
    let mut wide = WideBvh::<8>::default();
    let boxes = triangle_boxes(&rest);
    DynamicBvh::new(&boxes, PhrOptions::FAST).update_wide(&boxes, &mut wide);
    let n_tris = rest.len() - others;
    let widened = |b: Aabb| Aabb::new(b.min - b.min.abs() * f32::EPSILON, b.max + b.max.abs() * f32::EPSILON);
    for frame in 1..6 {
        let shift = |v: Vec3| v + Vec3::new(0.0, 0.3 * (4.0 * v.x + frame as f32).sin(), 0.1 * frame as f32);
        let tris: Vec<[Vec3; 3]> = rest.iter().map(|t| t.map(shift)).collect();
        // The triangles as the packed test sees them: v0, v0 + e1, v0 + e2.
        let seen: Vec<[Vec3; 3]> = tris.iter().map(|&[a, b, c]| [a, a + (b - a), a + (c - a)]).collect();
        let mut expected = triangle_boxes(&seen);
        expected[n_tris..].copy_from_slice(&triangle_boxes(&tris[n_tris..]));
        let packed = PackedTriangles::new(&wide.prim_indices, &tris[..n_tris]);
        wide.refit_packed(&packed, n_tris, |p| expected[p as usize]);
        wide.validate(&expected).unwrap_or_else(|e| panic!("frame {frame}: {e}"));
        for node in &wide.nodes {
            for s in 0..8 {
                let (first, count) = (node.child[s] as usize, node.count[s] as usize);
                let want = match count {
                    0 if node.is_used(s) => wide.nodes[first].bounds(),
                    0 => continue,
                    _ => {
                        let leaf = &wide.prim_indices[first..first + count];
                        leaf.iter().fold(Aabb::EMPTY, |b, &p| {
                            b.union(if (p as usize) < n_tris {
                                widened(expected[p as usize])
                            } else {
                                expected[p as usize]
                            })
                        })
                    }
                };
                assert_eq!(node.child_bounds(s), want, "frame {frame}: slot {s} of a node");
            }
        }
        let bounds = expected.iter().fold(Aabb::EMPTY, |b, x| b.union(*x));
        let all = PackedTriangles::new(&wide.prim_indices, &tris);
        for ray in random_rays(bounds, 50, &mut rng) {
            let hit = wide.closest_triangle(&all, &ray).map(|(p, h)| (h.t, p));
            assert_eq!(hit, brute_force(&tris, &ray), "frame {frame}");
        }
    }
}

/// [`phr_bvh::WideBvh::refit_repacking`], the one pass a deforming mesh's frames run while
/// its tree stays, gives the tree and the packed triangles of a repack followed by
/// [`phr_bvh::WideBvh::refit_packed`], to the bit: with small leaves sharing blocks, padding
/// between leaves, entries that are not triangles, and a `packed` of another size.
#[test]
fn refitting_while_repacking_equals_repacking_then_refitting() {
    use phr_bvh::{PackedTriangles, WideBvh};
    let mut rng = Rng::new(12);
    let rest = random_soup(6000, 1.0, &mut rng);
    let others = 90;
    let n_tris = rest.len() - others;
    let mut tree = WideBvh::<8>::default();
    let boxes = triangle_boxes(&rest);
    DynamicBvh::new(&boxes, PhrOptions::FAST).update_wide(&boxes, &mut tree);
    let leaf_starts: Vec<usize> =
        tree.nodes.iter().flat_map(|n| (0..8).filter(|&s| n.count[s] > 0).map(|s| n.child[s] as usize)).collect();
    assert!(leaf_starts.iter().any(|&f| f % 4 != 0), "no two leaves share a block");
    assert!(tree.prim_indices.len() > rest.len(), "no padding");
    let mut packed = PackedTriangles::new(&tree.prim_indices, &rest[..n_tris]);
    for frame in 1..5 {
        let f = frame as f32;
        // Every coordinate moves, and edges change: each of the nine rows of an entry.
        let shift = |v: Vec3| v + Vec3::new(0.2 * (3.0 * v.z + f).sin(), 0.05 * f * v.x, 0.1 * (2.0 * v.y - f).sin());
        let tris: Vec<[Vec3; 3]> = rest.iter().map(|t| t.map(shift)).collect();
        let other = |p: u32| triangle_boxes(&tris[p as usize..p as usize + 1])[0];
        let mut want = tree.clone();
        let want_packed = PackedTriangles::new(&want.prim_indices, &tris[..n_tris]);
        want.refit_packed(&want_packed, n_tris, other);
        let mut fresh = (tree.clone(), PackedTriangles::default());
        tree.refit_repacking(&mut packed, &tris[..n_tris], other);
        fresh.0.refit_repacking(&mut fresh.1, &tris[..n_tris], other);
        // Compared bit for bit (`==` on floats takes −0 for +0).
        let node_bits = |t: &WideBvh<8>| {
            t.nodes.iter().map(|n| (n.bounds.map(|row| row.map(f32::to_bits)), n.child, n.count)).collect::<Vec<_>>()
        };
        let block_bits =
            |p: &PackedTriangles| p.blocks.iter().map(|b| b.rows.map(|row| row.map(f32::to_bits))).collect::<Vec<_>>();
        for (got, got_packed) in [(&tree, &packed), (&fresh.0, &fresh.1)] {
            assert!(node_bits(got) == node_bits(&want), "frame {frame}: the nodes differ");
            assert!(block_bits(got_packed) == block_bits(&want_packed), "frame {frame}: the blocks differ");
        }
    }
}

/// Every refit returns the areas it computed ([`phr_bvh::RefitAreas`]), whose SAH cost is
/// the refitted tree's ([`phr_bvh::wide_sah_cost`], summed in another order): through
/// boxes, packed triangles and repacking, with the traversal and intersection constants
/// apart, on a tree with leaves and interior slots side by side.
#[test]
fn a_refit_costs_the_tree_it_refits() {
    use phr_bvh::{wide_sah_cost, PackedTriangles, SahConstants, WideBvh};
    let mut rng = Rng::new(14);
    let rest = random_soup(7000, 1.0, &mut rng);
    let mut tree = WideBvh::<8>::default();
    let boxes = triangle_boxes(&rest);
    DynamicBvh::new(&boxes, PhrOptions::FAST).update_wide(&boxes, &mut tree);
    assert!(tree
        .nodes
        .iter()
        .any(|n| (0..8).any(|s| n.count[s] > 0) && (0..8).any(|s| n.count[s] == 0 && n.is_used(s))));
    // More nodes than one of the refit's parallel chunks (256).
    assert!(tree.nodes.len() > 512, "{} nodes", tree.nodes.len());
    let mut packed = PackedTriangles::new(&tree.prim_indices, &rest);
    let constants = [SahConstants::UNIT, SahConstants::THESIS, SahConstants { traversal: 0.5, intersection: 3.0 }];
    for frame in 1..4 {
        let f = frame as f32;
        let shift = |v: Vec3| v + Vec3::new(0.3 * (2.0 * v.y + f).sin(), 0.1 * f, 0.2 * (3.0 * v.x - f).cos());
        let tris: Vec<[Vec3; 3]> = rest.iter().map(|t| t.map(shift)).collect();
        let moved = triangle_boxes(&tris);
        let none = |_: u32| phr_bvh::Aabb::EMPTY;
        let mut by_boxes = tree.clone();
        let boxes_areas = by_boxes.refit(&moved);
        let mut by_packed = tree.clone();
        let packed_areas =
            by_packed.refit_packed(&PackedTriangles::new(&by_packed.prim_indices, &tris), tris.len(), none);
        let repacked_areas = tree.refit_repacking(&mut packed, &tris, none);
        for (areas, refitted) in [(boxes_areas, &by_boxes), (packed_areas, &by_packed), (repacked_areas, &tree)] {
            for c in constants {
                let (got, want) = (areas.sah_cost(c), wide_sah_cost(refitted, c));
                assert!((got - want).abs() <= 1e-9 * want, "frame {frame}, {c:?}: {got} against {want}");
            }
        }
    }
}

/// [`phr_bvh::RefitAreas`] at the edges: a tree that is one node of leaves (the root's box
/// counted once, as the traversal step into it), and no tree at all.
#[test]
fn a_refit_costs_a_single_node_and_an_empty_tree() {
    use phr_bvh::{wide_sah_cost, RefitAreas, SahConstants, WideBvh};
    let mut rng = Rng::new(15);
    let rest = random_soup(12, 1.0, &mut rng);
    let boxes = triangle_boxes(&rest);
    let mut tree = WideBvh::<8>::default();
    DynamicBvh::new(&boxes, PhrOptions::FAST).update_wide(&boxes, &mut tree);
    assert_eq!(tree.nodes.len(), 1, "not a single node");
    let moved: Vec<_> = boxes.iter().map(|b| phr_bvh::Aabb::new(b.min * 1.5, b.max * 1.5)).collect();
    let areas = tree.refit(&moved);
    for c in [SahConstants::UNIT, SahConstants::THESIS] {
        let (got, want) = (areas.sah_cost(c), wide_sah_cost(&tree, c));
        assert!((got - want).abs() <= 1e-9 * want, "{c:?}: {got} against {want}");
    }
    let mut empty = WideBvh::<8>::default();
    assert_eq!(empty.refit(&[]), RefitAreas::default());
    assert_eq!(RefitAreas::default().sah_cost(SahConstants::UNIT), 0.0);
}

/// A subtree whose primitives' boxes are all empty for one frame (its slot's box empty) is
/// refitted again the frame after: the refit tells interior slots by their child, not by
/// their box.
#[test]
fn a_subtree_that_vanishes_for_a_frame_comes_back() {
    use phr_bvh::{Aabb, WideBvh};
    let mut rng = Rng::new(16);
    let rest = random_soup(3000, 1.0, &mut rng);
    let boxes = triangle_boxes(&rest);
    let mut tree = WideBvh::<8>::default();
    DynamicBvh::new(&boxes, PhrOptions::FAST).update_wide(&boxes, &mut tree);
    // An interior child of the root, and the primitives under it.
    let root = &tree.nodes[0];
    let slot = (0..8).find(|&s| root.count[s] == 0 && root.child[s] != 0).expect("an interior slot");
    let mut under = Vec::new();
    let mut stack = vec![root.child[slot] as usize];
    while let Some(i) = stack.pop() {
        let n = &tree.nodes[i];
        for s in 0..8 {
            match (n.count[s], n.child[s]) {
                (0, 0) => {}
                (0, c) => stack.push(c as usize),
                (count, first) => under.extend_from_slice(&tree.prim_indices[first as usize..(first + count) as usize]),
            }
        }
    }
    let mut gone = boxes.clone();
    for &p in &under {
        if (p as usize) < gone.len() {
            gone[p as usize] = Aabb::EMPTY;
        }
    }
    let mut want = tree.clone();
    want.refit(&boxes);
    tree.refit(&gone);
    assert!(tree.nodes[0].child_bounds(slot).is_empty(), "the slot did not vanish");
    tree.refit(&boxes);
    let bits = |t: &WideBvh<8>| t.nodes.iter().map(|n| n.bounds.map(|row| row.map(f32::to_bits))).collect::<Vec<_>>();
    assert!(bits(&tree) == bits(&want), "the subtree did not come back");
}
