//! Denoising guided by the camera's first hits ([`Guide`]).
//!
//! The filters smooth the **illumination**, the colour divided by the first surface's albedo,
//! and multiply the albedo back afterwards, so surface detail (albedo edges) stays sharp
//! whatever they do. Pixels that see no surface (the sky) or a light are left as they are
//! and never mix with surfaces.
//! - [`Atrous`]: the spatial filter, for an accumulated image whose variance is known (a
//!   finished render, a still view);
//! - [`Temporal`]: SVGF's temporal accumulation in front of it, for one sample per pixel per
//!   frame while the view moves.

mod atrous;
mod temporal;

pub use atrous::Atrous;
pub use temporal::Temporal;

use crate::geometry::{Hit, SurfacePoint};
use crate::render::Renderer;
use crate::sampler::Pcg32;
use glam::Vec3;
use rayon::prelude::*;

/// Jittered first hits per pixel for the guide of a finished render (`phr render`, Python),
/// or its spp if lower: enough to anti-alias the albedo as the colour is.
pub const GUIDE_SAMPLES: u32 = 16;

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
        let pixels: Vec<(Vec3, Vec3, Vec3, f32)> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let mut rng = Pcg32::for_pixel(renderer.seed ^ 0x6a09_e667, 0, i);
                // The centre's hit guides the filter; it and jittered ones average the albedo.
                let centre = camera.ray(x + 0.5, y + 0.5);
                let centre_surface =
                    geometry.intersect(&centre).map(|hit| (geometry.surface_point(&centre, &hit), hit));
                let mut sees_light = false;
                let mut albedo_of = |first: Option<&(SurfacePoint, Hit)>| match first {
                    Some((surface, hit)) => {
                        sees_light |= tracer.materials[surface.material as usize].is_emissive();
                        tracer.albedo_at(surface, hit)
                    }
                    None => Vec3::ONE,
                };
                let mut albedo = albedo_of(centre_surface.as_ref());
                for _ in 1..samples.max(1) {
                    let ray = camera.ray(x + rng.next_f32(), y + rng.next_f32());
                    let first = geometry.intersect(&ray).map(|hit| (geometry.surface_point(&ray, &hit), hit));
                    albedo += albedo_of(first.as_ref());
                }
                let albedo = albedo / samples.max(1) as f32;
                match centre_surface {
                    // A light's pixels, its edges included, are exact but for their coverage
                    // noise, and far brighter than what surrounds them: never filtered.
                    _ if sees_light => (albedo, Vec3::ZERO, Vec3::ZERO, 0.0),
                    Some((surface, _)) => {
                        let normal = if surface.front { surface.normal } else { -surface.normal };
                        let beside = camera.ray(x + 1.5, y + 0.5).dir;
                        let footprint = (surface.position - centre.origin).length() * (beside - centre.dir).length();
                        (albedo, normal, surface.position, footprint)
                    }
                    None => (albedo, Vec3::ZERO, Vec3::ZERO, 0.0),
                }
            })
            .collect();
        Guide {
            width: w,
            height: h,
            albedo: pixels.iter().map(|p| p.0).collect(),
            normal: pixels.iter().map(|p| p.1).collect(),
            position: pixels.iter().map(|p| p.2).collect(),
            footprint: pixels.iter().map(|p| p.3).collect(),
        }
    }
}
