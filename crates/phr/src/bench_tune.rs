//! `phr bench-tune`: how well the tuners do, on every shared mesh at 256² and 512².
//!
//! - **Check**: Bayesian optimisation (budget 20, 10 seeds) against the best of a dense 16 × 16
//!   grid over the same box, with each objective; the median gap must stay within 2 %.
//! - **Frame times**, measured (PHR build including its auxiliary LBVH, plus one 1-spp frame
//!   from the mesh's framing camera): LBVH, PHR-Fast, PHR-HQ, PHR-Grid (the thesis's 4 × 4
//!   grid, thesis objective), PHR-BO with the thesis objective and with the frame-time model.

use crate::bench_build::{open_mesh, scenes_folder, MESHES};
use crate::tune::calibrate;
use anyhow::{Context, Result};
use clap::Args;
use phr_bench::frame::median_frame;
use phr_bvh::phr::PhrOptions;
use phr_bvh::Builder;
use phr_render::output::write_atomically;
use phr_render::scene::RenderSettings;
use phr_tune::bayes::BoOptions;
use phr_tune::grid::{THESIS_ALPHAS, THESIS_DELTAS};
use phr_tune::objective::{OMEGA_P, OMEGA_R};
use phr_tune::tune::{tune, Method, ObjectiveKind, TuneOptions};
use phr_tune::{PhrEvaluator, SearchBox};
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct BenchTuneArgs {
    #[arg(long)]
    scenes: Option<PathBuf>,
    #[arg(long, value_delimiter = ',', default_value = "256,512")]
    resolutions: Vec<u32>,
    #[arg(long, default_value_t = 10)]
    seeds: u64,
    #[arg(long, default_value_t = 20)]
    budget: usize,
    /// Side of the dense reference grid.
    #[arg(long, default_value_t = 16)]
    dense: usize,
    /// Only meshes whose path contains one of these texts.
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    #[arg(long, default_value = "bench-tune.csv")]
    csv: PathBuf,
}

const MAX_DEPTH: u32 = 6;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

const CSV_HEADER: &str = "mesh,res,objective,median_gap_pct,max_gap_pct,bo_evals,grid_evals,lbvh_ms,fast_ms,hq_ms,grid_ms,bo_thesis_ms,bo_frametime_ms,grid_alpha,grid_delta,bo_alpha,bo_delta,bo_ft_alpha,bo_ft_delta";

pub fn run(args: &BenchTuneArgs) -> Result<()> {
    let dir = scenes_folder(&args.scenes)?;
    let meshes: Vec<&str> = MESHES
        .iter()
        .copied()
        .filter(|m| !m.starts_with("cornell"))
        .filter(|m| args.only.is_empty() || args.only.iter().any(|o| m.contains(o.as_str())))
        .collect();
    let progress = crate::progress::bar((meshes.len() * args.resolutions.len()) as u64);
    let mut csv = vec![CSV_HEADER.to_string()];
    println!(
        "{:<36} {:>4} | {:>14} {:>14} | {:>8} {:>8} {:>8} {:>8} {:>9} {:>9}",
        "mesh",
        "res",
        "BO gap e (med)",
        "BO gap T (med)",
        "LBVH ms",
        "Fast ms",
        "HQ ms",
        "Grid ms",
        "BO(e) ms",
        "BO(T) ms"
    );
    for name in meshes {
        let (mut geometry, scene) = open_mesh(&dir, name)?;
        let evaluator = PhrEvaluator::new(&geometry.boxes, PhrOptions::FAST);
        for &res in &args.resolutions {
            progress.set_message(format!("{name} at {res}²"));
            let m = measure(args, &evaluator, &scene, &mut geometry, res);
            progress.suspend(|| {
                let (g, t) = (&m.gaps, &m.times);
                println!(
                    "{:<36} {:>4} | {:>6.2}% (≤{:>5.2}) {:>6.2}% (≤{:>5.2}) | {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>9.1} {:>9.1}",
                    name, res, g[0].0, g[0].1, g[1].0, g[1].1, t[0], t[1], t[2], t[3], t[4], t[5]
                )
            });
            csv.extend(m.csv_rows(name, res, args));
            progress.inc(1);
        }
    }
    progress.finish_and_clear();
    write_atomically(&args.csv, |tmp| std::fs::File::create(tmp)?.write_all((csv.join("\n") + "\n").as_bytes()))
        .with_context(|| format!("writing {}", args.csv.display()))?;
    println!("wrote {}", args.csv.display());
    Ok(())
}

/// One mesh at one resolution.
struct Measurement {
    /// Per objective (thesis, frame time): median and largest gap of BO's optimum over the
    /// dense grid's, in %.
    gaps: Vec<(f64, f64)>,
    /// The thesis's 4 × 4 grid's choice, and BO's first choice per objective.
    grid_choice: (f64, f64),
    bo_choice: Vec<(f64, f64)>,
    /// Frame ms (build + render) of LBVH, PHR-Fast, PHR-HQ, the grid's, BO(e)'s and BO(T)'s.
    times: [f64; 6],
}

impl Measurement {
    fn csv_rows(&self, name: &str, res: u32, args: &BenchTuneArgs) -> Vec<String> {
        let t = &self.times;
        let (g, b) = (self.grid_choice, &self.bo_choice);
        ["thesis", "frame-time"]
            .iter()
            .zip(&self.gaps)
            .map(|(objective, (med, max))| {
                format!(
                    "{name},{res},{objective},{med:.3},{max:.3},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{},{},{},{},{},{}",
                    args.budget,
                    args.dense * args.dense,
                    t[0], t[1], t[2], t[3], t[4], t[5],
                    g.0, g.1, b[0].0, b[0].1, b[1].0, b[1].1
                )
            })
            .collect()
    }
}

fn measure(
    args: &BenchTuneArgs,
    evaluator: &PhrEvaluator,
    scene: &phr_render::Scene,
    geometry: &mut phr_render::geometry::Geometry,
    res: u32,
) -> Measurement {
    let view = scene.framing_camera();
    let size = RenderSettings { width: res, height: res, spp: 1, max_depth: MAX_DEPTH };
    let thesis = ObjectiveKind::Thesis { width: res, height: res, omega_p: OMEGA_P, omega_r: OMEGA_R };
    let model = calibrate(evaluator, scene, geometry, &view, &size, &SearchBox::THESIS);
    let (mut gaps, mut bo_choice) = (Vec::new(), Vec::new());
    for objective in [thesis, ObjectiveKind::FrameTime(model)] {
        let (gap, choice) = bo_gap(args, evaluator, objective);
        gaps.push(gap);
        bo_choice.push(choice);
    }
    let grid4 = tune(
        evaluator,
        &options(Method::Grid { alphas: THESIS_ALPHAS.to_vec(), deltas: THESIS_DELTAS.to_vec() }, thesis),
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
    Measurement { gaps, grid_choice, bo_choice, times }
}

fn options(method: Method, objective: ObjectiveKind) -> TuneOptions {
    TuneOptions { method, objective, search: SearchBox::THESIS, cache: None }
}

/// BO's gap to the dense grid under `objective` over the seeds (median, largest, in %), and
/// the first seed's choice.
fn bo_gap(args: &BenchTuneArgs, evaluator: &PhrEvaluator, objective: ObjectiveKind) -> ((f64, f64), (f64, f64)) {
    let (alphas, deltas) = SearchBox::THESIS.grid(args.dense);
    let dense = Method::Grid { alphas, deltas };
    let mut gaps = Vec::new();
    let mut first = None;
    for seed in 0..args.seeds {
        let bo_options = BoOptions { budget: args.budget, seed, ..Default::default() };
        let bo = tune(evaluator, &options(Method::Bayes(bo_options), objective));
        // Score the dense grid with the BO run's own objective (same normalisation).
        let grid = tune(evaluator, &options(dense.clone(), objective));
        let grid_best = grid.evaluations.iter().map(|(e, _)| bo.objective.value(e)).fold(f64::INFINITY, f64::min);
        gaps.push((bo.best_value / grid_best - 1.0) * 100.0);
        first.get_or_insert((bo.best.alpha, bo.best.delta));
    }
    let largest = gaps.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    ((median(gaps), largest), first.expect("at least one seed"))
}

/// The median of three builds plus the median of three frames, ms.
fn frame_ms(
    builder: Builder,
    scene: &phr_render::Scene,
    geometry: &mut phr_render::geometry::Geometry,
    view: &phr_render::camera::CameraDesc,
    size: &RenderSettings,
) -> f64 {
    let mut builds: Vec<(f64, phr_bvh::Bvh)> = (0..3)
        .map(|_| {
            let start = Instant::now();
            let bvh = builder.build(&geometry.boxes);
            (start.elapsed().as_secs_f64() * 1e3, bvh)
        })
        .collect();
    builds.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (build_ms, bvh) = builds.swap_remove(1);
    build_ms + median_frame(scene, geometry, bvh, view, size).0
}
