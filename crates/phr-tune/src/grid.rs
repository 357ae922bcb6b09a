//! Grid search (thesis 6.2): every (α, δ) of a grid, evaluated in parallel from one shared
//! auxiliary LBVH.

use crate::evaluator::{Evaluation, PhrEvaluator};
use rayon::prelude::*;

/// The thesis's grid: α ∈ {0.4, 0.45, 0.5, 0.55} × δ ∈ {6, 7, 8, 9}.
pub const THESIS_ALPHAS: [f64; 4] = [0.4, 0.45, 0.5, 0.55];
pub const THESIS_DELTAS: [f64; 4] = [6.0, 7.0, 8.0, 9.0];

/// `n` evenly spaced values from `lo` to `hi` inclusive.
pub fn linspace(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    match n {
        0 => Vec::new(),
        1 => vec![lo],
        _ => (0..n).map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64).collect(),
    }
}

/// Evaluates every point of `alphas × deltas`, in parallel, in row-major order.
pub fn evaluate_grid(evaluator: &PhrEvaluator, alphas: &[f64], deltas: &[f64]) -> Vec<Evaluation> {
    let points: Vec<(f64, f64)> = alphas.iter().flat_map(|&a| deltas.iter().map(move |&d| (a, d))).collect();
    points.par_iter().map(|&(a, d)| evaluator.evaluate(a, d)).collect()
}
