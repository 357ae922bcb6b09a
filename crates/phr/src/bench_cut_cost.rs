//! `phr bench-cut-cost`: how well PHR's build cost `b = Σ |cut|` predicts its build time
//! (the thesis found a correlation of 0.99). For each mesh, PHR is built from one auxiliary
//! LBVH over a grid of α and δ; the Pearson correlation of Σ|cut| with the median build time
//! is printed per mesh, and every point goes to a CSV.

use crate::bench_build::{open_mesh, scenes_folder, MESHES};
use anyhow::{bail, Context, Result};
use clap::Args;
use phr_bvh::builder::PHR_AUX;
use phr_bvh::phr::{build_phr_with, AuxCounts, PhrOptions};
use phr_bvh::{build_lbvh, sah_cost, SahConstants};
use phr_render::output::write_atomically;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

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
    let dir = scenes_folder(&args.scenes)?;
    let meshes: Vec<&str> = MESHES
        .iter()
        .copied()
        .filter(|m| args.only.is_empty() || args.only.iter().any(|o| m.contains(o.as_str())))
        .collect();
    let points = args.alphas.len() * args.deltas.len();
    let progress = crate::progress::bar((meshes.len() * points) as u64);
    let mut lines = vec!["mesh,alpha,delta,build_cost,build_ms,sah_cost_1_1".to_string()];
    println!("{:<36} {:>7} {:>12} {:>12}", "mesh", "points", "corr(b, ms)", "ms per Mcut");
    for name in meshes {
        progress.set_message(name.to_string());
        let (geometry, _) = open_mesh(&dir, name)?;
        let aux = build_lbvh(&geometry.boxes, PHR_AUX);
        let counts = AuxCounts::new(&aux);
        let (mut costs, mut times) = (Vec::new(), Vec::new());
        for &alpha in &args.alphas {
            for &delta in &args.deltas {
                let options = PhrOptions::with(alpha, delta);
                let mut runs: Vec<(f64, u64, f64)> = (0..args.repeats)
                    .map(|_| {
                        let start = Instant::now();
                        let (bvh, stats) = build_phr_with(&aux, &counts, &options);
                        let ms = start.elapsed().as_secs_f64() * 1e3;
                        (ms, stats.build_cost, sah_cost(&bvh, SahConstants::UNIT))
                    })
                    .collect();
                runs.sort_by(|a, b| a.0.total_cmp(&b.0));
                let (ms, cost, sah) = runs[runs.len() / 2];
                lines.push(format!("{name},{alpha},{delta},{cost},{ms:.3},{sah:.4}"));
                costs.push(cost as f64);
                times.push(ms);
                progress.inc(1);
            }
        }
        let per_mcut = times.iter().sum::<f64>() / (costs.iter().sum::<f64>() / 1e6);
        progress.suspend(|| {
            println!(
                "{:<36} {:>7} {:>12.3} {:>12.1}",
                name,
                costs.len(),
                phr_bench::stats::correlation(&costs, &times),
                per_mcut
            )
        });
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
