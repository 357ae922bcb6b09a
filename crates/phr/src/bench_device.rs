//! `phr bench-device`: the thesis's frame on the CPU and on the GPU (`crates/phr-gpu`), per
//! scene and resolution, in one run: build, upload, frame time per device. The table the
//! thesis's task statement asked for ("the performance difference between your CPU ray tracer
//! and an equivalent CUDA ray tracer"), on whatever GPU the machine has. Without the cargo
//! feature `gpu`, or without an adapter, the GPU column says why it is empty.

use anyhow::{bail, Context, Result};
use clap::Args;
use phr_bench::device_report::{markdown, write_device_report, DeviceRow, DeviceRunInfo, GpuRun};
use phr_bench::frame::time_frames;
use phr_bench::suite::{load_thesis_scene, scene_name, suite_files, SUITE};
use phr_bvh::Builder;
use phr_render::geometry::Geometry;
use phr_render::render::Tracing;
use phr_render::scene::RenderSettings;
use std::path::PathBuf;

#[derive(Args)]
pub struct BenchDeviceArgs {
    /// Scene files (default: the suite in scenes/suite).
    pub scenes: Vec<PathBuf>,
    #[arg(long, value_delimiter = ',', default_value = "256,512")]
    pub resolutions: Vec<u32>,
    /// Timed frames per scene, resolution and device (after the warm-up).
    #[arg(long, default_value_t = 16)]
    pub frames: usize,
    /// Untimed frames first (caches, the GPU's pipeline and clocks).
    #[arg(long, default_value_t = 2)]
    pub warmup: usize,
    /// The builder of the tree both devices trace (binary: the GPU's layout).
    #[arg(long, default_value = "sbvh")]
    pub builder: Builder,
    /// Leave the GPU out.
    #[arg(long)]
    pub no_gpu: bool,
    /// Output folder (device.csv, device.json, device.md).
    #[arg(long, default_value = "bench-device")]
    pub out: PathBuf,
}

pub fn run(args: &BenchDeviceArgs) -> Result<()> {
    if args.frames == 0 || args.resolutions.is_empty() || args.resolutions.contains(&0) {
        bail!("need at least one frame and one non-zero resolution");
    }
    let files = if args.scenes.is_empty() { suite_files(SUITE)? } else { args.scenes.clone() };
    let threads = rayon::current_num_threads();
    let gpu = if args.no_gpu { Err("--no-gpu".to_string()) } else { gpu::open() };
    let progress = crate::progress::bar((files.len() * args.resolutions.len()) as u64);
    let mut rows = Vec::new();
    for file in &files {
        let scene = load_thesis_scene(file)?;
        let view = scene.view(None).with_context(|| format!("{} has no view", file.display()))?;
        let name = scene_name(file);
        progress.set_message(format!("{name}: build"));
        let mut geometry = Geometry::new(&scene);
        let report = geometry.build_report(&args.builder);
        let build = report.total_time();
        let collapse = geometry.set_bvh(report.bvh);
        let build_ms = (build + collapse).as_secs_f64() * 1e3;
        for &res in &args.resolutions {
            let settings = RenderSettings { width: res, height: res, spp: 1, max_depth: scene.settings.max_depth };
            settings.check().map_err(anyhow::Error::msg)?;
            progress.set_message(format!("{name} {res}²: CPU"));
            let cpu = time_frames(&scene, &geometry, &view, &settings, Tracing::default(), args.warmup, args.frames);
            progress.set_message(format!("{name} {res}²: GPU"));
            let gpu_run = match &gpu {
                Ok(gpu) => gpu::time(gpu, &scene, &geometry, &view, &settings, args.warmup, args.frames)?,
                Err(why) => GpuRun::Skipped(why.clone()),
            };
            rows.push(DeviceRow {
                scene: name.clone(),
                triangles: geometry.triangle_count(),
                res,
                builder: args.builder.to_string(),
                build_ms,
                cpu,
                gpu: gpu_run,
            });
            progress.inc(1);
        }
    }
    progress.finish_and_clear();
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let (adapter, software) = match &gpu {
        Ok(gpu) => gpu::describe(gpu),
        Err(why) => (format!("none ({why})"), false),
    };
    let info = DeviceRunInfo { command: &command, threads, adapter: &adapter, software };
    write_device_report(&args.out, &info, &rows)?;
    println!("{}", markdown(&info, &rows));
    println!("wrote {}", args.out.join("device.md").display());
    Ok(())
}

#[cfg(not(feature = "gpu"))]
mod gpu {
    use super::*;
    use phr_render::camera::CameraDesc;
    use phr_render::Scene;

    /// Never made: this build has no GPU tracer.
    pub enum Gpu {}

    pub fn open() -> Result<Gpu, String> {
        Err("this phr was built without the GPU tracer (build with `--features gpu`)".into())
    }

    pub fn describe(gpu: &Gpu) -> (String, bool) {
        match *gpu {}
    }

    pub fn time(
        gpu: &Gpu,
        _: &Scene,
        _: &Geometry,
        _: &CameraDesc,
        _: &RenderSettings,
        _: usize,
        _: usize,
    ) -> Result<GpuRun> {
        match *gpu {}
    }
}

#[cfg(feature = "gpu")]
mod gpu {
    use super::*;
    use phr_bench::frame::FrameTiming;
    use phr_bench::Stat;
    use phr_gpu::{GpuScene, GpuTracer};
    use phr_render::camera::{Camera, CameraDesc};
    use phr_render::Scene;
    use std::time::Instant;

    pub use phr_gpu::Gpu;

    pub fn open() -> Result<Gpu, String> {
        Gpu::new().map_err(|e| e.to_string())
    }

    pub fn describe(gpu: &Gpu) -> (String, bool) {
        (gpu.describe(), gpu.is_software())
    }

    /// Uploads the scene (three times: the median is reported) and times `frames` frames after
    /// `warmup`, each submitted and waited for. A scene the GPU cannot trace is a skipped row,
    /// saying why.
    pub fn time(
        gpu: &Gpu,
        scene: &Scene,
        geometry: &Geometry,
        view: &CameraDesc,
        settings: &RenderSettings,
        warmup: usize,
        frames: usize,
    ) -> Result<GpuRun> {
        let mut uploads = Vec::new();
        let mut uploaded = None;
        for _ in 0..3 {
            let start = Instant::now();
            let scene = match GpuScene::upload(gpu, scene, geometry, None) {
                Ok(s) => s,
                Err(e) => return Ok(GpuRun::Skipped(e.to_string())),
            };
            gpu.wait()?;
            uploads.push(start.elapsed().as_secs_f64() * 1e3);
            uploaded = Some(scene);
        }
        let uploaded = uploaded.expect("uploaded three times");
        let (w, h) = (settings.width, settings.height);
        let camera = Camera::new(view, w, h);
        let mut tracer = match GpuTracer::new(gpu, &uploaded, &camera, w, h, settings.max_depth, 0) {
            Ok(tracer) => tracer,
            Err(e) => return Ok(GpuRun::Skipped(e.to_string())),
        };
        let mut times = Vec::with_capacity(frames);
        for k in 0..(warmup + frames) as u32 {
            if k as usize == warmup {
                tracer.clear();
                tracer.wait()?;
            }
            let start = Instant::now();
            tracer.render(&uploaded, k..k + 1);
            tracer.wait()?;
            if k as usize >= warmup {
                times.push(start.elapsed().as_secs_f64() * 1e3);
            }
        }
        let rays = tracer.rays()? as f64 / frames as f64;
        let frame = FrameTiming { ms: Stat::of(times), rays, frames };
        Ok(GpuRun::Ran { upload_ms: Stat::of(uploads).median, bytes: uploaded.bytes, frame })
    }
}
