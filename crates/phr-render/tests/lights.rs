//! The light set of next-event estimation (`lights.rs`) against what its documentation
//! promises, with every expected value recomputed here in f64: lights are the emissive
//! triangles with some emission (not other triangles, not spheres); one is picked with
//! probability power / total power, power = area × brightest emission channel (degenerate
//! ones never); the point is uniform on it (barycentric moments and sub-triangle frequencies
//! of the uniform distribution); the unit normal is `(v1 − v0) × (v2 − v0)` normalised; the
//! density is the selection probability over the area; `refresh` follows moved vertices.
//! Frequencies are judged with a 5-sigma binomial tolerance.

use glam::Vec3;
use phr_bvh::sphere::Sphere;
use phr_render::geometry::Geometry;
use phr_render::lights::LightSet;
use phr_render::material::Material;
use phr_render::sampler::Pcg32;
use phr_render::scene::{Mesh, Scene, SphereObject};

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
/// diffuse, 5 emits nothing, 6 is a degenerate emitter; sphere 0 (primitive 7) is emissive.
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
    });
    let sphere = Sphere { center: v(0.0, 0.0, 20.0), radius: 1.0 };
    scene.spheres.push(SphereObject { sphere, material: a });
    scene
}

/// The lights of [`scene`]: (primitive, material, power) with power = area × max channel.
fn expected_lights(geometry: &Geometry) -> Vec<(u32, u32, f64)> {
    [(1, 1, 3.0), (3, 2, 4.0), (4, 3, 0.5)]
        .map(|(p, m, emit)| (p, m, area(geometry.triangles[p as usize]) * emit))
        .into()
}

#[test]
fn only_emissive_triangles_with_emission_are_lights() {
    let scene = scene();
    let geometry = Geometry::new(&scene);
    let lights = LightSet::new(&geometry, &scene.materials);
    assert!(!lights.is_empty());
    for (prim, is_light) in
        [(0, false), (1, true), (2, false), (3, true), (4, true), (5, false), (7, false), (99, false)]
    {
        assert_eq!(lights.contains(prim), is_light, "primitive {prim}");
    }
    // Nothing emissive (or only zero-area emitters): nothing to sample.
    let mut dark = scene.clone();
    for m in 1..=3 {
        dark.materials[m] = Material::Lambertian { albedo: Vec3::ONE };
    }
    let glow = dark.add_material("glow", Material::Emissive { emit: Vec3::ONE, two_sided: false });
    dark.meshes[0].triangle_material[6] = glow;
    let geometry = Geometry::new(&dark);
    let lights = LightSet::new(&geometry, &dark.materials);
    assert!(lights.is_empty(), "only a degenerate emitter left");
    assert!(lights.sample(&geometry, &mut Pcg32::new(1, 1)).is_none());
}

#[test]
fn lights_are_picked_in_proportion_to_power_with_the_matching_density() {
    let scene = scene();
    let geometry = Geometry::new(&scene);
    let lights = LightSet::new(&geometry, &scene.materials);
    let expected = expected_lights(&geometry);
    let total: f64 = expected.iter().map(|l| l.2).sum();
    const N: usize = 200_000;
    let mut counts = [0usize; 3];
    let mut rng = Pcg32::new(7, 3);
    for _ in 0..N {
        let s = lights.sample(&geometry, &mut rng).expect("a light");
        let k = expected
            .iter()
            .position(|l| l.1 == s.material)
            .unwrap_or_else(|| panic!("sampled material {}", s.material));
        counts[k] += 1;
        let (prim, _, power) = expected[k];
        let tri = geometry.triangles[prim as usize];
        // On the light: barycentrics sum to 1 (in its plane) and are all non-negative.
        let b = barycentric(tri, s.point);
        assert!(b.iter().all(|&x| x > -1e-5) && (b.iter().sum::<f64>() - 1.0).abs() < 1e-4, "{s:?} off {tri:?}");
        let normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
        assert!((s.normal - normal).length() < 1e-6, "normal {} of light {prim}, expected {normal}", s.normal);
        let pdf = power / total / area(tri);
        assert!(
            (f64::from(s.pdf_area) / pdf - 1.0).abs() < 1e-5,
            "light {prim}: pdf_area {}, expected {pdf}",
            s.pdf_area
        );
    }
    for (k, &(prim, _, power)) in expected.iter().enumerate() {
        let (p, got) = (power / total, counts[k] as f64 / N as f64);
        let tolerance = 5.0 * (p * (1.0 - p) / N as f64).sqrt();
        assert!(
            (got - p).abs() < tolerance,
            "light {prim} picked {got:.4} of the time, power share {p:.4} ± {tolerance:.4}"
        );
    }
}

#[test]
fn light_points_are_uniform_on_the_triangle() {
    let scene = scene();
    let geometry = Geometry::new(&scene);
    let lights = LightSet::new(&geometry, &scene.materials);
    let tri = geometry.triangles[3];
    const N: usize = 100_000;
    let (mut sum, mut quarters, mut n) = ([0.0f64; 3], [0usize; 4], 0usize);
    let mut rng = Pcg32::new(11, 5);
    for _ in 0..10 * N {
        if n == N {
            break;
        }
        let s = lights.sample(&geometry, &mut rng).unwrap();
        if s.material != 2 {
            continue;
        }
        let b = barycentric(tri, s.point);
        (0..3).for_each(|i| sum[i] += b[i]);
        // The midpoints cut the triangle into four of equal area: three corners, one centre.
        quarters[(0..3).find(|&i| b[i] > 0.5).unwrap_or(3)] += 1;
        n += 1;
    }
    assert_eq!(n, N, "light 3 (selection probability 0.41) picked only {n} times in {} draws", 10 * N);
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

#[test]
fn refresh_follows_moved_lights() {
    let scene = scene();
    let mut geometry = Geometry::new(&scene);
    let mut lights = LightSet::new(&geometry, &scene.materials);
    // Light 1 grows to three times its size (nine times its area), light 4 shrinks to a point.
    let [a, b, c] = geometry.triangles[1];
    geometry.triangles[1] = [a, a + 3.0 * (b - a), a + 3.0 * (c - a)];
    geometry.triangles[4] = [geometry.triangles[4][0]; 3];
    lights.refresh(&geometry, &scene.materials);
    let powers = [(1u32, area(geometry.triangles[1]) * 3.0), (2, area(geometry.triangles[3]) * 4.0)];
    assert!((powers[0].1 - 18.0 * 3.0).abs() < 1e-9);
    let total = powers[0].1 + powers[1].1;
    let mut rng = Pcg32::new(3, 9);
    let mut seen = [false; 2];
    for _ in 0..1000 {
        let s = lights.sample(&geometry, &mut rng).unwrap();
        let k =
            powers.iter().position(|p| p.0 == s.material).unwrap_or_else(|| panic!("sampled material {}", s.material));
        seen[k] = true;
        let prim = [1, 3][k];
        let pdf = powers[k].1 / total / area(geometry.triangles[prim]);
        assert!(
            (f64::from(s.pdf_area) / pdf - 1.0).abs() < 1e-5,
            "light {prim}: pdf_area {}, expected {pdf}",
            s.pdf_area
        );
        let b = barycentric(geometry.triangles[prim], s.point);
        assert!(b.iter().all(|&x| x > -1e-5) && (b.iter().sum::<f64>() - 1.0).abs() < 1e-4, "point off light {prim}");
    }
    assert_eq!(seen, [true, true]);
}
