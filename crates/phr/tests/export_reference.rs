//! `phr export-reference`: the built-in scene written in the reference renderer's format
//! (JSON and PLY, which Mitsuba 3 renders through `render_reference.py`) reads back, through
//! phr's own loader, as the same triangles with the same materials, the same spheres, view,
//! background and settings; what the format cannot say (a texture) is refused before
//! anything is written.

mod common;

use common::{phr_ok, phr_within, repo_path, TempDir};
use phr_render::scene::{load_scene, Background, Scene};
use std::time::Duration;

/// Every triangle of the scene as its corners' bits and its material, sorted.
fn triangles(scene: &Scene) -> Vec<([u32; 9], String)> {
    let mut out: Vec<([u32; 9], String)> = scene
        .meshes
        .iter()
        .flat_map(|mesh| {
            mesh.triangles.iter().zip(&mesh.triangle_material).map(|(t, &m)| {
                let corners: Vec<u32> =
                    t.iter().flat_map(|&v| mesh.positions[v as usize].to_array().map(f32::to_bits)).collect();
                (corners.try_into().unwrap(), format!("{:?}", scene.materials[m as usize]))
            })
        })
        .collect();
    out.sort_by(|a, b| a.0.cmp(&b.0).then(a.1.cmp(&b.1)));
    out
}

fn spheres(scene: &Scene) -> Vec<String> {
    let mut out: Vec<String> =
        scene.spheres.iter().map(|s| format!("{:?} {:?}", s.sphere, scene.materials[s.material as usize])).collect();
    out.sort();
    out
}

#[test]
fn the_builtin_scene_reads_back_as_itself() {
    let dir = TempDir::new("export-reference");
    let args = ["export-reference", "builtin", "--out", "ex", "--width", "64", "--height", "48", "--spp", "8"];
    let out = phr_ok(&dir.0, &args, Duration::from_secs(120));
    assert!(out.stdout.contains("builtin.json"), "{}", out.stdout);
    let back = load_scene(&dir.join("ex/builtin.json")).unwrap();
    let original = phr_bench::suite::open_scene("builtin").unwrap();
    let (a, b) = (triangles(&original), triangles(&back));
    assert_eq!(a.len(), b.len());
    assert!(a == b, "the triangles or their materials differ");
    assert_eq!(spheres(&original), spheres(&back));
    assert_eq!(original.view(None), back.view(None));
    match (&original.background, &back.background) {
        (Background::Constant(x), Background::Constant(y)) => assert_eq!(x, y),
        _ => panic!("the built-in scene's background is a constant"),
    }
    let s = back.settings;
    assert_eq!((s.width, s.height, s.spp, s.max_depth), (64, 48, 8, original.settings.max_depth));
}

#[test]
fn a_textured_scene_is_refused_before_anything_is_written() {
    let dir = TempDir::new("export-reference-textured");
    let scene = repo_path("crates/phr-render/tests/references/textured.json");
    let out =
        phr_within(&dir.0, &["export-reference", scene.to_str().unwrap(), "--out", "ex"], Duration::from_secs(60));
    assert_ne!(out.code, Some(0));
    assert!(out.stderr.contains("texture"), "{}", out.stderr);
    assert!(!dir.join("ex").exists(), "nothing written");
}
