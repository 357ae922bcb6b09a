//! `phr bench-device`: the thesis's frame on the CPU and on the GPU (`crates/phr-gpu`), per
//! scene and resolution, in one run: build, upload, frame time per device. The table the
//! thesis's task statement asked for ("the performance difference between your CPU ray tracer
//! and an equivalent CUDA ray tracer"), on whatever GPU the machine has. Without the cargo
//! feature `gpu`, or without an adapter, the GPU column says why it is empty.

use crate::bench_frame::FrameSweep;
use anyhow::{Context, Result};
use clap::Args;
use phr_bench::device_report::{markdown, write_device_report, DeviceRow, DeviceRunInfo, GpuRun};
use phr_bench::frame::time_frames;
use phr_bench::suite::{load_thesis_scene, scene_name};
use phr_render::geometry::Geometry;
use phr_render::render::Tracing;
use phr_render::scene::RenderSettings;
use std::path::PathBuf;

#[derive(Args)]
pub struct BenchDeviceArgs {
    #[command(flatten)]
    pub sweep: FrameSweep,
    /// Leave the GPU out.
    #[arg(long)]
    pub no_gpu: bool,
    /// Output folder (device.csv, device.json, device.md).
    #[arg(long, default_value = "bench-device")]
    pub out: PathBuf,
}

pub fn run(args: &BenchDeviceArgs) -> Result<()> {
    let sweep = &args.sweep;
    let files = sweep.files()?;
    let threads = rayon::current_num_threads();
    let gpu = if args.no_gpu { Err("--no-gpu".to_string()) } else { gpu::open() };
    let progress = crate::progress::bar((files.len() * sweep.resolutions.len()) as u64);
    let mut rows = Vec::new();
    for file in &files {
        let scene = load_thesis_scene(file)?;
        let view = scene.view(None).with_context(|| format!("{} has no view", file.display()))?;
        let name = scene_name(file);
        progress.set_message(format!("{name}: build"));
        let mut geometry = Geometry::new(&scene);
        let report = geometry.build_report(&sweep.builder);
        let build = report.total_time();
        let collapse = geometry.set_bvh(report.bvh);
        let build_ms = (build + collapse).as_secs_f64() * 1e3;
        progress.set_message(format!("{name}: upload"));
        let uploaded = match &gpu {
            Ok(gpu) => gpu::upload(gpu, &scene, &geometry)?,
            Err(why) => Err(why.clone()),
        };
        for &res in &sweep.resolutions {
            let settings = RenderSettings { width: res, height: res, spp: 1, max_depth: scene.settings.max_depth };
            settings.check().map_err(anyhow::Error::msg)?;
            progress.set_message(format!("{name} {res}²: CPU"));
            let cpu = time_frames(&scene, &geometry, &view, &settings, Tracing::default(), sweep.warmup, sweep.frames);
            progress.set_message(format!("{name} {res}²: GPU"));
            let gpu_run = match (&gpu, &uploaded) {
                (Ok(gpu), Ok(uploaded)) => gpu::time(gpu, uploaded, &view, &settings, sweep.warmup, sweep.frames)?,
                (_, Err(why)) => GpuRun::Skipped(why.clone()),
                (Err(why), _) => GpuRun::Skipped(why.clone()),
            };
            rows.push(DeviceRow {
                scene: name.clone(),
                triangles: geometry.triangle_count(),
                res,
                builder: sweep.builder.to_string(),
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
    pub enum Uploaded {}

    pub fn open() -> Result<Gpu, String> {
        Err("this phr was built without the GPU tracer (build with `--features gpu`)".into())
    }

    pub fn describe(gpu: &Gpu) -> (String, bool) {
        match *gpu {}
    }

    pub fn upload(gpu: &Gpu, _: &Scene, _: &Geometry) -> Result<Result<Uploaded, String>> {
        match *gpu {}
    }

    pub fn time(gpu: &Gpu, _: &Uploaded, _: &CameraDesc, _: &RenderSettings, _: usize, _: usize) -> Result<GpuRun> {
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

    /// A scene on the GPU and the median time of its uploads.
    pub struct Uploaded {
        scene: GpuScene,
        ms: f64,
    }

    /// Uploads the scene (three times: the median is reported), or says why the GPU cannot
    /// trace it (a skipped row).
    pub fn upload(gpu: &Gpu, scene: &Scene, geometry: &Geometry) -> Result<Result<Uploaded, String>> {
        let mut uploads = Vec::new();
        let mut uploaded = None;
        for _ in 0..3 {
            let start = Instant::now();
            let scene = match GpuScene::upload(gpu, scene, geometry, None) {
                Ok(s) => s,
                Err(e) => return Ok(Err(e.to_string())),
            };
            gpu.wait()?;
            uploads.push(start.elapsed().as_secs_f64() * 1e3);
            uploaded = Some(scene);
        }
        let scene = uploaded.expect("uploaded three times");
        Ok(Ok(Uploaded { scene, ms: Stat::of(uploads).median }))
    }

    /// Times `frames` frames of the uploaded scene after `warmup`, each submitted and waited
    /// for. A size the GPU cannot trace is a skipped row, saying why.
    pub fn time(
        gpu: &Gpu,
        uploaded: &Uploaded,
        view: &CameraDesc,
        settings: &RenderSettings,
        warmup: usize,
        frames: usize,
    ) -> Result<GpuRun> {
        let Uploaded { scene: uploaded, ms: upload_ms } = uploaded;
        let (w, h) = (settings.width, settings.height);
        let camera = Camera::new(view, w, h);
        let mut tracer = match GpuTracer::new(gpu, uploaded, &camera, w, h, settings.max_depth, 0) {
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
            tracer.render(uploaded, k..k + 1);
            tracer.wait()?;
            if k as usize >= warmup {
                times.push(start.elapsed().as_secs_f64() * 1e3);
            }
        }
        let rays = tracer.rays()? as f64 / frames as f64;
        let frame = FrameTiming { ms: Stat::of(times), rays, frames };
        Ok(GpuRun::Ran { upload_ms: *upload_ms, bytes: uploaded.bytes, frame })
    }
}
