//! Denoising guided by the camera's first hits ([`Guide`]).
//!
//! The filters smooth the **illumination**, the colour divided by the first surface's albedo,
//! and multiply the albedo back afterwards, so surface detail (albedo edges) stays sharp
//! whatever they do. Pixels that see no surface (the sky) or a light are left as they are
//! and never mix with surfaces.
//! - [`Atrous`]: the spatial filter, for an accumulated image whose variance is known (a
//!   finished render, a still view);
//! - [`Temporal`]: SVGF's temporal accumulation in front of it, for one sample per pixel per
//!   frame while the view moves;
//! - [`oidn`]: Intel Open Image Denoise, behind the cargo feature `oidn`.

mod atrous;
mod lanes;
pub mod oidn;
mod temporal;

pub use atrous::Atrous;
pub use temporal::Temporal;

use crate::camera::Camera;
use crate::film::{luminance, Film};
use crate::integrator::FirstHit;
use crate::render::Renderer;
use crate::sampler::Pcg32;
use glam::Vec3;
use rayon::prelude::*;

/// Jittered first hits per pixel for the guide of a finished render (`phr render`, Python),
/// or its spp if lower: enough to anti-alias the albedo as the colour is.
pub const GUIDE_SAMPLES: u32 = 16;

/// The filters of an accumulated image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Filter {
    Atrous,
    /// Intel Open Image Denoise ([`oidn`]; an error in builds without the feature).
    Oidn,
}

impl Filter {
    /// `film`'s mean, filtered with the guide of its view.
    pub fn apply(self, film: &Film, guide: &Guide) -> Result<Vec<Vec3>, String> {
        match self {
            Filter::Atrous => Ok(Atrous::default().denoise(&film.mean(), &film.variance_of_mean(), guide)),
            Filter::Oidn => oidn::denoise(&film.mean(), guide),
        }
    }

    /// A finished render from `renderer` (its film of `film.samples` frames), filtered: the
    /// guide is traced with [`GUIDE_SAMPLES`] rays per pixel (or the film's samples, if
    /// fewer), and the pixels it leaves alone that are still noisy are sampled again
    /// ([`refine_unfiltered`]).
    pub fn finish(self, renderer: &Renderer, film: &Film) -> Result<Finished, String> {
        let guide = Guide::render(renderer, film.samples.min(GUIDE_SAMPLES));
        let mut image = self.apply(film, &guide)?;
        let refined = refine_unfiltered(renderer, film, &guide);
        for &(pixel, colour) in &refined.pixels {
            image[pixel as usize] = colour;
        }
        Ok(Finished { image, guide, refined_pixels: refined.pixels.len(), extra_samples: refined.samples })
    }
}

/// What [`Filter::finish`] made.
pub struct Finished {
    pub image: Vec<Vec3>,
    pub guide: Guide,
    /// Pixels sampled again, and the samples each got.
    pub refined_pixels: usize,
    pub extra_samples: u32,
}

/// The pixels [`refine_unfiltered`] sampled again (row-major index, new value), and how many
/// samples each got.
pub struct Refined {
    pub pixels: Vec<(u32, Vec3)>,
    pub samples: u32,
}

/// A finished render's pixels that the filters leave alone (a light or the sky seen
/// directly: [`Guide::footprint`] 0) are exact but for their coverage noise, which is large
/// at a lamp's edge: on `cornell_obj` at 16 spp, 89 % of the denoised image's squared error
/// lay within two pixels of the lamp, and a border row whose 16 samples all fell on the lamp
/// read 11.0 against a true 10.0, with zero variance. Those of them that are noisy (standard
/// error above [`NOISY_UNFILTERED`] of their luminance) or at an edge (a neighbour twice as
/// bright, or half) get [`UNFILTERED_EXTRA`] times the film's samples, within
/// [`UNFILTERED_BUDGET`] of the film's work: the frames after the film's, so their positions
/// in the pixel continue its stratified sequence. The new value is the mean of these new
/// samples alone: they are independent of the film's samples that chose the pixel, so the
/// choice biases nothing.
pub fn refine_unfiltered(renderer: &Renderer, film: &Film, guide: &Guide) -> Refined {
    let (pixels, samples) = unfiltered_to_refine(film, &film.mean(), guide);
    if pixels.is_empty() || samples == 0 {
        return Refined { pixels: Vec::new(), samples: 0 };
    }
    let spp = film.samples;
    let means = renderer.pixel_means(&pixels, spp..spp.saturating_add(samples));
    Refined { pixels: pixels.into_iter().zip(means).collect(), samples }
}

/// The pixels [`refine_unfiltered`] samples again (row-major indices), and how many samples
/// each gets.
pub fn unfiltered_to_refine(film: &Film, mean: &[Vec3], guide: &Guide) -> (Vec<u32>, u32) {
    let variance = film.variance_of_mean();
    let (w, h) = (guide.width as usize, guide.height as usize);
    let lum: Vec<f32> = mean.iter().map(|&c| luminance(c)).collect();
    let edge_with = |i: usize, j: usize| (lum[i] - lum[j]).abs() > 0.5 * lum[i].max(lum[j]).max(1e-3);
    let pixels: Vec<u32> = (0..mean.len())
        .filter(|&i| {
            let (x, y) = (i % w, i / w);
            let noisy = luminance(variance[i]).sqrt() > NOISY_UNFILTERED * lum[i].max(1e-3);
            let edge = (x > 0 && edge_with(i, i - 1))
                || (x + 1 < w && edge_with(i, i + 1))
                || (y > 0 && edge_with(i, i - w))
                || (y + 1 < h && edge_with(i, i + w));
            guide.footprint[i] == 0.0 && (noisy || edge)
        })
        .map(|i| i as u32)
        .collect();
    let affordable = UNFILTERED_BUDGET * mean.len() as f64 / pixels.len().max(1) as f64;
    let samples = (f64::from(UNFILTERED_EXTRA).min(affordable) * f64::from(film.samples)).min(f64::from(u32::MAX / 2));
    (pixels, samples as u32)
}

/// How many times the film's samples a refined pixel gets ([`refine_unfiltered`]).
pub const UNFILTERED_EXTRA: u32 = 15;
/// The extra samples' cap, as a share of the film's samples over the whole image.
pub const UNFILTERED_BUDGET: f64 = 0.25;
/// A pixel is noisy when the standard error of its mean exceeds this share of its luminance.
pub const NOISY_UNFILTERED: f32 = 0.01;

/// The first surface each pixel sees: what the filter is guided by.
#[derive(Clone, Debug)]
pub struct Guide {
    pub width: u32,
    pub height: u32,
    /// [`crate::integrator::PathTracer::albedo_at`] the first hit, averaged over the pixel (white for the sky).
    pub albedo: Vec<Vec3>,
    /// Unit normal facing the camera at the pixel's centre (zero: no surface).
    pub normal: Vec<Vec3>,
    /// World position at the pixel's centre.
    pub position: Vec<Vec3>,
    /// Width of a pixel at that distance (0: no surface to filter: the sky, or a light seen
    /// by any of the pixel's rays).
    pub footprint: Vec<f32>,
}

impl Guide {
    /// The first hits of `renderer`'s camera: the albedo averaged over `samples` jittered
    /// rays per pixel (as the colour is), the normal and position of the pixel's centre.
    pub fn render(renderer: &Renderer, samples: u32) -> Guide {
        let (w, h) = (renderer.width, renderer.height);
        let geometry = renderer.tracer.geometry;
        let tracer = &renderer.tracer;
        let camera = &renderer.camera;
        Self::from_fn(w, h, |i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let mut rng = Pcg32::for_pixel(renderer.seed ^ 0x6a09_e667, 0, i);
            // The centre's hit guides the filter; it and jittered ones average the albedo.
            let first_hit = |ray: &phr_bvh::Ray| {
                let hit = geometry.intersect(ray);
                hit.map_or(FirstHit::SKY, |hit| tracer.first_hit(&geometry.surface_point(ray, &hit), &hit))
            };
            let centre_ray = camera.ray(x + 0.5, y + 0.5);
            let mut centre = first_hit(&centre_ray);
            let mut albedo = centre.albedo;
            for _ in 1..samples.max(1) {
                let first = first_hit(&camera.ray(x + rng.next_f32(), y + rng.next_f32()));
                albedo += first.albedo;
                centre.light |= first.light;
            }
            centre.albedo = albedo / samples.max(1) as f32;
            guide_pixel(&centre_ray, camera.ray(x + 1.5, y + 0.5).dir, &centre)
        })
    }

    /// The guide of one sample per pixel: each pixel's own camera ray's first hit (as
    /// [`crate::render::Renderer::render_frame_guided`] returns them, row-major), in the
    /// memory of `old` if given (a moving view makes one guide a frame: 2.6 MB at 256², which
    /// zeroing took 0.25 ms of on one thread).
    pub fn from_first_hits_reusing(
        old: Option<Guide>,
        camera: &Camera,
        width: u32,
        height: u32,
        hits: &[FirstHit],
    ) -> Guide {
        assert_eq!(hits.len(), (width * height) as usize, "one first hit per pixel");
        Self::from_rows_reusing(old, width, height, |y, mut row| {
            let hits = &hits[y as usize * width as usize..][..width as usize];
            // The ray beside a pixel's centre is the next pixel's centre ray: each is made once.
            let mut beside = camera.ray(0.5, y as f32 + 0.5);
            for (x, hit) in hits.iter().enumerate() {
                let centre = beside;
                beside = camera.ray(x as f32 + 1.5, y as f32 + 0.5);
                row.set(x, guide_pixel(&centre, beside.dir, hit));
            }
        })
    }

    /// The guide whose pixel `i` has the albedo, normal, position and footprint `pixel(i)`;
    /// rows in parallel.
    fn from_fn(width: u32, height: u32, pixel: impl Fn(u32) -> GuidePixel + Sync) -> Guide {
        Self::from_rows_reusing(None, width, height, |y, mut row| {
            for x in 0..width {
                row.set(x as usize, pixel(y * width + x));
            }
        })
    }

    /// The guide whose row `y` `row(y, its pixels)` writes (every pixel of it), rows in
    /// parallel, in the memory of `old` if given.
    fn from_rows_reusing(old: Option<Guide>, width: u32, height: u32, row: impl Fn(u32, GuideRow) + Sync) -> Guide {
        let n = (width * height) as usize;
        let mut guide = old.unwrap_or(Guide {
            width,
            height,
            albedo: Vec::new(),
            normal: Vec::new(),
            position: Vec::new(),
            footprint: Vec::new(),
        });
        (guide.width, guide.height) = (width, height);
        guide.albedo.resize(n, Vec3::ZERO);
        guide.normal.resize(n, Vec3::ZERO);
        guide.position.resize(n, Vec3::ZERO);
        guide.footprint.resize(n, 0.0);
        let w = (width as usize).max(1);
        let rows = (
            guide.albedo.par_chunks_mut(w),
            guide.normal.par_chunks_mut(w),
            guide.position.par_chunks_mut(w),
            guide.footprint.par_chunks_mut(w),
        );
        rows.into_par_iter().enumerate().for_each(|(y, (albedo, normal, position, footprint))| {
            row(y as u32, GuideRow { albedo, normal, position, footprint });
        });
        guide
    }
}

/// A pixel of a [`Guide`]: its albedo, normal, position and footprint.
type GuidePixel = (Vec3, Vec3, Vec3, f32);

/// A row of a [`Guide`] being made.
struct GuideRow<'a> {
    albedo: &'a mut [Vec3],
    normal: &'a mut [Vec3],
    position: &'a mut [Vec3],
    footprint: &'a mut [f32],
}

impl GuideRow<'_> {
    fn set(&mut self, x: usize, (albedo, normal, position, footprint): GuidePixel) {
        (self.albedo[x], self.normal[x], self.position[x], self.footprint[x]) = (albedo, normal, position, footprint);
    }
}

/// A pixel's albedo, normal, position and footprint (the width of a pixel at the hit's
/// distance) from its first hit, the camera ray through its centre and the direction of
/// the ray one pixel to the right.
fn guide_pixel(centre: &phr_bvh::Ray, beside: Vec3, hit: &FirstHit) -> GuidePixel {
    if hit.light || hit.normal == Vec3::ZERO {
        // A light's pixels, its edges included, are exact but for their coverage noise, and
        // far brighter than what surrounds them: never filtered; nor is the sky.
        return (hit.albedo, Vec3::ZERO, Vec3::ZERO, 0.0);
    }
    let footprint = (hit.position - centre.origin).length() * (beside - centre.dir).length();
    (hit.albedo, hit.normal, hit.position, footprint)
}
