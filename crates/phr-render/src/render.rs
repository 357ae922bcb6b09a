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
use crate::integrator::{FirstHit, Path, PathTracer};
use crate::lights::LightSet;
use crate::sampler::{JitterTable, Pcg32};
use crate::scene::{RenderSettings, Scene};
use glam::Vec3;
use phr_bvh::TraversalStats;
use rayon::prelude::*;
use std::sync::{Arc, OnceLock};

const TILE: u32 = 16;

/// How a frame's paths are traced. Both give the same image, bit for bit: each pixel's
/// path consumes the same random numbers through [`PathTracer::advance`], and its rays get the
/// same closest hits.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Tracing {
    /// A tile's paths advance together, one segment at a time: the rays of all live paths
    /// are intersected as one batch ([`Geometry::intersect_batch`]: several rays traversed at
    /// once, overlapping their memory waits), then each path is shaded.
    #[default]
    Wavefront,
    /// Each pixel's path is traced to its end before the next starts (the thesis's loop; the
    /// reference).
    Single,
}

impl std::str::FromStr for Tracing {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "wavefront" => Ok(Tracing::Wavefront),
            "single" => Ok(Tracing::Single),
            _ => Err(format!("unknown tracing `{s}` (wavefront, single)")),
        }
    }
}

impl std::fmt::Display for Tracing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Tracing::Wavefront => "wavefront",
            Tracing::Single => "single",
        })
    }
}

pub struct Renderer<'a> {
    pub tracer: PathTracer<'a>,
    pub camera: Camera,
    pub width: u32,
    pub height: u32,
    pub seed: u64,
    pub tracing: Tracing,
    /// The pixels' jitter offsets under `seed`, made at the first camera ray (or handed over
    /// by [`Renderer::with_jitter`]: a caller that makes a renderer per frame keeps them).
    jitter: OnceLock<Arc<JitterTable>>,
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
            tracing: Tracing::default(),
            jitter: OnceLock::new(),
        }
    }

    /// The same renderer with another seed (images differ by seed, not by thread count).
    pub fn with_seed(self, seed: u64) -> Self {
        let table = self.jitter.into_inner();
        Self { seed, jitter: OnceLock::new(), ..self }.with_jitter(table)
    }

    /// The same renderer with the jitter offsets of an earlier one ([`Renderer::jitter_table`]),
    /// if they are for its seed and size (else it makes its own when it needs them).
    pub fn with_jitter(self, table: Option<Arc<JitterTable>>) -> Self {
        let jitter = OnceLock::new();
        if let Some(table) = table.filter(|t| t.fits(self.seed, self.pixel_count())) {
            let _ = jitter.set(table);
        }
        Self { jitter, ..self }
    }

    /// The pixels' jitter offsets under this renderer's seed (made now if not yet), to hand
    /// to the next frame's renderer.
    pub fn jitter_table(&self) -> Arc<JitterTable> {
        Arc::clone(self.jitter())
    }

    fn jitter(&self) -> &Arc<JitterTable> {
        self.jitter.get_or_init(|| Arc::new(JitterTable::new(self.seed, self.pixel_count())))
    }

    /// Where in pixel `pixel` frame `frame` puts its camera ray ([`Pcg32::pixel_jitter`]),
    /// from the table while it fits the renderer's seed and size (they are public fields).
    #[inline]
    fn pixel_jitter(&self, frame: u32, pixel: u32) -> (f32, f32) {
        let table = self.jitter();
        if table.fits(self.seed, self.pixel_count()) {
            table.jitter(frame, pixel)
        } else {
            Pcg32::pixel_jitter(self.seed, frame, pixel)
        }
    }

    fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The same renderer tracing its paths another way (the same image).
    pub fn with_tracing(self, tracing: Tracing) -> Self {
        Self { tracing, ..self }
    }
}

impl Renderer<'_> {
    fn tiles(&self) -> Vec<(u32, u32)> {
        let (tx, ty) = (self.width.div_ceil(TILE), self.height.div_ceil(TILE));
        (0..ty).flat_map(|y| (0..tx).map(move |x| (x * TILE, y * TILE))).collect()
    }

    /// Renders frame number `frame` (1 sample per pixel); pixels row-major from the top left.
    pub fn render_frame(&self, frame: u32) -> (Vec<Vec3>, FrameStats) {
        if self.tracing == Tracing::Wavefront {
            return self.render_tiles(|x0, y0| self.wavefront_tile::<false, _>(frame, x0, y0, |colour, _| colour));
        }
        self.render_frame_with(frame, |ray, rng| {
            let sample = self.tracer.trace(ray, rng);
            (sample.radiance, sample.rays)
        })
    }

    /// [`Renderer::render_frame`], also returning each pixel's first hit, from the ray its
    /// colour came from (what the denoiser's guide is made of, at no extra ray).
    pub fn render_frame_guided(&self, frame: u32) -> (Vec<Vec3>, Vec<FirstHit>, FrameStats) {
        match self.tracing {
            Tracing::Wavefront => self.render_tiles_split(|x0, y0| {
                self.wavefront_tile::<true, _>(frame, x0, y0, |colour, first| (colour, first))
            }),
            Tracing::Single => self.render_tiles_split(|x0, y0| {
                self.single_tile(frame, x0, y0, &|ray, rng| {
                    let (sample, first) = self.tracer.trace_guided(ray, rng);
                    ((sample.radiance, first), sample.rays)
                })
            }),
        }
    }

    /// The first hits [`Renderer::render_frame_guided`] gives frame `frame`, from the same
    /// camera rays, without the paths: the guide of samples another device traced
    /// ([`crate::frame_tracer`]).
    pub fn first_hits(&self, frame: u32) -> Vec<FirstHit> {
        let geometry = self.tracer.geometry;
        let (hits, _) = self.render_frame_with(frame, |ray, _| {
            if !self.tracer.traces_anything() {
                return (FirstHit::SKY, 0);
            }
            let first = geometry
                .intersect(&ray)
                .map_or(FirstHit::SKY, |hit| self.tracer.first_hit(&geometry.surface_point(&ray, &hit), &hit));
            (first, 1)
        });
        hits
    }

    /// The paths of one tile (corner `x0, y0`) as a wavefront: every live path's next ray is
    /// intersected in one batch, then each path advances one segment, until none is left.
    /// Pixels in the tile's row-major order, each `pixel(colour, first hit)`, with the rays
    /// traced. `GUIDE`: the first hits are found (else they are [`FirstHit::SKY`]).
    fn wavefront_tile<const GUIDE: bool, T>(
        &self,
        frame: u32,
        x0: u32,
        y0: u32,
        pixel: impl Fn(Vec3, FirstHit) -> T,
    ) -> (Vec<T>, u64) {
        let mut paths = Vec::with_capacity((TILE * TILE) as usize);
        for y in y0..(y0 + TILE).min(self.height) {
            for x in x0..(x0 + TILE).min(self.width) {
                let (ray, rng) = self.camera_sample_at(frame, x, y);
                paths.push((Path::new(ray), rng));
            }
        }
        // The first hits, kept apart (and only when asked for): a plain frame's paths stay
        // 40 bytes smaller.
        let mut firsts = vec![FirstHit::SKY; if GUIDE { paths.len() } else { 0 }];
        let geometry = self.tracer.geometry;
        let mut live: Vec<usize> = if self.tracer.traces_anything() { (0..paths.len()).collect() } else { Vec::new() };
        let mut rays = Vec::with_capacity(paths.len());
        let mut hits = Vec::with_capacity(paths.len());
        // The paths whose light sample waits for its shadow ray, and their answers.
        let mut waiting = Vec::with_capacity(paths.len());
        let mut occluded = Vec::with_capacity(paths.len());
        while !live.is_empty() {
            rays.clear();
            rays.extend(live.iter().map(|&i| paths[i].0.ray));
            hits.clear();
            hits.resize(rays.len(), None);
            geometry.intersect_batch(&rays, &mut hits);
            let mut k = 0;
            waiting.clear();
            live.retain(|&i| {
                let (path, rng) = &mut paths[i];
                let mut unused = FirstHit::SKY;
                let first = if GUIDE { &mut firsts[i] } else { &mut unused };
                let going = self.tracer.advance::<GUIDE>(path, hits[k], rng, first);
                k += 1;
                if path.shadow_ray().is_some() {
                    waiting.push(i);
                }
                going
            });
            if !waiting.is_empty() {
                rays.clear();
                rays.extend(waiting.iter().map(|&i| paths[i].0.shadow_ray().expect("a waiting path has a shadow ray")));
                occluded.clear();
                occluded.resize(rays.len(), false);
                geometry.occluded_batch(&rays, &mut occluded);
                for (&i, &blocked) in waiting.iter().zip(&occluded) {
                    paths[i].0.settle_shadow(blocked);
                }
            }
        }
        let mut traced = 0;
        let pixels = paths
            .iter()
            .enumerate()
            .map(|(i, (path, _))| {
                let sample = path.sample();
                traced += u64::from(sample.rays);
                pixel(sample.radiance, if GUIDE { firsts[i] } else { FirstHit::SKY })
            })
            .collect();
        (pixels, traced)
    }

    /// The one-path-at-a-time tile loop (that of [`Renderer::render_frame`] with
    /// [`Tracing::Single`]) with any per-pixel estimator:
    /// `shade(camera_ray, rng)` returns what the pixel holds (a colour) and the number of
    /// rays it traced. The viewer's normal, albedo and heatmap modes use it.
    pub fn render_frame_with<T: Copy + Default + Send + Sync>(
        &self,
        frame: u32,
        shade: impl Fn(phr_bvh::Ray, &mut Pcg32) -> (T, u32) + Sync,
    ) -> (Vec<T>, FrameStats) {
        self.render_tiles(|x0, y0| self.single_tile(frame, x0, y0, &shade))
    }

    /// One tile (corner `x0, y0`) of the one-path-at-a-time loop
    /// ([`Renderer::render_frame_with`], and [`Renderer::render_frame_guided`] with
    /// [`Tracing::Single`]): its pixels in its row-major order, and the rays traced.
    fn single_tile<T>(
        &self,
        frame: u32,
        x0: u32,
        y0: u32,
        shade: &impl Fn(phr_bvh::Ray, &mut Pcg32) -> (T, u32),
    ) -> (Vec<T>, u64) {
        let mut out = Vec::with_capacity((TILE * TILE) as usize);
        let mut rays = 0u64;
        for y in y0..(y0 + TILE).min(self.height) {
            for x in x0..(x0 + TILE).min(self.width) {
                let (colour, traced) = self.pixel_sample(frame, y * self.width + x, shade);
                out.push(colour);
                rays += traced as u64;
            }
        }
        (out, rays)
    }

    /// Renders the tiles as rayon tasks: `tile(x0, y0)` gives a tile's pixels in its
    /// row-major order and the rays it traced; returns the image, row-major.
    fn render_tiles<T: Copy + Default + Send + Sync>(
        &self,
        tile: impl Fn(u32, u32) -> (Vec<T>, u64) + Sync,
    ) -> (Vec<T>, FrameStats) {
        let mut image = self.blank_image();
        let stride = self.width as usize * TILE as usize;
        let stats = self.lay_tiles(tile, image.par_chunks_mut(stride.max(1)), |rows, at, pixels| {
            rows[at..at + pixels.len()].copy_from_slice(pixels);
        });
        (image, stats)
    }

    /// [`Renderer::render_tiles`] of pixels in two parts, laid into two images (the
    /// colours and the first hits of a guided frame: one copy, not a second pass to split
    /// them, which took 0.46 ms of a 256² frame).
    fn render_tiles_split<A, B>(
        &self,
        tile: impl Fn(u32, u32) -> (Vec<(A, B)>, u64) + Sync,
    ) -> (Vec<A>, Vec<B>, FrameStats)
    where
        A: Copy + Default + Send + Sync,
        B: Copy + Default + Send + Sync,
    {
        let (mut first, mut second) = (self.blank_image(), self.blank_image());
        let stride = (self.width as usize * TILE as usize).max(1);
        let tile_rows = first.par_chunks_mut(stride).zip(second.par_chunks_mut(stride));
        let stats = self.lay_tiles(tile, tile_rows, |(firsts, seconds), at, pixels| {
            let run = at..at + pixels.len();
            for ((a, b), &(left, right)) in firsts[run.clone()].iter_mut().zip(&mut seconds[run]).zip(pixels) {
                (*a, *b) = (left, right);
            }
        });
        (first, second, stats)
    }

    /// An image of default pixels (or none, for an empty image), made in parallel.
    fn blank_image<T: Default + Send>(&self) -> Vec<T> {
        (0..self.width as usize * self.height as usize).into_par_iter().map(|_| T::default()).collect()
    }

    /// Traces the tiles (`tile(x0, y0)`: a tile's pixels in its row-major order and its
    /// rays) as rayon tasks and lays each into `tile_rows`, the image's rows of tiles
    /// (`TILE` rows of pixels each): `put(rows, at, pixels)` writes a run of a tile's pixels at
    /// index `at` of its row of tiles. A row of tiles per task: copied on one thread, the
    /// guided frame's 52-byte pixels took a tenth of the carousel's render.
    fn lay_tiles<T: Send + Sync, R: Send>(
        &self,
        tile: impl Fn(u32, u32) -> (Vec<T>, u64) + Sync,
        tile_rows: impl IndexedParallelIterator<Item = R>,
        put: impl Fn(&mut R, usize, &[T]) + Sync,
    ) -> FrameStats {
        if self.width == 0 || self.height == 0 {
            return FrameStats::default();
        }
        let tiles: Vec<(Vec<T>, u64)> = self.tiles().into_par_iter().map(|(x0, y0)| tile(x0, y0)).collect();
        let width = self.width as usize;
        let tiles_per_row = self.width.div_ceil(TILE) as usize;
        tile_rows.zip(tiles.par_chunks(tiles_per_row)).for_each(|(mut rows, row_tiles)| {
            for (k, (pixels, _)) in row_tiles.iter().enumerate() {
                let x0 = k * TILE as usize;
                let tile_w = (x0 + TILE as usize).min(width) - x0;
                for (r, tile_row) in pixels.chunks(tile_w).enumerate() {
                    put(&mut rows, r * width + x0, tile_row);
                }
            }
        });
        FrameStats { rays: tiles.iter().map(|(_, rays)| rays).sum() }
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
        let (ray, mut rng) = self.camera_sample(frame, pixel);
        shade(ray, &mut rng)
    }

    /// The camera ray of sample `frame` of `pixel` (row-major index) and the random numbers
    /// of its path: they depend on (seed, frame, pixel) alone.
    #[inline]
    fn camera_sample(&self, frame: u32, pixel: u32) -> (phr_bvh::Ray, Pcg32) {
        self.camera_sample_at(frame, pixel % self.width, pixel / self.width)
    }

    /// [`Renderer::camera_sample`] of the pixel in column `x` of row `y` (no division).
    #[inline]
    fn camera_sample_at(&self, frame: u32, x: u32, y: u32) -> (phr_bvh::Ray, Pcg32) {
        let pixel = y * self.width + x;
        let rng = Pcg32::for_pixel(self.seed, frame, pixel);
        let (jx, jy) = self.pixel_jitter(frame, pixel);
        (self.camera.ray(x as f32 + jx, y as f32 + jy), rng)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::builtin::cornell_knot;

    /// Every tile's pixels land where they belong, at sizes that cut the last row and column
    /// of tiles short, narrower and lower than one tile included.
    #[test]
    fn tiles_are_laid_where_they_belong() {
        let scene = cornell_knot();
        let geometry = Geometry::new(&scene);
        let view = scene.view(None).expect("a view");
        for (width, height) in [(1, 1), (5, 3), (17, 33), (40, 24), (33, 16), (16, 47)] {
            let settings = RenderSettings { width, height, spp: 1, max_depth: 1 };
            let renderer = Renderer::new(&scene, &geometry, &view, &settings, None);
            let (image, stats) = renderer.render_tiles(|x0, y0| {
                let (x1, y1) = ((x0 + TILE).min(width), (y0 + TILE).min(height));
                let pixels: Vec<(u32, u32)> = (y0..y1).flat_map(|y| (x0..x1).map(move |x| (x, y))).collect();
                let n = pixels.len() as u64;
                (pixels, n)
            });
            assert_eq!(stats.rays, u64::from(width * height), "{width} × {height}");
            for (i, &(x, y)) in image.iter().enumerate() {
                assert_eq!((x, y), (i as u32 % width, i as u32 / width), "{width} × {height}, pixel {i}");
            }
            // The same, split: each pixel's coordinates into one image, swapped into the other.
            let (first, second, stats) = renderer.render_tiles_split(|x0, y0| {
                let (x1, y1) = ((x0 + TILE).min(width), (y0 + TILE).min(height));
                let pixels: Vec<((u32, u32), (u32, u32))> =
                    (y0..y1).flat_map(|y| (x0..x1).map(move |x| ((x, y), (y, x)))).collect();
                let n = pixels.len() as u64;
                (pixels, n)
            });
            assert_eq!(stats.rays, u64::from(width * height), "{width} × {height}, split");
            for (i, (&a, &b)) in first.iter().zip(&second).enumerate() {
                let (x, y) = (i as u32 % width, i as u32 / width);
                assert_eq!((a, b), ((x, y), (y, x)), "{width} × {height}, split, pixel {i}");
            }
        }
    }
}
