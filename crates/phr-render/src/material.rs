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

impl Material {
    /// Whether [`Material::scatter`] samples a spread of directions whose density
    /// [`Material::lobe_pdf`] gives (diffuse, fuzzy metal), so that light sampling can be
    /// weighed against it; mirrors, glass and lights scatter into single directions or none.
    #[inline]
    pub fn has_lobe(&self) -> bool {
        match self {
            Material::Lambertian { .. } => true,
            Material::Metal { fuzz, .. } => *fuzz > 0.0,
            _ => false,
        }
    }

    /// The density (per solid angle) with which [`Material::scatter`] leaves in the unit
    /// direction `out` from a path arriving along `dir`, with the arguments of `scatter`; 0
    /// without a lobe. Its product with the scatter weight is the BSDF times the cosine, so a
    /// light sample in `out` carries `weight × lobe_pdf / light_pdf` of the light's radiance.
    ///
    /// Lambertian: `cos θ / π` (RTIOW's normal plus a unit vector is cosine-distributed).
    /// Fuzzy metal: the direction of `r + f s` with `r` the unit mirror direction and `s`
    /// uniform on the unit sphere (RTIOW v4) or in the unit ball (v3): along `out`, the ray
    /// `t · out` meets the sphere of radius `f` about `r` at `t± = b ± √(b² − 1 + f²)` with
    /// `b = out · r`. On the sphere each crossing adds `t² / (4π f √disc)` (area density
    /// times the area a solid angle covers there); in the ball the segment between them adds
    /// `(t+³ − t−³) / (4π f³)`. Directions below the surface are absorbed by `scatter`, so
    /// their density is 0 here.
    pub fn lobe_pdf(&self, dir: Vec3, normal: Vec3, front: bool, out: Vec3) -> f32 {
        let facing = if front { normal } else { -normal };
        let cos = facing.dot(out);
        if cos <= 0.0 {
            return 0.0;
        }
        match self {
            Material::Lambertian { .. } => cos * std::f32::consts::FRAC_1_PI,
            Material::Metal { fuzz, fuzz_in_sphere, .. } if *fuzz > 0.0 => {
                let r = reflect(dir.normalize(), facing).normalize();
                let f = fuzz.min(1.0);
                let b = out.dot(r);
                // b² − 1 + f² with sin² θ from the cross product: no cancellation near r.
                let disc = f * f - out.cross(r).length_squared();
                if disc <= 0.0 {
                    return 0.0;
                }
                let sq = disc.sqrt();
                let (far, near) = (b + sq, (b - sq).max(0.0));
                if far <= 0.0 {
                    return 0.0;
                }
                let four_pi = 4.0 * std::f32::consts::PI;
                if *fuzz_in_sphere {
                    (far * far * far - near * near * near) / (four_pi * f * f * f)
                } else {
                    (far * far + near * near) / (four_pi * f * sq)
                }
            }
            _ => 0.0,
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

    /// `lobe_pdf` against `scatter` itself, where a quadrature can integrate it (diffuse, and
    /// fuzzy metal with the ball's density, which vanishes at the lobe's rim; at a grazing and
    /// a steep angle): its integral over the sphere of directions is the share of samples
    /// `scatter` does not absorb, and it predicts how many fall into each of 12 cones about the
    /// normal within 5 sigma.
    #[test]
    fn lobe_densities_match_the_sampling() {
        let materials = [
            Material::Lambertian { albedo: Vec3::splat(0.5) },
            Material::Metal { albedo: Vec3::ONE, fuzz: 0.3, fuzz_in_sphere: true },
            Material::Metal { albedo: Vec3::ONE, fuzz: 1.0, fuzz_in_sphere: true },
        ];
        let incoming = [Vec3::new(1.0, -0.3, 0.2), Vec3::new(0.2, -1.0, -0.1)];
        const N: usize = 200_000;
        const BINS: usize = 12;
        let (rows, cols) = (1200usize, 2400usize);
        for m in &materials {
            for dir in incoming {
                let mut rng = Pcg32::new(3, 7);
                let mut counts = [0usize; BINS];
                let mut kept = 0;
                for _ in 0..N {
                    if let Interaction::Scatter { dir: out, .. } = m.scatter(dir, Vec3::Y, true, &mut rng) {
                        let out = out.normalize();
                        if out.y > 0.0 {
                            kept += 1;
                            counts[((out.y * BINS as f32) as usize).min(BINS - 1)] += 1;
                        }
                    }
                }
                // Midpoint quadrature over cells of equal solid angle (rings about x, so the
                // lobes, about y, fall on no pole).
                let mut expected = [0.0f64; BINS];
                let cell = 4.0 * std::f64::consts::PI / (rows * cols) as f64;
                for i in 0..rows {
                    let x = 1.0 - 2.0 * (i as f64 + 0.5) / rows as f64;
                    let r = (1.0 - x * x).sqrt();
                    for j in 0..cols {
                        let phi = std::f64::consts::TAU * (j as f64 + 0.5) / cols as f64;
                        let out = Vec3::new(x as f32, (r * phi.cos()) as f32, (r * phi.sin()) as f32);
                        let p = f64::from(m.lobe_pdf(dir, Vec3::Y, true, out)) * cell;
                        if out.y > 0.0 {
                            expected[((out.y * BINS as f32) as usize).min(BINS - 1)] += p;
                        }
                    }
                }
                let total: f64 = expected.iter().sum();
                let share = kept as f64 / N as f64;
                assert!((total - share).abs() < 0.005, "{m:?}, {dir}: ∫pdf = {total}, kept {share}");
                for (b, (&c, &e)) in counts.iter().zip(&expected).enumerate() {
                    let got = c as f64 / N as f64;
                    let tolerance = 5.0 * (e.max(1e-4) / N as f64).sqrt() + 0.005 * e;
                    assert!(
                        (got - e).abs() < tolerance,
                        "{m:?}, {dir}: bin {b}: {got:.5} sampled, {e:.5} by the density"
                    );
                }
            }
        }
    }

    /// RTIOW v4's fuzz (a point on the sphere, whose density is infinite at the lobe's rim, out
    /// of a quadrature's reach), and v3's: the mean of `1 / lobe_pdf` over `scatter`'s samples
    /// is the solid angle the lobe covers, the cap `2π (1 − √(1 − f²))` about the mirror
    /// direction (at steep incidence, where no sample is absorbed).
    #[test]
    fn fuzzy_lobes_cover_their_cap() {
        let dir = Vec3::new(0.2, -1.0, -0.1);
        for (fuzz, fuzz_in_sphere) in [(0.3, false), (0.05, false), (0.3, true), (0.6, false)] {
            let m = Material::Metal { albedo: Vec3::ONE, fuzz, fuzz_in_sphere };
            let mut rng = Pcg32::new(5, 1);
            const N: usize = 400_000;
            let (mut sum, mut on_rim) = (0.0f64, 0);
            for _ in 0..N {
                match m.scatter(dir, Vec3::Y, true, &mut rng) {
                    Interaction::Scatter { dir: out, .. } => match m.lobe_pdf(dir, Vec3::Y, true, out.normalize()) {
                        // Rounding put it a hair outside the rim, where 1 / pdf tends to 0.
                        0.0 => on_rim += 1,
                        pdf => sum += 1.0 / f64::from(pdf),
                    },
                    Interaction::Absorb => panic!("{m:?}: a sample below the surface at steep incidence"),
                }
            }
            assert!(on_rim < N / 1000, "{m:?}: {on_rim} samples of density 0");
            let cap = std::f64::consts::TAU * (1.0 - (1.0 - f64::from(fuzz) * f64::from(fuzz)).sqrt());
            let mean = sum / N as f64;
            assert!((mean / cap - 1.0).abs() < 0.01, "{m:?}: mean 1/pdf {mean}, cap {cap}");
        }
    }
}
