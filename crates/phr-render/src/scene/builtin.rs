//! The built-in default scene, so the first command works anywhere without a file: RTIOW's
//! Cornell box (0..555 units) with a large ceiling light (large, so that implicit light
//! sampling converges in a few dozen samples), a glass and a mirror sphere, and a
//! procedurally made (2, 3) torus knot of 100,000 triangles to give the BVH something to do.

use super::{Background, Mesh, RenderSettings, Scene, SphereObject};
use crate::camera::CameraDesc;
use crate::material::Material;
use glam::Vec3;
use phr_bvh::sphere::Sphere;
use std::f32::consts::TAU;

/// Segments along the knot and around its tube: 1000 × 50 quads = 100,000 triangles.
const KNOT_SEGMENTS: u32 = 1000;
const TUBE_SEGMENTS: u32 = 50;

pub fn cornell_knot() -> Scene {
    let mut s = Scene {
        background: Background::Constant(Vec3::ZERO),
        settings: RenderSettings { width: 512, height: 512, spp: 32, max_depth: 8 },
        ..Scene::default()
    };
    let red = s.add_material("red", Material::Lambertian { albedo: Vec3::new(0.65, 0.05, 0.05) });
    let white = s.add_material("white", Material::Lambertian { albedo: Vec3::splat(0.73) });
    let green = s.add_material("green", Material::Lambertian { albedo: Vec3::new(0.12, 0.45, 0.15) });
    let light = s.add_material("light", Material::Emissive { emit: Vec3::splat(6.0), two_sided: false });
    let glass = s.add_material("glass", Material::Dielectric { ior: 1.5 });
    let mirror = s.add_material(
        "mirror",
        Material::Metal { albedo: Vec3::new(0.8, 0.85, 0.88), fuzz: 0.0, fuzz_in_sphere: false },
    );
    let gold =
        s.add_material("gold", Material::Metal { albedo: Vec3::new(0.9, 0.7, 0.3), fuzz: 0.25, fuzz_in_sphere: false });

    let quads = [
        (Vec3::new(555.0, 0.0, 0.0), Vec3::new(0.0, 555.0, 0.0), Vec3::new(0.0, 0.0, 555.0), green),
        (Vec3::ZERO, Vec3::new(0.0, 555.0, 0.0), Vec3::new(0.0, 0.0, 555.0), red),
        (Vec3::new(408.0, 554.0, 408.0), Vec3::new(-260.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -260.0), light),
        (Vec3::ZERO, Vec3::new(555.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 555.0), white),
        (Vec3::splat(555.0), Vec3::new(-555.0, 0.0, 0.0), Vec3::new(0.0, 0.0, -555.0), white),
        (Vec3::new(0.0, 0.0, 555.0), Vec3::new(555.0, 0.0, 0.0), Vec3::new(0.0, 555.0, 0.0), white),
    ];
    for (q, u, v, m) in quads {
        s.meshes.push(Mesh {
            name: s.material_names[m as usize].clone(),
            positions: vec![q, q + u, q + v, q + u + v],
            triangles: vec![[0, 1, 2], [1, 3, 2]],
            triangle_material: vec![m; 2],
            uvs: Vec::new(),
        });
    }
    let mut knot = torus_knot(2, 3, 110.0, 28.0, KNOT_SEGMENTS, TUBE_SEGMENTS);
    knot.positions.iter_mut().for_each(|p| *p += Vec3::new(278.0, 330.0, 330.0));
    knot.triangle_material = vec![gold; knot.triangles.len()];
    s.meshes.push(knot);
    s.spheres
        .push(SphereObject { sphere: Sphere { center: Vec3::new(150.0, 80.0, 140.0), radius: 80.0 }, material: glass });
    s.spheres.push(SphereObject {
        sphere: Sphere { center: Vec3::new(410.0, 90.0, 160.0), radius: 90.0 },
        material: mirror,
    });

    let view =
        |position: Vec3, look_at: Vec3, vfov_degrees: f32| CameraDesc { position, look_at, up: Vec3::Y, vfov_degrees };
    s.views = vec![
        ("front".into(), view(Vec3::new(278.0, 278.0, -800.0), Vec3::new(278.0, 278.0, 0.0), 40.0)),
        ("close".into(), view(Vec3::new(278.0, 300.0, -250.0), Vec3::new(278.0, 290.0, 300.0), 55.0)),
        ("corner".into(), view(Vec3::new(60.0, 480.0, 40.0), Vec3::new(330.0, 200.0, 330.0), 70.0)),
    ];
    s
}

/// A (p, q) torus knot tube: the curve winds p times around the z axis and q times through
/// the torus's hole; a circle of `radius_tube` is swept along it with a rotation-minimising
/// frame. Triangles are wound counter-clockwise seen from outside the tube.
pub fn torus_knot(p: u32, q: u32, radius: f32, radius_tube: f32, segments: u32, sides: u32) -> Mesh {
    let curve = |t: f32| {
        let (p, q) = (p as f32, q as f32);
        let r = radius * (0.6 + 0.4 * (q * t).cos());
        Vec3::new(r * (p * t).cos(), r * (p * t).sin(), -radius * 0.4 * (q * t).sin())
    };
    let mut positions = Vec::with_capacity((segments * sides) as usize);
    for i in 0..segments {
        let t = i as f32 / segments as f32 * TAU;
        let c = curve(t);
        let tangent = (curve(t + 1e-3) - curve(t - 1e-3)).normalize();
        let normal = tangent.any_orthonormal_vector();
        let normal = (c - tangent * c.dot(tangent)).try_normalize().unwrap_or(normal);
        let binormal = tangent.cross(normal);
        for j in 0..sides {
            let a = j as f32 / sides as f32 * TAU;
            positions.push(c + radius_tube * (a.cos() * normal + a.sin() * binormal));
        }
    }
    let mut triangles = Vec::with_capacity((2 * segments * sides) as usize);
    for i in 0..segments {
        let i1 = (i + 1) % segments;
        for j in 0..sides {
            let j1 = (j + 1) % sides;
            let (a, b, c, d) = (i * sides + j, i1 * sides + j, i1 * sides + j1, i * sides + j1);
            triangles.push([a, c, b]);
            triangles.push([a, d, c]);
        }
    }
    let n = triangles.len();
    Mesh { name: "torus knot".into(), positions, triangles, triangle_material: vec![0; n], uvs: Vec::new() }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_scene_has_about_100k_triangles_and_views() {
        let s = cornell_knot();
        assert_eq!(s.triangle_count(), 100_000 + 12);
        assert_eq!(s.spheres.len(), 2);
        assert_eq!(s.view_names(), vec!["front", "close", "corner"]);
        let b = s.bounds();
        assert!(b.min.cmpge(Vec3::splat(-1e-3)).all() && b.max.cmple(Vec3::splat(555.001)).all(), "{b:?}");
    }

    #[test]
    fn knot_faces_outwards() {
        // The divergence theorem: positive signed volume means outward-facing triangles.
        let k = torus_knot(2, 3, 110.0, 28.0, 200, 16);
        let volume: f32 = k
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| k.positions[i as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum();
        assert!(volume > 0.0, "signed volume {volume}");
    }
}
