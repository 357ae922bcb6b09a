//! The path tracer of the thesis (section 3) and of RTIOW: pure BSDF sampling, implicit light
//! sources only (a path collects an emitter's radiance when it hits it, and the sky's when it
//! escapes), no Russian roulette, at most `max_depth` ray segments per path.
//!
//! It is exactly the estimator of the Mitsuba references in `shared/reference`, so renders can
//! be checked against them with `compare_images.py --test-spp N`.
//!
//! With a [`LightSet`] (`lights: Some`) it becomes the path tracer of pbrt and Mitsuba's
//! `path` integrator: at every diffuse or fuzzy-metal hit one light (an emissive triangle or
//! sphere, or the sky) is sampled through a shadow ray, and the light a path's own bounce
//! reaches is weighed against it by multiple importance sampling (the power heuristic), so
//! neither small lights nor large ones are noisy; after [`RR_START`] segments Russian
//! roulette ends paths whose throughput has become small. The expected image is the same
//! (the reference checks run with both).

use crate::geometry::{Geometry, Hit, SurfacePoint};
use crate::lights::{power_heuristic, LightSet};
use crate::material::{Interaction, Material};
use crate::sampler::Pcg32;
use crate::scene::Background;
use crate::texture::Texture;
use glam::Vec3;
use phr_bvh::Ray;

/// Russian roulette starts after this many segments (the camera ray is the first).
pub const RR_START: u32 = 3;

pub struct PathTracer<'a> {
    pub geometry: &'a Geometry,
    pub materials: &'a [Material],
    /// The scene's textures, and each material's colour texture (see
    /// [`crate::scene::Scene::material_texture`]).
    pub textures: &'a [Texture],
    pub material_texture: &'a [Option<u32>],
    pub background: &'a Background,
    /// Maximum number of segments per path, the camera ray included.
    pub max_depth: u32,
    /// Light sampling with MIS and Russian roulette (`None`: implicit lights only, the
    /// thesis's estimator).
    pub lights: Option<&'a LightSet>,
}

/// The radiance estimate of one path and the number of rays it traced.
#[derive(Clone, Copy, Debug)]
pub struct PathSample {
    pub radiance: Vec3,
    pub rays: u32,
}

/// What a camera ray's first hit gives the denoiser's guide ([`crate::denoise::Guide`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FirstHit {
    /// [`PathTracer::albedo_at`] the hit (white where the ray leaves the scene).
    pub albedo: Vec3,
    /// Unit normal on the camera's side (zero: no surface).
    pub normal: Vec3,
    pub position: Vec3,
    /// The surface emits (a light).
    pub light: bool,
}

impl FirstHit {
    /// A ray that leaves the scene.
    pub const SKY: FirstHit = FirstHit { albedo: Vec3::ONE, normal: Vec3::ZERO, position: Vec3::ZERO, light: false };
}

impl Default for FirstHit {
    fn default() -> Self {
        Self::SKY
    }
}

/// A vertex whose lights were sampled (diffuse, fuzzy metal): what the next segment's MIS
/// weight needs.
#[derive(Clone, Copy)]
struct LitVertex {
    position: Vec3,
    /// The unit normal on the side the path left from.
    facing: Vec3,
    /// Density of the direction the path took, by BSDF sampling.
    pdf: f32,
}

/// A path being traced: the ray of its next segment and what it has gathered so far. The
/// single-ray loop ([`PathTracer::trace`]) and the renderer's wavefront (which intersects the
/// rays of many paths at once) both advance it one segment at a time through
/// [`PathTracer::advance`], so they compute the same estimate from the same random numbers.
#[derive(Clone, Copy)]
pub struct Path {
    /// The ray of the next segment (unit direction not required).
    pub ray: Ray,
    radiance: Vec3,
    throughput: Vec3,
    /// Segments traced so far.
    segment: u32,
    /// Rays traced so far (segments and shadow rays).
    rays: u32,
    /// The previous vertex, if it sampled the lights (`None`: the camera, or a mirror or
    /// glass, whose direction no light sample could have taken).
    lit: Option<LitVertex>,
    /// The light sample of the last segment, waiting for its shadow ray's answer.
    shadow: Option<Shadow>,
}

/// A light sample and what it adds to the path's radiance if nothing blocks its shadow ray.
#[derive(Clone, Copy)]
struct Shadow {
    ray: Ray,
    radiance: Vec3,
}

impl Path {
    /// A path whose first segment is `ray`.
    pub fn new(ray: Ray) -> Self {
        Self { ray, radiance: Vec3::ZERO, throughput: Vec3::ONE, segment: 0, rays: 0, lit: None, shadow: None }
    }

    /// The shadow ray of the light sample [`PathTracer::advance`] left waiting, if any (it
    /// leaves one at most, whether or not the path goes on).
    pub fn shadow_ray(&self) -> Option<Ray> {
        self.shadow.map(|s| s.ray)
    }

    /// Settles the waiting light sample with its shadow ray's answer: the light arrives
    /// unless `occluded`. Call it before the path's next [`PathTracer::advance`].
    pub fn settle_shadow(&mut self, occluded: bool) {
        if let Some(s) = self.shadow.take() {
            if !occluded {
                self.radiance += s.radiance;
            }
        }
    }

    /// What the path has gathered (its estimate once [`PathTracer::advance`] has said it
    /// ended).
    pub fn sample(&self) -> PathSample {
        PathSample { radiance: self.radiance, rays: self.rays }
    }
}

impl PathTracer<'_> {
    /// Traces one path starting with `ray` (unit direction not required).
    #[inline]
    pub fn trace(&self, ray: Ray, rng: &mut Pcg32) -> PathSample {
        let mut unused = FirstHit::SKY;
        self.trace_path::<false>(ray, rng, &mut unused)
    }

    /// [`PathTracer::trace`], also returning what the path's first hit gives the denoiser's
    /// guide: the guide then follows the very rays the colour came from, at no extra ray.
    pub fn trace_guided(&self, ray: Ray, rng: &mut Pcg32) -> (PathSample, FirstHit) {
        let mut first = FirstHit::SKY;
        let sample = self.trace_path::<true>(ray, rng, &mut first);
        (sample, first)
    }

    /// The single-ray loop: intersect, advance, until the path ends.
    #[inline(always)]
    fn trace_path<const GUIDE: bool>(&self, ray: Ray, rng: &mut Pcg32, first: &mut FirstHit) -> PathSample {
        let mut path = Path::new(ray);
        if !self.traces_anything() {
            return path.sample();
        }
        loop {
            let hit = self.geometry.intersect(&path.ray);
            let going = self.advance::<GUIDE>(&mut path, hit, rng, first);
            if let Some(shadow) = path.shadow_ray() {
                path.settle_shadow(self.geometry.occluded(&shadow));
            }
            if !going {
                break;
            }
        }
        path.sample()
    }

    /// Whether paths have any segment to trace (`max_depth > 0`): a path of none is black and
    /// traces no ray, and its first segment must not be traced.
    #[inline(always)]
    pub fn traces_anything(&self) -> bool {
        self.max_depth > 0
    }

    /// One segment of `path`: `hit` is the closest hit of `path.ray` (the caller traced it).
    /// Gathers what the segment brings and, if the path goes on, sets `path.ray` to the next
    /// segment's ray and returns true. With light sampling it may leave a light sample
    /// waiting for its shadow ray ([`Path::shadow_ray`]), which the caller traces and settles
    /// ([`Path::settle_shadow`]) before the next segment. `GUIDE`: record the first hit in
    /// `first`.
    #[inline(always)]
    pub fn advance<const GUIDE: bool>(
        &self,
        path: &mut Path,
        hit: Option<Hit>,
        rng: &mut Pcg32,
        first: &mut FirstHit,
    ) -> bool {
        match self.lights {
            Some(lights) => self.advance_with_lights::<GUIDE>(path, hit, lights, rng, first),
            None => self.advance_implicit::<GUIDE>(path, hit, rng, first),
        }
    }

    /// The guide's view of a camera ray's hit.
    pub fn first_hit(&self, surface: &SurfacePoint, hit: &Hit) -> FirstHit {
        FirstHit {
            albedo: self.albedo_at(surface, hit),
            normal: if surface.front { surface.normal } else { -surface.normal },
            position: surface.position,
            light: self.materials[surface.material as usize].is_emissive(),
        }
    }

    /// The thesis's estimator: BSDF sampling alone. `GUIDE`: record the first hit.
    #[inline(always)]
    fn advance_implicit<const GUIDE: bool>(
        &self,
        path: &mut Path,
        hit: Option<Hit>,
        rng: &mut Pcg32,
        first: &mut FirstHit,
    ) -> bool {
        path.rays += 1;
        let Some(hit) = hit else {
            path.radiance += path.throughput * self.background.radiance(path.ray.dir.normalize());
            return false;
        };
        let ray = path.ray;
        let surface = self.geometry.surface_point(&ray, &hit);
        if GUIDE && path.segment == 0 {
            *first = self.first_hit(&surface, &hit);
        }
        let material = &self.materials[surface.material as usize];
        path.radiance += path.throughput * material.emitted(surface.front);
        match material.scatter(ray.dir, surface.normal, surface.front, rng) {
            Interaction::Absorb => false,
            Interaction::Scatter { dir, weight } => {
                path.throughput *= self.textured(weight, &surface, &hit);
                path.ray = Ray::new(surface.spawn_origin(dir), dir);
                path.segment += 1;
                path.segment < self.max_depth
            }
        }
    }

    /// A Lambertian hit's scattering weight (its albedo, `weight`) times its material's
    /// texture at the hit, if it has one.
    #[inline]
    fn textured(&self, weight: Vec3, surface: &SurfacePoint, hit: &Hit) -> Vec3 {
        match self.material_texture.get(surface.material as usize) {
            Some(Some(t)) if matches!(self.materials[surface.material as usize], Material::Lambertian { .. }) => {
                weight * self.textures[*t as usize].sample(self.geometry.uv(hit))
            }
            _ => weight,
        }
    }

    /// [`Material::albedo`] at a hit, textured: the viewer's albedo mode and the denoiser's
    /// guide.
    pub fn albedo_at(&self, surface: &SurfacePoint, hit: &Hit) -> Vec3 {
        self.textured(self.materials[surface.material as usize].albedo(), surface, hit)
    }

    /// Light sampling at diffuse and fuzzy-metal hits, MIS with BSDF sampling, Russian
    /// roulette.
    #[inline(always)]
    fn advance_with_lights<const GUIDE: bool>(
        &self,
        path: &mut Path,
        hit: Option<Hit>,
        lights: &LightSet,
        rng: &mut Pcg32,
        first: &mut FirstHit,
    ) -> bool {
        path.rays += 1;
        let ray = path.ray;
        let Some(hit) = hit else {
            let dir = ray.dir.normalize();
            let weight = path.lit.map_or(1.0, |v| power_heuristic(v.pdf, lights.pdf_sky(v.facing, dir)));
            path.radiance += path.throughput * self.background.radiance(dir) * weight;
            return false;
        };
        let surface = self.geometry.surface_point(&ray, &hit);
        if GUIDE && path.segment == 0 {
            *first = self.first_hit(&surface, &hit);
        }
        let material = &self.materials[surface.material as usize];
        let emitted = material.emitted(surface.front);
        if emitted != Vec3::ZERO {
            let weight = path.lit.map_or(1.0, |v| {
                let light_pdf = lights.pdf_hit(self.geometry, hit.prim, v.position, surface.position, surface.normal);
                power_heuristic(v.pdf, light_pdf)
            });
            path.radiance += path.throughput * emitted * weight;
        }
        // Neither a light sample nor a bounce from here would arrive within max_depth.
        if path.segment + 1 >= self.max_depth {
            return false;
        }
        let facing = if surface.front { surface.normal } else { -surface.normal };
        // The scatter weight of a material with a lobe (diffuse, textured; fuzzy metal):
        // light samples are weighed against it.
        let lobe = match material {
            Material::Lambertian { albedo } => Some(self.textured(*albedo, &surface, &hit)),
            Material::Metal { albedo, .. } if material.has_lobe() => Some(*albedo),
            _ => None,
        };
        if let Some(albedo) = lobe {
            if let Some(light) = lights.sample(self.geometry, surface.position, facing, rng) {
                let lobe_pdf = material.lobe_pdf(ray.dir, surface.normal, surface.front, light.dir);
                if lobe_pdf > 0.0 && light.radiance != Vec3::ZERO {
                    path.rays += 1;
                    let origin = surface.spawn_origin(light.dir);
                    // To the light's point, stopping short of it by a relative margin well
                    // above float error; to the sky, without end.
                    let shadow = match light.point {
                        Some(p) => Ray::with_interval(origin, p - origin, 0.0, 1.0 - 1e-4),
                        None => Ray::new(origin, light.dir),
                    };
                    let weight = power_heuristic(light.pdf, lobe_pdf);
                    // BSDF × cosine = scatter weight × lobe density, over the light's.
                    let radiance = path.throughput * albedo * light.radiance * (lobe_pdf * weight / light.pdf);
                    path.shadow = Some(Shadow { ray: shadow, radiance });
                }
            }
        }
        match material.scatter(ray.dir, surface.normal, surface.front, rng) {
            Interaction::Absorb => return false,
            Interaction::Scatter { dir, weight } => {
                path.throughput *= lobe.unwrap_or(weight);
                path.lit = lobe.map(|_| {
                    let pdf = material.lobe_pdf(ray.dir, surface.normal, surface.front, dir.normalize());
                    LitVertex { position: surface.position, facing, pdf }
                });
                path.ray = Ray::new(surface.spawn_origin(dir), dir);
            }
        }
        path.segment += 1;
        if path.segment >= RR_START {
            let survive = path.throughput.max_element().min(1.0);
            if rng.next_f32() >= survive {
                return false;
            }
            path.throughput /= survive;
        }
        // The loop's own bound (the check above stops one segment earlier).
        path.segment < self.max_depth
    }
}
