//! The extra samples of a finished render's unfiltered pixels (`denoise::refine_unfiltered`):
//! a refined pixel's value is the mean of the very samples the following frames would give
//! it (not of the film's, which chose it), only pixels the filters leave alone get them, and
//! the lamp's uniform inside gets none.

use glam::Vec3;
use phr_render::denoise::{refine_unfiltered, unfiltered_to_refine, Guide, UNFILTERED_EXTRA};
use phr_render::film::Film;
use phr_render::geometry::Geometry;
use phr_render::lights::LightSet;
use phr_render::render::Renderer;
use phr_render::scene::{load_scene, RenderSettings};
use std::path::PathBuf;

fn cornell_obj() -> phr_render::Scene {
    let file = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/reference/scenes/cornell_obj.json"));
    assert!(file.is_file(), "{} is missing: the shared references are needed", file.display());
    load_scene(&file).unwrap()
}

#[test]
fn unfiltered_noisy_pixels_get_the_samples_of_the_next_frames() {
    let scene = cornell_obj();
    let mut geometry = Geometry::new(&scene);
    geometry.build(&phr_bvh::Builder::default());
    let lights = LightSet::new(&geometry, &scene.materials, &scene.background);
    let settings = RenderSettings { width: 128, height: 128, spp: 1, max_depth: 8 };
    let view = scene.view(None).unwrap();
    let renderer = Renderer::new(&scene, &geometry, &view, &settings, Some(&lights));
    let spp = 4;
    let mut film = Film::new(128, 128);
    let frames: Vec<Vec<Vec3>> = (0..spp * (1 + UNFILTERED_EXTRA)).map(|k| renderer.render_frame(k).0).collect();
    for frame in &frames[..spp as usize] {
        film.add_frame(frame);
    }
    let guide = Guide::render(&renderer, spp);
    let mean = film.mean();
    let (pixels, extra) = unfiltered_to_refine(&film, &mean, &guide);
    // Within the budget: at 128² the image's edges are many of its pixels.
    assert!(extra > 0 && extra <= UNFILTERED_EXTRA * spp, "{extra}");
    assert!(!pixels.is_empty() && pixels.len() * extra as usize <= mean.len() * spp as usize / 4);
    assert!(pixels.iter().all(|&i| guide.footprint[i as usize] == 0.0), "only pixels the filters leave alone");
    // The lamp's inside (radiance (17, 12, 4) in every sample and around) is exact already.
    let lamp: Vec<usize> = (0..mean.len()).filter(|&i| mean[i] == Vec3::new(17.0, 12.0, 4.0)).collect();
    let inside: Vec<usize> =
        lamp.iter().copied().filter(|&i| [i - 1, i + 1, i - 128, i + 128].iter().all(|j| lamp.contains(j))).collect();
    assert!(!inside.is_empty() && inside.iter().all(|i| !pixels.contains(&(*i as u32))), "{inside:?}");
    // Each refined pixel's value is the mean of frames spp..spp + extra, to rounding.
    let refined = refine_unfiltered(&renderer, &film, &guide);
    assert_eq!((refined.pixels.len(), refined.samples), (pixels.len(), extra));
    for (i, value) in refined.pixels {
        let used = &frames[spp as usize..(spp + extra) as usize];
        let expected = used.iter().map(|f| f[i as usize]).sum::<Vec3>() / used.len() as f32;
        assert!(
            (value - expected).abs().max_element() <= 1e-4 * expected.max_element().max(1.0),
            "pixel {i}: {value} vs {expected}"
        );
    }
}
