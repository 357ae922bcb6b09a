//! The path tracer's expected value against closed forms, judged with a 5-sigma tolerance
//! from the samples' own variance.
//!
//! - A furnace: the camera between two concentric spheres, a diffuse outer one of albedo `a`
//!   and an emitting inner one of radius ratio `r/R`. From any point of the outer sphere the
//!   inner one fills a cone of half-angle `asin(r/R)` around the surface normal, which a
//!   cosine-weighted bounce enters with probability `p = (r/R)²`; every other bounce lands on
//!   the outer sphere again. A camera ray that sees the outer sphere therefore has the
//!   expected radiance of a truncated geometric series,
//!   `Le · p · a · Σ_{m=0}^{D−2} (a (1 − p))^m` for paths of at most `D` segments. The world
//!   outside is bright, so a path leaking out of the closed sphere shows.
//! - Direct light: a diffuse floor lit by two one-sided triangular emitters and a black sky,
//!   seen through a tiny field of view at one point `x`: the radiance is `a/π · Σ Le·Φ`, with
//!   `Φ` the projected solid angle of each emitter from `x` by Lambert's polygon formula
//!   (`Φ = ½ Σ_edges γ_i n·(R_i × R_i+1)/|R_i × R_i+1|`), with implicit lights and with next-event
//!   estimation alike.

use glam::Vec3;
use phr_bvh::sphere::Sphere;
use phr_bvh::Builder;
use phr_render::camera::CameraDesc;
use phr_render::geometry::Geometry;
use phr_render::lights::LightSet;
use phr_render::material::Material;
use phr_render::render::Renderer;
use phr_render::scene::{Background, Mesh, RenderSettings, Scene, SphereObject};

const SIZE: u32 = 32;

/// Renders `frames` samples per pixel of a `SIZE`² image; returns per channel the mean over all
/// samples and the standard error of that mean.
fn render(scene: &Scene, view: &CameraDesc, max_depth: u32, nee: bool, frames: u32) -> ([f64; 3], [f64; 3]) {
    let mut geometry = Geometry::new(scene);
    geometry.build(&Builder::default());
    let lights = nee.then(|| LightSet::new(&geometry, &scene.materials, &scene.background));
    let settings = RenderSettings { width: SIZE, height: SIZE, spp: frames, max_depth };
    let renderer = Renderer::new(scene, &geometry, view, &settings, lights.as_ref())
        .with_seed(u64::from(max_depth) + 100 * u64::from(nee));
    let (mut sum, mut sum_sq, mut n) = ([0.0f64; 3], [0.0f64; 3], 0.0);
    for frame in 0..frames {
        for p in renderer.render_frame(frame).0 {
            for c in 0..3 {
                sum[c] += f64::from(p[c]);
                sum_sq[c] += f64::from(p[c]).powi(2);
            }
            n += 1.0;
        }
    }
    let mean = sum.map(|s| s / n);
    let error = std::array::from_fn(|c| ((sum_sq[c] / n - mean[c] * mean[c]).max(0.0) / (n - 1.0)).sqrt());
    (mean, error)
}

fn assert_close(what: &str, mean: [f64; 3], error: [f64; 3], expected: [f64; 3]) {
    for c in 0..3 {
        let tolerance = 5.0 * error[c] + 1e-4 * expected[c].abs() + 1e-6;
        assert!(
            (mean[c] - expected[c]).abs() < tolerance,
            "{what}, channel {c}: rendered {:.5} ± {:.5}, expected {:.5}",
            mean[c],
            error[c],
            expected[c]
        );
    }
}

#[test]
fn furnace_between_concentric_spheres_sums_the_truncated_geometric_series() {
    let albedo = Vec3::new(0.5, 0.8, 0.9);
    let (outer, inner, emit) = (1.0f32, 0.5f32, 2.0f32);
    let mut scene = Scene { background: Background::Constant(Vec3::splat(50.0)), ..Scene::default() };
    let wall = scene.add_material("wall", Material::Lambertian { albedo });
    let lamp = scene.add_material("lamp", Material::Emissive { emit: Vec3::splat(emit), two_sided: false });
    scene.spheres.push(SphereObject { sphere: Sphere { center: Vec3::ZERO, radius: outer }, material: wall });
    scene.spheres.push(SphereObject { sphere: Sphere { center: Vec3::ZERO, radius: inner }, material: lamp });
    // Between the spheres, looking outwards: every camera ray moves away from the centre and
    // sees the outer wall.
    let view = CameraDesc {
        position: Vec3::new(0.0, 0.0, 0.75),
        look_at: Vec3::new(0.0, 0.0, 2.0),
        up: Vec3::Y,
        vfov_degrees: 30.0,
    };
    let p = f64::from(inner / outer).powi(2);
    for depth in [1u32, 2, 3, 6, 40] {
        let expected = albedo.to_array().map(|a| {
            let a = f64::from(a);
            let q = a * (1.0 - p);
            f64::from(emit) * p * a * (1.0 - q.powi(depth as i32 - 1)) / (1.0 - q)
        });
        let (mean, error) = render(&scene, &view, depth, false, 64);
        assert_close(&format!("max_depth {depth}"), mean, error, expected);
    }
}

/// `Φ`, the cosine-weighted solid angle of the polygon `v` seen from `x` on a surface with
/// unit normal `n` (Lambert; all of the polygon above the surface).
fn projected_solid_angle(x: Vec3, n: Vec3, v: &[Vec3]) -> f64 {
    let f = |p: Vec3| p.to_array().map(f64::from);
    let n = f(n);
    let unit: Vec<[f64; 3]> = v
        .iter()
        .map(|&p| {
            let d = f(p - x);
            let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            d.map(|c| c / l)
        })
        .collect();
    let mut sum = 0.0;
    for i in 0..unit.len() {
        let (a, b) = (unit[i], unit[(i + 1) % unit.len()]);
        let cross = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
        let len = (cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]).sqrt();
        let gamma = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]).clamp(-1.0, 1.0).acos();
        sum += gamma * (n[0] * cross[0] + n[1] * cross[1] + n[2] * cross[2]) / len;
    }
    0.5 * sum.abs()
}

#[test]
fn direct_light_on_a_floor_matches_lamberts_polygon_formula() {
    let albedo = 0.7f32;
    let lights = [
        // Level, facing down, off to +x: Le 4.
        ([Vec3::new(0.3, 1.0, -0.2), Vec3::new(0.8, 1.0, -0.2), Vec3::new(0.3, 1.0, 0.4)], Vec3::splat(4.0)),
        // Tilted towards the origin from -x: coloured.
        ([Vec3::new(-0.8, 0.6, 0.0), Vec3::new(-0.4, 0.9, -0.5), Vec3::new(-0.4, 0.9, 0.5)], Vec3::new(1.0, 2.0, 3.0)),
    ];
    let mut scene = Scene::default();
    let floor = scene.add_material("floor", Material::Lambertian { albedo: Vec3::splat(albedo) });
    let mut positions = vec![
        Vec3::new(-1000.0, 0.0, -1000.0),
        Vec3::new(-1000.0, 0.0, 1000.0),
        Vec3::new(1000.0, 0.0, 1000.0),
        Vec3::new(1000.0, 0.0, -1000.0),
    ];
    let mut triangles = vec![[0, 1, 2], [0, 2, 3]];
    let mut triangle_material = vec![floor, floor];
    let x = Vec3::ZERO;
    let mut expected = [0.0f64; 3];
    for (i, (corners, emit)) in lights.iter().enumerate() {
        let m = scene.add_material(format!("lamp{i}"), Material::Emissive { emit: *emit, two_sided: false });
        let normal = (corners[1] - corners[0]).cross(corners[2] - corners[0]);
        assert!((x - corners[0]).dot(normal) > 0.0, "light {i} faces the floor point");
        let phi = projected_solid_angle(x, Vec3::Y, corners);
        for c in 0..3 {
            expected[c] += f64::from(albedo) / std::f64::consts::PI * f64::from(emit[c]) * phi;
        }
        let base = positions.len() as u32;
        positions.extend(corners);
        triangles.push([base, base + 1, base + 2]);
        triangle_material.push(m);
    }
    scene.meshes.push(Mesh {
        name: "floor and lights".into(),
        positions,
        triangles,
        triangle_material,
        uvs: Vec::new(),
    });
    // Straight down at x through a 0.2° field of view: the footprint is 3.5 mm wide.
    let view = CameraDesc { position: Vec3::new(0.0, 1.0, 0.0), look_at: x, up: Vec3::Z, vfov_degrees: 0.2 };
    for (nee, depth, frames) in [(false, 2, 128), (false, 5, 128), (true, 2, 16), (true, 5, 16)] {
        let (mean, error) = render(&scene, &view, depth, nee, frames);
        let what = format!("{} lights, max_depth {depth}", if nee { "sampled" } else { "implicit" });
        assert_close(&what, mean, error, expected);
    }
    // A single segment sees only the floor, which does not emit.
    let (mean, _) = render(&scene, &view, 1, true, 2);
    assert_eq!(mean, [0.0; 3]);
}
