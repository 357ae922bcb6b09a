//! Timed 1-spp frames of our renderer: the frame of the thesis's interactive loop (trace
//! one sample per pixel, add it to the film), on a tree built once.

use crate::stats::Stat;
use phr_render::camera::CameraDesc;
use phr_render::film::Film;
use phr_render::geometry::Geometry;
use phr_render::render::{Renderer, Tracing};
use phr_render::scene::RenderSettings;
use phr_render::Scene;
use std::time::Instant;

/// Wall-clock times of repeated frames.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct FrameTiming {
    /// Milliseconds per frame, over the timed frames.
    pub ms: Stat,
    /// Rays per frame (camera rays and bounces; mean over the timed frames).
    pub rays: f64,
    /// Frames timed (after the warm-up ones).
    pub frames: usize,
}

impl FrameTiming {
    /// Million rays per second at the median frame time.
    pub fn mrays_per_s(&self) -> f64 {
        self.rays / self.ms.median / 1e3
    }
}

/// The median of three 1-spp frames of `scene` from `view` with `bvh` set in `geometry`
/// (collapse not timed): (render ms, rays per frame). What `phr tune`'s frame-time
/// calibration and `phr bench` measure per tree.
pub fn median_frame(
    scene: &Scene,
    geometry: &mut Geometry,
    bvh: phr_bvh::Bvh,
    view: &CameraDesc,
    settings: &RenderSettings,
) -> (f64, f64) {
    geometry.set_bvh(bvh);
    // Meshes placed many times keep their own trees (built once, by the default builder).
    geometry.build_copies(&phr_bvh::Builder::default());
    let timing = time_frames(scene, geometry, view, settings, Tracing::default(), 0, 3);
    (timing.ms.median, timing.rays)
}

/// Renders `warmup` untimed and then `frames` timed 1-spp frames of `scene` from `view` at
/// the size and depth of `settings`, each added to a film (as the viewer does), on the tree
/// already set in `geometry`, its paths traced as `tracing` says. Frame `k` uses seed `k`, so
/// each frame is a new sample.
pub fn time_frames(
    scene: &Scene,
    geometry: &Geometry,
    view: &CameraDesc,
    settings: &RenderSettings,
    tracing: Tracing,
    warmup: usize,
    frames: usize,
) -> FrameTiming {
    assert!(frames > 0, "time_frames needs at least one timed frame");
    let renderer = Renderer::new(scene, geometry, view, settings, None).with_tracing(tracing);
    let mut film = Film::new(settings.width, settings.height);
    let mut times = Vec::with_capacity(frames);
    let mut rays = 0u64;
    for k in 0..warmup + frames {
        let start = Instant::now();
        let (image, stats) = renderer.render_frame(k as u32);
        film.add_frame(&image);
        let ms = start.elapsed().as_secs_f64() * 1e3;
        if k >= warmup {
            times.push(ms);
            rays += stats.rays;
        }
    }
    FrameTiming { ms: Stat::of(times), rays: rays as f64 / frames as f64, frames }
}
