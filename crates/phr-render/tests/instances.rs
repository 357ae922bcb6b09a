//! Meshes placed many times (a scene file's `instances`) against the same scene with every
//! copy's triangles written out (flattened): hits, surface points, materials, texture
//! coordinates, shadow queries and images must agree, through rotations, non-uniform scales,
//! mirrors and general matrices. And the scene file's rules for `instances`.

use glam::Vec3;
use phr_bvh::{Builder, Ray, TraversalStats};
use phr_render::geometry::{Geometry, COPY};
use phr_render::render::Renderer;
use phr_render::sampler::Pcg32;
use phr_render::scene::json::parse_scene;
use phr_render::scene::{RenderSettings, Scene};
use std::path::{Path, PathBuf};

/// A floor; a glTF grid copied four times (standing, turned, squashed, mirrored); a small
/// closed solid copied six times (one a general matrix); a textured OBJ copied twice.
const SCENE: &str = r#"{
  "background": {"type": "gradient", "bottom": [1, 1, 1], "top": [0.5, 0.7, 1.0]},
  "camera": { "position": [0, 3, 9], "look_at": [0, 0.8, 0], "vfov": 55 },
  "materials": {
    "white": { "type": "lambertian", "albedo": 0.7 },
    "red": { "type": "lambertian", "albedo": [0.8, 0.2, 0.1] },
    "steel": { "type": "metal", "albedo": 0.8, "fuzz": 0.2 }
  },
  "objects": [
    { "type": "quad", "Q": [-6, 0, -6], "u": [12, 0, 0], "v": [0, 0, 12], "material": "white" },
    { "type": "mesh", "file": "../../../scenes/dynamic/floor.gltf", "material": "steel",
      "transform": { "scale": 0.25 },
      "instances": [
        { "rotate": [1, 0, 0, 90], "translate": [-3, 1, -3] },
        { "rotate": [[1, 0, 0, 70], [0, 1, 0, 35]], "translate": [2, 1.2, -2.5] },
        { "scale": [1.5, 1, 0.4], "translate": [0, 0.05, 2] },
        { "scale": [-1, 1, 1], "rotate": [0, 0, 1, 80], "translate": [4, 1, 0] }
      ] },
    { "type": "triangles", "material": "red",
      "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.6, 0.7, 0.6]],
      "faces": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 4, 3], [1, 2, 4], [2, 3, 4]],
      "instances": [
        { "translate": [-1, 0, 0] },
        { "scale": 0.5, "translate": [1, 0, 1] },
        { "scale": [1, 2, 0.5], "rotate": [0.3, 1, 0.2, 40], "translate": [0, 0.1, -1] },
        { "scale": [1, -1, 1], "translate": [-2.5, 1.5, 1.5] },
        { "matrix": [[0.5, 0.2, 0, 1.5], [0, 0.7, 0.1, 0.2], [0.1, 0, 0.9, -2], [0, 0, 0, 1]] },
        { "rotate": [0, 1, 0, 120], "translate": [2.5, 0, 2.5] }
      ] },
    { "type": "obj_mtl", "file": "references/textured.obj",
      "instances": [ { "translate": [-4, 0.3, 3] }, { "rotate": [0, 1, 0, -30], "scale": 0.8, "translate": [3, 0.2, 3] } ] }
  ]
}"#;

fn scene_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/instances.json")
}

fn instanced() -> Scene {
    parse_scene(SCENE, &scene_path()).unwrap()
}

/// `scene` with every copy written out as a mesh of its own, in the world.
fn flattened(mut scene: Scene) -> Scene {
    scene.flatten_instanced();
    assert!(scene.instanced.is_empty());
    scene
}

fn built(scene: &Scene, builder: Builder) -> Geometry {
    let mut g = Geometry::new(scene);
    g.build(&builder);
    g
}

/// Rays from all over the scene's box towards all over it.
fn rays(n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Pcg32::for_pixel(seed, 0, 0);
    let mut point = |scale: f32| {
        Vec3::new(rng.next_f32() - 0.5, rng.next_f32() * 0.5, rng.next_f32() - 0.5) * Vec3::new(12.0, 6.0, 12.0) * scale
    };
    (0..n)
        .map(|_| {
            let o = point(1.1);
            let target = point(0.7);
            Ray::new(o, (target - o).normalize_or(Vec3::Y))
        })
        .collect()
}

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-4 * (1.0 + a.abs().max(b.abs()))
}

#[test]
fn the_scene_file_keeps_one_mesh_per_instanced_object() {
    let scene = instanced();
    assert_eq!(scene.meshes.len(), 1, "only the floor is placed once");
    let copies: Vec<usize> = scene.instanced.iter().map(|i| i.copies.len()).collect();
    assert_eq!(copies, [4, 6, 2]);
    assert_eq!(scene.instanced[1].mesh.triangles.len(), 6);
    assert!(!scene.instanced[2].mesh.uvs.is_empty(), "the OBJ keeps its texture coordinates");
    let (placed, stored) = scene.instanced_triangle_count();
    let n: Vec<u64> = scene.instanced.iter().map(|i| i.mesh.triangles.len() as u64).collect();
    assert_eq!(placed, 4 * n[0] + 6 * n[1] + 2 * n[2]);
    assert_eq!(stored as u64, n.iter().sum::<u64>());
}

/// Asserts that `actual` hits what `expected` hits on `rays`: distance, position, normal,
/// side, material and texture coordinates (rays grazing an edge may fall on either side of it
/// in two layouts: at most one in 200). Returns how many rays hit a copy in `actual`.
fn assert_same_hits(expected: &Geometry, actual: &Geometry, rays: &[Ray], what: &str) -> usize {
    let (mut differ, mut on_copies) = (0, 0);
    for (i, ray) in rays.iter().enumerate() {
        match (expected.intersect(ray), actual.intersect(ray)) {
            (None, None) => {}
            (Some(w), Some(h)) if close(w.t, h.t) => {
                on_copies += usize::from(h.part & COPY != 0);
                let (sw, sh) = (expected.surface_point(ray, &w), actual.surface_point(ray, &h));
                assert!((sw.position - sh.position).length() < 1e-3, "{what}, ray {i}: position");
                assert!(
                    sw.normal.dot(sh.normal) > 0.9999,
                    "{what}, ray {i}: normal {} vs {} (part {:x}, prim {}, t {})",
                    sw.normal,
                    sh.normal,
                    h.part,
                    h.prim,
                    h.t
                );
                assert_eq!(sw.front, sh.front, "{what}, ray {i}: side");
                assert_eq!(sw.material, sh.material, "{what}, ray {i}: material");
                let (uw, uh) = (expected.uv(&w), actual.uv(&h));
                assert!((uw - uh).length() < 1e-4, "{what}, ray {i}: uv {uw} vs {uh}");
            }
            _ => differ += 1,
        }
    }
    assert!(differ <= rays.len() / 200, "{what}: {differ} of {} rays differ", rays.len());
    on_copies
}

#[test]
fn copies_hit_what_their_flattened_triangles_hit() {
    for builder in [Builder::PHR_FAST, "sbvh".parse().unwrap()] {
        let (copies, flat) = (built(&instanced(), builder), built(&flattened(instanced()), builder));
        assert_eq!(copies.copy_count(), 12);
        assert_eq!(flat.copy_count(), 0);
        let all = rays(4000, 7);
        let on_copies = assert_same_hits(&flat, &copies, &all, &builder.to_string());
        assert!(on_copies > all.len() / 10, "{builder}: only {on_copies} rays hit a copy");
        // The heatmap's counting traversal and the shadow queries agree with closest hits.
        for ray in &all[..500] {
            let counted = copies.intersect_counted(ray, &mut TraversalStats::default()).map(|h| (h.t, h.prim, h.part));
            assert_eq!(counted, copies.intersect(ray).map(|h| (h.t, h.prim, h.part)));
            assert_eq!(copies.occluded(ray), copies.intersect(ray).is_some());
        }
    }
}

#[test]
fn images_of_copies_equal_those_of_their_flattened_triangles() {
    let (scene, flat_scene) = (instanced(), flattened(instanced()));
    let (copies, flat) = (built(&scene, Builder::PHR_FAST), built(&flat_scene, Builder::PHR_FAST));
    let view = scene.view(None).unwrap();
    let settings = RenderSettings { width: 48, height: 32, spp: 1, max_depth: 4 };
    let render = |scene: &Scene, g: &Geometry| {
        let renderer = Renderer::new(scene, g, &view, &settings, None).with_seed(3);
        (0..4).map(|f| renderer.render_frame(f).0).collect::<Vec<_>>().concat()
    };
    let (a, b) = (render(&scene, &copies), render(&flat_scene, &flat));
    // Same random numbers for the same paths: pixels agree unless a ray grazed an edge.
    let same = a.iter().zip(&b).filter(|(x, y)| (**x - **y).abs().max_element() < 1e-3).count();
    assert!(same * 100 >= a.len() * 97, "{same} of {} pixels agree", a.len());
    let mean = |v: &[Vec3]| v.iter().copied().sum::<Vec3>() / v.len() as f32;
    assert!((mean(&a) - mean(&b)).abs().max_element() < 0.01, "{} vs {}", mean(&a), mean(&b));
}

#[test]
fn a_scene_of_copies_alone_renders() {
    let scene = parse_scene(
        r#"{"materials": {"m": {"type": "diffuse", "albedo": 0.5}}, "background": [1, 1, 1],
            "objects": [{"type": "triangle", "v0": [0, 0, 0], "v1": [1, 0, 0], "v2": [0, 1, 0], "material": "m",
                         "instances": [{"translate": [0, 0, 0]}, {"translate": [2, 0, 0]}]}]}"#,
        &scene_path(),
    )
    .unwrap();
    assert!(scene.meshes.is_empty());
    let g = built(&scene, Builder::default());
    assert_eq!(g.prim_count(), 0);
    let down = |x: f32| Ray::new(Vec3::new(x, 0.2, 1.0), -Vec3::Z);
    assert_eq!(g.intersect(&down(0.2)).map(|h| (h.part, h.prim)), Some((COPY, 0)));
    assert_eq!(g.intersect(&down(2.2)).map(|h| (h.part, h.prim)), Some((COPY | 1, 0)));
    assert!(g.intersect(&down(1.5)).is_none());
    // The framing camera sees both copies.
    let view = scene.view(None).unwrap();
    assert!(view.look_at.x > 1.0 && view.look_at.x < 2.0, "{:?}", view.look_at);
}

fn error_of(objects: &str) -> String {
    let text = format!(
        r#"{{"materials": {{"m": {{"type": "diffuse", "albedo": 0.5}}, "lamp": {{"type": "light", "emit": 4}}}},
            "objects": [{objects}]}}"#
    );
    match parse_scene(&text, &scene_path()) {
        Ok(_) => String::new(),
        Err(e) => e.to_string(),
    }
}

#[test]
fn the_scene_file_refuses_instances_it_cannot_place() {
    let triangle = r#""type": "triangle", "v0": [0, 0, 0], "v1": [1, 0, 0], "v2": [0, 1, 0]"#;
    let e = error_of(&format!(r#"{{{triangle}, "material": "m", "instances": []}}"#));
    assert!(e.contains("object 0: instances: the list is empty"), "{e}");
    let e = error_of(&format!(r#"{{{triangle}, "material": "m", "instances": [{{"scale": [1, 0, 1]}}]}}"#));
    assert!(e.contains("transform 0 is not finite or cannot be inverted"), "{e}");
    let e = error_of(&format!(
        r#"{{{triangle}, "material": "m", "instances": [{{}}], "animate": {{"type": "wave", "amplitude": 0.1, "wavelength": 1, "period": 1}}}}"#
    ));
    assert!(e.contains("copies can only move rigidly"), "{e}");
    let e = error_of(&format!(
        r#"{{{triangle}, "material": "m", "instances": [{{}}], "animate": {{"type": "oscillate", "amplitude": [1, 0, 0], "period": 1}}}}"#
    ));
    assert_eq!(e, "", "copies may move rigidly");
    let e = error_of(r#"{"type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m", "instances": [{}]}"#);
    assert!(e.contains("unknown key \"instances\""), "{e}");
}

#[test]
fn copies_of_an_emitter_are_written_out() {
    let text = r#"{"materials": {"lamp": {"type": "light", "emit": 4}},
        "objects": [{"type": "quad", "Q": [0, 0, 0], "u": [1, 0, 0], "v": [0, 1, 0], "material": "lamp",
                     "instances": [{"translate": [0, 0, 0]}, {"translate": [3, 0, 0]}, {"rotate": [0, 1, 0, 90]}]}]}"#;
    let scene = parse_scene(text, &scene_path()).unwrap();
    assert!(scene.instanced.is_empty());
    assert_eq!(scene.meshes.len(), 3);
    assert_eq!(scene.meshes[1].positions[0], Vec3::new(3.0, 0.0, 0.0));
    let g = built(&scene, Builder::default());
    let lights = phr_render::lights::LightSet::new(&g, &scene.materials, &scene.background);
    assert_eq!(lights.len(), 6, "each copy's two triangles are lights where they are");
}

/// Copies of a mesh with an alpha mask (MTL `map_d`) are written out too: the copies' leaf
/// test does not look at masks, the scene's parts do.
#[test]
fn copies_of_an_alpha_masked_mesh_are_written_out() {
    let path = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/references/alpha_mask.json"));
    let text = r#"{"objects": [{"type": "obj_mtl", "file": "alpha_mask.obj",
                     "instances": [{"translate": [0, 0, 0]}, {"translate": [4, 0, 0]}]}]}"#;
    let scene = parse_scene(text, &path).unwrap();
    assert!(scene.instanced.is_empty());
    assert_eq!(scene.meshes.len(), 2);
    assert_eq!(scene.triangle_count(), 12);
}

/// A glTF whose one-triangle mesh three nodes place: at the root, under a moved and turned
/// parent, and scaled to zero (hidden); and a second mesh placed once.
fn shared_gltf() -> String {
    let floats: [f32; 18] = [0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 2., 1., 0., 2., 0., 1., 2.];
    let bytes: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    let data = base64::encode(bytes);
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0,
  "scenes": [{{"nodes": [0, 1, 3, 4]}}],
  "nodes": [{{"mesh": 0}}, {{"translation": [3, 0, 0], "rotation": [0, 0.7071068, 0, 0.7071068], "children": [2]}},
            {{"mesh": 0, "scale": [1, 2, 1]}}, {{"mesh": 0, "scale": [0, 0, 0]}}, {{"mesh": 1}}],
  "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}, {{"primitives": [{{"attributes": {{"POSITION": 1}}}}]}}],
  "buffers": [{{"byteLength": 72, "uri": "data:application/octet-stream;base64,{data}"}}],
  "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": 36}}, {{"buffer": 0, "byteOffset": 36, "byteLength": 36}}],
  "accessors": [{{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}},
                {{"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 2], "max": [1, 1, 2]}}]}}"#
    )
}

#[test]
fn a_gltf_mesh_that_several_nodes_place_is_instanced() {
    let dir = std::env::temp_dir().join(format!("phr_shared_gltf_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("shared.gltf");
    std::fs::write(&file, shared_gltf()).unwrap();
    // Loading the mesh alone writes every placement out, the hidden one included.
    let flat = phr_render::load::load_mesh(&file).unwrap();
    assert_eq!(flat.triangles.len(), 4);
    assert!(flat.shared.is_empty());
    // A scene keeps the shared mesh once, with its two visible placements, under the object's transform.
    let text = format!(
        r#"{{"materials": {{}}, "background": [1, 1, 1],
            "objects": [{{"type": "gltf", "file": "{}", "transform": {{"translate": [0, 0, -5]}}}}]}}"#,
        file.display()
    );
    let scene = parse_scene(&text, &dir.join("s.json")).unwrap();
    assert_eq!(scene.meshes.len(), 1);
    assert_eq!(scene.meshes[0].triangles.len(), 1, "the mesh placed once stays as it is");
    assert_eq!(scene.instanced.len(), 1);
    assert_eq!(scene.instanced[0].copies.len(), 2);
    let (copies, written) = (built(&scene, Builder::default()), built(&flattened(scene.clone()), Builder::default()));
    let p = scene.instanced[0].copies[1].world_point(Vec3::new(0.2, 0.3, 0.0));
    assert!((p - Vec3::new(3.0, 0.6, -5.2)).length() < 1e-5, "{p}: child of the moved, turned parent");
    for target in [Vec3::new(0.2, 0.3, -5.0), p, Vec3::new(0.2, 0.3, -3.0)] {
        let ray = Ray::new(target + Vec3::new(0.3, 0.2, 4.0), -Vec3::new(0.3, 0.2, 4.0).normalize());
        let (a, b) = (copies.intersect(&ray).unwrap(), written.intersect(&ray).unwrap());
        assert!(close(a.t, b.t), "{target}: {} vs {}", a.t, b.t);
    }
    // A moving object is one mesh too: the shared one is written out, so it moves with the rest.
    let moving = text.replace(
        r#""transform""#,
        r#""animate": {"type": "oscillate", "amplitude": [1, 0, 0], "period": 2}, "transform""#,
    );
    let scene = parse_scene(&moving, &dir.join("s.json")).unwrap();
    assert!(scene.instanced.is_empty());
    assert_eq!(scene.meshes[0].triangles.len(), 4);
    // With instances of its own, the object is one mesh: the shared one is written out.
    let text = text.replace(r#""transform""#, r#""instances": [{}, {"translate": [9, 0, 0]}], "transform""#);
    let scene = parse_scene(&text, &dir.join("s.json")).unwrap();
    assert_eq!(scene.instanced.len(), 1);
    assert_eq!(scene.instanced[0].mesh.triangles.len(), 4);
    std::fs::remove_dir_all(&dir).ok();
}

/// The tetrahedron of [`moving_copies_hit_what_the_same_moving_objects_hit`].
const TETRAHEDRON: &str = r#""type": "triangles", "material": "m",
    "vertices": [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.6, 0.7, 0.6]],
    "faces": [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 4, 3], [1, 2, 4], [2, 3, 4]]"#;

/// A scene of a floor and `objects`.
fn scene_of(objects: &str) -> Scene {
    let text = format!(
        r#"{{"materials": {{ "m": {{ "type": "lambertian", "albedo": 0.5 }} }},
            "objects": [{{ "type": "quad", "Q": [-6, 0, -6], "u": [12, 0, 0], "v": [0, 0, 12], "material": "m" }}, {objects}]}}"#
    );
    parse_scene(&text, &scene_path()).unwrap()
}

/// Copies that move (the object's `animate`: a turn about each copy's own centre, a bob)
/// against the same moving objects written one by one (each with its transform, and its
/// pivot worked out here), and against the scene flattened: the same hits at several
/// times, where only the copies' top level is rebuilt.
#[test]
fn moving_copies_hit_what_the_same_moving_objects_hit() {
    let placements = [
        r#"{ "translate": [-2, 0.5, 0] }"#,
        r#"{ "scale": [1, 2, 0.5], "rotate": [0.3, 1, 0.2, 40], "translate": [1, 0.5, -1] }"#,
        r#"{ "scale": [1, -1, 1], "translate": [2, 1.5, 2] }"#,
    ];
    let motions = |pivot: &str| {
        format!(
            r#"[{{ "type": "rotate", "axis": [0, 1, 0], "degrees_per_second": 90{pivot} }},
                {{ "type": "oscillate", "amplitude": [0, 0.5, 0.2], "period": 2 }}]"#
        )
    };
    let copies = scene_of(&format!(
        r#"{{ {TETRAHEDRON}, "instances": [{}], "animate": {} }}"#,
        placements.join(", "),
        motions("")
    ));
    assert_eq!((copies.instanced.len(), copies.instanced[0].motions.len()), (1, 2));
    // Each copy's pivot: the centre of the tetrahedron's box, (0.5, 0.5, 0.5), placed by it.
    let centre = Vec3::splat(0.5);
    let turn = glam::Quat::from_axis_angle(Vec3::new(0.3, 1.0, 0.2).normalize(), 40f32.to_radians());
    let pivots = [
        centre + Vec3::new(-2.0, 0.5, 0.0),
        turn * (Vec3::new(1.0, 2.0, 0.5) * centre) + Vec3::new(1.0, 0.5, -1.0),
        Vec3::new(1.0, -1.0, 1.0) * centre + Vec3::new(2.0, 1.5, 2.0),
    ];
    let objects: Vec<String> = placements
        .iter()
        .zip(pivots)
        .map(|(p, c)| {
            format!(
                r#"{{ {TETRAHEDRON}, "transform": {p}, "animate": {} }}"#,
                motions(&format!(r#", "pivot": [{}, {}, {}]"#, c.x, c.y, c.z))
            )
        })
        .collect();
    let one_by_one = scene_of(&objects.join(", "));
    let flat = flattened(copies.clone());
    assert_eq!(flat.animations.len(), 3, "each written-out copy moves");
    let mut moving = Geometry::new(&copies);
    moving.build(&Builder::PHR_FAST);
    let mut animator = phr_render::animation::Animator::new(&copies);
    assert!(animator.is_animated());
    let all = rays(3000, 11);
    let mut hits_before = None;
    for t in [0.0, 0.7, 2.3] {
        animator.pose(&mut moving, t);
        for (what, other) in [("one by one", &one_by_one), ("flattened", &flat)] {
            let mut expected = Geometry::new(other);
            phr_render::animation::Animator::new(other).pose(&mut expected, t);
            expected.build(&Builder::PHR_FAST);
            let on_copies = assert_same_hits(&expected, &moving, &all, &format!("{what}, t {t}"));
            assert!(on_copies > 20, "{what}, t {t}: only {on_copies} rays hit a copy");
        }
        let hits: Vec<Option<f32>> = all.iter().map(|r| moving.intersect(r).map(|h| h.t)).collect();
        if t > 0.0 {
            assert_ne!(Some(&hits), hits_before.as_ref(), "t {t}: the copies did not move");
        }
        hits_before = Some(hits);
    }
}
