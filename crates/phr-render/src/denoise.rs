//! Denoising: the edge-avoiding à-trous wavelet filter (Dammertz, Sewtz, Hanika & Lensch
//! 2010), with the variance-guided luminance weight of SVGF (Schied et al. 2017).
//!
//! The filter smooths the **illumination**, the colour divided by the first surface's albedo,
//! and multiplies the albedo back afterwards, so surface detail (albedo edges) stays sharp
//! whatever the filter does. Each of its passes is a 5×5 B3-spline kernel whose taps lie
//! `2^i` pixels apart (pass `i`), so five passes cover 61×61 pixels at 25 taps per pixel
//! each. A tap's weight is cut down where it leaves the surface of the centre pixel:
//! - **normals** that differ: `max(0, n_p · n_q)^σn`;
//! - **positions** off the centre's tangent plane, measured in pixel footprints at the
//!   centre's distance (the plane distance of a neighbour on the same flat surface is 0, a
//!   step in depth is many footprints);
//! - **illumination** that differs by more than its noise: `|l_p − l_q| / (σl · σ(l_p))`, with
//!   σ(l_p) the standard deviation of the pixel's mean (the film's variance, carried through
//!   the passes as a filtered variance shrinks).
//!
//! Pixels that see no surface (the sky) or a light are left as they are and never mix with
//! surfaces.
//! The [`Guide`] buffers come from the camera's first hits.

use crate::geometry::{Hit, SurfacePoint};
use crate::render::Renderer;
use crate::sampler::Pcg32;
use glam::Vec3;
use rayon::prelude::*;
use std::f32::consts::SQRT_2;

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

/// The filter's settings; the defaults are SVGF's (σl = 4, and the normal exponent 128) and
/// one footprint for the plane distance.
#[derive(Clone, Copy, Debug)]
pub struct Atrous {
    /// Passes (`2^passes − 1` pixels reach, times 2, on each side).
    pub passes: u32,
    pub sigma_luminance: f32,
    pub sigma_plane: f32,
}

impl Default for Atrous {
    fn default() -> Self {
        Self { passes: 5, sigma_luminance: 4.0, sigma_plane: 1.0 }
    }
}

/// The normal weight is `max(0, n_p · n_q)^(2^NORMAL_POWER)`: SVGF's exponent 128, by squaring.
const NORMAL_POWER: u32 = 7;

/// The B3-spline kernel's weights at offsets −2..=2.
const KERNEL: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

/// Smallest albedo channel divided by (dark surfaces would blow their noise up).
const MIN_ALBEDO: f32 = 0.01;

fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// One pixel as the passes read it, in one cache line: its guide and what is filtered (at
/// the far steps every tap is a different line).
#[derive(Clone, Copy)]
struct Texel {
    normal: Vec3,
    /// 0: not filtered (see [`Guide::footprint`]).
    footprint: f32,
    position: Vec3,
    /// Luminance of `illumination`.
    luminance: f32,
    illumination: Vec3,
    /// Variance of `luminance`.
    var: f32,
}

impl Texel {
    fn is_surface(&self) -> bool {
        self.footprint > 0.0
    }
}

/// The variance at `(x, y)` smoothed by a 3×3 Gaussian over surface pixels, as SVGF does: one
/// pixel's variance estimate from few samples is itself noisy.
fn blurred_variance(texels: &[Texel], w: i32, h: i32, x: i32, y: i32) -> f32 {
    const GAUSS: [f32; 3] = [0.25, 0.5, 0.25];
    let (mut sum, mut total) = (0.0, 0.0);
    for (dy, ky) in (-1..=1).zip(GAUSS) {
        for (dx, kx) in (-1..=1).zip(GAUSS) {
            let (qx, qy) = (x + dx, y + dy);
            if (0..w).contains(&qx) && (0..h).contains(&qy) {
                let q = &texels[(qy * w + qx) as usize];
                if q.is_surface() {
                    sum += kx * ky * q.var.max(0.0);
                    total += kx * ky;
                }
            }
        }
    }
    sum / total
}

impl Atrous {
    /// The denoised image of `colour` (a film's mean), whose per-pixel variance of the mean is
    /// `variance`, guided by `guide` (same size).
    pub fn denoise(&self, colour: &[Vec3], variance: &[Vec3], guide: &Guide) -> Vec<Vec3> {
        let n = (guide.width * guide.height) as usize;
        assert!(colour.len() == n && variance.len() == n, "image and guide sizes differ");
        let albedo: Vec<Vec3> = guide.albedo.iter().map(|a| a.max(Vec3::splat(MIN_ALBEDO))).collect();
        let mut texels: Vec<Texel> = (0..n)
            .map(|i| {
                let illumination = colour[i] / albedo[i];
                let v = variance[i];
                // The luminance's standard deviation, channels taken as fully correlated (one
                // path makes all three), then squared.
                let sd = luminance(Vec3::new(v.x.sqrt(), v.y.sqrt(), v.z.sqrt()) / albedo[i]);
                Texel {
                    normal: guide.normal[i],
                    footprint: guide.footprint[i],
                    position: guide.position[i],
                    luminance: luminance(illumination),
                    illumination,
                    var: sd * sd,
                }
            })
            .collect();
        for pass in 0..self.passes {
            texels = self.pass(&texels, guide.width as i32, guide.height as i32, 1 << pass);
        }
        texels
            .iter()
            .zip(&albedo)
            .enumerate()
            .map(|(i, (t, a))| if t.is_surface() { t.illumination * *a } else { colour[i] })
            .collect()
    }

    /// One pass with taps `step` pixels apart: the filtered illumination and its variance.
    fn pass(&self, texels: &[Texel], w: i32, h: i32, step: i32) -> Vec<Texel> {
        (0..w * h)
            .into_par_iter()
            .with_min_len(256)
            .map(|i| {
                let p = &texels[i as usize];
                if !p.is_surface() {
                    return *p;
                }
                let (x, y) = (i % w, i / w);
                let luminance_scale = 1.0 / (self.sigma_luminance * blurred_variance(texels, w, h, x, y).sqrt() + 1e-6);
                let plane_scale = 1.0 / (self.sigma_plane * p.footprint * step as f32);
                let (mut sum, mut sum_var, mut total) = (Vec3::ZERO, 0.0f32, 0.0f32);
                for (dy, ky) in (-2..=2).zip(KERNEL) {
                    let qy = y + dy * step;
                    if !(0..h).contains(&qy) {
                        continue;
                    }
                    for (dx, kx) in (-2..=2).zip(KERNEL) {
                        let qx = x + dx * step;
                        if !(0..w).contains(&qx) {
                            continue;
                        }
                        let q = &texels[(qy * w + qx) as usize];
                        if !q.is_surface() {
                            continue;
                        }
                        let weight = if dx == 0 && dy == 0 {
                            kx * ky
                        } else {
                            let mut normal = p.normal.dot(q.normal).max(0.0);
                            for _ in 0..NORMAL_POWER {
                                normal *= normal;
                            }
                            let distance = OFFSET_LENGTH[(dy + 2) as usize][(dx + 2) as usize];
                            let plane = p.normal.dot(q.position - p.position).abs() * plane_scale / distance;
                            let light = (q.luminance - p.luminance).abs() * luminance_scale;
                            // Beyond e^-20 a tap counts for nothing (and exp's underflow path
                            // is slow).
                            let exponent = plane + light;
                            if exponent > 20.0 || normal < 1e-9 {
                                continue;
                            }
                            kx * ky * normal * (-exponent).exp()
                        };
                        sum += q.illumination * weight;
                        sum_var += q.var * weight * weight;
                        total += weight;
                    }
                }
                let illumination = sum / total;
                Texel { illumination, luminance: luminance(illumination), var: sum_var / (total * total), ..*p }
            })
            .collect()
    }
}

/// `sqrt(dx² + dy²)` of the kernel's taps (the centre's, unused, is 1).
const OFFSET_LENGTH: [[f32; 5]; 5] = [
    [2.828_427, 2.236_068, 2.0, 2.236_068, 2.828_427],
    [2.236_068, SQRT_2, 1.0, SQRT_2, 2.236_068],
    [2.0, 1.0, 1.0, 1.0, 2.0],
    [2.236_068, SQRT_2, 1.0, SQRT_2, 2.236_068],
    [2.828_427, 2.236_068, 2.0, 2.236_068, 2.828_427],
];

#[cfg(test)]
mod tests {
    use super::*;

    const W: u32 = 48;
    const H: u32 = 32;

    /// A flat wall facing the camera (normal +z at z = 0) seen head-on, one unit per pixel.
    fn wall() -> Guide {
        let n = (W * H) as usize;
        Guide {
            width: W,
            height: H,
            albedo: vec![Vec3::splat(0.5); n],
            normal: vec![Vec3::Z; n],
            position: (0..n).map(|i| Vec3::new((i as u32 % W) as f32, (i as u32 / W) as f32, 0.0)).collect(),
            footprint: vec![1.0; n],
        }
    }

    /// Noise of standard deviation `sd` around `base`, the same in all three channels.
    fn noisy(base: impl Fn(usize) -> f32, sd: f32, seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
        let mut rng = Pcg32::new(seed, 1);
        let colour = (0..(W * H) as usize)
            .map(|i| {
                // A sum of 4 uniforms, scaled to the standard deviation: near Gaussian.
                let u: f32 = (0..4).map(|_| rng.next_f32() - 0.5).sum::<f32>() * (3.0f32).sqrt();
                Vec3::splat(base(i) + sd * u)
            })
            .collect();
        (colour, vec![Vec3::splat(sd * sd); (W * H) as usize])
    }

    fn variance(v: impl Iterator<Item = f32>) -> f32 {
        let v: Vec<f32> = v.collect();
        let mean = v.iter().sum::<f32>() / v.len() as f32;
        v.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / v.len() as f32
    }

    #[test]
    fn a_constant_image_stays_constant() {
        let mut guide = wall();
        // Albedo edges too: the illumination is what is filtered, the albedo comes back.
        guide
            .albedo
            .iter_mut()
            .enumerate()
            .for_each(|(i, a)| *a = if (i / 3) % 2 == 0 { Vec3::splat(0.2) } else { Vec3::ONE });
        let colour: Vec<Vec3> = guide.albedo.iter().map(|a| *a * Vec3::new(0.3, 0.6, 0.9)).collect();
        let variance = vec![Vec3::splat(0.01); colour.len()];
        let out = Atrous::default().denoise(&colour, &variance, &guide);
        for (i, (a, b)) in out.iter().zip(&colour).enumerate() {
            assert!((*a - *b).abs().max_element() < 1e-5, "pixel {i}: {a} from {b}");
        }
    }

    #[test]
    fn noise_on_a_flat_surface_is_removed() {
        let guide = wall();
        let (colour, var) = noisy(|_| 0.4, 0.1, 1);
        let out = Atrous::default().denoise(&colour, &var, &guide);
        let (before, after) = (variance(colour.iter().map(|c| c.x)), variance(out.iter().map(|c| c.x)));
        assert!(after < 0.02 * before, "pixel variance {before} → {after}");
        let mean = out.iter().map(|c| c.x).sum::<f32>() / out.len() as f32;
        assert!((mean - 0.4).abs() < 0.01, "mean {mean}");
    }

    /// Left and right halves at different levels, split by a normal edge or a depth edge: the
    /// filter keeps each side's level right up to the edge.
    #[test]
    fn no_blur_across_a_normal_or_depth_edge() {
        let left = |i: usize| (i as u32 % W) < W / 2;
        let level = |i: usize| if left(i) { 0.4 } else { 0.55 };
        for edge in ["normal", "depth"] {
            let mut guide = wall();
            for i in 0..(W * H) as usize {
                if !left(i) {
                    match edge {
                        "normal" => guide.normal[i] = Vec3::X,
                        _ => guide.position[i].z = 20.0,
                    }
                }
            }
            let (colour, var) = noisy(level, 0.05, 2);
            let out = Atrous::default().denoise(&colour, &var, &guide);
            for (i, c) in out.iter().enumerate() {
                // Columns next to the edge: averages of a side's noise, nothing of the other.
                let column = i as u32 % W;
                if column + 1 == W / 2 || column == W / 2 {
                    assert!((c.x - level(i)).abs() < 0.03, "{edge} edge, pixel {i} (column {column}): {}", c.x);
                }
            }
        }
    }

    #[test]
    fn the_sky_and_lights_are_left_alone() {
        let mut guide = wall();
        let (colour, var) = noisy(|_| 0.5, 0.2, 3);
        for i in 0..W as usize {
            guide.footprint[i] = 0.0;
        }
        let out = Atrous::default().denoise(&colour, &var, &guide);
        assert_eq!(out[..W as usize], colour[..W as usize]);
        assert_ne!(out[W as usize..], colour[W as usize..]);
    }
}
