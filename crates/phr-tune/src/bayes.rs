//! Bayesian optimisation of a function on a 2-D box (thesis 6.3): a Gaussian process models the
//! objective from the points evaluated so far, and the next point maximises the expected
//! improvement over the best value seen (Jones, Schonlau & Welch 1998).
//!
//! Done properly: inputs are scaled to the unit square and outputs standardised before
//! fitting; the GP (the `friedrich` crate, squared-exponential kernel, constant prior) has its
//! kernel hyper-parameters, noise term and prior fitted by maximum likelihood at every step;
//! the expected improvement is maximised over a dense candidate grid plus random points.

use crate::search_box::SearchBox;
use friedrich::gaussian_process::GaussianProcess;
use friedrich::kernel::SquaredExp;
use friedrich::prior::ConstantPrior;
use std::time::{Duration, Instant};

/// A point and its objective value, in the box's own units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation {
    pub x: [f64; 2],
    pub y: f64,
}

#[derive(Clone, Copy, Debug)]
pub struct BoOptions {
    /// Total evaluations, the given initial observations included.
    pub budget: usize,
    pub seed: u64,
    /// Stop early once this much time has passed.
    pub time_budget: Option<Duration>,
    /// Random points evaluated before the GP takes over (after the initial observations), so
    /// that the first fit sees at least this many plus the initial ones.
    pub random_starts: usize,
    /// Candidate grid side for maximising the expected improvement.
    pub candidate_grid: usize,
    /// Exploration margin ξ of the expected improvement, in standardised units.
    pub xi: f64,
}

impl Default for BoOptions {
    fn default() -> Self {
        Self { budget: 20, seed: 0, time_budget: None, random_starts: 3, candidate_grid: 41, xi: 0.01 }
    }
}

/// A small xorshift generator: the optimiser must be reproducible for a seed.
struct Rng(u64);

impl Rng {
    fn new(seed: u64) -> Self {
        Self(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0x2545_f491_4f6c_dd1d | 1)
    }
    fn unit(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Complementary error function (Numerical Recipes' Chebyshev fit, relative error < 1.2e-7).
pub fn erfc(x: f64) -> f64 {
    let z = x.abs();
    let t = 1.0 / (1.0 + 0.5 * z);
    let poly = -z * z - 1.265_512_23
        + t * (1.000_023_68
            + t * (0.374_091_96
                + t * (0.096_784_18
                    + t * (-0.186_288_06
                        + t * (0.278_868_07
                            + t * (-1.135_203_98 + t * (1.488_515_87 + t * (-0.822_152_23 + t * 0.170_872_77))))))));
    let r = t * poly.exp();
    if x >= 0.0 {
        r
    } else {
        2.0 - r
    }
}

/// Expected improvement below `best` of a normal prediction (mean, standard deviation).
pub fn expected_improvement(mean: f64, std: f64, best: f64, xi: f64) -> f64 {
    if std <= 1e-12 {
        return (best - mean - xi).max(0.0);
    }
    let z = (best - mean - xi) / std;
    let cdf = 0.5 * erfc(-z / std::f64::consts::SQRT_2);
    let pdf = (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt();
    (best - mean - xi) * cdf + std * pdf
}

/// Minimises `f` over `search`, starting from `initial` (already evaluated).
/// Returns every observation in evaluation order.
pub fn minimize(
    mut f: impl FnMut([f64; 2]) -> f64,
    search: &SearchBox,
    initial: &[Observation],
    options: &BoOptions,
) -> Vec<Observation> {
    let start = Instant::now();
    let mut rng = Rng::new(options.seed);
    let mut observations = initial.to_vec();
    let randoms_until = initial.len() + options.random_starts;
    while observations.len() < options.budget {
        if options.time_budget.is_some_and(|t| start.elapsed() >= t) {
            break;
        }
        let next = if observations.len() < randoms_until.max(3) {
            [rng.unit(), rng.unit()]
        } else {
            next_by_expected_improvement(
                &observations.iter().map(|o| (search.to_unit(o.x), o.y)).collect::<Vec<_>>(),
                options,
                &mut rng,
            )
        };
        let x = search.from_unit(next);
        let y = f(x);
        observations.push(Observation { x, y });
    }
    observations
}

/// The unit-square point with the largest expected improvement under a GP fitted to `data`.
fn next_by_expected_improvement(data: &[([f64; 2], f64)], options: &BoOptions, rng: &mut Rng) -> [f64; 2] {
    let n = data.len() as f64;
    let mean = data.iter().map(|d| d.1).sum::<f64>() / n;
    let std = (data.iter().map(|d| (d.1 - mean).powi(2)).sum::<f64>() / n).sqrt().max(1e-12);
    let inputs: Vec<Vec<f64>> = data.iter().map(|d| d.0.to_vec()).collect();
    let outputs: Vec<f64> = data.iter().map(|d| (d.1 - mean) / std).collect();
    let best = outputs.iter().copied().fold(f64::INFINITY, f64::min);
    let gp: GaussianProcess<SquaredExp, ConstantPrior> = GaussianProcess::builder(inputs, outputs)
        .set_kernel(SquaredExp::default())
        .set_noise(1e-2)
        .set_cholesky_epsilon(Some(1e-9))
        .fit_kernel()
        .fit_prior()
        .train();
    let side = options.candidate_grid.max(2);
    let mut candidates: Vec<Vec<f64>> = (0..side * side)
        .map(|i| vec![(i % side) as f64 / (side - 1) as f64, (i / side) as f64 / (side - 1) as f64])
        .collect();
    candidates.extend((0..256).map(|_| vec![rng.unit(), rng.unit()]));
    // Points already evaluated teach nothing new.
    candidates.retain(|c| data.iter().all(|d| (d.0[0] - c[0]).powi(2) + (d.0[1] - c[1]).powi(2) > 1e-8));
    let (means, variances) = gp.predict_mean_variance(&candidates);
    let mut chosen = (f64::NEG_INFINITY, [rng.unit(), rng.unit()]);
    for (c, (m, v)) in candidates.iter().zip(means.iter().zip(&variances)) {
        let ei = expected_improvement(*m, v.max(0.0).sqrt(), best, options.xi);
        if ei > chosen.0 {
            chosen = (ei, [c[0], c[1]]);
        }
    }
    chosen.1
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn erfc_matches_known_values() {
        for (x, want) in
            [(0.0, 1.0), (0.5, 0.479_500_122), (1.0, 0.157_299_207), (2.0, 0.004_677_735), (-1.0, 1.842_700_793)]
        {
            assert!((erfc(x) - want).abs() < 2e-7, "erfc({x}) = {} vs {want}", erfc(x));
        }
    }

    #[test]
    fn expected_improvement_properties() {
        // Far better mean: EI ≈ improvement; far worse with little spread: ≈ 0.
        assert!((expected_improvement(-5.0, 0.01, 0.0, 0.0) - 5.0).abs() < 1e-6);
        assert!(expected_improvement(5.0, 0.01, 0.0, 0.0) < 1e-12);
        // More uncertainty, more expected improvement at the same mean.
        assert!(expected_improvement(0.5, 2.0, 0.0, 0.0) > expected_improvement(0.5, 0.5, 0.0, 0.0));
    }

    /// A smooth bowl with its minimum inside the box: BO must find it to a fraction of the
    /// range with 20 evaluations, where random search of the same size mostly does not.
    #[test]
    fn finds_the_minimum_of_a_bowl() {
        let f = |x: [f64; 2]| (x[0] - 0.47).powi(2) * 40.0 + (x[1] - 7.6).powi(2) + 1.0;
        let mut found = Vec::new();
        for seed in 0..5 {
            let obs = minimize(f, &SearchBox::THESIS, &[], &BoOptions { seed, ..Default::default() });
            assert_eq!(obs.len(), 20);
            let best = obs.iter().map(|o| o.y).fold(f64::INFINITY, f64::min);
            found.push(best);
        }
        found.sort_by(f64::total_cmp);
        let median = found[found.len() / 2];
        assert!(median < 1.0 + 0.01, "median best {median} (minimum 1.0)");
    }

    /// The minimum in a corner, as the thesis objective usually has it.
    #[test]
    fn finds_a_corner_minimum() {
        let f = |x: [f64; 2]| (x[0] - 0.4) * 3.0 + (x[1] - 6.0) * 0.5 + 2.0;
        let obs = minimize(f, &SearchBox::THESIS, &[], &BoOptions { seed: 1, ..Default::default() });
        let best = obs.iter().map(|o| o.y).fold(f64::INFINITY, f64::min);
        assert!(best < 2.0 + 0.02, "best {best}");
    }

    #[test]
    fn time_budget_stops_early() {
        let obs = minimize(
            |x| {
                std::thread::sleep(Duration::from_millis(20));
                x[0]
            },
            &SearchBox { lower: [0.0, 0.0], upper: [1.0, 1.0] },
            &[],
            &BoOptions { time_budget: Some(Duration::from_millis(50)), ..Default::default() },
        );
        assert!(obs.len() < 20 && !obs.is_empty(), "{} evaluations", obs.len());
    }

    /// The time budget bounds the run: it may only finish the iteration (GP fit and
    /// evaluation) under way when the budget runs out, so the whole run takes at most the
    /// budget plus the longest iteration, measured here, plus slack for the machine.
    #[test]
    fn time_budget_bounds_the_overrun() {
        let budget = Duration::from_millis(300);
        let mut ends = Vec::new();
        let start = Instant::now();
        let obs = minimize(
            |x| {
                std::thread::sleep(Duration::from_millis(20));
                ends.push(Instant::now());
                x[0] + x[1]
            },
            &SearchBox { lower: [0.0, 0.0], upper: [1.0, 1.0] },
            &[],
            &BoOptions { budget: 40, time_budget: Some(budget), ..Default::default() },
        );
        let elapsed = start.elapsed();
        let longest = std::iter::once(start)
            .chain(ends.iter().copied())
            .collect::<Vec<_>>()
            .windows(2)
            .map(|w| w[1] - w[0])
            .max()
            .expect("at least one evaluation");
        let slack = Duration::from_millis(100);
        assert_eq!(obs.len(), ends.len());
        assert!(obs.len() < 40, "{} evaluations: the 300 ms budget did not stop 40 × 20 ms", obs.len());
        assert!(
            elapsed <= budget + longest + slack,
            "took {elapsed:?}: more than the {budget:?} budget + the longest iteration {longest:?} + {slack:?}"
        );
        assert!(elapsed >= budget, "stopped after {elapsed:?}, before the {budget:?} budget ran out");
    }
}
