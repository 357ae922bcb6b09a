//! `phr bench-cut-cost`: how well PHR's build cost `b = Σ |cut|` predicts its build time
//! (the thesis found a correlation of 0.99): per mesh, the Pearson correlation of Σ|cut| with
//! the median build time over a grid of α and δ is printed, and every point goes to a CSV.
//! What is measured and how: [`phr_bench::cut_cost`].

use crate::progress::Bar;
use anyhow::{bail, Context, Result};
use clap::Args;
use phr_bench::cut_cost::{measure_cut_cost, summary, CSV_HEADER};
use phr_bench::suite::{open_mesh, select, shared_scenes_dir, SHARED_MESHES};
use phr_render::output::write_atomically;
use std::io::Write;
use std::path::PathBuf;

#[derive(Args)]
pub struct BenchCutCostArgs {
    #[arg(long)]
    scenes: Option<PathBuf>,
    /// α values.
    #[arg(long, value_delimiter = ',', default_value = "0.3,0.4,0.5,0.6,0.7")]
    alphas: Vec<f32>,
    /// δ values.
    #[arg(long, value_delimiter = ',', default_value = "4,6,8,10,12")]
    deltas: Vec<f32>,
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    /// Only meshes whose path contains one of these texts.
    #[arg(long, value_delimiter = ',')]
    only: Vec<String>,
    #[arg(long, default_value = "bench-cut-cost.csv")]
    csv: PathBuf,
}

pub fn run(args: &BenchCutCostArgs) -> Result<()> {
    if args.repeats == 0 || args.alphas.is_empty() || args.deltas.is_empty() {
        bail!("need at least one repeat, α and δ");
    }
    let dir = shared_scenes_dir(args.scenes.as_deref())?;
    let meshes = select(SHARED_MESHES, &args.only);
    let progress = crate::progress::bar((meshes.len() * args.alphas.len() * args.deltas.len()) as u64);
    let mut lines = vec![CSV_HEADER.to_string()];
    println!("{:<36} {:>7} {:>12} {:>12}", "mesh", "points", "corr(b, ms)", "ms per Mcut");
    for name in meshes {
        progress.set_message(name.to_string());
        let (geometry, _) = open_mesh(&dir, name)?;
        let points = measure_cut_cost(&geometry.boxes, &args.alphas, &args.deltas, args.repeats, &Bar(&progress));
        lines.extend(points.iter().map(|p| p.csv_row(name)));
        let (correlation, per_mcut) = summary(&points);
        progress.suspend(|| println!("{:<36} {:>7} {:>12.3} {:>12.1}", name, points.len(), correlation, per_mcut));
    }
    progress.finish_and_clear();
    write_atomically(&args.csv, |tmp| {
        let mut f = std::fs::File::create(tmp)?;
        f.write_all((lines.join("\n") + "\n").as_bytes())
    })
    .with_context(|| format!("writing {}", args.csv.display()))?;
    println!("wrote {}", args.csv.display());
    Ok(())
}
