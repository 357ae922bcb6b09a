//! The path tracer of the thesis (section 3) and of RTIOW: pure BSDF sampling, implicit light
//! sources only (a path collects an emitter's radiance when it hits it, and the sky's when it
//! escapes), no Russian roulette, at most `max_depth` ray segments per path.
//!
//! It is exactly the estimator of the Mitsuba references in `shared/reference`, so renders can
//! be checked against them with `compare_images.py --test-spp N`.

use crate::geometry::Geometry;
use crate::material::{Interaction, Material};
use crate::sampler::Pcg32;
use crate::scene::Background;
use glam::Vec3;
use phr_bvh::Ray;

pub struct PathTracer<'a> {
    pub geometry: &'a Geometry,
    pub materials: &'a [Material],
    pub background: &'a Background,
    /// Maximum number of segments per path, the camera ray included.
    pub max_depth: u32,
}

/// The radiance estimate of one path and the number of rays it traced.
#[derive(Clone, Copy, Debug)]
pub struct PathSample {
    pub radiance: Vec3,
    pub rays: u32,
}

impl PathTracer<'_> {
    /// Traces one path starting with `ray` (unit direction not required).
    pub fn trace(&self, mut ray: Ray, rng: &mut Pcg32) -> PathSample {
        let mut radiance = Vec3::ZERO;
        let mut throughput = Vec3::ONE;
        let mut rays = 0;
        for _segment in 0..self.max_depth {
            rays += 1;
            let Some(hit) = self.geometry.intersect(&ray) else {
                radiance += throughput * self.background.radiance(ray.dir.normalize());
                break;
            };
            let surface = self.geometry.surface_point(&ray, &hit);
            let material = &self.materials[surface.material as usize];
            radiance += throughput * material.emitted(surface.front);
            match material.scatter(ray.dir, surface.normal, surface.front, rng) {
                Interaction::Absorb => break,
                Interaction::Scatter { dir, weight } => {
                    throughput *= weight;
                    ray = Ray::new(surface.spawn_origin(dir), dir);
                }
            }
        }
        PathSample { radiance, rays }
    }
}
