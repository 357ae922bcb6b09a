//! `phr bench-quality`'s own references (`references/`, made by `make_references.py` with
//! Mitsuba 3) hold what our renderer draws, judged by the team's comparison tool
//! (`compare_images.py --check`, with our film's variance): textured Sponza, rendered by
//! Mitsuba through `tools/render_textured.py` (its 18 `map_Kd` images as Mitsuba `bitmap`
//! textures on the OBJ's own texture coordinates), and the built-in scene, written out by
//! `export-reference` (PLY meshes, a fuzzy metal knot, glass and mirror spheres). A benchmark
//! that scores images against these references is only as good as they are.

use phr_bench::quality_bench::{open_scene_with_reference, ScoredScene};
use phr_bvh::Builder;
use phr_render::film::Film;
use phr_render::geometry::Geometry;
use phr_render::lights::LightSet;
use phr_render::output::write_image;
use phr_render::render::Renderer;

#[path = "../../phr-render/tests/support/compare_images.rs"]
mod compare_images;
use compare_images::{compare, Noise};

/// Renders the scene with light sampling at `spp` samples per pixel and compares it with
/// its reference.
fn check(name: &str, spp: u32) {
    let work = std::env::temp_dir().join(format!("phr-own-references-{name}-{}", std::process::id()));
    let scored = ScoredScene::named(name, &work).unwrap();
    let (scene, view, _) = open_scene_with_reference(&scored).unwrap();
    let mut geometry = Geometry::new(&scene);
    geometry.build(&Builder::default());
    let lights = LightSet::new(&geometry, &scene.materials, &scene.background);
    let renderer = Renderer::new(&scene, &geometry, &view, &scene.settings, Some(&lights)).with_seed(12345);
    let (w, h) = (scene.settings.width, scene.settings.height);
    let mut film = Film::new(w, h);
    for frame in 0..spp {
        film.add_frame(&renderer.render_frame(frame).0);
    }
    std::fs::create_dir_all(&work).unwrap();
    let (out, variance) = (work.join("ours.pfm"), work.join("ours_var.pfm"));
    write_image(&out, w, h, &film.mean()).unwrap();
    write_image(&variance, w, h, &film.variance_of_mean()).unwrap();
    let (passed, text) = compare(&out, &scored.reference, Noise::Variance(&variance));
    let _ = std::fs::remove_dir_all(&work);
    println!("{name}, {spp} spp:\n{text}");
    assert!(passed, "{name} does not match its reference:\n{text}");
}

#[test]
fn textured_sponza_matches_its_reference() {
    check("sponza_textured", 128);
}

#[test]
fn the_builtin_scene_matches_its_reference() {
    check("builtin", 128);
}
