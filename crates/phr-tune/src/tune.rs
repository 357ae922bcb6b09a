//! A whole optimisation, as `phr tune` runs it: grid search or Bayesian optimisation of either
//! objective over a box of (α, δ).
//!
//! With the thesis's objective, the maxima `max b` and `max c` come from the grid itself, or,
//! for Bayesian optimisation, from the thesis's two normalisation runs: the lowest parameters
//! give the worst tree (max c), the highest the most work (max b). Both runs count towards
//! the budget and seed the Gaussian process; with a cache, a later run of the same scene and
//! box reuses the maxima and skips them.

use crate::bayes::{minimize, BoOptions, Observation};
use crate::cache::{self, Maxima};
use crate::evaluator::{Evaluation, PhrEvaluator};
use crate::grid::evaluate_grid;
use crate::objective::{omega, FrameTimeModel, Objective, ThesisObjective};
use crate::search_box::SearchBox;
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(Clone, Debug)]
pub enum Method {
    Grid { alphas: Vec<f64>, deltas: Vec<f64> },
    Bayes(BoOptions),
}

#[derive(Clone, Copy, Debug)]
pub enum ObjectiveKind {
    /// `e(α, δ)` for an image of `width × height` with the given `ω_p`, `ω_r`.
    Thesis { width: u32, height: u32, omega_p: f64, omega_r: f64 },
    /// Predicted frame time with a calibrated model.
    FrameTime(FrameTimeModel),
}

#[derive(Clone, Debug)]
pub struct TuneOptions {
    pub method: Method,
    pub objective: ObjectiveKind,
    /// The box searched (Bayesian optimisation) or whose corners normalise the thesis's
    /// objective when it is not cached.
    pub search: SearchBox,
    /// Where to cache the thesis objective's maxima, and under which key.
    pub cache: Option<(PathBuf, String)>,
}

#[derive(Clone, Debug)]
pub struct TuneResult {
    pub best: Evaluation,
    pub best_value: f64,
    /// Every evaluation in order, with its objective value.
    pub evaluations: Vec<(Evaluation, f64)>,
    pub objective: Objective,
    pub elapsed: Duration,
}

pub fn tune(evaluator: &PhrEvaluator, options: &TuneOptions) -> TuneResult {
    let start = Instant::now();
    let (objective, evaluations) = match &options.method {
        Method::Grid { alphas, deltas } => {
            let evals = evaluate_grid(evaluator, alphas, deltas);
            let objective = make_objective(evaluator, options, || maxima_of(&evals));
            (objective, evals)
        }
        Method::Bayes(bo) => {
            let mut initial_evals = Vec::new();
            let objective = make_objective(evaluator, options, || {
                let cached = options.cache.as_ref().and_then(|(path, key)| cache::load(path, key));
                cached.unwrap_or_else(|| {
                    let [lower, upper] = [options.search.lower, options.search.upper];
                    let (low, high) = (evaluator.evaluate(lower[0], lower[1]), evaluator.evaluate(upper[0], upper[1]));
                    initial_evals.extend([low, high]);
                    let m = maxima_of(&[low, high]);
                    if let Some((path, key)) = &options.cache {
                        // A failed cache write costs only the next run's two builds.
                        let _ = cache::store(path, key, m);
                    }
                    m
                })
            });
            let initial: Vec<Observation> =
                initial_evals.iter().map(|e| Observation { x: [e.alpha, e.delta], y: objective.value(e) }).collect();
            let observations =
                minimize(|x| objective.value(&evaluator.evaluate(x[0], x[1])), &options.search, &initial, bo);
            let evals = observations.iter().map(|o| evaluator.evaluate(o.x[0], o.x[1])).collect();
            (objective, evals)
        }
    };
    let evaluations: Vec<(Evaluation, f64)> = evaluations.into_iter().map(|e| (e, objective.value(&e))).collect();
    let (best, best_value) =
        evaluations.iter().copied().min_by(|a, b| a.1.total_cmp(&b.1)).expect("at least one evaluation");
    TuneResult { best, best_value, evaluations, objective, elapsed: start.elapsed() }
}

fn make_objective(evaluator: &PhrEvaluator, options: &TuneOptions, maxima: impl FnOnce() -> Maxima) -> Objective {
    match options.objective {
        ObjectiveKind::Thesis { width, height, omega_p, omega_r } => {
            let m = maxima();
            Objective::Thesis(ThesisObjective {
                max_build_cost: m.max_build_cost,
                max_sah_cost: m.max_sah_cost,
                omega: omega(evaluator.prims, width, height, omega_p, omega_r),
            })
        }
        ObjectiveKind::FrameTime(model) => Objective::FrameTime(model),
    }
}

fn maxima_of(evals: &[Evaluation]) -> Maxima {
    Maxima {
        max_build_cost: evals.iter().map(|e| e.build_cost).fold(0.0, f64::max).max(1.0),
        max_sah_cost: evals.iter().map(|e| e.sah_cost).fold(0.0, f64::max).max(f64::MIN_POSITIVE),
    }
}
