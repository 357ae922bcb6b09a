//! The four materials of the thesis, which are those of *Ray Tracing in One Weekend*
//! (Shirley, v4): Lambertian, metal (mirror + fuzz), dielectric (Snell + Schlick), emissive.
//!
//! Each scatters with a weight ("attenuation") that multiplies the path throughput and
//! nothing else: the estimator is RTIOW's, the one the Mitsuba references in
//! `shared/reference` were rendered with, so the images can be compared statistically.

use crate::sampler::Pcg32;
use glam::Vec3;

#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    /// Cosine-weighted diffuse reflection; weight = albedo.
    Lambertian { albedo: Vec3 },
    /// Mirror reflection perturbed by `fuzz` (0 = perfect mirror, at most 1).
    /// `fuzz_in_sphere` picks RTIOW v3's perturbation (a point in the unit ball) instead of
    /// v4's (a point on the unit sphere).
    Metal { albedo: Vec3, fuzz: f32, fuzz_in_sphere: bool },
    /// Clear glass with index of refraction `ior` (below 1 for e.g. an air bubble in glass).
    Dielectric { ior: f32 },
    /// A light: adds `emit` to the path and ends it; one-sided unless `two_sided`.
    Emissive { emit: Vec3, two_sided: bool },
}

/// What a surface does to a path arriving along `dir`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Interaction {
    /// Continue in `dir` (not normalised) with the throughput multiplied by `weight`.
    Scatter { dir: Vec3, weight: Vec3 },
    /// The path ends here (absorbed, or an emitter).
    Absorb,
}

impl Material {
    /// Radiance emitted towards a ray that arrived on the `front` side (that the geometric
    /// normal points to).
    #[inline]
    pub fn emitted(&self, front: bool) -> Vec3 {
        match self {
            Material::Emissive { emit, two_sided } if front || *two_sided => *emit,
            _ => Vec3::ZERO,
        }
    }

    /// The colour a surface gives what it reflects (white for glass; for a light, its emission's
    /// hue at unit brightness): the viewer's albedo mode and the denoiser's albedo guide.
    pub fn albedo(&self) -> Vec3 {
        match self {
            Material::Lambertian { albedo } | Material::Metal { albedo, .. } => *albedo,
            Material::Dielectric { .. } => Vec3::ONE,
            Material::Emissive { emit, .. } => *emit / emit.max_element().max(1e-6),
        }
    }

    pub fn is_emissive(&self) -> bool {
        matches!(self, Material::Emissive { .. })
    }

    /// Samples the continuation of a path that hits the surface. `dir` is the incoming ray
    /// direction (any length), `normal` the unit geometric normal, `front` whether the ray
    /// arrived on the side `normal` points to.
    #[inline]
    pub fn scatter(&self, dir: Vec3, normal: Vec3, front: bool, rng: &mut Pcg32) -> Interaction {
        let facing = if front { normal } else { -normal };
        match self {
            Material::Lambertian { albedo } => {
                let d = facing + rng.unit_vector();
                // RTIOW: a sample that cancels the normal would give a zero direction.
                let d = if d.abs().max_element() < 1e-8 { facing } else { d };
                Interaction::Scatter { dir: d, weight: *albedo }
            }
            Material::Metal { albedo, fuzz, fuzz_in_sphere } => {
                let reflected = reflect(dir.normalize(), facing).normalize();
                let jitter = if *fuzz_in_sphere { rng.in_unit_sphere() } else { rng.unit_vector() };
                let d = reflected + fuzz.min(1.0) * jitter;
                if d.dot(facing) > 0.0 {
                    Interaction::Scatter { dir: d, weight: *albedo }
                } else {
                    Interaction::Absorb
                }
            }
            Material::Dielectric { ior } => {
                let unit = dir.normalize();
                let eta = if front { 1.0 / ior } else { *ior };
                let cos_theta = (-unit).dot(facing).min(1.0);
                let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
                let d = if eta * sin_theta > 1.0 || schlick(cos_theta, eta) > rng.next_f32() {
                    reflect(unit, facing)
                } else {
                    refract(unit, facing, eta, cos_theta)
                };
                Interaction::Scatter { dir: d, weight: Vec3::ONE }
            }
            Material::Emissive { .. } => Interaction::Absorb,
        }
    }
}

#[inline]
pub fn reflect(v: Vec3, n: Vec3) -> Vec3 {
    v - 2.0 * v.dot(n) * n
}

/// Snell's law for a unit `v` arriving against the unit normal `n`, with `eta = n_i / n_t`.
#[inline]
pub fn refract(v: Vec3, n: Vec3, eta: f32, cos_theta: f32) -> Vec3 {
    let perp = eta * (v + cos_theta * n);
    let parallel = -(1.0 - perp.length_squared()).abs().sqrt() * n;
    perp + parallel
}

/// Schlick's approximation of the Fresnel reflectance.
#[inline]
pub fn schlick(cos_theta: f32, eta: f32) -> f32 {
    let r0 = ((1.0 - eta) / (1.0 + eta)).powi(2);
    r0 + (1.0 - r0) * (1.0 - cos_theta).powi(5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lambertian_stays_above_the_surface() {
        let m = Material::Lambertian { albedo: Vec3::splat(0.5) };
        let mut rng = Pcg32::new(1, 1);
        for _ in 0..1000 {
            match m.scatter(Vec3::new(0.0, -1.0, 0.2), Vec3::Y, true, &mut rng) {
                Interaction::Scatter { dir, weight } => {
                    assert!(dir.y >= 0.0);
                    assert_eq!(weight, Vec3::splat(0.5));
                }
                Interaction::Absorb => panic!("lambertian never absorbs"),
            }
        }
        // From the back the facing normal flips.
        if let Interaction::Scatter { dir, .. } = m.scatter(Vec3::Y, Vec3::Y, false, &mut rng) {
            assert!(dir.y <= 0.0);
        }
    }

    #[test]
    fn mirror_reflects_exactly() {
        let m = Material::Metal { albedo: Vec3::ONE, fuzz: 0.0, fuzz_in_sphere: false };
        let mut rng = Pcg32::new(1, 1);
        let d = Vec3::new(1.0, -1.0, 0.0);
        match m.scatter(d, Vec3::Y, true, &mut rng) {
            Interaction::Scatter { dir, .. } => assert!((dir - Vec3::new(1.0, 1.0, 0.0).normalize()).length() < 1e-6),
            _ => panic!(),
        }
    }

    #[test]
    fn glass_total_internal_reflection_and_normal_incidence() {
        let glass = Material::Dielectric { ior: 1.5 };
        let mut rng = Pcg32::new(1, 1);
        // Inside glass at a grazing angle: sin θ · 1.5 > 1, always reflects.
        let d = Vec3::new(1.0, 0.2, 0.0);
        for _ in 0..100 {
            match glass.scatter(d, -Vec3::Y, false, &mut rng) {
                Interaction::Scatter { dir, weight } => {
                    assert!(dir.y < 0.0, "reflected back inside");
                    assert_eq!(weight, Vec3::ONE);
                }
                _ => panic!(),
            }
        }
        // Normal incidence from outside: reflects with probability r0 = 0.04.
        let mut reflected = 0;
        for _ in 0..20_000 {
            if let Interaction::Scatter { dir, .. } = glass.scatter(-Vec3::Y, Vec3::Y, true, &mut rng) {
                reflected += (dir.y > 0.0) as u32;
            }
        }
        let p = reflected as f32 / 20_000.0;
        assert!((p - 0.04).abs() < 0.006, "reflectance {p}");
    }

    #[test]
    fn one_sided_emitter() {
        let light = Material::Emissive { emit: Vec3::splat(4.0), two_sided: false };
        assert_eq!(light.emitted(true), Vec3::splat(4.0));
        assert_eq!(light.emitted(false), Vec3::ZERO);
        let both = Material::Emissive { emit: Vec3::splat(4.0), two_sided: true };
        assert_eq!(both.emitted(false), Vec3::splat(4.0));
    }
}
