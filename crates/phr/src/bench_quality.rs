//! `phr bench-quality`: image quality at equal time, ours (implicit, path, path + à-trous,
//! path + OIDN in builds with it) against Mitsuba 3's path tracer, as RMSE against converged references. The measuring
//! lives in `phr_bench::quality_bench`; this parses arguments and prints.

use crate::progress::Bar;
use anyhow::{bail, Context, Result};
use clap::Args;
use phr_bench::mitsuba::MitsubaPeer;
use phr_bench::quality_bench::{
    measure_scene, open_scene_with_reference, QualityOptions, ScoredScene, OWN_SCENES, REFERENCE_SCENES,
};
use phr_bench::quality_report::{markdown, write_quality_report, QualityRunInfo};
use phr_bvh::Builder;
use std::path::PathBuf;

#[derive(Args)]
pub struct BenchQualityArgs {
    /// Scene files, each with its reference at `../images/NAME.exr` from its folder, or the
    /// names of the reference scenes (default: those of shared/reference, textured Sponza and
    /// `builtin`, the built-in scene).
    pub scenes: Vec<String>,
    /// Time budgets in seconds.
    #[arg(long, value_delimiter = ',', default_value = "1,5")]
    pub seconds: Vec<f64>,
    /// BVH builder of our renderer.
    #[arg(long, default_value = "sbvh")]
    pub builder: Builder,
    /// Leave Mitsuba 3 out.
    #[arg(long)]
    pub no_mitsuba: bool,
    /// Output folder (quality.csv, quality.json, quality.md, images/, and mitsuba/: Mitsuba's
    /// scene, images and timings).
    #[arg(long, default_value = "bench-quality")]
    pub out: PathBuf,
}

pub fn run(args: &BenchQualityArgs) -> Result<()> {
    if args.seconds.is_empty() || args.seconds.iter().any(|s| !(s.is_finite() && *s > 0.0 && *s <= 3600.0)) {
        bail!("--seconds: budgets must lie in (0, 3600]");
    }
    let mut budgets = args.seconds.clone();
    budgets.sort_by(f64::total_cmp);
    budgets.dedup();
    let names: Vec<String> = match args.scenes.is_empty() {
        false => args.scenes.clone(),
        true => REFERENCE_SCENES.iter().chain(OWN_SCENES).map(|s| s.to_string()).collect(),
    };
    let files = names.iter().map(|n| ScoredScene::named(n, &args.out)).collect::<Result<Vec<_>>>()?;
    // Every scene and its reference first: a bad one stops the run before anything is written.
    for scored in &files {
        open_scene_with_reference(scored).with_context(|| format!("{}", scored.file.display()))?;
    }
    let threads = rayon::current_num_threads();
    let mitsuba = match args.no_mitsuba {
        true => Err("--no-mitsuba".to_string()),
        false => files
            .iter()
            .find_map(|f| phr_render::scene::json::scenes_dir(&f.file))
            .or_else(|| phr_bench::suite::shared_scenes_dir(None).ok())
            .map(|dir| MitsubaPeer::next_to(&dir))
            .ok_or_else(|| "no shared scenes folder next to the scene files".to_string()),
    };
    let options = QualityOptions { budgets, builder: args.builder, mitsuba, threads, out: args.out.clone() };
    let progress = crate::progress::bar(files.len() as u64);
    let mut rows = Vec::new();
    for scored in &files {
        let file = &scored.file;
        rows.extend(measure_scene(scored, &options, &Bar(&progress)).with_context(|| format!("{}", file.display()))?);
    }
    progress.finish_and_clear();
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let info = QualityRunInfo { command: &command, threads, builder: args.builder.to_string() };
    write_quality_report(&args.out, &info, &rows)?;
    println!("{}", markdown(&info, &rows));
    println!("wrote {} and the images in {}", args.out.join("quality.md").display(), args.out.join("images").display());
    Ok(())
}
