//! Dynamic scenes: the scene file's `animate` motions and glTF node animations pose the
//! geometry as documented; the shipped example scenes load with their animations.

use glam::Vec3;
use phr_render::animation::{Animation, AnimationTarget, Animator};
use phr_render::geometry::Geometry;
use phr_render::scene::json::parse_scene;
use phr_render::scene::load_scene;
use std::path::{Path, PathBuf};

fn dynamic(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/dynamic").join(name)
}

/// Centroid of the triangles with material `name`.
fn centroid(scene: &phr_render::Scene, geometry: &Geometry, name: &str) -> Vec3 {
    let m = scene.material_index(name).expect("material");
    let (mut sum, mut n) = (Vec3::ZERO, 0.0);
    for (t, &tm) in geometry.triangles.iter().zip(&geometry.triangle_material) {
        if tm == m {
            sum += t[0] + t[1] + t[2];
            n += 3.0;
        }
    }
    sum / n
}

#[test]
fn gltf_node_animation_plays_through_the_hierarchy() {
    let scene = load_scene(&dynamic("carousel.json")).unwrap();
    let targets: Vec<AnimationTarget> = scene.animations.iter().map(|a| a.target).collect();
    assert_eq!(targets, [AnimationTarget::Mesh(0), AnimationTarget::Mesh(1), AnimationTarget::Sphere(0)]);
    assert!(matches!(scene.animations[0].animation, Animation::Nodes(_)));
    let mut geometry = Geometry::new(&scene);
    let mut animator = Animator::new(&scene);
    assert!(animator.is_animated());
    let triangles = geometry.triangles.len();
    // The red rider sits at (1.5, 0.8, 0) on the platform. At t = 2 s the platform has turned
    // -90° about y (linear slerp between keys) and the rider's cubic-spline bob is at its
    // second key, +0.5.
    animator.pose(&mut geometry, 2.0);
    let red = centroid(&scene, &geometry, "red");
    assert!((red - Vec3::new(0.0, 1.3, 1.5)).length() < 0.02, "red rider at {red}");
    // Half-way between keys: 45° and the spline's midpoint (+0.25 between 0 and 0.5).
    animator.pose(&mut geometry, 1.0);
    let red = centroid(&scene, &geometry, "red");
    let expected = Vec3::new(1.5 * 0.5f32.sqrt(), 1.05, 1.5 * 0.5f32.sqrt());
    assert!((red - expected).length() < 0.02, "red rider at {red}, expected {expected}");
    // The loop: t = 9 is t = 1.
    animator.pose(&mut geometry, 9.0);
    assert!((centroid(&scene, &geometry, "red") - expected).length() < 0.02);
    assert_eq!(geometry.triangles.len(), triangles, "posing keeps the primitives");
    assert_eq!(geometry.boxes.len(), geometry.prim_count());
    // The swinging glass ball: amplitude 1.2 along x, period 3 s.
    animator.pose(&mut geometry, 0.75);
    assert!((geometry.spheres[0].sphere.center - Vec3::new(1.2, 2.9, 0.0)).length() < 1e-4);
}

#[test]
fn scene_file_motions_move_their_object_only() {
    let text = r#"{
        "materials": {"m": {"type": "lambertian", "albedo": 0.5}},
        "objects": [
            {"type": "triangle", "v0": [0,0,0], "v1": [1,0,0], "v2": [0,1,0], "material": "m"},
            {"type": "triangle", "v0": [0,0,0], "v1": [1,0,0], "v2": [0,1,0], "material": "m",
             "animate": [{"type": "rotate", "axis": [0,0,1], "pivot": [0,0,0], "degrees_per_second": 90},
                         {"type": "oscillate", "amplitude": [0,0,2], "period": 4}]}
        ]
    }"#;
    let scene = parse_scene(text, Path::new("inline.json")).unwrap();
    let mut geometry = Geometry::new(&scene);
    let mut animator = Animator::new(&scene);
    animator.pose(&mut geometry, 1.0);
    assert_eq!(geometry.triangles[0], [Vec3::ZERO, Vec3::X, Vec3::Y], "the static object stays");
    let moved = geometry.triangles[1];
    assert!((moved[1] - Vec3::new(0.0, 1.0, 2.0)).length() < 1e-5, "{moved:?}");
    assert!((moved[2] - Vec3::new(-1.0, 0.0, 2.0)).length() < 1e-5, "{moved:?}");
    assert!(geometry.boxes[1].max.z >= 2.0 - 1e-5, "boxes follow");
}

#[test]
fn bad_motions_are_errors_naming_the_object() {
    let scene = |animate: &str| {
        let text = format!(
            r#"{{"materials": {{"m": {{"type": "lambertian", "albedo": 0.5}}}},
                "objects": [{{"type": "sphere", "center": [0,0,0], "radius": 1, "material": "m", "animate": {animate}}}]}}"#
        );
        parse_scene(&text, Path::new("bad.json")).map(|_| ()).unwrap_err().to_string()
    };
    let e = scene(r#"{"type": "oscillate", "amplitude": [0,1,0], "period": 0}"#);
    assert!(e.contains("bad.json") && e.contains("object 0") && e.contains("period"), "{e}");
    let e = scene(r#"{"type": "rotate", "axis": [0,0,0], "degrees_per_second": 5}"#);
    assert!(e.contains("axis"), "{e}");
    let e = scene(r#"{"type": "spin"}"#);
    assert!(e.contains("bad.json"), "{e}");
}

#[test]
fn shipped_dynamic_scenes_load_animated() {
    for (name, moving) in [("bunny_in_sponza.json", 69_451), ("dragon_in_cornell.json", 871_414)] {
        let path = dynamic(name);
        let scene = load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
        let animator = Animator::new(&scene);
        assert_eq!(animator.moving_triangles(), moving, "{name}");
        assert!(scene.views.len() >= 2, "{name} has named views");
    }
}
