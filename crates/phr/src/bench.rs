//! `phr bench`: the thesis's evaluation (chapter 7) reproduced by one command; the
//! measurement and the report are [`phr_bench::thesis`], this file parses arguments.

use crate::progress::{bar, Bar};
use anyhow::{bail, Result};
use clap::Args;
use phr_bench::suite::{suite_files, SUITE};
use phr_bench::thesis::{self, Materials, Plan, BUILDERS};
use std::path::PathBuf;

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
    pub materials: MaterialsArg,
    /// Also run the peers (Embree via embreex, bench/peers.py) on the same triangles and rays.
    #[arg(long)]
    pub peers: bool,
    /// Skip the full-sweep SAH builder on scenes above this many triangles (it is slow).
    #[arg(long, default_value_t = 2_000_000)]
    pub sweep_limit: usize,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum MaterialsArg {
    Thesis,
    Own,
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
            materials: materials(args.materials),
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
        materials: materials(args.materials),
    })
}

fn materials(arg: MaterialsArg) -> Materials {
    match arg {
        MaterialsArg::Thesis => Materials::Thesis,
        MaterialsArg::Own => Materials::Own,
    }
}

pub fn run(args: &BenchArgs) -> Result<()> {
    let plan = plan(args)?;
    let progress = bar(plan.steps() as u64);
    let results = thesis::run(&plan, &args.out, &Bar(&progress))?;
    progress.finish_and_clear();
    println!("{}", thesis::summary(&results));
    println!("wrote {}", thesis::report_path(&args.out).display());
    Ok(())
}
