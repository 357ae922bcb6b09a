//! The optimisers on real PHR builds of a synthetic scene: Bayesian optimisation against a
//! dense grid, the thesis's normalisation runs, and the maxima cache.

use glam::Vec3;
use phr_bvh::phr::PhrOptions;
use phr_bvh::Aabb;
use phr_tune::bayes::BoOptions;
use phr_tune::grid::linspace;
use phr_tune::objective::FrameTimeModel;
use phr_tune::tune::{tune, Method, ObjectiveKind, TuneOptions};
use phr_tune::{PhrEvaluator, SearchBox};

fn soup(n: usize) -> Vec<Aabb> {
    let mut s = 7u64;
    let mut r = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    (0..n)
        .map(|_| {
            let c = Vec3::new(r(), r(), r());
            Aabb::new(c, c + Vec3::new(r(), r(), r()) * 0.02)
        })
        .collect()
}

fn options(method: Method, objective: ObjectiveKind) -> TuneOptions {
    TuneOptions { method, objective, search: SearchBox::THESIS, cache: None }
}

/// A frame-time model whose optimum lies inside the box: build cost and trace cost compete.
fn balanced_model(evaluator: &PhrEvaluator) -> FrameTimeModel {
    let lo = evaluator.evaluate(0.4, 6.0);
    let hi = evaluator.evaluate(0.55, 9.0);
    // Weigh the SAH gain over the box as much as the build-cost growth.
    let k_build = 1.0 / (hi.build_cost - lo.build_cost);
    let k_render = 1.0 / (lo.sah_cost - hi.sah_cost).max(1e-9);
    FrameTimeModel { k_build, k_render, rays: 1.0 }
}

#[test]
fn bayes_matches_a_dense_grid_with_fewer_evaluations() {
    let evaluator = PhrEvaluator::new(&soup(20_000), PhrOptions::FAST);
    let objective = ObjectiveKind::FrameTime(balanced_model(&evaluator));
    let grid = tune(
        &evaluator,
        &options(Method::Grid { alphas: linspace(0.4, 0.55, 16), deltas: linspace(6.0, 9.0, 16) }, objective),
    );
    assert_eq!(grid.evaluations.len(), 256);
    let mut gaps = Vec::new();
    for seed in 0..5 {
        let bo = tune(&evaluator, &options(Method::Bayes(BoOptions { seed, ..Default::default() }), objective));
        assert!(bo.evaluations.len() <= 20);
        gaps.push(bo.best_value / grid.best_value - 1.0);
    }
    gaps.sort_by(f64::total_cmp);
    assert!(gaps[2] <= 0.02, "median gap to the dense grid's best: {:?}", gaps);
}

#[test]
fn thesis_objective_normalises_and_caches() {
    let evaluator = PhrEvaluator::new(&soup(5_000), PhrOptions::FAST);
    let dir = std::env::temp_dir().join(format!("phr-tune-test-{}", std::process::id()));
    let cache = Some((dir.join("maxima.json"), "soup".to_string()));
    let thesis = ObjectiveKind::Thesis { width: 256, height: 256, omega_p: 2e6, omega_r: 2e5 };
    let bo = BoOptions { budget: 6, ..Default::default() };
    let first = tune(&evaluator, &TuneOptions { cache: cache.clone(), ..options(Method::Bayes(bo), thesis) });
    // The two normalisation runs come first: the lowest and the highest parameters.
    assert_eq!((first.evaluations[0].0.alpha, first.evaluations[0].0.delta), (0.4, 6.0));
    assert_eq!((first.evaluations[1].0.alpha, first.evaluations[1].0.delta), (0.55, 9.0));
    assert!(first.evaluations[1].0.build_cost > first.evaluations[0].0.build_cost);
    // With the maxima cached, a second run starts straight with the optimiser.
    let second = tune(&evaluator, &TuneOptions { cache, ..options(Method::Bayes(bo), thesis) });
    assert_ne!((second.evaluations[0].0.alpha, second.evaluations[0].0.delta), (0.4, 6.0));
    assert_eq!(second.objective, first.objective);
    std::fs::remove_dir_all(dir).unwrap();
}
