//! `phr tune --time-budget-ms`: Bayesian optimisation on a real mesh stops on time, with fewer
//! evaluations than its evaluation budget, within the time budget plus one iteration, and
//! reports every evaluation it made (inside the search box, finite) and the builds it did.

mod common;

use common::{phr_ok, repo_path, TempDir};
use std::time::Duration;

/// The rows of the evaluation table: α, δ, Σ|cut|, SAH(2,1), build ms, objective.
fn evaluations(stdout: &str) -> Vec<[f64; 6]> {
    stdout
        .lines()
        .filter_map(|l| {
            let fields: Vec<&str> = l.split_whitespace().collect();
            fields.first()?.parse::<usize>().ok()?;
            let numbers: Vec<f64> = fields[1..].iter().map(|f| f.parse().unwrap_or(f64::NAN)).collect();
            Some(numbers.try_into().unwrap_or_else(|_| panic!("evaluation row {l:?}")))
        })
        .collect()
}

/// The number after `before` and up to `after` in `text`.
fn number_between(text: &str, before: &str, after: &str) -> f64 {
    let start = text.find(before).unwrap_or_else(|| panic!("no {before:?} in {text}")) + before.len();
    let len = text[start..].find(after).unwrap_or_else(|| panic!("no {after:?} after {before:?} in {text}"));
    text[start..start + len].trim().parse().unwrap_or_else(|_| panic!("{before}…{after} in {text}"))
}

#[test]
fn time_budget_stops_bayesian_optimisation() {
    let bunny = repo_path("../shared/scenes/bunny/bun_zipper.ply");
    assert!(bunny.is_file(), "{} is missing: the shared scenes are needed", bunny.display());
    let dir = TempDir::new("tune-budget");
    let (budget, time_budget_ms) = (100, 300.0);
    let args = [
        "tune",
        bunny.to_str().unwrap(),
        "--method",
        "bo",
        "--width",
        "16",
        "--height",
        "16",
        "--budget",
        &budget.to_string(),
        "--time-budget-ms",
        &time_budget_ms.to_string(),
        "--cache",
        "cache.json",
    ];
    let out = phr_ok(&dir.0, &args, Duration::from_secs(120));
    let rows = evaluations(&out.stdout);
    // The two normalisation runs (no cached maxima yet) and at least one step of the optimiser.
    assert!(rows.len() >= 3, "{} evaluations:\n{}", rows.len(), out.stdout);
    assert!(rows.len() < budget, "{} evaluations: the time budget did not stop the optimiser", rows.len());
    for (i, &[alpha, delta, cut, sah, build_ms, value]) in rows.iter().enumerate() {
        assert!((0.4..=0.55).contains(&alpha) && (6.0..=9.0).contains(&delta), "evaluation {i}: α {alpha}, δ {delta}");
        assert!(cut > 0.0 && sah > 0.0 && build_ms >= 0.0 && value.is_finite(), "evaluation {i}: {:?}", rows[i]);
    }
    let summary = out.stdout.lines().find(|l| l.starts_with("chosen α")).unwrap_or_else(|| panic!("{}", out.stdout));
    let builds = number_between(summary, "frames, ", " builds");
    assert_eq!(builds, rows.len() as f64, "every evaluation reported is one build: {summary}");
    // The optimisation time: the normalisation builds, the budget, and the iteration under way
    // when it ran out (a build, the Gaussian process fit: a second is plenty for the latter).
    let optimisation_ms = number_between(summary, "optimisation ", " ms");
    let normalisation_ms = rows[0][4] + rows[1][4];
    let longest_build_ms = rows.iter().map(|r| r[4]).fold(0.0, f64::max);
    let bound = time_budget_ms + normalisation_ms + longest_build_ms + 1000.0;
    assert!(optimisation_ms <= bound, "optimisation took {optimisation_ms} ms, more than {bound} ms: {summary}");
}
