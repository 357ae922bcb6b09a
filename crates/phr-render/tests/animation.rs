//! Dynamic scenes: the scene file's `animate` motions and glTF node animations pose the
//! geometry as documented; the shipped example scenes load with their animations.
//!
//! Keyframe interpolation away from the cases where every scheme agrees (zero tangents, the
//! midpoint of a segment) is checked against the glTF 2.0 specification (Appendix C,
//! "Interpolation"), recomputed here in f64: the cubic Hermite spline with the out-tangent of
//! key k, the in-tangent of key k+1 and both scaled by the segment's duration, and slerp
//! (constant angular speed along the shortest arc) for LINEAR rotations; both on `Track`
//! directly and through a small glTF file written by the test.

use glam::{Quat, Vec3};
use phr_render::animation::Animator;
use phr_render::geometry::Geometry;
use phr_render::load::load_mesh;
use phr_render::motion::{Animation, AnimationTarget, Interpolation, Track};
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
    let shipped =
        [("bunny_in_sponza.json", 69_451), ("dragon_in_cornell.json", 871_414), ("dragon_wave.json", 871_414)];
    for (name, moving) in shipped {
        let path = dynamic(name);
        let scene = load_scene(&path).unwrap_or_else(|e| panic!("{e}"));
        let animator = Animator::new(&scene);
        assert_eq!(animator.moving_triangles(), moving, "{name}");
        assert!(scene.views.len() >= 2, "{name} has named views");
    }
}

/// The glTF spec's cubic spline on one segment, per component:
/// `p(s) = (2s³ − 3s² + 1) v_k + (s³ − 2s² + s) Δt b_k + (−2s³ + 3s²) v_k+1 + (s³ − s²) Δt a_k+1`
/// with `b_k` the out-tangent of key k and `a_k+1` the in-tangent of key k+1.
fn hermite_spec<const N: usize>(v0: [f64; N], b0: [f64; N], v1: [f64; N], a1: [f64; N], s: f64, dt: f64) -> [f64; N] {
    let (s2, s3) = (s * s, s * s * s);
    std::array::from_fn(|i| {
        (2.0 * s3 - 3.0 * s2 + 1.0) * v0[i]
            + (s3 - 2.0 * s2 + s) * dt * b0[i]
            + (-2.0 * s3 + 3.0 * s2) * v1[i]
            + (s3 - s2) * dt * a1[i]
    })
}

fn f64s<const N: usize>(v: [f32; N]) -> [f64; N] {
    v.map(f64::from)
}

fn distance<const N: usize>(a: [f64; N], b: [f64; N]) -> f64 {
    a.iter().zip(&b).map(|(x, y)| (x - y).powi(2)).sum::<f64>().sqrt()
}

/// Keys at t = 1, 3.5 and 4 (segments of 2.5 s and 0.5 s, so a missing Δt shows), each as
/// (in-tangent, value, out-tangent), all different.
const KEY_TIMES: [f32; 3] = [1.0, 3.5, 4.0];
const KEYS: [[[f32; 3]; 3]; 3] = [
    [[9.0, 9.0, 9.0], [0.0, 0.0, 0.0], [1.0, -2.0, 0.5]],
    [[-3.0, 1.0, 2.0], [2.0, 1.0, -1.0], [0.5, 4.0, -2.0]],
    [[1.0, 1.0, 1.0], [-1.0, 3.0, 0.0], [7.0, 7.0, 7.0]],
];

#[test]
fn cubic_spline_uses_out_then_in_tangents_scaled_by_the_segment_duration() {
    let track = Track {
        times: KEY_TIMES.to_vec(),
        values: KEYS.iter().flatten().map(|&v| Vec3::from(v)).collect(),
        interpolation: Interpolation::CubicSpline,
    };
    for k in 0..2 {
        let (t0, t1) = (f64::from(KEY_TIMES[k]), f64::from(KEY_TIMES[k + 1]));
        let dt = t1 - t0;
        for s in [0.25, 0.7] {
            let t = t0 + s * dt;
            let expected =
                hermite_spec(f64s(KEYS[k][1]), f64s(KEYS[k][2]), f64s(KEYS[k + 1][1]), f64s(KEYS[k + 1][0]), s, dt);
            let got = f64s(track.sample(t as f32).to_array());
            assert!(distance(got, expected) < 1e-4, "segment {k}, s = {s} (t = {t}): got {got:?}, spec {expected:?}");
        }
    }
    // At the keys and beyond the ends: the key's value, never a tangent.
    for (t, key) in [(0.0, 0), (1.0, 0), (3.5, 1), (4.0, 2), (9.0, 2)] {
        assert_eq!(track.sample(t).to_array(), KEYS[key][1], "t = {t}");
    }
}

#[test]
fn cubic_spline_rotation_is_the_normalised_spline_of_the_components() {
    // glTF: cubic-spline rotations interpolate the four components, then normalise.
    let q = |axis: Vec3, degrees: f32| Quat::from_axis_angle(axis.normalize(), degrees.to_radians());
    let keys: [[Quat; 3]; 2] = [
        [Quat::from_xyzw(0.0, 0.0, 0.0, 0.0), q(Vec3::Z, 10.0), Quat::from_xyzw(0.3, -0.2, 0.1, 0.05)],
        [Quat::from_xyzw(-0.1, 0.4, 0.2, 0.0), q(Vec3::new(1.0, 1.0, 0.0), 100.0), Quat::from_xyzw(0.0, 0.0, 0.0, 0.0)],
    ];
    let track = Track {
        times: vec![0.5, 2.5],
        values: keys.iter().flatten().copied().collect(),
        interpolation: Interpolation::CubicSpline,
    };
    let c = |q: Quat| f64s(q.to_array());
    for s in [0.25, 0.7] {
        let raw = hermite_spec(c(keys[0][1]), c(keys[0][2]), c(keys[1][1]), c(keys[1][0]), s, 2.0);
        let norm = raw.iter().map(|x| x * x).sum::<f64>().sqrt();
        let expected = raw.map(|x| x / norm);
        let got = c(track.sample((0.5 + 2.0 * s) as f32));
        assert!(distance(got, expected) < 1e-5, "s = {s}: got {got:?}, spec {expected:?}");
    }
}

/// The rotation angle of a unit quaternion, in degrees (0..=180).
fn angle_degrees(q: [f64; 4]) -> f64 {
    let v = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
    (2.0 * v.atan2(q[3].abs())).to_degrees()
}

#[test]
fn linear_rotation_is_slerp_at_constant_angular_speed() {
    // Two orientations 120° apart about one axis: slerp turns 30° by s = 0.25 and 84° by
    // s = 0.7; normalised lerp would give 27.8° and 86.0°.
    let axis = Vec3::new(1.0, 2.0, 3.0).normalize();
    let end = Quat::from_axis_angle(axis, 120f32.to_radians());
    // The same end orientation written as −q: slerp takes the shorter arc all the same.
    for end in [end, -end] {
        let track =
            Track { times: vec![1.0, 3.0], values: vec![Quat::IDENTITY, end], interpolation: Interpolation::Linear };
        for s in [0.25, 0.7] {
            let q = f64s(track.sample(1.0 + 2.0 * s as f32).to_array());
            let angle = angle_degrees(q);
            assert!((angle - 120.0 * s).abs() < 0.01, "s = {s}: turned {angle:.3}° of 120°, expected {}°", 120.0 * s);
            // About the same axis (sign-independent).
            let v = Vec3::new(q[0] as f32, q[1] as f32, q[2] as f32).normalize();
            assert!(v.dot(axis).abs() > 1.0 - 1e-5, "s = {s}: axis {v}");
        }
    }
}

#[test]
fn gltf_cubic_translation_and_slerped_rotation_off_the_midpoint() {
    // One node holding a triangle with corners at its origin and at +x, animated from t = 0.5
    // to t = 3 (Δt = 2.5): translation as a cubic spline with non-zero tangents, rotation
    // LINEAR from identity to 120° about z. The corner at the origin shows the translation,
    // the one at +x the rotation.
    let (t0, t1) = (0.5f32, 3.0f32);
    let translation: [[f32; 3]; 6] =
        [[5.0, 5.0, 5.0], [0.0, 1.0, 0.0], [2.0, 0.0, -1.0], [0.0, 3.0, 1.0], [1.0, 2.0, 0.0], [-5.0, -5.0, -5.0]];
    let half = 60f32.to_radians();
    let rotation: [[f32; 4]; 2] = [[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, half.sin(), half.cos()]];
    let mut buffer = Vec::new();
    let floats = [0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, t0, t1]
        .into_iter()
        .chain(translation.into_iter().flatten())
        .chain(rotation.into_iter().flatten());
    floats.for_each(|f| buffer.extend_from_slice(&f.to_le_bytes()));
    assert_eq!(buffer.len(), 148);
    let uri = format!("data:application/octet-stream;base64,{}", base64::encode(&buffer));
    let gltf = format!(
        r#"{{
  "asset": {{"version": "2.0"}},
  "scene": 0,
  "scenes": [{{"nodes": [0]}}],
  "nodes": [{{"mesh": 0}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
  "animations": [{{
    "channels": [{{"sampler": 0, "target": {{"node": 0, "path": "translation"}}}},
                 {{"sampler": 1, "target": {{"node": 0, "path": "rotation"}}}}],
    "samplers": [{{"input": 1, "output": 2, "interpolation": "CUBICSPLINE"}},
                 {{"input": 1, "output": 3, "interpolation": "LINEAR"}}]
  }}],
  "buffers": [{{"byteLength": 148, "uri": "{uri}"}}],
  "bufferViews": [
    {{"buffer": 0, "byteOffset": 0, "byteLength": 36}},
    {{"buffer": 0, "byteOffset": 36, "byteLength": 8}},
    {{"buffer": 0, "byteOffset": 44, "byteLength": 72}},
    {{"buffer": 0, "byteOffset": 116, "byteLength": 32}}
  ],
  "accessors": [
    {{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
    {{"bufferView": 1, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [{t0}], "max": [{t1}]}},
    {{"bufferView": 2, "componentType": 5126, "count": 6, "type": "VEC3"}},
    {{"bufferView": 3, "componentType": 5126, "count": 2, "type": "VEC4"}}
  ]
}}"#
    );
    let dir = std::env::temp_dir().join(format!("phr-animation-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("spline.gltf");
    std::fs::write(&path, gltf).unwrap();
    let mesh = load_mesh(&path);
    std::fs::remove_dir_all(&dir).unwrap();
    let mut mesh = mesh.unwrap_or_else(|e| panic!("{e}"));
    let animation = mesh.animation.take().expect("the file is animated");
    let dt = f64::from(t1 - t0);
    for s in [0.25, 0.7] {
        let t = f64::from(t0) + s * dt;
        animation.pose(&mut mesh.positions, t as f32);
        let [origin, x_corner] = [0, 1].map(|i| f64s(mesh.positions[i].to_array()));
        let expected =
            hermite_spec(f64s(translation[1]), f64s(translation[2]), f64s(translation[4]), f64s(translation[3]), s, dt);
        assert!(distance(origin, expected) < 1e-4, "s = {s}: translated to {origin:?}, spec {expected:?}");
        let arm = [0, 1, 2].map(|i| x_corner[i] - origin[i]);
        let angle = arm[1].atan2(arm[0]).to_degrees();
        assert!(
            (angle - 120.0 * s).abs() < 0.01 && arm[2].abs() < 1e-5,
            "s = {s}: turned {angle:.3}°, slerp {}°",
            120.0 * s
        );
    }
}
