//! Explicit light sampling (next-event estimation), beyond the thesis's implicit lights.
//!
//! A [`LightSet`] holds every emitter of a scene: the emissive triangles, the emissive spheres
//! and the sky (the background, when it is not black). At a diffuse hit the path tracer asks it
//! for one direction towards a light ([`LightSet::sample`]) and traces a shadow ray; the same
//! light may also be reached by the path's own next bounce. Multiple importance sampling
//! weighs the two ways, so each needs the other's density: [`LightSet::pdf_hit`] and
//! [`LightSet::pdf_sky`] give the density with which `sample` would have chosen a direction
//! the path took. All densities are with respect to solid angle at the shading point.
//!
//! How each emitter is sampled:
//! - the sky, with probability [`SKY_SHARE`] when there are other lights too (1 when it is the
//!   only one): a cosine-weighted direction around the surface's normal, which is exact for a
//!   constant sky over a diffuse surface; an environment map by its own luminance
//!   distribution ([`crate::environment`]), which finds a small bright sun;
//! - the other emitters are chosen in proportion to their power (area × brightest emission
//!   channel): a triangle by a uniform point on it (Shirley's square-root warp), a sphere by a
//!   uniform direction in the cone it subtends (pbrt's method, exact for any distance).
//!
//! Spheres in moved parts are placed by their instance; the radius follows the transform's
//! scale (exact for rotations, translations and uniform scales, which is what rigid motion
//! gives).

use crate::geometry::Geometry;
use crate::material::Material;
use crate::sampler::Pcg32;
use crate::scene::Background;
use glam::Vec3;
use phr_bvh::sphere::Sphere;
use std::f32::consts::{FRAC_1_PI, TAU};

/// The sky's share of the light samples when the scene has other emitters as well.
pub const SKY_SHARE: f32 = 0.5;

/// Every emitter of a scene and how to pick one.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    /// Primitive indices of the emissive triangles and spheres, ascending (triangles first,
    /// as in [`Geometry`]'s primitive numbering).
    prims: Vec<u32>,
    /// Each emitter's area and emission, refreshed with the selection weights.
    emitters: Vec<Emitter>,
    /// Cumulative selection weights over `prims` (the last is the total); empty when none
    /// of them can be picked.
    cdf: Vec<f32>,
    /// The background, when it emits anything.
    sky: Option<Background>,
    /// Probability of sampling the sky rather than one of `prims`.
    sky_probability: f32,
}

#[derive(Clone, Debug)]
struct Emitter {
    area: f32,
    /// Its material ([`Material::emitted`] says what it sends to each side).
    material: Material,
}

/// A direction towards a light, chosen from a shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point.
    pub dir: Vec3,
    /// The point on the light (`None` for the sky, which lies at infinity).
    pub point: Option<Vec3>,
    /// Radiance the light sends back along `-dir` (zero from the back of a one-sided light).
    pub radiance: Vec3,
    /// Density of `dir` with respect to solid angle, the light's selection included.
    pub pdf: f32,
    /// The sampled primitive ([`SKY`] for the sky).
    pub prim: u32,
}

/// [`LightSample::prim`] of a sky sample.
pub const SKY: u32 = u32::MAX;

/// The cone a sphere subtends from `from`: `1 − cos θmax`, computed without cancellation
/// for far spheres; `None` from inside the sphere or on it.
fn cone(sphere: &Sphere, from: Vec3) -> Option<f32> {
    let r = sphere.radius.abs();
    let dist2 = (sphere.center - from).length_squared();
    let sin2 = r * r / dist2;
    if sin2.is_nan() || sin2 >= 1.0 {
        return None;
    }
    let one_minus_cos = sin2 / (1.0 + (1.0 - sin2).sqrt());
    (one_minus_cos > 0.0).then_some(one_minus_cos)
}

impl LightSet {
    /// The emitters of `geometry` with `materials`, and `background` if it is not black.
    pub fn new(geometry: &Geometry, materials: &[Material], background: &Background) -> Self {
        let n_tris = geometry.triangle_count();
        let emits = |m: u32| materials[m as usize].emitted(true).max_element() > 0.0;
        let triangles = (0..n_tris).filter(|&i| emits(geometry.triangle_material[i]));
        let spheres = (0..geometry.spheres.len()).filter(|&i| emits(geometry.spheres[i].material));
        let prims = triangles.chain(spheres.map(|i| n_tris + i)).map(|p| p as u32).collect();
        let sky = (background.max_radiance() > 0.0).then(|| background.clone());
        let mut set = Self { prims, sky, ..Self::default() };
        set.refresh(geometry, materials);
        set
    }

    /// Recomputes the emitters' areas and selection weights after they moved (animated lights
    /// change area when they deform or scale).
    pub fn refresh(&mut self, geometry: &Geometry, materials: &[Material]) {
        self.cdf.clear();
        self.emitters.clear();
        let n_tris = geometry.triangle_count();
        let mut total = 0.0f32;
        for &p in &self.prims {
            let p = p as usize;
            let (area, material) = if p < n_tris {
                let [_, e1, e2] = geometry.world_triangle_edges(p);
                (0.5 * e1.cross(e2).length(), geometry.triangle_material[p])
            } else {
                let r = geometry.world_sphere(p - n_tris).radius;
                (2.0 * TAU * r * r, geometry.spheres[p - n_tris].material)
            };
            let material = materials[material as usize].clone();
            let power = area * material.emitted(true).max_element();
            // Degenerate lights get no weight (and so are never picked).
            total += if power.is_finite() && area > 0.0 { power.max(0.0) } else { 0.0 };
            self.emitters.push(Emitter { area, material });
            self.cdf.push(total);
        }
        if !(total > 0.0 && total.is_finite()) {
            self.cdf.clear();
        }
        self.sky_probability = match (&self.sky, self.cdf.is_empty()) {
            (None, _) => 0.0,
            (Some(_), true) => 1.0,
            (Some(_), false) => SKY_SHARE,
        };
    }

    /// No light can be sampled.
    pub fn is_empty(&self) -> bool {
        self.cdf.is_empty() && self.sky.is_none()
    }

    /// Number of emitting primitives (the sky not counted).
    pub fn len(&self) -> usize {
        self.prims.len()
    }

    /// The sky is one of the lights.
    pub fn has_sky(&self) -> bool {
        self.sky.is_some()
    }

    /// Each emitting primitive with its area and the probability [`LightSet::sample`] picks
    /// it, in the order of [`LightSet::cdf`]: what a tracer elsewhere (the GPU's) needs to
    /// sample the same way.
    pub fn emitters(&self) -> impl Iterator<Item = (u32, f32, f32)> + '_ {
        self.prims.iter().zip(&self.emitters).enumerate().map(|(k, (&p, e))| (p, e.area, self.selection(k)))
    }

    /// The cumulative selection weights [`LightSet::sample`] searches (empty: no emitter
    /// can be picked).
    pub fn cdf(&self) -> &[f32] {
        &self.cdf
    }

    /// Probability of sampling the sky rather than an emitter.
    pub fn sky_probability(&self) -> f32 {
        self.sky_probability
    }

    /// Whether primitive `prim` is a light that can be picked.
    pub fn contains(&self, prim: u32) -> bool {
        self.emitter(prim).is_some_and(|k| self.selection(k) > 0.0)
    }

    /// The index of primitive `prim` among the emitters.
    fn emitter(&self, prim: u32) -> Option<usize> {
        self.prims.binary_search(&prim).ok()
    }

    /// Probability of picking emitter `k`.
    fn selection(&self, k: usize) -> f32 {
        let Some(&total) = self.cdf.last() else { return 0.0 };
        let weight = self.cdf[k] - if k > 0 { self.cdf[k - 1] } else { 0.0 };
        (1.0 - self.sky_probability) * weight / total
    }

    /// Picks a light and a direction towards it from `position`, whose unit normal on the
    /// side the path is on is `facing`.
    pub fn sample(&self, geometry: &Geometry, position: Vec3, facing: Vec3, rng: &mut Pcg32) -> Option<LightSample> {
        let pick = rng.next_f32();
        if pick < self.sky_probability {
            return self.sample_sky(facing, rng);
        }
        let total = *self.cdf.last()?;
        // Reuse the pick's remainder for the emitter: one uniform number chooses both.
        let x = (pick - self.sky_probability) / (1.0 - self.sky_probability) * total;
        let k = self.cdf.partition_point(|&c| c <= x).min(self.cdf.len() - 1);
        let selection = self.selection(k);
        if selection.is_nan() || selection <= 0.0 {
            return None;
        }
        let prim = self.prims[k];
        let emitter = &self.emitters[k];
        let n_tris = geometry.triangle_count();
        let (u1, u2) = (rng.next_f32(), rng.next_f32());
        let sample = if (prim as usize) < n_tris {
            let [v0, e1, e2] = geometry.world_triangle_edges(prim as usize);
            // Shirley's warp, `(1 - s) v0 + s (1 - u2) v1 + s u2 v2` written with the edges.
            let s = u1.sqrt();
            let point = v0 + e1 * (s * (1.0 - u2)) + e2 * (s * u2);
            let to_light = point - position;
            let dist2 = to_light.length_squared();
            let dir = to_light / dist2.sqrt();
            let cos_light = -e1.cross(e2).normalize().dot(dir);
            let pdf = selection / emitter.area * dist2 / cos_light.abs();
            LightSample { dir, point: Some(point), radiance: emitter.material.emitted(cos_light > 0.0), pdf, prim }
        } else {
            let sphere = geometry.world_sphere(prim as usize - n_tris);
            let one_minus_cos_max = cone(&sphere, position)?;
            // A uniform direction in the cone: 1 − cos θ uniform in [0, 1 − cos θmax].
            let one_minus_cos = u1 * one_minus_cos_max;
            let cos = 1.0 - one_minus_cos;
            let sin = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
            let axis = sphere.center - position;
            let dist = axis.length();
            let axis = axis / dist;
            // Duff et al. 2017's basis ("Building an Orthonormal Basis, Revisited").
            let (x, y) = axis.any_orthonormal_pair();
            let (sp, cp) = (TAU * u2).sin_cos();
            let dir = (x * (sin * cp) + y * (sin * sp) + axis * cos).normalize();
            // The nearest point of the sphere along `dir` (clamped at the silhouette).
            let r = sphere.radius.abs();
            let t = dist * cos - (r * r - dist * dist * sin * sin).max(0.0).sqrt();
            let point = position + dir * t;
            let front = dir.dot(sphere.normal(point)) < 0.0;
            let pdf = selection / (TAU * one_minus_cos_max);
            LightSample { dir, point: Some(point), radiance: emitter.material.emitted(front), pdf, prim }
        };
        (sample.pdf > 0.0 && sample.pdf.is_finite() && sample.dir.is_finite()).then_some(sample)
    }

    /// A direction towards the sky: by an environment map's distribution, else
    /// cosine-weighted around `facing`.
    fn sample_sky(&self, facing: Vec3, rng: &mut Pcg32) -> Option<LightSample> {
        let sky = self.sky.as_ref()?;
        if let Background::Environment(map) = sky {
            let (dir, pdf) = map.sample(rng.next_f32(), rng.next_f32())?;
            // Below the surface it lights nothing.
            return (facing.dot(dir) > 0.0).then(|| LightSample {
                dir,
                point: None,
                radiance: map.radiance(dir),
                pdf: self.sky_probability * pdf,
                prim: SKY,
            });
        }
        // RTIOW's construction: the normal plus a uniform unit vector is cosine-distributed.
        let d = facing + rng.unit_vector();
        let length = d.length();
        if length.is_nan() || length <= 1e-6 {
            return None;
        }
        let dir = d / length;
        let pdf = self.pdf_sky(facing, dir);
        (pdf > 0.0).then(|| LightSample { dir, point: None, radiance: sky.radiance(dir), pdf, prim: SKY })
    }

    /// Density with which [`LightSet::sample`] from `from` (normal `facing`) picks the
    /// unit direction `dir` that escapes to the sky.
    #[inline]
    pub fn pdf_sky(&self, facing: Vec3, dir: Vec3) -> f32 {
        match &self.sky {
            // `sample_sky` returns no direction below the surface.
            Some(Background::Environment(map)) if facing.dot(dir) > 0.0 => self.sky_probability * map.pdf(dir),
            Some(Background::Environment(_)) => 0.0,
            _ => self.sky_probability * facing.dot(dir).max(0.0) * FRAC_1_PI,
        }
    }

    /// Density with which [`LightSet::sample`] from `from` picks the direction towards
    /// `point` on primitive `prim`, whose unit geometric normal there is `normal` (0 if
    /// `prim` is not a light).
    pub fn pdf_hit(&self, geometry: &Geometry, prim: u32, from: Vec3, point: Vec3, normal: Vec3) -> f32 {
        let Some(k) = self.emitter(prim) else { return 0.0 };
        let selection = self.selection(k);
        let n_tris = geometry.triangle_count();
        if (prim as usize) < n_tris {
            let to_light = point - from;
            let dist2 = to_light.length_squared();
            let cos_light = normal.dot(to_light).abs() / dist2.sqrt();
            let pdf = selection / self.emitters[k].area * dist2 / cos_light;
            if pdf.is_finite() {
                pdf
            } else {
                0.0
            }
        } else {
            let sphere = geometry.world_sphere(prim as usize - n_tris);
            cone(&sphere, from).map_or(0.0, |one_minus_cos_max| selection / (TAU * one_minus_cos_max))
        }
    }
}

/// The power heuristic (β = 2) weight of a strategy with density `pdf` against one with
/// density `other` (Veach 1997).
#[inline]
pub fn power_heuristic(pdf: f32, other: f32) -> f32 {
    let (a, b) = (pdf * pdf, other * other);
    if a + b > 0.0 && (a + b).is_finite() {
        a / (a + b)
    } else if pdf.is_infinite() {
        1.0
    } else {
        0.0
    }
}
