//! The progressive, multi-threaded render loop: one sample per pixel per frame, accumulated
//! by the caller's [`crate::film::Film`].
//!
//! A frame is cut into 16×16 tiles rendered as rayon tasks (tiles keep neighbouring rays,
//! which visit the same nodes, on one core). Each pixel's random numbers depend only on
//! (seed, frame, pixel) ([`Pcg32::for_pixel`]), so the image is the same for any thread count.
//! Where the camera ray falls in its pixel follows a low-discrepancy sequence over the frames
//! ([`Pcg32::pixel_jitter`]), so edges anti-alias with few samples.

use crate::camera::{Camera, CameraDesc};
use crate::geometry::Geometry;
use crate::integrator::{FirstHit, PathTracer};
use crate::lights::LightSet;
use crate::sampler::Pcg32;
use crate::scene::{RenderSettings, Scene};
use glam::Vec3;
use phr_bvh::TraversalStats;
use rayon::prelude::*;

const TILE: u32 = 16;

pub struct Renderer<'a> {
    pub tracer: PathTracer<'a>,
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
    pub seed: u64,
}

/// Work done in one frame.
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameStats {
    /// Rays traced (camera rays and bounces).
    pub rays: u64,
}

impl<'a> Renderer<'a> {
    /// The renderer of `scene` (its materials and background) over `geometry` (its primitives
    /// and tree) seen from `view`, at the size and path depth of `settings` (their `spp` is
    /// the caller's loop), with seed 0. `lights` turns on explicit light sampling. The one way
    /// front ends and tests make a renderer.
    pub fn new(
        scene: &'a Scene,
        geometry: &'a Geometry,
        view: &CameraDesc,
        settings: &RenderSettings,
        lights: Option<&'a LightSet>,
    ) -> Self {
        let RenderSettings { width, height, max_depth, .. } = *settings;
        Self {
            tracer: PathTracer {
                geometry,
                materials: &scene.materials,
                textures: &scene.textures,
                material_texture: &scene.material_texture,
                background: &scene.background,
                max_depth,
                lights,
            },
            camera: Camera::new(view, width, height),
            width,
            height,
            seed: 0,
        }
    }

    /// The same renderer with another seed (images differ by seed, not by thread count).
    pub fn with_seed(self, seed: u64) -> Self {
        Self { seed, ..self }
    }
}

impl Renderer<'_> {
    fn tiles(&self) -> Vec<(u32, u32)> {
        let (tx, ty) = (self.width.div_ceil(TILE), self.height.div_ceil(TILE));
        (0..ty).flat_map(|y| (0..tx).map(move |x| (x * TILE, y * TILE))).collect()
    }

    /// Renders frame number `frame` (1 sample per pixel); pixels row-major from the top left.
    pub fn render_frame(&self, frame: u32) -> (Vec<Vec3>, FrameStats) {
        self.render_frame_with(frame, |ray, rng| {
            let sample = self.tracer.trace(ray, rng);
            (sample.radiance, sample.rays)
        })
    }

    /// [`Renderer::render_frame`], also returning each pixel's first hit, from the ray its
    /// colour came from (what the denoiser's guide is made of, at no extra ray).
    pub fn render_frame_guided(&self, frame: u32) -> (Vec<Vec3>, Vec<FirstHit>, FrameStats) {
        let (pixels, stats) = self.render_frame_with(frame, |ray, rng| {
            let (sample, first) = self.tracer.trace_guided(ray, rng);
            ((sample.radiance, first), sample.rays)
        });
        let (colours, hits) = pixels.into_iter().unzip();
        (colours, hits, stats)
    }

    /// The tile loop of [`Renderer::render_frame`] with another per-pixel estimator:
    /// `shade(camera_ray, rng)` returns what the pixel holds (a colour) and the number of
    /// rays it traced. The viewer's normal, albedo and heatmap modes use it.
    pub fn render_frame_with<T: Copy + Default + Send>(
        &self,
        frame: u32,
        shade: impl Fn(phr_bvh::Ray, &mut Pcg32) -> (T, u32) + Sync,
    ) -> (Vec<T>, FrameStats) {
        let tiles: Vec<(Vec<T>, u64)> = self
            .tiles()
            .into_par_iter()
            .map(|(x0, y0)| {
                let mut out = Vec::with_capacity((TILE * TILE) as usize);
                let mut rays = 0u64;
                for y in y0..(y0 + TILE).min(self.height) {
                    for x in x0..(x0 + TILE).min(self.width) {
                        let (colour, traced) = self.pixel_sample(frame, y * self.width + x, &shade);
                        out.push(colour);
                        rays += traced as u64;
                    }
                }
                (out, rays)
            })
            .collect();
        let mut image = vec![T::default(); (self.width * self.height) as usize];
        let mut stats = FrameStats::default();
        for ((x0, y0), (pixels, rays)) in self.tiles().into_iter().zip(tiles) {
            let tile_w = (x0 + TILE).min(self.width) - x0;
            for (i, p) in pixels.into_iter().enumerate() {
                let (x, y) = (x0 + i as u32 % tile_w, y0 + i as u32 / tile_w);
                image[(y * self.width + x) as usize] = p;
            }
            stats.rays += rays;
        }
        (image, stats)
    }

    /// Sample `frame` of `pixel` (row-major index) through `shade`: its random numbers and
    /// its position in the pixel depend on (seed, frame, pixel) alone.
    #[inline]
    fn pixel_sample<T>(
        &self,
        frame: u32,
        pixel: u32,
        shade: impl Fn(phr_bvh::Ray, &mut Pcg32) -> (T, u32),
    ) -> (T, u32) {
        let (x, y) = (pixel % self.width, pixel / self.width);
        let mut rng = Pcg32::for_pixel(self.seed, frame, pixel);
        let (jx, jy) = Pcg32::pixel_jitter(self.seed, frame, pixel);
        shade(self.camera.ray(x as f32 + jx, y as f32 + jy), &mut rng)
    }

    /// The mean of samples `frames` of each of `pixels` (row-major indices): of the samples
    /// [`Renderer::render_frame`] gives those pixels in those frames (summed in f64, as the
    /// film does).
    pub fn pixel_means(&self, pixels: &[u32], frames: std::ops::Range<u32>) -> Vec<Vec3> {
        let n = frames.len().max(1) as f64;
        pixels
            .par_iter()
            .map(|&pixel| {
                let sum: glam::DVec3 = frames
                    .clone()
                    .map(|frame| {
                        self.pixel_sample(frame, pixel, |ray, rng| (self.tracer.trace(ray, rng).radiance, 0)).0
                    })
                    .map(|c| c.as_dvec3())
                    .sum();
                (sum / n).as_vec3()
            })
            .collect()
    }

    /// Traversal work of the camera ray through each pixel's centre (thesis Figure 5.3).
    pub fn primary_ray_stats(&self) -> Vec<TraversalStats> {
        let geometry: &Geometry = self.tracer.geometry;
        (0..self.width * self.height)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % self.width, i / self.width);
                let ray = self.camera.ray(x as f32 + 0.5, y as f32 + 0.5);
                let mut stats = TraversalStats::default();
                geometry.intersect_counted(&ray, &mut stats);
                stats
            })
            .collect()
    }
}
