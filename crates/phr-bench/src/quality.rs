//! Equal-time image quality: what each estimator makes of the same wall-clock budget,
//! measured as the RMSE against a converged reference (`phr bench-quality`).
//!
//! Ours renders 1-spp frames into a film, as the viewer and `phr render` do, until the
//! budget is spent; the denoised outputs reserve the time of what follows the last frame
//! (the guide, the extra samples of the unfiltered noisy pixels, the filter) and count it.
//! Mitsuba 3's `path` integrator (light sampling with MIS and Russian roulette,
//! `llvm_ad_rgb`) gets the number of samples its warm rate fits into the same budget
//! ([`crate::quality_bench`], [`crate::mitsuba`]). Each image is scored by [`rmse`] over all pixels and
//! channels, the RMSE of `compare_images.py`.

use anyhow::{bail, Context, Result};
use glam::Vec3;
use phr_render::denoise::{oidn, refine_unfiltered, unfiltered_to_refine, Filter, Guide, GUIDE_SAMPLES};
use phr_render::film::Film;
use phr_render::render::Renderer;
use std::path::Path;
use std::time::{Duration, Instant};

/// The ways of making an image that are compared.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// The thesis's estimator: light only from paths that hit an emitter or escape.
    Implicit,
    /// Light sampling with MIS and Russian roulette (`phr render --denoiser none`).
    Path,
    /// The same, denoised by the à-trous filter: `phr render`'s default output.
    PathAtrous,
    /// The same, denoised by Intel Open Image Denoise (`--denoiser oidn`, builds with it).
    PathOidn,
    /// Mitsuba 3's `path` integrator (NEE + MIS + Russian roulette), `llvm_ad_rgb`.
    MitsubaPath,
}

impl Method {
    /// Our outputs in this build (with OIDN when it has it).
    pub fn ours() -> Vec<Method> {
        let all = [Method::Implicit, Method::Path, Method::PathAtrous, Method::PathOidn];
        all.into_iter().filter(|&m| m != Method::PathOidn || oidn::AVAILABLE).collect()
    }

    /// The filter of a denoised output.
    pub fn filter(self) -> Option<Filter> {
        match self {
            Method::PathAtrous => Some(Filter::Atrous),
            Method::PathOidn => Some(Filter::Oidn),
            _ => None,
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            Method::Implicit => "ours, implicit (the thesis's)",
            Method::Path => "ours, path (NEE + MIS + RR)",
            Method::PathAtrous => "ours, path + à-trous",
            Method::PathOidn => "ours, path + OIDN",
            Method::MitsubaPath => "Mitsuba 3 path (llvm_ad_rgb)",
        }
    }

    /// A file-name word.
    pub fn slug(self) -> &'static str {
        match self {
            Method::Implicit => "implicit",
            Method::Path => "path",
            Method::PathAtrous => "path-atrous",
            Method::PathOidn => "path-oidn",
            Method::MitsubaPath => "mitsuba-path",
        }
    }
}

/// An image made within a budget.
#[derive(Clone, Debug)]
pub struct Rendered {
    pub spp: u32,
    /// Wall-clock ms: the frames, plus [`Filter::finish`] when denoised.
    pub ms: f64,
    pub image: Vec<Vec3>,
}

/// What a denoised output adds after the last frame ([`Filter::finish`]): the guide's
/// camera rays (up to [`GUIDE_SAMPLES`] per pixel, as many as there are frames), the extra
/// samples of the pixels the filter leaves noisy, and the filter. Measured once on
/// `renderer` (each time the faster of two runs: the first is cold); what [`render_within`]
/// reserves.
pub struct DenoiseCost {
    pub filter: Filter,
    pub filter_ms: f64,
    pub guide_ms_per_sample: f64,
    /// One extra sample of one refined pixel (they see lights or the sky: short paths).
    pub ms_per_extra_sample: f64,
    /// A 4-sample guide, which says which pixels the filter leaves alone.
    guide: Guide,
}

impl DenoiseCost {
    pub fn measure(renderer: &Renderer, filter: Filter) -> Result<Self, String> {
        let mut film = Film::new(renderer.width, renderer.height);
        for frame in 0..4 {
            film.add_frame(&renderer.render_frame(frame).0);
        }
        let time = |f: &dyn Fn() -> Result<(), String>| -> Result<f64, String> {
            let run = || {
                let start = Instant::now();
                f().map(|()| start.elapsed().as_secs_f64() * 1e3)
            };
            Ok(run()?.min(run()?))
        };
        let guide = Guide::render(renderer, 4);
        let filter_ms = time(&|| filter.apply(&film, &guide).map(drop))?;
        let guide_ms = time(&|| {
            let _ = Guide::render(renderer, GUIDE_SAMPLES);
            Ok(())
        })?;
        let (pixels, samples) = unfiltered_to_refine(&film, &film.mean(), &guide);
        let extra = (pixels.len() as f64 * f64::from(samples)).max(1.0);
        let refine_ms = time(&|| {
            let _ = refine_unfiltered(renderer, &film, &guide);
            Ok(())
        })?;
        let (guide_ms_per_sample, ms_per_extra_sample) = (guide_ms / f64::from(GUIDE_SAMPLES), refine_ms / extra);
        Ok(Self { filter, filter_ms, guide_ms_per_sample, ms_per_extra_sample, guide })
    }

    /// The ms after `film`'s last frame.
    pub fn ms(&self, film: &Film) -> f64 {
        let (pixels, samples) = unfiltered_to_refine(film, &film.mean(), &self.guide);
        let extra_ms = pixels.len() as f64 * f64::from(samples) * self.ms_per_extra_sample;
        self.filter_ms + self.guide_ms_per_sample * f64::from(film.samples.clamp(1, GUIDE_SAMPLES)) + extra_ms
    }
}

/// Renders 1-spp frames (frame `k` is sample `k`) until `budget` is spent, stopping where
/// the total lands closest to it (at least one frame). With `denoise`, the time its
/// [`Filter::finish`] takes after the last frame is part of the total (its estimate is
/// updated every 8 frames, as the pixels it samples again change with the film), and it
/// then runs.
pub fn render_within(renderer: &Renderer, budget: Duration, denoise: Option<&DenoiseCost>) -> Result<Rendered, String> {
    let budget_ms = budget.as_secs_f64() * 1e3;
    let mut film = Film::new(renderer.width, renderer.height);
    let start = Instant::now();
    let mut reserve_ms = 0.0;
    loop {
        film.add_frame(&renderer.render_frame(film.samples).0);
        if let Some(cost) = denoise.filter(|_| film.samples % 8 == 1) {
            reserve_ms = cost.ms(&film);
        }
        let elapsed = start.elapsed().as_secs_f64() * 1e3;
        // Totals if we stop now, and after one more frame (of the mean length so far): go on
        // while the second lands closer to the budget. (The reserve grows with the frames;
        // this frame's is close enough to the next one's.)
        let now = elapsed + reserve_ms;
        let next = now + elapsed / f64::from(film.samples);
        if 0.5 * (now + next) >= budget_ms {
            break;
        }
    }
    let spp = film.samples;
    let image = match denoise {
        Some(d) => d.filter.finish(renderer, &film)?.image,
        None => film.mean(),
    };
    Ok(Rendered { spp, ms: start.elapsed().as_secs_f64() * 1e3, image })
}

/// The RMSE of `test` against `reference` over all pixels and channels (as
/// `compare_images.py` computes it), in f64.
pub fn rmse(test: &[Vec3], reference: &[Vec3]) -> f64 {
    assert_eq!(test.len(), reference.len(), "images of different sizes");
    let sum: f64 = test
        .iter()
        .zip(reference)
        .map(|(t, r)| {
            let d = (*t - *r).as_dvec3();
            d.length_squared()
        })
        .sum();
    (sum / (3 * test.len().max(1)) as f64).sqrt()
}

/// Reads a linear image (OpenEXR, the references' format) as rows from the top: (width,
/// height, pixels).
pub fn read_linear_image(path: &Path) -> Result<(u32, u32, Vec<Vec3>)> {
    let image = image::open(path).with_context(|| format!("reading {}", path.display()))?.into_rgb32f();
    let (w, h) = image.dimensions();
    let pixels: Vec<Vec3> = image.pixels().map(|p| Vec3::from(p.0)).collect();
    if let Some(i) = pixels.iter().position(|p| !p.is_finite()) {
        bail!("{}: pixel ({}, {}) is not finite", path.display(), i as u32 % w, i as u32 / w);
    }
    Ok((w, h, pixels))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rmse_over_pixels_and_channels() {
        let r = vec![Vec3::ZERO; 2];
        assert_eq!(rmse(&r, &r), 0.0);
        // Squared errors 1, 4, 0 and 0, 0, 7: mean 2, RMSE √2.
        let t = vec![Vec3::new(1.0, -2.0, 0.0), Vec3::new(0.0, 0.0, 7.0f32.sqrt())];
        assert!((rmse(&t, &r) - 2f64.sqrt()).abs() < 1e-6);
    }
}
