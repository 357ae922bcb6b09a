//! `phr bench-tune`: how well the tuners do, on every shared mesh at 256² and 512²: BO's gap
//! to a dense grid per objective, and the frame times of the builders and tuners' choices.
//! What is measured and how: [`phr_bench::tune_bench`].

use anyhow::{Context, Result};
use clap::Args;
use phr_bench::suite::{open_mesh, select, shared_scenes_dir, SHARED_MESHES};
use phr_bench::tune_bench::{measure_tuning, TuneBenchOptions, CSV_HEADER};
use phr_bvh::phr::PhrOptions;
use phr_render::output::write_atomically;
use phr_tune::PhrEvaluator;
use std::io::Write;
use std::path::PathBuf;

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

pub fn run(args: &BenchTuneArgs) -> Result<()> {
    let dir = shared_scenes_dir(args.scenes.as_deref())?;
    // The Cornell box is too small for tuning to matter.
    let meshes: Vec<&str> =
        select(SHARED_MESHES, &args.only).into_iter().filter(|m| !m.starts_with("cornell")).collect();
    let options = TuneBenchOptions { seeds: args.seeds, budget: args.budget, dense: args.dense };
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
            let m = measure_tuning(&options, &evaluator, &scene, &mut geometry, res);
            progress.suspend(|| {
                let (g, t) = (&m.gaps, &m.times);
                println!(
                    "{:<36} {:>4} | {:>6.2}% (≤{:>5.2}) {:>6.2}% (≤{:>5.2}) | {:>8.1} {:>8.1} {:>8.1} {:>8.1} {:>9.1} {:>9.1}",
                    name, res, g[0].0, g[0].1, g[1].0, g[1].1, t[0], t[1], t[2], t[3], t[4], t[5]
                )
            });
            csv.extend(m.csv_rows(name, res, &options));
            progress.inc(1);
        }
    }
    progress.finish_and_clear();
    write_atomically(&args.csv, |tmp| std::fs::File::create(tmp)?.write_all((csv.join("\n") + "\n").as_bytes()))
        .with_context(|| format!("writing {}", args.csv.display()))?;
    println!("wrote {}", args.csv.display());
    Ok(())
}
