//! `phr render --device gpu`: the render on the GPU (`crates/phr-gpu`), in a `phr` built with
//! the cargo feature `gpu`. The CPU builds the tree (any builder, collapsed into the 8-wide
//! tree its own renderer traces), the GPU traces and accumulates the frames; then the CPU
//! render's last step (`render::finish`): the denoiser, whose guide and few extra samples the
//! CPU traces (the GPU's samples are the CPU's, so they mix), and the output files.

use crate::render::{prepare, RenderArgs};
use anyhow::{bail, Result};
use phr_render::camera::CameraDesc;
use phr_render::scene::{RenderSettings, Scene};

pub fn run(args: &RenderArgs) -> Result<()> {
    if args.heatmap.is_some() {
        bail!("--device gpu: the heatmap counts the CPU's traversal steps; render it with --device cpu");
    }
    let (scene, view, settings) = prepare(args)?;
    imp::run(args, scene, &view, &settings)
}

#[cfg(not(feature = "gpu"))]
mod imp {
    use super::*;

    pub fn run(_: &RenderArgs, _: Scene, _: &CameraDesc, _: &RenderSettings) -> Result<()> {
        Err(crate::render::without_gpu("render"))
    }
}

#[cfg(feature = "gpu")]
mod imp {
    use super::*;
    use crate::render::{describe_build, describe_copies, finish, Integrator};
    use phr_gpu::{Gpu, GpuScene, GpuTracer};
    use phr_render::camera::Camera;
    use phr_render::geometry::Geometry;
    use phr_render::lights::LightSet;
    use phr_render::render::Renderer;
    use std::time::Instant;

    /// Frames submitted between two progress updates (each update waits for the GPU and moves
    /// its single-precision sums into the film's double-precision ones).
    const CHUNK: u32 = 16;

    pub fn run(args: &RenderArgs, scene: Scene, view: &CameraDesc, settings: &RenderSettings) -> Result<()> {
        let RenderSettings { width, height, spp, max_depth } = *settings;
        let gpu = Gpu::new()?;
        let mut geometry = Geometry::new(&scene);
        let builder = args.builder.with_branching(args.branching).map_err(anyhow::Error::msg)?;
        let report = geometry.build_report(&builder);
        let mut build = describe_build(&builder, &report);
        geometry.set_bvh(report.bvh);
        // Meshes placed many times: one tree each, their copies instances of it.
        build += &describe_copies(&scene, geometry.build_copies(&builder));

        let start = Instant::now();
        let lights = (args.integrator == Integrator::Path)
            .then(|| LightSet::new(&geometry, &scene.materials, &scene.background));
        let uploaded = GpuScene::upload(&gpu, &scene, &geometry, lights.as_ref())?;
        let mut tracer =
            GpuTracer::new(&gpu, &uploaded, &Camera::new(view, width, height), width, height, max_depth, args.seed)?;
        gpu.wait()?;
        let upload_ms = start.elapsed().as_secs_f64() * 1e3;

        let progress = if args.quiet { indicatif::ProgressBar::hidden() } else { crate::progress::bar(spp as u64) };
        progress.set_message(format!("spp on {}", gpu.describe()));
        let start = Instant::now();
        let mut film = phr_render::film::Film::new(width, height);
        let mut frame = 0;
        while frame < spp {
            let next = (frame + CHUNK).min(spp);
            tracer.render(&uploaded, frame..next);
            tracer.drain_into(&mut film)?;
            progress.set_position(next as u64);
            frame = next;
        }
        let render_ms = start.elapsed().as_secs_f64() * 1e3;
        progress.finish_and_clear();
        let rays = tracer.rays()?;
        let cpu = Renderer::new(&scene, &geometry, view, settings, lights.as_ref()).with_seed(args.seed);
        let notes = finish(args, &cpu, &film)?;
        let software = if gpu.is_software() { " (a software device: its times are the CPU's)" } else { "" };
        println!(
            "{}: {} triangles, {} spheres | {build} | upload {upload_ms:.0} ms ({:.1} MiB) | GPU {}{software} | \
             render {render_ms:.0} ms ({width}x{height}, {spp} spp, {:.1} ms per frame) | {:.2} Mrays/s",
            args.scene,
            geometry.triangle_count(),
            geometry.spheres.len(),
            uploaded.bytes as f64 / (1 << 20) as f64,
            gpu.describe(),
            render_ms / spp.max(1) as f64,
            rays as f64 / (render_ms / 1e3) / 1e6,
        );
        notes.iter().for_each(|line| println!("{line} (on the CPU)"));
        println!("wrote {}", args.out.display());
        Ok(())
    }
}
