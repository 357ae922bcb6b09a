//! The wide BVH (4 and 8 children, SIMD traversal): tree invariants after the collapse, and
//! closest hits identical to the binary reference traversal and to brute force, for every
//! SIMD level this CPU has (including the forced scalar fallback), on the adversarial meshes
//! with random and diffuse-bounce rays. Any-hit agrees with closest-hit.

mod common;

use common::*;
use glam::Vec3;
use phr_bvh::node::Node;
use phr_bvh::triangle::intersect_triangle;
use phr_bvh::wide::triangles::SlotHit;
use phr_bvh::wide::{CollapseOptions, Lanes, Width};
use phr_bvh::{refit, validate, Builder, Bvh, PackedTriangles, Ray, SimdLevel, WideBvh};

fn builders() -> Vec<Builder> {
    let mut b: Vec<Builder> = ["lbvh", "phr-hq", "binned-sah", "sbvh"].iter().map(|s| s.parse().unwrap()).collect();
    for k in [3, 4, 8, 16] {
        b.push(Builder::PHR_HQ.with_branching(k).unwrap());
    }
    b
}

/// Diffuse-bounce-like rays: from the brute-force hits of `rays`, a random direction in the
/// hemisphere the ray came from, starting a little off the surface.
fn bounce_rays(tris: &[[Vec3; 3]], rays: &[Ray], rng: &mut Rng) -> Vec<Ray> {
    rays.iter()
        .filter_map(|r| {
            let (t, p) = brute_force(tris, r)?;
            let [a, b, c] = tris[p as usize];
            let n = (b - a).cross(c - a).normalize_or(Vec3::Z);
            let facing = if n.dot(r.dir) < 0.0 { n } else { -n };
            let dir = (facing + rng.unit_vector()).normalize_or(facing);
            let hit = r.at(t);
            Some(Ray::new(hit + facing * 1e-5 * (1.0 + hit.abs().max_element()), dir))
        })
        .collect()
}

/// The per-primitive closure path, with the same tie rule as `bvh_hit`.
fn wide_hit_closure<const N: usize>(wide: &WideBvh<N>, tris: &[[Vec3; 3]], ray: &Ray) -> Option<(f32, u32)>
where
    Lanes<N>: Width<N>,
{
    let mut r = *ray;
    let mut best: Option<(f32, u32)> = None;
    wide.closest_hit(&mut r, |p, r| {
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

/// Checks one wide tree at every SIMD level; returns the number of hits. `split`: the source
/// tree has spatial splits.
fn check_wide<const N: usize>(bvh: &Bvh, tris: &[[Vec3; 3]], rays: &[Ray], what: &str, split: bool) -> usize
where
    Lanes<N>: Width<N>,
{
    let keep = format!("{what} (source leaves)");
    check_wide_with::<N>(bvh, tris, rays, what, CollapseOptions::default(), split)
        + check_wide_with::<N>(bvh, tris, rays, &keep, CollapseOptions::KEEP_LEAVES, split)
}

fn check_wide_with<const N: usize>(
    bvh: &Bvh,
    tris: &[[Vec3; 3]],
    rays: &[Ray],
    what: &str,
    options: CollapseOptions,
    split: bool,
) -> usize
where
    Lanes<N>: Width<N>,
{
    let boxes = triangle_boxes(tris);
    let mut wide = WideBvh::<N>::from_bvh_with(bvh, options);
    let valid = if split { wide.validate_split(&boxes) } else { wide.validate(&boxes) };
    valid.unwrap_or_else(|e| panic!("{what}, wide-{N}: {e}"));
    if !split {
        // (With spatial splits a merged leaf holds each primitive once, so its count can be
        // below its references' and the order is by references.)
        assert_slots_largest_first(&wide, &format!("{what}, wide-{N}"));
    }
    let mut packed = PackedTriangles::new(&wide.prim_indices, tris);
    let mut hits = 0;
    for level in SimdLevel::supported() {
        wide.set_simd(level);
        packed.set_simd(level);
        assert_eq!(wide.simd(), level);
        let what = format!("{what}, wide-{N} {}", level.name());
        for (i, ray) in rays.iter().enumerate() {
            let expected = brute_force(tris, ray);
            assert_eq!(bvh_hit(bvh, tris, ray), expected, "{what}: binary reference, ray {i} {ray:?}");
            let packed_hit = wide.closest_triangle(&packed, ray).map(|(p, h)| (h.t, p));
            assert_eq!(packed_hit, expected, "{what}: packed triangles, ray {i} {ray:?}");
            if let Some((p, h)) = wide.closest_triangle(&packed, ray) {
                let [a, b, c] = tris[p as usize];
                let scalar = intersect_triangle(ray, a, b, c).expect("the scalar test hits too");
                let bits = |h: phr_bvh::triangle::TriangleHit| [h.t.to_bits(), h.u.to_bits(), h.v.to_bits()];
                assert_eq!(bits(h), bits(scalar), "{what}: t/u/v bits, ray {i}");
            }
            assert_eq!(wide_hit_closure(&wide, tris, ray), expected, "{what}: closure path, ray {i} {ray:?}");
            assert_eq!(wide.any_triangle(&packed, ray), expected.is_some(), "{what}: any hit, ray {i} {ray:?}");
            let any = wide.any_hit(ray, |p, r| {
                let t = &tris[p as usize];
                intersect_triangle(r, t[0], t[1], t[2]).is_some()
            });
            assert_eq!(any, expected.is_some(), "{what}: any hit (closure), ray {i} {ray:?}");
            hits += expected.is_some() as usize;
        }
        check_interleaved(&wide, &packed, tris, rays, &what);
    }
    hits
}

/// The interleaved traversal (1 to 4 rays at once) gives every ray the single-ray answer,
/// slot and barycentrics included.
fn check_interleaved<const N: usize>(
    wide: &WideBvh<N>,
    packed: &PackedTriangles,
    tris: &[[Vec3; 3]],
    rays: &[Ray],
    what: &str,
) where
    Lanes<N>: Width<N>,
{
    let single: Vec<_> = rays.iter().map(|r| wide.closest_triangle_slot(packed, r)).collect();
    for (ray, hit) in rays.iter().zip(&single) {
        assert_eq!(hit.map(|h| (h.hit.t, h.prim)), brute_force(tris, ray), "{what}: slot query, ray {ray:?}");
    }
    let mut hits = vec![None; rays.len()];
    wide.closest_triangles_interleaved::<1>(packed, rays, &mut hits);
    assert_eq!(hits, single, "{what}: 1 ray at once");
    wide.closest_triangles_interleaved::<2>(packed, rays, &mut hits);
    assert_eq!(hits, single, "{what}: 2 rays at once");
    wide.closest_triangles_interleaved::<3>(packed, rays, &mut hits);
    assert_eq!(hits, single, "{what}: 3 rays at once");
    wide.closest_triangles_interleaved::<4>(packed, rays, &mut hits);
    assert_eq!(hits, single, "{what}: 4 rays at once");
    // Fewer rays than slots, and none.
    let few = &rays[..rays.len().min(3)];
    let mut few_hits = vec![None; few.len()];
    wide.closest_triangles_interleaved::<4>(packed, few, &mut few_hits);
    assert_eq!(few_hits, single[..few.len()], "{what}: fewer rays than slots");
    wide.closest_triangles_interleaved::<4>(packed, &[], &mut []);
    check_packets(wide, packed, rays, &single, what);
    // Any-hit queries likewise.
    let single: Vec<bool> = rays.iter().map(|r| wide.any_triangle(packed, r)).collect();
    let mut occluded = vec![false; rays.len()];
    wide.any_triangles_interleaved::<1>(packed, rays, &mut occluded);
    assert_eq!(occluded, single, "{what}: any hit, 1 ray at once");
    wide.any_triangles_interleaved::<2>(packed, rays, &mut occluded);
    assert_eq!(occluded, single, "{what}: any hit, 2 rays at once");
    wide.any_triangles_interleaved::<4>(packed, rays, &mut occluded);
    assert_eq!(occluded, single, "{what}: any hit, 4 rays at once");
}

/// The packet traversal of an 8-wide tree (`single`: the single-ray answers of `rays`)
/// gives every ray the single-ray answer, in full packets and in a short last one: the same
/// primitive, `t`, `u` and `v`, found in a slot that holds it (with spatial splits a
/// primitive has several, and which one a ray meets first depends on the visit order).
fn check_packets<const N: usize>(
    wide: &WideBvh<N>,
    packed: &PackedTriangles,
    rays: &[Ray],
    single: &[Option<SlotHit>],
    what: &str,
) {
    let Some(wide) = (wide as &dyn std::any::Any).downcast_ref::<WideBvh<8>>() else { return };
    let answers = |hits: &[Option<SlotHit>]| {
        for h in hits.iter().flatten() {
            assert_eq!(wide.prim_indices[h.slot as usize], h.prim, "{what}: the slot holds the primitive");
        }
        hits.iter().map(|h| h.map(|h| (h.prim, [h.hit.t, h.hit.u, h.hit.v].map(f32::to_bits)))).collect::<Vec<_>>()
    };
    let mut hits = vec![None; rays.len()];
    wide.closest_triangles_packets(packed, rays, &mut hits);
    assert_eq!(answers(&hits), answers(single), "{what}: packets");
    let odd = &rays[..rays.len().min(21)];
    let mut odd_hits = vec![None; odd.len()];
    wide.closest_triangles_packets(packed, odd, &mut odd_hits);
    assert_eq!(answers(&odd_hits), answers(&single[..odd.len()]), "{what}: packets, a short last one");
}

/// Camera rays: from a point before the box through a grid over it, row by row (the
/// coherent rays packets are made for).
fn camera_rays(bounds: phr_bvh::Aabb, side: usize) -> Vec<Ray> {
    let (c, e) = (bounds.center(), bounds.extent());
    let eye = c - Vec3::new(0.3, 0.2, 2.0) * e.max_element();
    (0..side * side)
        .map(|i| {
            let (x, y) = ((i % side) as f32 / side as f32, (i / side) as f32 / side as f32);
            let target = bounds.min + e * Vec3::new(x, y, 0.5);
            Ray::new(eye, (target - eye).normalize())
        })
        .collect()
}

#[test]
fn packets_match_single_rays_on_camera_rays() {
    for (name, tris) in adversarial_meshes() {
        let boxes = triangle_boxes(&tris);
        for builder in ["phr-hq", "binned-sah", "sbvh"] {
            let builder: Builder = builder.parse().unwrap();
            let bvh = builder.build_with_triangles(&boxes, &tris);
            let wide = WideBvh::<8>::from_bvh(&bvh);
            let packed = PackedTriangles::new(&wide.prim_indices, &tris);
            let rays = camera_rays(bvh.root_bounds(), 24);
            let single: Vec<_> = rays.iter().map(|r| wide.closest_triangle_slot(&packed, r)).collect();
            assert!(single.iter().any(Option::is_some), "{name}, {builder}: some camera ray hits");
            check_packets(&wide, &packed, &rays, &single, &format!("{name}, {builder}"));
        }
    }
}

#[test]
fn wide_matches_binary_and_brute_force_on_adversarial_meshes() {
    let mut total_rays = 0;
    let mut total_hits = 0;
    for (name, tris) in adversarial_meshes() {
        let boxes = triangle_boxes(&tris);
        let mut rng = Rng::new(tris.len() as u64 + 5);
        for builder in builders() {
            let bvh = builder.build_with_triangles(&boxes, &tris);
            builder.validate(&bvh, &boxes).unwrap();
            let mut rays = random_rays(bvh.root_bounds(), 150, &mut rng);
            let bounces = bounce_rays(&tris, &rays, &mut rng);
            rays.extend(bounces);
            let what = format!("{name}, {builder}");
            let split = builder.splits_primitives();
            total_hits += check_wide::<4>(&bvh, &tris, &rays, &what, split);
            total_hits += check_wide::<8>(&bvh, &tris, &rays, &what, split);
            total_rays += 2 * rays.len() * SimdLevel::supported().len();
        }
    }
    // Not vacuous: a good share of the rays hit something.
    assert!(total_hits * 10 > total_rays, "{total_hits} hits of {total_rays} rays");
}

#[test]
fn detection_picks_a_supported_level_and_set_simd_clamps() {
    let levels = SimdLevel::supported();
    assert_eq!(levels[0], SimdLevel::Scalar);
    assert_eq!(*levels.last().unwrap(), SimdLevel::detect());
    #[cfg(target_arch = "x86_64")]
    assert!(levels.contains(&SimdLevel::Sse));
    let tris = random_soup(100, 1.0, &mut Rng::new(3));
    let bvh = Builder::default().build(&triangle_boxes(&tris));
    let wide = WideBvh::<8>::from_bvh(&bvh).with_simd(SimdLevel::Avx2);
    assert!(wide.simd() <= SimdLevel::detect());
}

/// The collapse fills nodes: on a binary tree of many leaves most slots are used, and the
/// wide tree has about (leaves - 1) / (N - 1) nodes.
#[test]
fn collapse_fills_the_slots() {
    let tris = random_soup(20_000, 1.0, &mut Rng::new(11));
    let boxes = triangle_boxes(&tris);
    let bvh = Builder::PHR_HQ.build(&boxes);
    let leaves = bvh.nodes.iter().filter(|n| n.is_leaf()).count();
    let w4 = WideBvh::<4>::from_bvh_with(&bvh, CollapseOptions::KEEP_LEAVES);
    let w8 = WideBvh::<8>::from_bvh_with(&bvh, CollapseOptions::KEEP_LEAVES);
    assert_eq!(w4.leaf_count(), leaves);
    assert_eq!(w8.leaf_count(), leaves);
    assert!(w4.mean_fill() > 2.8, "wide-4 fill {}", w4.mean_fill());
    assert!(w8.mean_fill() > 4.5, "wide-8 fill {}", w8.mean_fill());
    eprintln!("fill: wide-4 {:.2}, wide-8 {:.2}", w4.mean_fill(), w8.mean_fill());
    assert!(w8.nodes.len() < leaves / 3, "{} wide-8 nodes for {leaves} leaves", w8.nodes.len());
}

/// A degenerate chain (every interior node has a leaf and an interior child): deep enough
/// that the traversal stack does not fit on the call stack and goes to the heap.
#[test]
fn deep_chain_uses_the_heap_stack_and_still_matches() {
    let n = 2000;
    let mut rng = Rng::new(5);
    let tris = random_soup(n, 1.0, &mut rng);
    let boxes = triangle_boxes(&tris);
    let mut nodes = Vec::new();
    for i in 0..n as u32 - 1 {
        let first_child = nodes.len() as u32 + 1;
        nodes.push(Node::interior(Default::default(), first_child));
        nodes.push(Node::leaf(Default::default(), i, 1));
        if i == n as u32 - 2 {
            nodes.push(Node::leaf(Default::default(), i + 1, 1));
        }
    }
    // Children of node at 2i are 2i+1 (leaf) and 2i+2 (next interior or the last leaf).
    let mut bvh = Bvh { nodes, prim_indices: (0..n as u32).collect(), parents: Vec::new() };
    bvh.compute_parents();
    refit(&mut bvh, &boxes);
    validate(&bvh, &boxes, 1).unwrap();
    let rays = random_rays(bvh.root_bounds(), 60, &mut rng);
    let hits =
        check_wide::<4>(&bvh, &tris, &rays, "chain", false) + check_wide::<8>(&bvh, &tris, &rays, "chain", false);
    assert!(hits > 0);
}

#[test]
fn empty_and_single_triangle_trees() {
    let empty = WideBvh::<8>::from_bvh(&Bvh::default());
    assert!(empty.validate(&[]).is_ok());
    let ray = Ray::new(Vec3::ZERO, Vec3::Z);
    assert!(!empty.closest_hit(&mut ray.clone(), |_, _| true));
    let mut hits =
        vec![Some(SlotHit { slot: 0, prim: 0, hit: phr_bvh::triangle::TriangleHit { t: 1.0, u: 0.0, v: 0.0 } })];
    empty.closest_triangles_packets(&PackedTriangles::default(), &[ray], &mut hits);
    assert_eq!(hits, [None], "packets through an empty tree");
    let tris = vec![[Vec3::new(-1.0, -1.0, 1.0), Vec3::new(1.0, -1.0, 1.0), Vec3::new(0.0, 1.0, 1.0)]];
    let bvh = Builder::default().build(&triangle_boxes(&tris));
    let wide = WideBvh::<4>::from_bvh(&bvh);
    wide.validate(&triangle_boxes(&tris)).unwrap();
    let packed = PackedTriangles::new(&wide.prim_indices, &tris);
    assert_eq!(wide.closest_triangle(&packed, &ray).map(|(p, h)| (p, h.t)), Some((0, 1.0)));
    // Packets through a tree whose root holds the one leaf, and an interval that ends at 0.
    let wide = WideBvh::<8>::from_bvh(&bvh);
    let packed = PackedTriangles::new(&wide.prim_indices, &tris);
    let rays = [ray, Ray::with_interval(Vec3::ZERO, Vec3::Z, 0.0, 0.0), Ray::new(Vec3::ZERO, -Vec3::Z)];
    let mut hits = vec![None; rays.len()];
    wide.closest_triangles_packets(&packed, &rays, &mut hits);
    let answers: Vec<_> = hits.iter().map(|h| h.map(|h| (h.prim, h.hit.t))).collect();
    assert_eq!(answers, [Some((0, 1.0)), None, None], "packets through a one-leaf tree");
}

#[test]
fn validate_catches_broken_wide_trees() {
    let tris = random_soup(500, 1.0, &mut Rng::new(9));
    let boxes = triangle_boxes(&tris);
    let wide = WideBvh::<4>::from_bvh(&Builder::default().build(&boxes));
    wide.validate(&boxes).unwrap();
    // A child box that no longer encloses its subtree.
    let mut broken = wide.clone();
    let slot = (0..4).find(|&s| broken.nodes[0].count[s] == 0 && broken.nodes[0].is_used(s)).unwrap();
    broken.nodes[0].bounds[phr_bvh::wide::MAX_X][slot] = broken.nodes[0].bounds[phr_bvh::wide::MIN_X][slot];
    assert!(broken.validate(&boxes).is_err());
    // A primitive referenced twice (and another one lost).
    let mut broken = wide.clone();
    broken.prim_indices[1] = broken.prim_indices[0];
    assert!(broken.validate(&boxes).is_err());
}

/// Merged leaves: at most 4 primitives (unless a source leaf was larger), each within one
/// 4-lane block; small leaves share blocks, which saves at least 30 % of the padding that
/// starting each leaf at a block would need; fewer nodes than without merging.
#[test]
fn merged_leaves_are_small_and_within_a_block() {
    let tris = random_soup(20_000, 1.0, &mut Rng::new(12));
    let boxes = triangle_boxes(&tris);
    let bvh = phr_bvh::build_lbvh(&boxes, phr_bvh::LbvhOptions { max_leaf_size: 1 });
    let merged = WideBvh::<8>::from_bvh(&bvh);
    let kept = WideBvh::<8>::from_bvh_with(&bvh, CollapseOptions::KEEP_LEAVES);
    merged.validate(&boxes).unwrap();
    assert!(merged.nodes.len() < kept.nodes.len(), "{} vs {} nodes", merged.nodes.len(), kept.nodes.len());
    for n in &merged.nodes {
        for s in 0..8 {
            if n.count[s] > 0 {
                assert!(n.count[s] <= 4);
                assert!(n.child[s] % 4 + n.count[s] <= 4, "leaf at {} of {} crosses a block", n.child[s], n.count[s]);
            }
        }
    }
    // Each leaf starting a block would pad every leaf out to a multiple of 4.
    let counts = merged.nodes.iter().flat_map(|n| n.count).filter(|&c| c > 0);
    let block_per_leaf: u32 = counts.map(|c| c.next_multiple_of(4) - c).sum();
    let pad = merged.prim_indices.iter().filter(|&&p| p == phr_bvh::wide::PAD).count() as u32;
    assert!(10 * pad < 7 * block_per_leaf, "padding {pad}, a block per leaf {block_per_leaf}");
}

/// The 4-lane triangle test gives the scalar test's bits on random, degenerate, huge, tiny
/// and grazing triangles, hits and misses alike (compared through `leaf_hits`).
#[test]
fn packed_block_test_is_bit_identical_to_scalar() {
    let mut rng = Rng::new(77);
    let mut tris = Vec::new();
    for (_, mesh) in adversarial_meshes() {
        tris.extend(mesh.into_iter().take(300));
    }
    let prims: Vec<u32> = (0..tris.len() as u32).collect();
    let mut simd = PackedTriangles::new(&prims, &tris);
    let mut scalar = simd.clone();
    scalar.set_simd(SimdLevel::Scalar);
    simd.set_simd(SimdLevel::detect());
    let bounds = triangle_boxes(&tris).iter().fold(phr_bvh::Aabb::EMPTY, |a, b| a.union(*b));
    let mut rays = random_rays(bounds, 300, &mut rng);
    // Rays at the triangles, some grazing their planes.
    for t in tris.iter().step_by(7) {
        let target = (t[0] + t[1] + t[2]) / 3.0;
        let o = target + rng.unit_vector() * 2.0;
        rays.push(Ray::new(o, (target - o).normalize_or(Vec3::X)));
        let along = (t[1] - t[0]).normalize_or(Vec3::X);
        rays.push(Ray::new(target - along, along));
    }
    let mut hits = 0;
    for ray in &rays {
        for first in (0..tris.len() as u32).step_by(4) {
            let count = (tris.len() as u32 - first).min(4);
            let collect = |p: &PackedTriangles| {
                let mut r = *ray;
                let mut out = Vec::new();
                p.leaf_hits(first, count, &mut r, |i, h, _| {
                    out.push((i, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()));
                    false
                });
                out
            };
            let a = collect(&scalar);
            assert_eq!(collect(&simd), a, "ray {ray:?}, block at {first}");
            hits += a.len();
        }
    }
    assert!(hits > 100, "only {hits} hits");
}

#[test]
fn rebuilding_in_place_equals_a_fresh_collapse() {
    // The dynamic pipeline collapses and packs into the previous frame's memory: a big tree
    // first, then a smaller and a k-ary one, each must come out as a fresh collapse would.
    let mut rng = Rng::new(7);
    let big = random_soup(3000, 1.0, &mut rng);
    let small = random_soup(500, 1.0, &mut rng);
    let mut wide = WideBvh::<8>::default();
    let mut packed = PackedTriangles::default();
    for (tris, builder) in
        [(&big, Builder::default()), (&small, Builder::PHR_FAST.with_branching(4).unwrap()), (&big, Builder::PHR_HQ)]
    {
        let bvh = builder.build(&triangle_boxes(tris));
        wide.rebuild(&bvh);
        packed.repack(&wide.prim_indices, tris);
        let fresh = WideBvh::<8>::from_bvh(&bvh);
        assert_eq!(wide.nodes, fresh.nodes);
        assert_eq!(wide.prim_indices, fresh.prim_indices);
        assert_eq!(packed.blocks, PackedTriangles::new(&fresh.prim_indices, tris).blocks);
        wide.validate(&triangle_boxes(tris)).unwrap();
        for ray in random_rays(phr_bvh::Aabb::from_points(&tris.concat()), 300, &mut rng) {
            let hit = wide.closest_triangle(&packed, &ray).map(|(p, h)| (h.t, p));
            assert_eq!(hit, brute_force(tris, &ray));
        }
    }
}

/// Rays with NaN or infinite origins, directions or intervals (what a scene at the edge of
/// f32's range produces) hit nothing and stay inside the traversal's stack and node array, at
/// every width, SIMD level and query. Before the traversal refused them, a NaN slab distance
/// made empty slots look hit and the loop ran off its stack (a segmentation fault).
#[test]
fn non_finite_rays_hit_nothing_and_stay_memory_safe() {
    let tris = random_soup(5_000, 1.0, &mut Rng::new(21));
    let boxes = triangle_boxes(&tris);
    let bvh = Builder::PHR_HQ.build(&boxes);
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    let centre = bvh.root_bounds().center();
    let mut rays = Vec::new();
    for bad in [nan, inf, -inf] {
        for axis in 0..3 {
            let mut o = centre - Vec3::Z * 3.0;
            o[axis] = bad;
            rays.push(Ray::new(o, Vec3::Z));
            let mut d = Vec3::new(0.1, 0.2, 1.0);
            d[axis] = bad;
            rays.push(Ray::new(centre - Vec3::Z * 3.0, d));
        }
        rays.push(Ray::new(Vec3::splat(bad), Vec3::splat(bad)));
    }
    // A hand-made inverse direction that disagrees with the direction.
    let mut r = Ray::new(centre - Vec3::Z * 3.0, Vec3::Z);
    r.inv_dir = Vec3::new(nan, 0.0, inf);
    rays.push(r);
    let finite_nan_interval = Ray::with_interval(centre - Vec3::Z * 3.0, Vec3::Z, nan, nan);
    fn run<const N: usize>(bvh: &Bvh, tris: &[[Vec3; 3]], rays: &[Ray], extra: &Ray)
    where
        Lanes<N>: Width<N>,
    {
        let mut wide = WideBvh::<N>::from_bvh(bvh);
        let mut packed = PackedTriangles::new(&wide.prim_indices, tris);
        for level in SimdLevel::supported() {
            wide.set_simd(level);
            packed.set_simd(level);
            for ray in rays.iter().chain([extra]) {
                let what = format!("wide-{N} {}, ray {ray:?}", level.name());
                assert_eq!(wide.closest_triangle(&packed, ray).map(|(p, _)| p), None, "{what}");
                assert!(!wide.any_triangle(&packed, ray), "{what}");
                assert!(!wide.closest_hit(&mut ray.clone(), |_, _| true), "{what}");
                assert!(!wide.any_hit(ray, |_, _| true), "{what}");
            }
            // Among finite rays, in the interleaved traversal: the bad ones hit nothing, the
            // others what they hit alone.
            let finite = random_rays(bvh.root_bounds(), 40, &mut Rng::new(4));
            let mixed: Vec<Ray> =
                finite.iter().zip(rays.iter().cycle()).flat_map(|(a, b)| [*a, *b]).chain([*extra]).collect();
            let mut hits = vec![None; mixed.len()];
            wide.closest_triangles_interleaved::<3>(&packed, &mixed, &mut hits);
            for (ray, hit) in mixed.iter().zip(&hits) {
                assert_eq!(
                    *hit,
                    wide.closest_triangle_slot(&packed, ray),
                    "wide-{N} {}, interleaved, ray {ray:?}",
                    level.name()
                );
            }
            let single: Vec<_> = mixed.iter().map(|r| wide.closest_triangle_slot(&packed, r)).collect();
            check_packets(&wide, &packed, &mixed, &single, &format!("wide-{N} {}, bad rays", level.name()));
            assert!(hits.iter().step_by(2).any(Option::is_some), "some finite ray hits");
            let mut occluded = vec![false; mixed.len()];
            wide.any_triangles_interleaved::<3>(&packed, &mixed, &mut occluded);
            for (ray, &o) in mixed.iter().zip(&occluded) {
                assert_eq!(
                    o,
                    wide.any_triangle(&packed, ray),
                    "wide-{N} {}, interleaved any hit, ray {ray:?}",
                    level.name()
                );
            }
        }
    }
    run::<4>(&bvh, &tris, &rays, &finite_nan_interval);
    run::<8>(&bvh, &tris, &rays, &finite_nan_interval);
    // The binary reference agrees.
    for ray in &rays {
        assert_eq!(bvh_hit(&bvh, &tris, ray), None, "binary, ray {ray:?}");
    }
}

#[test]
fn large_trees_collapse_in_parallel_identically_and_correctly() {
    // Above 8192 primitives the collapse splits its top into parallel tasks: the pieces
    // must fit together (hits as brute force, invariants), whatever the thread count.
    let mut rng = Rng::new(12);
    let tris = random_soup(40_000, 1.0, &mut rng);
    let boxes = triangle_boxes(&tris);
    let rays = random_rays(boxes.iter().fold(phr_bvh::Aabb::EMPTY, |a, b| a.union(*b)), 300, &mut rng);
    let sbvh: Builder = "sbvh".parse().unwrap();
    for builder in [Builder::PHR_FAST, "lbvh".parse().unwrap(), Builder::PHR_HQ.with_branching(8).unwrap(), sbvh] {
        let bvh = builder.build_with_triangles(&boxes, &tris);
        let what = format!("40k soup, {builder}");
        let split = builder.splits_primitives();
        assert!(check_wide::<8>(&bvh, &tris, &rays, &what, split) > 0, "{what}: no hits");
        check_wide::<4>(&bvh, &tris, &rays, &what, split);
        let collapse = |threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| WideBvh::<8>::from_bvh(&bvh))
        };
        let (a, b) = (collapse(1), collapse(2));
        assert_eq!(a.nodes, b.nodes, "{what}");
        assert_eq!(a.prim_indices, b.prim_indices, "{what}");
    }
}

/// `wide_sah_cost` on a tree small enough to cost by hand: a root with two leaves (unit
/// cubes at x = 0 and x = 2, two and one primitives) and an interior child (the box
/// [0, 3] × [0, 1]², area 14) holding one leaf of four primitives in the same box.
#[test]
fn wide_sah_cost_by_hand() {
    use phr_bvh::wide::WideNode;
    use phr_bvh::{wide_sah_cost, Aabb, SahConstants};
    let cube = |x: f32| Aabb::new(Vec3::new(x, 0.0, 0.0), Vec3::new(x + 1.0, 1.0, 1.0));
    let long = Aabb::new(Vec3::ZERO, Vec3::new(3.0, 1.0, 1.0));
    let mut root = WideNode::<4>::EMPTY;
    let mut inner = WideNode::<4>::EMPTY;
    let set = |node: &mut WideNode<4>, i: usize, b: Aabb, child: u32, count: u32| {
        let (min, max) = (b.min.to_array(), b.max.to_array());
        for axis in 0..3 {
            node.bounds[2 * axis][i] = min[axis];
            node.bounds[2 * axis + 1][i] = max[axis];
        }
        (node.child[i], node.count[i]) = (child, count);
    };
    set(&mut root, 0, cube(0.0), 0, 2);
    set(&mut root, 1, cube(2.0), 2, 1);
    set(&mut root, 2, long, 1, 0);
    set(&mut inner, 0, long, 3, 4);
    let mut wide = WideBvh::<4>::default();
    wide.nodes = vec![root, inner];
    wide.prim_indices = (0..7).collect();
    // Root 2·14, leaves 6·2 + 6·1, interior 2·14, its leaf 14·4; over the root's 14.
    let thesis = (2.0 * 14.0 + 6.0 * 2.0 + 6.0 + 2.0 * 14.0 + 14.0 * 4.0) / 14.0;
    assert!((wide_sah_cost(&wide, SahConstants::THESIS) - thesis).abs() < 1e-9);
    let unit = (14.0 + 6.0 * 2.0 + 6.0 + 14.0 + 14.0 * 4.0) / 14.0;
    assert!((wide_sah_cost(&wide, SahConstants::UNIT) - unit).abs() < 1e-9);
    assert_eq!(wide_sah_cost(&WideBvh::<4>::default(), SahConstants::UNIT), 0.0);
}
