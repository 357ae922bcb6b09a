//! `phr bench-tune`: how well the tuners do on one mesh at one resolution.
//!
//! - **Check**: Bayesian optimisation (`budget` evaluations, `seeds` seeds) against the best
//!   of a dense `dense × dense` grid over the same box ([`SearchBox::THESIS`]), with each
//!   objective (the thesis's and the calibrated frame-time model, [`calibrate`]); the gap is
//!   BO's optimum over the grid's, in %.
//! - **Frame times**, measured (PHR build including its auxiliary LBVH, plus one 1-spp frame
//!   from the mesh's framing camera): LBVH, PHR-Fast, PHR-HQ, PHR-Grid (the thesis's 4 × 4
//!   grid, thesis objective), PHR-BO with the thesis objective and with the frame-time model.

use crate::frame::median_frame;
use crate::suite::THESIS_MAX_DEPTH;
use phr_bvh::phr::PhrOptions;
use phr_bvh::Builder;
use phr_render::camera::CameraDesc;
use phr_render::geometry::Geometry;
use phr_render::scene::RenderSettings;
use phr_render::Scene;
use phr_tune::bayes::BoOptions;
use phr_tune::grid::{THESIS_ALPHAS, THESIS_DELTAS};
use phr_tune::objective::{FrameTimeModel, OMEGA_P, OMEGA_R};
use phr_tune::tune::{tune, Method, ObjectiveKind, TuneOptions};
use phr_tune::{PhrEvaluator, SearchBox};
use std::time::Instant;

/// How hard to check BO.
#[derive(Clone, Copy, Debug)]
pub struct TuneBenchOptions {
    /// BO runs (seeds `0..seeds`).
    pub seeds: u64,
    /// Evaluations per BO run.
    pub budget: usize,
    /// Side of the dense reference grid.
    pub dense: usize,
}

/// The builders whose frame times are measured, in [`TuneMeasurement::times`] order.
pub const FRAME_BUILDERS: [&str; 6] = ["LBVH", "PHR-Fast", "PHR-HQ", "PHR-Grid", "PHR-BO(e)", "PHR-BO(T)"];

/// One mesh at one resolution.
#[derive(Clone, Debug)]
pub struct TuneMeasurement {
    /// Per objective (thesis, frame time): median and largest gap of BO's optimum over the
    /// dense grid's, in %.
    pub gaps: Vec<(f64, f64)>,
    /// The thesis's 4 × 4 grid's choice (α, δ), and BO's first choice per objective.
    pub grid_choice: (f64, f64),
    pub bo_choice: Vec<(f64, f64)>,
    /// Frame ms (build + render) of [`FRAME_BUILDERS`].
    pub times: [f64; 6],
}

/// The CSV's header; [`TuneMeasurement::csv_rows`] gives its rows.
pub const CSV_HEADER: &str = "mesh,res,objective,median_gap_pct,max_gap_pct,bo_evals,grid_evals,lbvh_ms,fast_ms,hq_ms,grid_ms,bo_thesis_ms,bo_frametime_ms,grid_alpha,grid_delta,bo_alpha,bo_delta,bo_ft_alpha,bo_ft_delta";

impl TuneMeasurement {
    /// One row per objective.
    pub fn csv_rows(&self, mesh: &str, res: u32, options: &TuneBenchOptions) -> Vec<String> {
        let t = &self.times;
        let (g, b) = (self.grid_choice, &self.bo_choice);
        ["thesis", "frame-time"]
            .iter()
            .zip(&self.gaps)
            .map(|(objective, (med, max))| {
                format!(
                    "{mesh},{res},{objective},{med:.3},{max:.3},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{},{},{},{},{},{}",
                    options.budget,
                    options.dense * options.dense,
                    t[0], t[1], t[2], t[3], t[4], t[5],
                    g.0, g.1, b[0].0, b[0].1, b[1].0, b[1].1
                )
            })
            .collect()
    }
}

/// Measures one mesh (`geometry` of `scene`) at `res`², from the scene's framing camera.
pub fn measure_tuning(
    options: &TuneBenchOptions,
    evaluator: &PhrEvaluator,
    scene: &Scene,
    geometry: &mut Geometry,
    res: u32,
) -> TuneMeasurement {
    let view = scene.framing_camera();
    let size = RenderSettings { width: res, height: res, spp: 1, max_depth: THESIS_MAX_DEPTH };
    let thesis = ObjectiveKind::Thesis { width: res, height: res, omega_p: OMEGA_P, omega_r: OMEGA_R };
    let model = calibrate(evaluator, scene, geometry, &view, &size, &SearchBox::THESIS);
    let (mut gaps, mut bo_choice) = (Vec::new(), Vec::new());
    for objective in [thesis, ObjectiveKind::FrameTime(model)] {
        let (gap, choice) = bo_gap(options, evaluator, objective);
        gaps.push(gap);
        bo_choice.push(choice);
    }
    let grid4 = tune(
        evaluator,
        &thesis_box(Method::Grid { alphas: THESIS_ALPHAS.to_vec(), deltas: THESIS_DELTAS.to_vec() }, thesis),
    );
    let grid_choice = (grid4.best.alpha, grid4.best.delta);
    let phr = |(a, d): (f64, f64)| Builder::Phr(PhrOptions::with(a as f32, d as f32));
    let builders = [
        Builder::default(),
        Builder::PHR_FAST,
        Builder::PHR_HQ,
        phr(grid_choice),
        phr(bo_choice[0]),
        phr(bo_choice[1]),
    ];
    let times = builders.map(|b| frame_ms(b, scene, geometry, &view, &size));
    TuneMeasurement { gaps, grid_choice, bo_choice, times }
}

/// The frame-time model `k_b·b + k_r·c·rays`, calibrated by building and rendering at the
/// search box's two corners.
pub fn calibrate(
    evaluator: &PhrEvaluator,
    scene: &Scene,
    geometry: &mut Geometry,
    view: &CameraDesc,
    settings: &RenderSettings,
    search: &SearchBox,
) -> FrameTimeModel {
    let mut builds = Vec::new();
    let mut renders = Vec::new();
    let mut rays_sum = 0.0;
    let corners = [search.lower, search.upper];
    for [a, d] in corners {
        let e = evaluator.evaluate(a, d);
        let (ms, rays) = median_frame(scene, geometry, evaluator.build(a, d), view, settings);
        builds.push(e);
        renders.push((e.sah_cost, rays, ms));
        rays_sum += rays;
    }
    FrameTimeModel::calibrate(&builds, &renders, rays_sum / corners.len() as f64)
}

fn thesis_box(method: Method, objective: ObjectiveKind) -> TuneOptions {
    TuneOptions { method, objective, search: SearchBox::THESIS, cache: None }
}

/// BO's gap to the dense grid under `objective` over the seeds (median, largest, in %), and
/// the first seed's choice.
fn bo_gap(options: &TuneBenchOptions, evaluator: &PhrEvaluator, objective: ObjectiveKind) -> ((f64, f64), (f64, f64)) {
    let (alphas, deltas) = SearchBox::THESIS.grid(options.dense);
    let dense = Method::Grid { alphas, deltas };
    let mut gaps = Vec::new();
    let mut first = None;
    for seed in 0..options.seeds.max(1) {
        let bo_options = BoOptions { budget: options.budget, seed, ..Default::default() };
        let bo = tune(evaluator, &thesis_box(Method::Bayes(bo_options), objective));
        // Score the dense grid with the BO run's own objective (same normalisation).
        let grid = tune(evaluator, &thesis_box(dense.clone(), objective));
        let grid_best = grid.evaluations.iter().map(|(e, _)| bo.objective.value(e)).fold(f64::INFINITY, f64::min);
        gaps.push((bo.best_value / grid_best - 1.0) * 100.0);
        first.get_or_insert((bo.best.alpha, bo.best.delta));
    }
    let gap = crate::Stat::of(gaps);
    ((gap.median, gap.max), first.expect("at least one seed"))
}

/// The median of three builds plus the median of three frames, ms.
fn frame_ms(builder: Builder, scene: &Scene, geometry: &mut Geometry, view: &CameraDesc, size: &RenderSettings) -> f64 {
    let mut builds: Vec<(f64, phr_bvh::Bvh)> = (0..3)
        .map(|_| {
            let start = Instant::now();
            let bvh = geometry.build_report(&builder).bvh;
            (start.elapsed().as_secs_f64() * 1e3, bvh)
        })
        .collect();
    builds.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (build_ms, bvh) = builds.swap_remove(1);
    build_ms + median_frame(scene, geometry, bvh, view, size).0
}
