//! `phr bench`: the thesis's evaluation (chapter 7) reproduced by one command, on the scene
//! suite in `scenes/suite` (Bunny, Sponza, Sibenik, Dragon, Conference, and eight dragons for
//! scaling; each with three views, white sky, diffuse, 5 bounces, 60° field of view).
//!
//! For every scene, resolution and builder it measures build time (auxiliary LBVH and PHR
//! apart), SAH cost, `Σ |cut|`, render time (1 spp, mean over the views), frame time and
//! Mrays/s, with median and spread over repeats; PHR-Grid and PHR-BO are tuned per scene and
//! resolution, and their tuning time is given in frames. Results go to `DIR` as CSV, JSON, a
//! Markdown report in the layout of the thesis's Table 7.1, and plots ([`plots`]); with
//! `--peers`, Embree on the same triangles and rays ([`peers`]).

mod measure;
mod peers;
mod plots;
mod report;

use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};

use phr_bench::suite::{suite_files, SUITE};
pub use phr_bench::Stat;

/// Builders measured by default, by name (`phr-grid` and `phr-bo` are tuned per scene).
pub const BUILDERS: &[&str] = &["lbvh", "phr-fast", "phr-hq", "phr-grid", "phr-bo", "binned-sah", "sweep-sah"];

#[derive(Args)]
pub struct BenchArgs {
    /// Scene files (default: the suite in scenes/suite).
    pub scenes: Vec<PathBuf>,
    #[arg(long, value_delimiter = ',', default_value = "256,512")]
    pub resolutions: Vec<u32>,
    #[arg(long, value_delimiter = ',', default_values_t = BUILDERS.iter().map(|s| s.to_string()))]
    pub builders: Vec<String>,
    /// Builds and frames per measurement (median and spread are reported).
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Output folder.
    #[arg(long, default_value = "bench-report")]
    pub out: PathBuf,
    /// A small run (bunny, one view, one repeat, 256², no reference builders), for CI.
    #[arg(long)]
    pub quick: bool,
    /// `thesis`: every surface diffuse (albedo 0.7), white sky, up to 6 path segments,
    /// whatever the scene file says (the thesis's benchmark setting); `own`: the scene files'
    /// own materials, background and depth.
    #[arg(long, value_enum, default_value = "thesis")]
    pub materials: Materials,
    /// Also run the peers (Embree via embreex, bench/peers.py) on the same triangles and rays.
    #[arg(long)]
    pub peers: bool,
    /// Skip the full-sweep SAH builder on scenes above this many triangles (it is slow).
    #[arg(long, default_value_t = 2_000_000)]
    pub sweep_limit: usize,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Materials {
    Thesis,
    Own,
}

/// What the measurement needs to know, after `--quick` is applied.
pub struct Plan {
    pub scenes: Vec<PathBuf>,
    pub resolutions: Vec<u32>,
    pub builders: Vec<String>,
    pub repeats: usize,
    pub max_views: usize,
    pub branching: Vec<u32>,
    pub cut_grid: (Vec<f64>, Vec<f64>),
    pub sweep_limit: usize,
    pub peers: bool,
    pub materials: Materials,
}

fn plan(args: &BenchArgs) -> Result<Plan> {
    let known = |b: &String| BUILDERS.contains(&b.as_str());
    if let Some(b) = args.builders.iter().find(|b| !known(b)) {
        bail!("unknown builder \"{b}\" for bench (available: {})", BUILDERS.join(", "));
    }
    if args.repeats == 0 || args.resolutions.is_empty() || args.resolutions.contains(&0) {
        bail!("need at least one repeat and one non-zero resolution");
    }
    let suite = suite_files;
    if args.quick {
        return Ok(Plan {
            scenes: if args.scenes.is_empty() { suite(&["bunny"])? } else { args.scenes.clone() },
            resolutions: vec![256],
            builders: ["lbvh", "phr-fast", "phr-hq", "phr-grid", "phr-bo"].iter().map(|s| s.to_string()).collect(),
            repeats: 1,
            max_views: 1,
            branching: vec![2, 4],
            cut_grid: (vec![0.4, 0.6], vec![6.0, 9.0]),
            sweep_limit: args.sweep_limit,
            peers: args.peers,
            materials: args.materials,
        });
    }
    Ok(Plan {
        scenes: if args.scenes.is_empty() { suite(SUITE)? } else { args.scenes.clone() },
        resolutions: args.resolutions.clone(),
        builders: args.builders.clone(),
        repeats: args.repeats,
        max_views: 3,
        branching: vec![2, 4, 8, 16],
        cut_grid: (vec![0.4, 0.5, 0.6, 0.7], vec![5.0, 7.0, 9.0, 11.0]),
        sweep_limit: args.sweep_limit,
        peers: args.peers,
        materials: args.materials,
    })
}

pub fn run(args: &BenchArgs) -> Result<()> {
    let plan = plan(args)?;
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let steps = plan.scenes.len() * (plan.resolutions.len() * plan.builders.len() + plan.branching.len() + 1);
    let progress = crate::progress::bar(steps as u64);
    let mut results = measure::Results::default();
    for scene in &plan.scenes {
        measure::measure_scene(scene, &plan, &args.out, &progress, &mut results)
            .with_context(|| format!("benchmarking {}", scene.display()))?;
    }
    progress.finish_and_clear();
    report::write_all(&args.out, &plan, &results)?;
    plots::write_all(&args.out, &results)?;
    println!("{}", report::summary(&results));
    println!("wrote {}", Path::new(&args.out).join("report.md").display());
    Ok(())
}
