//! Fuzzing the loaders (OBJ, MTL, PLY, glTF/GLB, gzip, scene files): mutations of the seed
//! files in `tests/fuzz_seeds` must give a mesh or a `LoadError`, never a panic; a scene that
//! loads must also build, collapse and render a tiny frame without one.
//!
//! CI runs a short smoke with a fixed seed. A long run, e.g. ten minutes a target:
//! `PHR_FUZZ_SECONDS=600 cargo test --release -p phr-render --test fuzz_loaders -- --nocapture`
//! (`PHR_FUZZ_TARGETS=gltf,scene` for some of the targets: obj, ply, gltf, gzip, scene, mtl).
//! Inputs that panic are written to `target/tmp/fuzz-crashes/`; once fixed, they belong in
//! `tests/bad_inputs/` (see `bad_inputs.rs`), where every bad file is checked for good.

#[path = "../../phr-bvh/tests/common/mutate.rs"]
mod mutate;

use phr_bvh::Builder;
use phr_render::geometry::Geometry;
use phr_render::load::parse_mesh;
use phr_render::render::Renderer;
use phr_render::scene::json::parse_scene;
use phr_render::scene::RenderSettings;
use std::path::{Path, PathBuf};
use std::time::Duration;

fn seeds_dir() -> PathBuf {
    PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fuzz_seeds"))
}

fn seed(name: &str) -> Vec<u8> {
    std::fs::read(seeds_dir().join(name)).unwrap()
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    e.write_all(bytes).unwrap();
    e.finish().unwrap()
}

const DICTIONARY: &[&[u8]] = &[
    b"v ",
    b"vt ",
    b"vn ",
    b"f ",
    b"usemtl ",
    b"mtllib ",
    b"newmtl ",
    b"Kd ",
    b"Ke ",
    b"Ni ",
    b"illum ",
    b"map_d ",
    b"map_Kd ",
    b"\"alphaMode\": \"MASK\"",
    b"\"KHR_texture_transform\": {\"rotation\": 1e39}",
    b"\"texCoord\": 1",
    b"/",
    b"//",
    b"element vertex ",
    b"element face ",
    b"property float x\n",
    b"property list uchar int vertex_indices\n",
    b"property list uint uint vertex_indices\n",
    b"property double ",
    b"end_header\n",
    b"format binary_big_endian 1.0\n",
    b"\"count\": ",
    b"\"byteOffset\": ",
    b"\"byteStride\": ",
    b"\"componentType\": 5125",
    b"\"type\": \"VEC4\"",
    b"\"children\": [0]",
    b"\"uri\": \"../x.bin\"",
    b"\"interpolation\": \"CUBICSPLINE\"",
    b"\"path\": \"rotation\"",
    b"\"type\": \"sphere\"",
    b"\"animate\": ",
    b"\"transform\": ",
    b"\"file\": \"/dev/zero\"",
    b"{scenes}",
    b"%FF",
    b"\xEF\xBB\xBF",
    b"-2147483648",
    b"65535",
];

/// Parses a mesh; when it loads, builds a tree over it (the renderer's path after loading).
fn mesh_target(path: &Path, bytes: &[u8]) {
    if let Ok(mesh) = parse_mesh(path, bytes) {
        assert_eq!(mesh.triangle_group.len(), mesh.triangles.len());
    }
}

/// Parses a scene file; when it loads, builds, collapses and renders 4×4 pixels at depth 3.
fn scene_target(bytes: &[u8]) {
    let text = String::from_utf8_lossy(bytes);
    let Ok(scene) = parse_scene(&text, &seeds_dir().join("scene.json")) else { return };
    let mut geometry = Geometry::new(&scene);
    geometry.build(&Builder::PHR_FAST);
    let view = scene.view(None).unwrap();
    let settings = RenderSettings { width: 4, height: 4, spp: 1, max_depth: 3 };
    let (pixels, _) = Renderer::new(&scene, &geometry, &view, &settings, None).render_frame(0);
    assert_eq!(pixels.len(), 16);
}

#[test]
fn seeds_load() {
    for name in ["cube.obj", "quad_ascii.ply", "quad_little.ply", "quad_big.ply", "tri.gltf", "tri.glb", "tex.gltf"] {
        let path = seeds_dir().join(name);
        let mesh = parse_mesh(&path, &seed(name)).unwrap_or_else(|e| panic!("{e}"));
        assert!(!mesh.triangles.is_empty(), "{name}");
    }
    let scene = parse_scene(&String::from_utf8(seed("scene.json")).unwrap(), &seeds_dir().join("scene.json"));
    assert!(scene.unwrap_or_else(|e| panic!("{e}")).meshes.len() >= 5);
}

#[test]
fn loaders_survive_mutated_inputs() {
    let budget = mutate::budget(Duration::from_secs(3));
    let crash_dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("fuzz-crashes");
    let dir = seeds_dir();
    let mut report = Vec::new();
    let mut crashes = Vec::new();
    // `PHR_FUZZ_TARGETS=gltf,scene` runs those targets alone.
    let chosen = std::env::var("PHR_FUZZ_TARGETS").ok();
    let mut run = |name: &str, seeds: Vec<Vec<u8>>, target: &(dyn Fn(&[u8]) + std::panic::RefUnwindSafe)| {
        if chosen.as_ref().is_some_and(|c| !c.split(',').any(|t| t == name)) {
            return;
        }
        let (runs, found) = mutate::fuzz(name, &seeds, DICTIONARY, budget, &crash_dir, target);
        report.push(format!("{name}: {runs} inputs"));
        crashes.extend(found);
    };
    run("obj", vec![seed("cube.obj")], &|b| mesh_target(&dir.join("cube.obj"), b));
    run("ply", vec![seed("quad_ascii.ply"), seed("quad_little.ply"), seed("quad_big.ply")], &|b| {
        mesh_target(&dir.join("quad.ply"), b)
    });
    run("gltf", vec![seed("tri.gltf"), seed("tri.glb"), seed("tex.gltf")], &|b| mesh_target(&dir.join("tri.gltf"), b));
    run("gzip", vec![gzip(&seed("cube.obj")), gzip(&seed("quad_little.ply"))], &|b| {
        mesh_target(&dir.join("mesh.obj.gz"), b);
        mesh_target(&dir.join("mesh.ply.gz"), b);
    });
    run("scene", vec![seed("scene.json")], &scene_target);
    // MTL: the mutated library next to the seed OBJ, in a folder of the test's own.
    let mtl_dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("fuzz-mtl-{}", std::process::id()));
    std::fs::create_dir_all(&mtl_dir).unwrap();
    let obj = seed("cube.obj");
    run("mtl", vec![seed("cube.mtl")], &|b| {
        std::fs::write(mtl_dir.join("cube.mtl"), b).unwrap();
        mesh_target(&mtl_dir.join("cube.obj"), &obj);
    });
    let _ = std::fs::remove_dir_all(&mtl_dir);
    eprintln!("{}", report.join(", "));
    assert!(crashes.is_empty(), "inputs that panic: {crashes:#?}");
}
