//! The path tracer of the thesis (section 3) and of RTIOW: pure BSDF sampling, implicit light
//! sources only (a path collects an emitter's radiance when it hits it, and the sky's when it
//! escapes), no Russian roulette, at most `max_depth` ray segments per path.
//!
//! It is exactly the estimator of the Mitsuba references in `shared/reference`, so renders can
//! be checked against them with `compare_images.py --test-spp N`.
//!
//! With a [`LightSet`] (`lights: Some`), diffuse hits also sample the emissive triangles
//! directly (next-event estimation, see [`crate::lights`]): the same expected image, far less
//! noise from small lights.

use crate::geometry::Geometry;
use crate::geometry::SurfacePoint;
use crate::lights::LightSet;
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
    /// Explicit light sampling at diffuse hits (`None`: implicit lights only, the thesis's).
    pub lights: Option<&'a LightSet>,
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
        let lights = self.lights.filter(|l| !l.is_empty());
        // The last bounce was diffuse and sampled the lights: their emission is counted.
        let mut sampled_lights = false;
        for segment in 0..self.max_depth {
            rays += 1;
            let Some(hit) = self.geometry.intersect(&ray) else {
                radiance += throughput * self.background.radiance(ray.dir.normalize());
                break;
            };
            let surface = self.geometry.surface_point(&ray, &hit);
            let material = &self.materials[surface.material as usize];
            if !(sampled_lights && lights.is_some_and(|l| l.contains(hit.prim))) {
                radiance += throughput * material.emitted(surface.front);
            }
            sampled_lights = false;
            if let (Some(lights), Material::Lambertian { albedo }) = (lights, material) {
                // A light seen from here would arrive on segment + 1: only within max_depth.
                if segment + 1 < self.max_depth {
                    let (direct, shadow_rays) = self.direct_light(lights, &surface, *albedo, rng);
                    radiance += throughput * direct;
                    rays += shadow_rays;
                    sampled_lights = true;
                }
            }
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

    /// One light sample's direct light at a Lambertian surface with `albedo`: the BRDF
    /// `albedo / π`, both cosines, the squared distance and the area density. Returns the
    /// radiance and the shadow rays traced.
    fn direct_light(&self, lights: &LightSet, surface: &SurfacePoint, albedo: Vec3, rng: &mut Pcg32) -> (Vec3, u32) {
        let Some(light) = lights.sample(self.geometry, rng) else { return (Vec3::ZERO, 0) };
        // The side of the surface the path arrived on.
        let n = if surface.front { surface.normal } else { -surface.normal };
        let to_light = light.point - surface.position;
        let distance2 = to_light.length_squared();
        if distance2 <= 0.0 || !distance2.is_finite() {
            return (Vec3::ZERO, 0);
        }
        let distance = distance2.sqrt();
        let wi = to_light / distance;
        let cos_surface = n.dot(wi);
        let cos_light = -light.normal.dot(wi);
        if cos_surface <= 0.0 {
            return (Vec3::ZERO, 0);
        }
        let emitted = self.materials[light.material as usize].emitted(cos_light > 0.0);
        if emitted == Vec3::ZERO {
            return (Vec3::ZERO, 0);
        }
        let origin = surface.spawn_origin(wi);
        // Stop short of the light itself (by a relative margin well above float error).
        let shadow = Ray::with_interval(origin, light.point - origin, 0.0, 1.0 - 1e-4);
        if self.geometry.occluded(&shadow) {
            return (Vec3::ZERO, 1);
        }
        let brdf = albedo * std::f32::consts::FRAC_1_PI;
        let geometry_term = cos_surface * cos_light.abs() / distance2;
        (brdf * emitted * (geometry_term / light.pdf_area), 1)
    }
}
