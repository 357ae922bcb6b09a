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

pub fn run(args: &BenchTuneArgs) -> Result<()> {
    let dir = scenes_folder(&args.scenes)?;
    let meshes: Vec<&str> = MESHES
        .iter()
        .copied()
        .filter(|m| !m.starts_with("cornell"))
        .filter(|m| args.only.is_empty() || args.only.iter().any(|o| m.contains(o.as_str())))
        .collect();
    let progress = crate::progress::bar((meshes.len() * args.resolutions.len()) as u64);
    let mut csv = vec!["mesh,res,objective,median_gap_pct,max_gap_pct,bo_evals,grid_evals,lbvh_ms,fast_ms,hq_ms,grid_ms,bo_thesis_ms,bo_frametime_ms,grid_alpha,grid_delta,bo_alpha,bo_delta,bo_ft_alpha,bo_ft_delta".to_string()];
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
        let (alphas, deltas) = SearchBox::THESIS.grid(args.dense);
        let dense = Method::Grid { alphas, deltas };
        for &res in &args.resolutions {
            progress.set_message(format!("{name} at {res}²"));
            let view = scene.framing_camera();
            let size = RenderSettings { width: res, height: res, spp: 1, max_depth: MAX_DEPTH };
            let thesis = ObjectiveKind::Thesis { width: res, height: res, omega_p: OMEGA_P, omega_r: OMEGA_R };
            let model = calibrate(&evaluator, &scene, &mut geometry, &view, &size, &SearchBox::THESIS);
            let frame_time = ObjectiveKind::FrameTime(model);
            let options =
                |method: Method, objective| TuneOptions { method, objective, search: SearchBox::THESIS, cache: None };
            let mut gaps = Vec::new();
            let mut bo_choice = Vec::new();
            for objective in [thesis, frame_time] {
                let mut seed_gaps = Vec::new();
                let mut first = None;
                for seed in 0..args.seeds {
                    let bo = tune(
                        &evaluator,
                        &options(
                            Method::Bayes(BoOptions { budget: args.budget, seed, ..Default::default() }),
                            objective,
                        ),
                    );
                    // Score the dense grid with the BO run's own objective (same normalisation).
                    let grid = tune(&evaluator, &options(dense.clone(), objective));
                    let grid_best =
                        grid.evaluations.iter().map(|(e, _)| bo.objective.value(e)).fold(f64::INFINITY, f64::min);
                    seed_gaps.push((bo.best_value / grid_best - 1.0) * 100.0);
                    first.get_or_insert((bo.best.alpha, bo.best.delta));
                }
                gaps.push((median(seed_gaps.clone()), seed_gaps.iter().copied().fold(f64::NEG_INFINITY, f64::max)));
                bo_choice.push(first.expect("at least one seed"));
            }
            let grid4 = tune(
                &evaluator,
                &options(Method::Grid { alphas: THESIS_ALPHAS.to_vec(), deltas: THESIS_DELTAS.to_vec() }, thesis),
            );
            let grid_choice = (grid4.best.alpha, grid4.best.delta);
            // Median of three builds plus the median of three frames.
            let mut frame = |builder: Builder| {
                let mut builds: Vec<(f64, phr_bvh::Bvh)> = (0..3)
                    .map(|_| {
                        let start = Instant::now();
                        let bvh = builder.build(&geometry.boxes);
                        (start.elapsed().as_secs_f64() * 1e3, bvh)
                    })
                    .collect();
                builds.sort_by(|a, b| a.0.total_cmp(&b.0));
                let (build_ms, bvh) = builds.swap_remove(1);
                build_ms + median_frame(&scene, &mut geometry, bvh, &view, &size).0
            };
            let phr = |(a, d): (f64, f64)| Builder::Phr(PhrOptions::with(a as f32, d as f32));
            let times = [
                frame(Builder::default()),
                frame(Builder::PHR_FAST),
                frame(Builder::PHR_HQ),
                frame(phr(grid_choice)),
                frame(phr(bo_choice[0])),
                frame(phr(bo_choice[1])),
            ];
            progress.suspend(|| {
                println!(
                    "{:<36} {:>4} | {:>6.2}% (≤{:>5.2}) {:>6.2}% (≤{:>5.2}) | {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>9.1} {:>9.1}",
                    name, res, gaps[0].0, gaps[0].1, gaps[1].0, gaps[1].1, times[0], times[1], times[2], times[3], times[4], times[5]
                )
            });
            for (objective, (med, max)) in ["thesis", "frame-time"].iter().zip(&gaps) {
                csv.push(format!(
                    "{name},{res},{objective},{med:.3},{max:.3},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{},{},{},{},{},{}",
                    args.budget,
                    args.dense * args.dense,
                    times[0],
                    times[1],
                    times[2],
                    times[3],
                    times[4],
                    times[5],
                    grid_choice.0,
                    grid_choice.1,
                    bo_choice[0].0,
                    bo_choice[0].1,
                    bo_choice[1].0,
                    bo_choice[1].1
                ));
            }
            progress.inc(1);
        }
    }
    progress.finish_and_clear();
    write_atomically(&args.csv, |tmp| std::fs::File::create(tmp)?.write_all((csv.join("\n") + "\n").as_bytes()))
        .with_context(|| format!("writing {}", args.csv.display()))?;
    println!("wrote {}", args.csv.display());
    Ok(())
}
