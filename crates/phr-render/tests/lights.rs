//! The light set of next-event estimation (`lights.rs`) against what its documentation
//! promises, with every expected value recomputed here in f64: lights are the emissive
//! triangles and spheres with some emission, and the sky when it is not black; an emitter is
//! picked with probability power / total power, power = area × brightest emission channel
//! (degenerate ones never), the sky with its fixed share; a triangle's point is uniform on it
//! (barycentric moments and sub-triangle frequencies of the uniform distribution); every
//! sample's density is the one `pdf_hit`/`pdf_sky` give for its direction, and the density
//! integrates to one over the sphere of directions (a numerical quadrature that finds the
//! lights by intersecting them, not by the sampler); `refresh` follows moved vertices; the MIS
//! weights of two strategies sum to one. Frequencies are judged with a 5-sigma binomial
//! tolerance.

use glam::Vec3;
use phr_bvh::sphere::Sphere;
use phr_bvh::triangle::intersect_triangle;
use phr_bvh::Ray;
use phr_render::geometry::Geometry;
use phr_render::lights::{power_heuristic, LightSet, SKY, SKY_SHARE};
use phr_render::material::Material;
use phr_render::sampler::Pcg32;
use phr_render::scene::{Background, Mesh, Scene, SphereObject};

/// Area of a triangle from its corners, in f64: half the length of the cross product.
fn area(t: [Vec3; 3]) -> f64 {
    let [a, b, c] = t.map(|p| p.to_array().map(f64::from));
    let (e1, e2) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
    let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
    0.5 * (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt()
}

/// Barycentric coordinates of `p` (assumed in the plane) with respect to `t`, in f64.
fn barycentric(t: [Vec3; 3], p: Vec3) -> [f64; 3] {
    let sub = |x: [Vec3; 3]| area(x);
    let total = area(t);
    [sub([p, t[1], t[2]]) / total, sub([t[0], p, t[2]]) / total, sub([t[0], t[1], p]) / total]
}

fn v(x: f32, y: f32, z: f32) -> Vec3 {
    Vec3::new(x, y, z)
}

/// Three lights of different sizes and colours among non-lights: triangle 1 (area 2, emit max
/// 3: power 6), triangle 3 (tilted, area √2, emit max 4: power 5.657), triangle 4 (area 4.5,
/// emit 0.5: power 2.25); selection probabilities 0.431, 0.407, 0.162. Triangles 0 and 2 are
/// diffuse, 5 emits nothing, 6 is a degenerate emitter; sphere 0 (primitive 7, radius 1, emit
/// max 3: power 4π · 3 = 37.70) is emissive. The background is black.
fn scene() -> Scene {
    let mut scene = Scene::default();
    let white = scene.add_material("white", Material::Lambertian { albedo: Vec3::splat(0.5) });
    let a = scene.add_material("a", Material::Emissive { emit: v(1.0, 3.0, 2.0), two_sided: false });
    let b = scene.add_material("b", Material::Emissive { emit: v(0.0, 0.0, 4.0), two_sided: false });
    let c = scene.add_material("c", Material::Emissive { emit: Vec3::splat(0.5), two_sided: true });
    let dark = scene.add_material("dark", Material::Emissive { emit: Vec3::ZERO, two_sided: false });
    let triangles = [
        [v(-5.0, -5.0, -1.0), v(5.0, -5.0, -1.0), v(0.0, 5.0, -1.0)],
        [v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(0.0, 2.0, 0.0)],
        [v(0.0, 0.0, 4.0), v(1.0, 0.0, 4.0), v(0.0, 1.0, 4.0)],
        [v(1.0, 1.0, 3.0), v(2.0, 1.0, 4.0), v(1.0, 3.0, 3.0)],
        [v(10.0, 0.0, 0.0), v(10.0, 3.0, 0.0), v(10.0, 0.0, 3.0)],
        [v(0.0, 0.0, 6.0), v(1.0, 0.0, 6.0), v(0.0, 1.0, 6.0)],
        [v(0.0, 0.0, 7.0), v(1.0, 1.0, 7.0), v(2.0, 2.0, 7.0)],
    ];
    let materials = [white, a, white, b, c, dark, a];
    scene.meshes.push(Mesh {
        name: "lights".into(),
        positions: triangles.iter().flatten().copied().collect(),
        triangles: (0..triangles.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect(),
        triangle_material: materials.to_vec(),
        uvs: Vec::new(),
    });
    let sphere = Sphere { center: v(0.0, 0.0, 20.0), radius: 1.0 };
    scene.spheres.push(SphereObject { sphere, material: a });
    scene
}

/// The lights of [`scene`]: (primitive, material, power) with power = area × max channel.
fn expected_lights(geometry: &Geometry) -> Vec<(u32, u32, f64)> {
    let mut lights: Vec<_> = [(1, 1, 3.0), (3, 2, 4.0), (4, 3, 0.5)]
        .map(|(p, m, emit)| (p, m, area(geometry.triangles[p as usize]) * emit))
        .into();
    lights.push((7, 1, 4.0 * std::f64::consts::PI * 3.0));
    lights
}

/// Where the samples are taken from: outside the sphere, off every light's plane, facing all
/// of them at least in part.
const FROM: Vec3 = Vec3::new(0.5, 0.4, 2.0);
const FACING: Vec3 = Vec3::Z;

#[test]
fn only_emitters_with_emission_are_lights() {
    let scene = scene();
    let geometry = Geometry::new(&scene);
    let lights = LightSet::new(&geometry, &scene.materials, &scene.background);
    assert!(!lights.is_empty() && !lights.has_sky());
    for (prim, is_light) in
        [(0, false), (1, true), (2, false), (3, true), (4, true), (5, false), (6, false), (7, true), (99, false)]
    {
        assert_eq!(lights.contains(prim), is_light, "primitive {prim}");
    }
    // Nothing emissive (or only zero-area emitters) and a black sky: nothing to sample.
    let mut dark = scene.clone();
    for m in 1..=3 {
        dark.materials[m] = Material::Lambertian { albedo: Vec3::ONE };
    }
    let glow = dark.add_material("glow", Material::Emissive { emit: Vec3::ONE, two_sided: false });
    dark.meshes[0].triangle_material[6] = glow;
    let geometry = Geometry::new(&dark);
    let lights = LightSet::new(&geometry, &dark.materials, &dark.background);
    assert!(lights.is_empty(), "only a degenerate emitter left");
    assert!(lights.sample(&geometry, FROM, FACING, &mut Pcg32::new(1, 1)).is_none());
    // A sky that is not black is a light, and then the only one.
    let lights = LightSet::new(&geometry, &dark.materials, &Background::Constant(Vec3::new(0.0, 0.1, 0.0)));
    assert!(!lights.is_empty() && lights.has_sky());
    let mut rng = Pcg32::new(1, 1);
    for _ in 0..100 {
        assert_eq!(lights.sample(&geometry, FROM, FACING, &mut rng).map(|s| s.prim), Some(SKY));
    }
}

/// Samples with `lights` from [`FROM`] until `n` are found; checks each one's density
/// against `pdf_hit`/`pdf_sky` and its point against its direction; counts them by primitive.
fn sample_counts(geometry: &Geometry, lights: &LightSet, n: usize, seed: u64) -> std::collections::HashMap<u32, usize> {
    let mut counts = std::collections::HashMap::new();
    let mut rng = Pcg32::new(seed, 3);
    let mut found = 0;
    while found < n {
        let Some(s) = lights.sample(geometry, FROM, FACING, &mut rng) else { continue };
        found += 1;
        *counts.entry(s.prim).or_insert(0) += 1;
        assert!((s.dir.length() - 1.0).abs() < 1e-5, "{s:?}");
        let pdf = match s.point {
            None => lights.pdf_sky(FACING, s.dir),
            Some(point) => {
                let to = point - FROM;
                assert!(to.normalize().dot(s.dir) > 0.99999, "{s:?}: the point is not along the direction");
                let normal = if (s.prim as usize) < geometry.triangles.len() {
                    let [a, b, c] = geometry.triangles[s.prim as usize];
                    (b - a).cross(c - a).normalize()
                } else {
                    let sphere = geometry.spheres[s.prim as usize - geometry.triangles.len()].sphere;
                    assert!(((point - sphere.center).length() - sphere.radius).abs() < 1e-4, "{s:?}: off the sphere");
                    sphere.normal(point)
                };
                lights.pdf_hit(geometry, s.prim, FROM, point, normal)
            }
        };
        assert!((s.pdf / pdf - 1.0).abs() < 1e-3, "{s:?}: density {} by the pdf function", pdf);
    }
    counts
}

#[test]
fn lights_are_picked_in_proportion_to_power_with_the_matching_density() {
    let mut scene = scene();
    let geometry = Geometry::new(&scene);
    const N: usize = 200_000;
    for sky in [false, true] {
        if sky {
            scene.background = Background::Gradient { bottom: Vec3::ONE, top: Vec3::new(0.5, 0.7, 1.0) };
        }
        let lights = LightSet::new(&geometry, &scene.materials, &scene.background);
        let counts = sample_counts(&geometry, &lights, N, 7);
        let expected = expected_lights(&geometry);
        let total: f64 = expected.iter().map(|l| l.2).sum();
        let share = if sky { 1.0 - f64::from(SKY_SHARE) } else { 1.0 };
        let sky_expected = (SKY, 1.0 - share);
        for (prim, p) in expected.iter().map(|&(prim, _, power)| (prim, share * power / total)).chain([sky_expected]) {
            let got = counts.get(&prim).copied().unwrap_or(0) as f64 / N as f64;
            let tolerance = 5.0 * (p * (1.0 - p) / N as f64).sqrt();
            assert!(
                (got - p).abs() <= tolerance,
                "sky {sky}: light {prim} picked {got:.4} of the time, expected {p:.4} ± {tolerance:.4}"
            );
        }
    }
}

#[test]
fn light_points_are_uniform_on_the_triangle() {
    let scene = scene();
    let geometry = Geometry::new(&scene);
    let lights = LightSet::new(&geometry, &scene.materials, &scene.background);
    let tri = geometry.triangles[3];
    const N: usize = 100_000;
    let (mut sum, mut quarters, mut n) = ([0.0f64; 3], [0usize; 4], 0usize);
    let mut rng = Pcg32::new(11, 5);
    for _ in 0..20 * N {
        if n == N {
            break;
        }
        let Some(s) = lights.sample(&geometry, FROM, FACING, &mut rng) else { continue };
        if s.prim != 3 {
            continue;
        }
        let b = barycentric(tri, s.point.unwrap());
        assert!(b.iter().all(|&x| x > -1e-5) && (b.iter().sum::<f64>() - 1.0).abs() < 1e-4, "{s:?} off {tri:?}");
        (0..3).for_each(|i| sum[i] += b[i]);
        // The midpoints cut the triangle into four of equal area: three corners, one centre.
        quarters[(0..3).find(|&i| b[i] > 0.5).unwrap_or(3)] += 1;
        n += 1;
    }
    assert_eq!(n, N, "light 3 picked only {n} times in {} draws", 20 * N);
    // Each barycentric coordinate of a uniform point is Beta(1, 2): mean 1/3, variance 1/18.
    let tolerance = 5.0 * (1.0 / 18.0 / N as f64).sqrt();
    for (i, s) in sum.iter().enumerate() {
        assert!((s / N as f64 - 1.0 / 3.0).abs() < tolerance, "mean barycentric {i}: {}", s / N as f64);
    }
    let tolerance = 5.0 * (0.25 * 0.75 / N as f64).sqrt();
    for (i, &q) in quarters.iter().enumerate() {
        let f = q as f64 / N as f64;
        assert!((f - 0.25).abs() < tolerance, "quarter {i} got {f:.4} of the points, expected 0.25 ± {tolerance:.4}");
    }
}

/// ∫ pdf(ω) dω over the whole sphere of directions is 1: a midpoint quadrature over cells of
/// equal solid angle (rings about the y axis, along which no light lies, so that none falls
/// into the few thin cells at a pole), each direction tested against every light on its own (a density does not
/// know about occluders) and against the sky.
#[test]
fn the_density_integrates_to_one() {
    let mut scene = scene();
    scene.background = Background::Constant(Vec3::splat(0.3));
    let geometry = Geometry::new(&scene);
    let lights = LightSet::new(&geometry, &scene.materials, &scene.background);
    let n_tris = geometry.triangles.len();
    let (rows, cols) = (1500usize, 3000usize);
    let cell = 4.0 * std::f64::consts::PI / (rows * cols) as f64;
    let mut integral = 0.0f64;
    for i in 0..rows {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / rows as f64;
        let r = (1.0 - z * z).sqrt();
        for j in 0..cols {
            let phi = std::f64::consts::TAU * (j as f64 + 0.5) / cols as f64;
            let dir = Vec3::new((r * phi.cos()) as f32, z as f32, (r * phi.sin()) as f32);
            let ray = Ray::new(FROM, dir);
            let mut pdf = f64::from(lights.pdf_sky(FACING, dir));
            for (prim, &[a, b, c]) in geometry.triangles.iter().enumerate() {
                if let Some(hit) = intersect_triangle(&ray, a, b, c) {
                    let n = (b - a).cross(c - a).normalize();
                    pdf += f64::from(lights.pdf_hit(&geometry, prim as u32, FROM, ray.at(hit.t), n));
                }
            }
            for (k, s) in geometry.spheres.iter().enumerate() {
                if let Some(t) = s.sphere.intersect(&ray) {
                    let p = ray.at(t);
                    pdf += f64::from(lights.pdf_hit(&geometry, (n_tris + k) as u32, FROM, p, s.sphere.normal(p)));
                }
            }
            integral += pdf * cell;
        }
    }
    assert!((integral - 1.0).abs() < 0.01, "the light density integrates to {integral}");
}

#[test]
fn refresh_follows_moved_lights() {
    let scene = scene();
    let mut geometry = Geometry::new(&scene);
    let mut lights = LightSet::new(&geometry, &scene.materials, &scene.background);
    // Light 1 grows to three times its size (nine times its area), light 4 shrinks to a point.
    let [a, b, c] = geometry.triangles[1];
    geometry.triangles[1] = [a, a + 3.0 * (b - a), a + 3.0 * (c - a)];
    geometry.triangles[4] = [geometry.triangles[4][0]; 3];
    lights.refresh(&geometry, &scene.materials);
    assert!(!lights.contains(4), "a light shrunk to a point is never picked");
    let powers = [(1u32, area(geometry.triangles[1]) * 3.0), (3, area(geometry.triangles[3]) * 4.0)];
    assert!((powers[0].1 - 18.0 * 3.0).abs() < 1e-9);
    let total = powers[0].1 + powers[1].1 + 4.0 * std::f64::consts::PI * 3.0;
    const N: usize = 100_000;
    let counts = sample_counts(&geometry, &lights, N, 9);
    assert_eq!(counts.get(&4), None);
    for (prim, power) in powers {
        let (p, got) = (power / total, counts[&prim] as f64 / N as f64);
        let tolerance = 5.0 * (p * (1.0 - p) / N as f64).sqrt();
        assert!((got - p).abs() <= tolerance, "light {prim} picked {got:.4} of the time, expected {p:.4}");
    }
}

#[test]
fn mis_weights_sum_to_one() {
    let mut rng = Pcg32::new(5, 5);
    for _ in 0..10_000 {
        let (a, b) = ((rng.next_f32() * 40.0 - 20.0).exp(), (rng.next_f32() * 40.0 - 20.0).exp());
        let sum = power_heuristic(a, b) + power_heuristic(b, a);
        assert!((sum - 1.0).abs() < 1e-5, "w({a}, {b}) + w({b}, {a}) = {sum}");
    }
    // A strategy that cannot make a sample gets no weight; the other all of it.
    assert_eq!(power_heuristic(0.0, 3.0), 0.0);
    assert_eq!(power_heuristic(3.0, 0.0), 1.0);
}
