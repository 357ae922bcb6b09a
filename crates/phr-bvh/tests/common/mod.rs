//! Shared helpers of the phr-bvh integration tests: a tiny deterministic RNG, triangle soups,
//! and brute-force reference intersection.
#![allow(dead_code)]

use glam::Vec3;
use phr_bvh::triangle::intersect_triangle;
use phr_bvh::{closest_hit, Aabb, Bvh, Ray};

pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    pub fn f32(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }
    pub fn vec3(&mut self, lo: Vec3, hi: Vec3) -> Vec3 {
        lo + (hi - lo) * Vec3::new(self.f32(), self.f32(), self.f32())
    }
    pub fn unit_vector(&mut self) -> Vec3 {
        loop {
            let v = self.vec3(Vec3::splat(-1.0), Vec3::ONE);
            let l = v.length_squared();
            if l > 1e-4 && l <= 1.0 {
                return v / l.sqrt();
            }
        }
    }
}

pub fn triangle_boxes(tris: &[[Vec3; 3]]) -> Vec<Aabb> {
    tris.iter().map(|t| Aabb::from_points(t)).collect()
}

/// Closest hit (t, primitive) by testing every triangle; ties go to the lower index.
pub fn brute_force(tris: &[[Vec3; 3]], ray: &Ray) -> Option<(f32, u32)> {
    let mut best: Option<(f32, u32)> = None;
    for (i, t) in tris.iter().enumerate() {
        if let Some(h) = intersect_triangle(ray, t[0], t[1], t[2]) {
            if best.is_none_or(|(bt, _)| h.t < bt) {
                best = Some((h.t, i as u32));
            }
        }
    }
    best
}

/// Closest hit through the BVH, with the same tie rule as [`brute_force`].
pub fn bvh_hit(bvh: &Bvh, tris: &[[Vec3; 3]], ray: &Ray) -> Option<(f32, u32)> {
    let mut r = *ray;
    let mut best: Option<(f32, u32)> = None;
    closest_hit(bvh, &mut r, |p, r| {
        let t = &tris[p as usize];
        // Hits at exactly tmax are reported too, so the lowest index wins ties whatever the
        // visit order.
        match intersect_triangle(r, t[0], t[1], t[2]) {
            Some(h) if h.t < r.tmax || (h.t == r.tmax && best.is_some_and(|(_, bp)| p < bp)) => {
                r.tmax = h.t;
                best = Some((h.t, p));
                true
            }
            _ => false,
        }
    });
    best
}

/// Random rays: from random points around the scene box towards random points inside it,
/// plus fully random directions.
pub fn random_rays(bounds: Aabb, count: usize, rng: &mut Rng) -> Vec<Ray> {
    let c = bounds.center();
    let e = bounds.extent().max(Vec3::splat(1e-6));
    (0..count)
        .map(|i| {
            let origin = rng.vec3(c - e, c + e);
            let dir = if i % 2 == 0 { rng.vec3(bounds.min, bounds.max) - origin } else { rng.unit_vector() };
            let dir = if dir.length_squared() > 0.0 { dir.normalize() } else { Vec3::X };
            Ray::new(origin, dir)
        })
        .collect()
}

/// Checks traversal against brute force for `rays`; returns the number of hits.
pub fn assert_matches_brute_force(bvh: &Bvh, tris: &[[Vec3; 3]], rays: &[Ray], what: &str) -> usize {
    let mut hits = 0;
    for (i, ray) in rays.iter().enumerate() {
        let expected = brute_force(tris, ray);
        let got = bvh_hit(bvh, tris, ray);
        assert_eq!(got, expected, "{what}: ray {i} {ray:?}");
        hits += expected.is_some() as usize;
    }
    hits
}

pub fn random_soup(n: usize, scale: f32, rng: &mut Rng) -> Vec<[Vec3; 3]> {
    (0..n)
        .map(|_| {
            let c = rng.vec3(Vec3::splat(-scale), Vec3::splat(scale));
            let s = scale * 0.05;
            [
                c + rng.vec3(Vec3::splat(-s), Vec3::splat(s)),
                c + rng.vec3(Vec3::splat(-s), Vec3::splat(s)),
                c + rng.vec3(Vec3::splat(-s), Vec3::splat(s)),
            ]
        })
        .collect()
}

/// Adversarial meshes every builder must survive, with a name for messages.
pub fn adversarial_meshes() -> Vec<(&'static str, Vec<[Vec3; 3]>)> {
    let mut rng = Rng::new(7);
    let one = vec![[Vec3::ZERO, Vec3::X, Vec3::Y]];
    // All centroids equal: triangles rotated about a common centre.
    let same_centroid: Vec<[Vec3; 3]> = (0..500)
        .map(|i| {
            let a = i as f32 * 0.1;
            let (s, c) = a.sin_cos();
            let p = Vec3::new(c, s, 0.3 * s);
            [
                p,
                Vec3::new(-c * 0.5 - s * 0.8, -s * 0.5 + c * 0.8, 0.1),
                Vec3::new(-c * 0.5 + s * 0.8, -s * 0.5 - c * 0.8, -0.3 * s - 0.1),
            ]
        })
        .collect();
    let identical: Vec<[Vec3; 3]> = (0..300).map(|_| [Vec3::ZERO, Vec3::X, Vec3::Y]).collect();
    // Degenerate triangles (points and segments) mixed with regular ones.
    let mut degenerate = random_soup(400, 1.0, &mut rng);
    for (i, t) in degenerate.iter_mut().enumerate() {
        match i % 3 {
            0 => *t = [t[0], t[0], t[0]],
            1 => *t = [t[0], t[1], t[1] + (t[1] - t[0])],
            _ => {}
        }
    }
    let huge: Vec<[Vec3; 3]> = random_soup(1000, 1.0e6, &mut rng);
    let tiny: Vec<[Vec3; 3]> = random_soup(1000, 1.0e-5, &mut rng);
    let offset_tiny: Vec<[Vec3; 3]> =
        random_soup(1000, 1.0e-2, &mut rng).into_iter().map(|t| t.map(|v| v + Vec3::splat(1000.0))).collect();
    // A flat mesh: all triangles in the z = 0 plane.
    let flat: Vec<[Vec3; 3]> =
        random_soup(1000, 1.0, &mut rng).into_iter().map(|t| t.map(|v| v * Vec3::new(1.0, 1.0, 0.0))).collect();
    vec![
        ("single triangle", one),
        ("equal centroids", same_centroid),
        ("identical triangles", identical),
        ("degenerate triangles", degenerate),
        ("huge coordinates", huge),
        ("tiny coordinates", tiny),
        ("tiny far from origin", offset_tiny),
        ("flat", flat),
        ("random soup", random_soup(5000, 1.0, &mut rng)),
    ]
}

/// A wide tree as its builder decided it, independent of where nodes sit in memory (to
/// compare a direct wide build with the collapse of a binary one): depth first, each slot's
/// box bits, then its sorted primitives (a leaf) or its subtree.
pub fn canonical_wide<const N: usize>(wide: &phr_bvh::WideBvh<N>) -> Vec<u64> {
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

/// Checks that every node of `wide` holds its children largest subtree first (primitives
/// under each slot, non-increasing), with the empty slots last: the order the any-hit
/// traversal relies on to visit the smallest hit subtree first.
pub fn assert_slots_largest_first<const N: usize>(wide: &phr_bvh::WideBvh<N>, what: &str) {
    fn size<const N: usize>(wide: &phr_bvh::WideBvh<N>, n: u32, memo: &mut [u64]) -> u64 {
        if memo[n as usize] == u64::MAX {
            let node = &wide.nodes[n as usize];
            memo[n as usize] = (0..N).map(|i| slot_size(wide, node, i, memo)).sum();
        }
        memo[n as usize]
    }
    fn slot_size<const N: usize>(
        wide: &phr_bvh::WideBvh<N>,
        node: &phr_bvh::wide::WideNode<N>,
        i: usize,
        memo: &mut [u64],
    ) -> u64 {
        match (node.is_used(i), node.count[i]) {
            (false, _) => 0,
            (true, 0) => size(wide, node.child[i], memo),
            (true, count) => u64::from(count),
        }
    }
    let mut memo = vec![u64::MAX; wide.nodes.len()];
    for (n, node) in wide.nodes.iter().enumerate() {
        let sizes: Vec<u64> = (0..N).map(|i| slot_size(wide, node, i, &mut memo)).collect();
        assert!(sizes.windows(2).all(|w| w[0] >= w[1]), "{what}: node {n}'s slots are not largest first: {sizes:?}");
        let used: Vec<bool> = (0..N).map(|i| node.is_used(i)).collect();
        assert!(used.windows(2).all(|w| w[0] >= w[1]), "{what}: node {n} has an empty slot before a used one");
    }
}

/// Checks a wide tree over `tris` (`boxes` their boxes): the wide invariants, the slots'
/// order, and brute force's closest hits on 100 random rays. Returns its leaf count.
pub fn assert_wide_tree_sound<const N: usize>(
    wide: &phr_bvh::WideBvh<N>,
    boxes: &[Aabb],
    tris: &[[Vec3; 3]],
    what: &str,
) -> usize
where
    phr_bvh::wide::Lanes<N>: phr_bvh::wide::Width<N>,
{
    wide.validate(boxes).unwrap_or_else(|e| panic!("{what}: {e}"));
    assert_slots_largest_first(wide, what);
    let packed = phr_bvh::PackedTriangles::new(&wide.prim_indices, tris);
    let bounds = boxes.iter().fold(Aabb::EMPTY, |a, b| a.union(*b));
    let mut rng = Rng::new(tris.len() as u64);
    for (i, ray) in random_rays(bounds, 100, &mut rng).iter().enumerate() {
        let hit = wide.closest_triangle(&packed, ray).map(|(p, h)| (h.t, p));
        assert_eq!(hit, brute_force(tris, ray), "{what}: ray {i} {ray:?}");
    }
    wide.leaf_count()
}

/// Runs `build` (which checks its tree) on pools of 1 and 2 threads and asserts that both
/// trees are laid out the same.
pub fn assert_same_on_1_and_2_threads<const N: usize>(build: impl Fn(usize) -> phr_bvh::WideBvh<N> + Sync) {
    let trees: Vec<_> = [1, 2]
        .into_iter()
        .map(|threads| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| build(threads))
        })
        .collect();
    assert_eq!(trees[0].nodes, trees[1].nodes, "the layout depends on the thread count");
    assert_eq!(trees[0].prim_indices, trees[1].prim_indices);
}
