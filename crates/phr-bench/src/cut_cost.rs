//! `phr bench-cut-cost`: how well PHR's build cost `b = Σ |cut|` predicts its build time (the
//! thesis found a correlation of 0.99). PHR is built from one auxiliary LBVH over a grid of
//! α and δ; each point keeps the median build time of `repeats` builds.

use crate::Progress;
use phr_bvh::phr::{build_phr, AuxTree, PhrOptions};
use phr_bvh::{sah_cost, Aabb, SahConstants};
use std::time::Instant;

/// One (α, δ) point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutCostPoint {
    pub alpha: f32,
    pub delta: f32,
    /// `Σ |cut|` of the build.
    pub build_cost: u64,
    /// Median build time (PHR from the auxiliary LBVH, which is built once).
    pub build_ms: f64,
    /// SAH cost with the constants (1, 1).
    pub sah_11: f64,
}

/// The CSV's header; [`CutCostPoint::csv_row`] gives its rows.
pub const CSV_HEADER: &str = "mesh,alpha,delta,build_cost,build_ms,sah_cost_1_1";

impl CutCostPoint {
    pub fn csv_row(&self, mesh: &str) -> String {
        format!("{mesh},{},{},{},{:.3},{:.4}", self.alpha, self.delta, self.build_cost, self.build_ms, self.sah_11)
    }
}

/// Builds PHR over `boxes` at every (α, δ) of `alphas × deltas`, `repeats` times each;
/// advances `progress` once per point.
pub fn measure_cut_cost(
    boxes: &[Aabb],
    alphas: &[f32],
    deltas: &[f32],
    repeats: usize,
    progress: &dyn Progress,
) -> Vec<CutCostPoint> {
    let aux = AuxTree::build(boxes);
    let mut points = Vec::new();
    for &alpha in alphas {
        for &delta in deltas {
            let options = PhrOptions::with(alpha, delta);
            let mut runs: Vec<(f64, u64, f64)> = (0..repeats.max(1))
                .map(|_| {
                    let start = Instant::now();
                    let (bvh, stats) = build_phr(&aux, &options);
                    let ms = start.elapsed().as_secs_f64() * 1e3;
                    (ms, stats.build_cost, sah_cost(&bvh, SahConstants::UNIT))
                })
                .collect();
            runs.sort_by(|a, b| a.0.total_cmp(&b.0));
            let (build_ms, build_cost, sah_11) = runs[runs.len() / 2];
            points.push(CutCostPoint { alpha, delta, build_cost, build_ms, sah_11 });
            progress.advance();
        }
    }
    points
}

/// The Pearson correlation of `Σ |cut|` with the build time over `points`, and the build
/// time per million cut nodes.
pub fn summary(points: &[CutCostPoint]) -> (f64, f64) {
    let costs: Vec<f64> = points.iter().map(|p| p.build_cost as f64).collect();
    let times: Vec<f64> = points.iter().map(|p| p.build_ms).collect();
    let per_mcut = times.iter().sum::<f64>() / (costs.iter().sum::<f64>() / 1e6);
    (crate::stats::correlation(&costs, &times), per_mcut)
}
