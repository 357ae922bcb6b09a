//! `phr tune`: choose PHR's α and δ for a scene, view and image size (thesis chapter 6), by
//! grid search or Bayesian optimisation, with the thesis's objective or a calibrated
//! frame-time model. Prints every evaluation, the choice, the optimisation time, and that time
//! expressed in frames of the chosen configuration (thesis Figure 7.2).

use crate::scene_arg::{open_scene, BUILTIN};
use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use phr_bench::frame::median_frame;
use phr_bench::tune_bench::calibrate;
use phr_bvh::phr::PhrOptions;
use phr_render::geometry::Geometry;
use phr_render::scene::RenderSettings;
use phr_tune::bayes::BoOptions;
use phr_tune::grid::{THESIS_ALPHAS, THESIS_DELTAS};
use phr_tune::objective::{OMEGA_P, OMEGA_R};
use phr_tune::tune::{tune, Method, ObjectiveKind, TuneOptions, TuneResult};
use phr_tune::{PhrEvaluator, SearchBox};
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum MethodArg {
    Grid,
    Bo,
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ObjectiveArg {
    /// The thesis's e(α, δ) = b / max b + ω² c / max c.
    Thesis,
    /// Predicted frame time k_b·b + k_r·c·rays, calibrated by measured frames.
    FrameTime,
}

#[derive(Args)]
pub struct TuneArgs {
    /// A scene file (.json), a mesh (.obj, .ply, .gltf, .glb, optionally .gz), `builtin`, or a
    /// scene of scenes/suite by name (sponza, dragon, ...).
    #[arg(default_value = BUILTIN)]
    pub scene: String,
    #[arg(long)]
    pub view: Option<String>,
    #[arg(long, default_value_t = 256)]
    pub width: u32,
    #[arg(long, default_value_t = 256)]
    pub height: u32,
    #[arg(long, value_enum, default_value = "bo")]
    pub method: MethodArg,
    #[arg(long, value_enum, default_value = "thesis")]
    pub objective: ObjectiveArg,
    /// Evaluations for Bayesian optimisation (the normalisation runs included).
    #[arg(long, default_value_t = 20)]
    pub budget: usize,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Stop Bayesian optimisation after this many milliseconds.
    #[arg(long)]
    pub time_budget_ms: Option<u64>,
    /// Grid values of α (grid search), also the search box (its smallest and largest).
    #[arg(long, value_delimiter = ',', default_values_t = THESIS_ALPHAS)]
    pub alphas: Vec<f64>,
    /// Grid values of δ (grid search), also the search box.
    #[arg(long, value_delimiter = ',', default_values_t = THESIS_DELTAS)]
    pub deltas: Vec<f64>,
    #[arg(long, default_value_t = OMEGA_P)]
    pub omega_p: f64,
    #[arg(long, default_value_t = OMEGA_R)]
    pub omega_r: f64,
    /// Maximum path segments of the measured frames (the thesis benchmark: 5 bounces).
    #[arg(long, default_value_t = 6)]
    pub max_depth: u32,
    /// Cache file for the thesis objective's maxima.
    #[arg(long, default_value = "phr-tune-cache.json")]
    pub cache: PathBuf,
}

pub fn run(args: &TuneArgs) -> Result<()> {
    if args.alphas.is_empty() || args.deltas.is_empty() || args.budget < 3 {
        bail!("need at least one α, one δ and a budget of 3");
    }
    let size = RenderSettings { width: args.width, height: args.height, spp: 1, max_depth: args.max_depth };
    size.check().map_err(anyhow::Error::msg)?;
    let scene = open_scene(&args.scene)?;
    let view = scene.view(args.view.as_deref()).with_context(|| format!("no view {:?}", args.view))?;
    let mut geometry = Geometry::new(&scene);
    let progress = ProgressBar::new_spinner();
    progress
        .set_style(ProgressStyle::with_template("{spinner} tuning: {pos} builds, {elapsed} {msg}").expect("template"));
    progress.enable_steady_tick(Duration::from_millis(100));
    let bar = progress.clone();
    let evaluator = PhrEvaluator::new(&geometry.boxes, PhrOptions::FAST).with_progress(move |e| {
        bar.inc(1);
        bar.set_message(format!("last α {:.3} δ {:.2}", e.alpha, e.delta));
    });
    let search = SearchBox::spanning(&args.alphas, &args.deltas);
    let objective = match args.objective {
        ObjectiveArg::Thesis => ObjectiveKind::Thesis {
            width: args.width,
            height: args.height,
            omega_p: args.omega_p,
            omega_r: args.omega_r,
        },
        ObjectiveArg::FrameTime => {
            ObjectiveKind::FrameTime(calibrate(&evaluator, &scene, &mut geometry, &view, &size, &search))
        }
    };
    let method = match args.method {
        MethodArg::Grid => Method::Grid { alphas: args.alphas.clone(), deltas: args.deltas.clone() },
        MethodArg::Bo => Method::Bayes(BoOptions {
            budget: args.budget,
            seed: args.seed,
            time_budget: args.time_budget_ms.map(Duration::from_millis),
            ..Default::default()
        }),
    };
    let key = format!("{}|{}|{:?}|{:?}", args.scene, geometry.prim_count(), search.lower, search.upper);
    let result = tune(&evaluator, &TuneOptions { method, objective, search, cache: Some((args.cache.clone(), key)) });
    progress.finish_and_clear();
    report(args, &result);
    let (a, d) = (result.best.alpha, result.best.delta);
    let start = Instant::now();
    let bvh = evaluator.build(a, d);
    let build_ms = start.elapsed().as_secs_f64() * 1e3;
    let (render_ms, _) = median_frame(&scene, &mut geometry, bvh, &view, &size);
    let frame_ms = build_ms + render_ms;
    let opt_ms = result.elapsed.as_secs_f64() * 1e3;
    println!(
        "chosen α = {a:.3}, δ = {d:.2} | frame {frame_ms:.1} ms (PHR build {build_ms:.1} + render {render_ms:.1}, {}x{}, 1 spp) | optimisation {opt_ms:.0} ms = {:.1} frames, {} builds",
        args.width,
        args.height,
        opt_ms / frame_ms,
        evaluator.builds()
    );
    Ok(())
}

fn report(args: &TuneArgs, result: &TuneResult) {
    let name = match args.objective {
        ObjectiveArg::Thesis => "e(α,δ)",
        ObjectiveArg::FrameTime => "T ms",
    };
    println!("{:>4} {:>7} {:>7} {:>10} {:>9} {:>9} {:>10}", "#", "α", "δ", "Σ|cut|", "SAH(2,1)", "build ms", name);
    for (i, (e, v)) in result.evaluations.iter().enumerate() {
        println!(
            "{:>4} {:>7.3} {:>7.2} {:>10} {:>9.3} {:>9.2} {:>10.4}",
            i + 1,
            e.alpha,
            e.delta,
            e.build_cost,
            e.sah_cost,
            e.build_ms,
            v
        );
    }
}
