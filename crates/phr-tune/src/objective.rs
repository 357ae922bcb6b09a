//! What "best (α, δ)" means.
//!
//! **The thesis's objective** (section 6.1): `e(α, δ) = b / max b + ω² · c / max c`, with `b`
//! the build cost `Σ |cut|`, `c` the SAH cost (2, 1), the maxima taken over the search box, and
//! `ω = (|prims| / ω_p)² · (w·h / ω_r)` weighting trace quality more for larger scenes and
//! images (the thesis code used `ω_p = 2,000,000`, `ω_r = 200,000`).
//!
//! **Predicted frame time** (ours): `T(α, δ) = k_b · b + k_r · c · rays` in milliseconds, with
//! `k_b` (ms per cut node) and `k_r` (ms per unit of SAH cost per ray) fitted to measured build
//! and render times. Unlike `e` it needs no maxima and its unit is the one the user cares about.

use crate::evaluator::Evaluation;

/// The thesis's normalised objective.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ThesisObjective {
    pub max_build_cost: f64,
    pub max_sah_cost: f64,
    pub omega: f64,
}

/// The thesis code's `ω_p` and `ω_r`.
pub const OMEGA_P: f64 = 2_000_000.0;
pub const OMEGA_R: f64 = 200_000.0;

/// `ω = (|prims| / ω_p)² · (w·h / ω_r)`.
pub fn omega(prims: usize, width: u32, height: u32, omega_p: f64, omega_r: f64) -> f64 {
    (prims as f64 / omega_p).powi(2) * (width as f64 * height as f64 / omega_r)
}

impl ThesisObjective {
    pub fn value(&self, e: &Evaluation) -> f64 {
        e.build_cost / self.max_build_cost + self.omega * self.omega * e.sah_cost / self.max_sah_cost
    }
}

/// `T = k_b · b + k_r · c · rays`, in milliseconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameTimeModel {
    /// Milliseconds per cut node built.
    pub k_build: f64,
    /// Milliseconds per unit SAH cost per ray traced.
    pub k_render: f64,
    /// Rays per frame.
    pub rays: f64,
}

impl FrameTimeModel {
    pub fn value(&self, e: &Evaluation) -> f64 {
        self.k_build * e.build_cost + self.k_render * e.sah_cost * self.rays
    }

    /// Least-squares slope through the origin: the `k` with `y ≈ k x`.
    pub fn fit_slope(points: &[(f64, f64)]) -> f64 {
        let (sxy, sxx) = points.iter().fold((0.0, 0.0), |(a, b), &(x, y)| (a + x * y, b + x * x));
        if sxx > 0.0 {
            sxy / sxx
        } else {
            0.0
        }
    }

    /// Calibrates from measured builds (`b`, ms) and renders (`c`, rays, ms).
    pub fn calibrate(builds: &[Evaluation], renders: &[(f64, f64, f64)], rays: f64) -> Self {
        let k_build = Self::fit_slope(&builds.iter().map(|e| (e.build_cost, e.build_ms)).collect::<Vec<_>>());
        let k_render = Self::fit_slope(&renders.iter().map(|&(c, r, ms)| (c * r, ms)).collect::<Vec<_>>());
        Self { k_build, k_render, rays }
    }
}

/// Either objective.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Objective {
    Thesis(ThesisObjective),
    FrameTime(FrameTimeModel),
}

impl Objective {
    pub fn value(&self, e: &Evaluation) -> f64 {
        match self {
            Objective::Thesis(o) => o.value(e),
            Objective::FrameTime(m) => m.value(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn eval(b: f64, c: f64, ms: f64) -> Evaluation {
        Evaluation { alpha: 0.5, delta: 6.0, build_cost: b, sah_cost: c, build_ms: ms }
    }

    #[test]
    fn thesis_objective_by_hand() {
        // 100k triangles at 512²: ω = (0.05)² · (262144 / 200000) = 0.0032768.
        let w = omega(100_000, 512, 512, OMEGA_P, OMEGA_R);
        assert!((w - 0.0032768).abs() < 1e-9);
        let o = ThesisObjective { max_build_cost: 1000.0, max_sah_cost: 50.0, omega: 2.0 };
        assert!((o.value(&eval(500.0, 25.0, 0.0)) - (0.5 + 4.0 * 0.5)).abs() < 1e-12);
    }

    #[test]
    fn frame_time_calibration_recovers_the_slopes() {
        let builds = [eval(1e5, 40.0, 2.0), eval(2e5, 38.0, 4.0), eval(4e5, 37.0, 8.0)];
        let renders = [(40.0, 1e5, 20.0), (20.0, 1e5, 10.0)];
        let m = FrameTimeModel::calibrate(&builds, &renders, 1e5);
        assert!((m.k_build - 2e-5).abs() < 1e-12);
        assert!((m.k_render - 5e-6).abs() < 1e-12);
        assert!((m.value(&eval(1e5, 30.0, 0.0)) - (2.0 + 15.0)).abs() < 1e-9);
    }
}
