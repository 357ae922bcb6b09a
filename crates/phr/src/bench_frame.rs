//! `phr bench-frame`: the thesis's frame (first view, 1 spp, 6 segments, white sky, diffuse)
//! on the suite, ours against Mitsuba 3 `llvm_ad_rgb` with the same estimator, side by side
//! in one run. The measuring lives in `phr_bench`; this parses arguments and prints.

use anyhow::{bail, Context, Result};
use clap::Args;
use phr_bench::frame::time_frames;
use phr_bench::frame_report::{markdown, write_frame_report, FrameRow, FrameRunInfo};
use phr_bench::mitsuba::{MitsubaPeer, MitsubaRun};
use phr_bench::suite::{load_thesis_scene, scene_name, suite_files, SUITE};
use phr_bvh::Builder;
use phr_render::geometry::Geometry;
use phr_render::render::Tracing;
use phr_render::scene::RenderSettings;
use std::path::PathBuf;

/// The thesis's frames to time, per scene and resolution: what `bench-frame` and
/// `bench-device` share.
#[derive(Args)]
pub struct FrameSweep {
    /// Scene files (default: the suite in scenes/suite).
    pub scenes: Vec<PathBuf>,
    #[arg(long, value_delimiter = ',', default_value = "256,512")]
    pub resolutions: Vec<u32>,
    /// Timed frames per scene, resolution and renderer (after the warm-up).
    #[arg(long, default_value_t = 16)]
    pub frames: usize,
    /// Untimed frames first (caches, page faults, thread pool start; the GPU's pipeline).
    #[arg(long, default_value_t = 2)]
    pub warmup: usize,
    /// BVH builder of our renderer (default: the SBVH, as Mitsuba 3 gets Embree's spatial-split
    /// build; the frames are of a still view, built once; collapsed into the 8-wide tree both
    /// devices trace).
    #[arg(long, default_value = "sbvh")]
    pub builder: Builder,
}

impl FrameSweep {
    /// The scene files, after checking there is something to time.
    pub fn files(&self) -> Result<Vec<PathBuf>> {
        if self.frames == 0 || self.resolutions.is_empty() || self.resolutions.contains(&0) {
            bail!("need at least one frame and one non-zero resolution");
        }
        Ok(if self.scenes.is_empty() { suite_files(SUITE)? } else { self.scenes.clone() })
    }
}

#[derive(Args)]
pub struct BenchFrameArgs {
    #[command(flatten)]
    pub sweep: FrameSweep,
    /// How our renderer traces a frame's paths: `wavefront` (a tile's rays intersected as a
    /// batch, several at once) or `single` (one path after the other; the same image).
    #[arg(long, default_value = "wavefront")]
    pub tracing: Tracing,
    /// Leave Mitsuba 3 out.
    #[arg(long)]
    pub no_mitsuba: bool,
    /// Output folder (frame.csv, frame.json, frame.md).
    #[arg(long, default_value = "bench-frame")]
    pub out: PathBuf,
}

pub fn run(args: &BenchFrameArgs) -> Result<()> {
    let sweep = &args.sweep;
    let files = sweep.files()?;
    let threads = rayon::current_num_threads();
    // The peer, or why it does not run (the reason every row then reports).
    let peer: Result<MitsubaPeer, &str> = match args.no_mitsuba {
        true => Err("--no-mitsuba"),
        false => phr_render::scene::json::scenes_dir(&files[0])
            .map(|dir| MitsubaPeer::next_to(&dir))
            .ok_or("no shared scenes folder next to the scene files"),
    };
    let progress = crate::progress::bar((files.len() * sweep.resolutions.len()) as u64);
    let mut rows = Vec::new();
    for file in &files {
        let scene = load_thesis_scene(file)?;
        let view = scene.view(None).with_context(|| format!("{} has no view", file.display()))?;
        let mut geometry = Geometry::new(&scene);
        geometry.build(&sweep.builder);
        let name = scene_name(file);
        for &res in &sweep.resolutions {
            progress.set_message(format!("{name} {res}²: ours"));
            let settings = RenderSettings { width: res, height: res, spp: 1, max_depth: scene.settings.max_depth };
            settings.check().map_err(anyhow::Error::msg)?;
            let ours = time_frames(&scene, &geometry, &view, &settings, args.tracing, sweep.warmup, sweep.frames);
            progress.set_message(format!("{name} {res}²: Mitsuba 3"));
            let mitsuba = match &peer {
                Ok(p) => p.thesis_frames(file, res, sweep.frames, threads, &args.out.join("mitsuba")),
                Err(why) => MitsubaRun::Skipped(why.to_string()),
            };
            rows.push(FrameRow {
                scene: name.clone(),
                triangles: geometry.triangle_count(),
                res,
                builder: sweep.builder.to_string(),
                ours,
                mitsuba,
            });
            progress.inc(1);
        }
    }
    progress.finish_and_clear();
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let info = FrameRunInfo { command: &command, threads };
    write_frame_report(&args.out, &info, &rows)?;
    println!("{}", markdown(&info, &rows));
    println!("wrote {}", args.out.join("frame.md").display());
    Ok(())
}
