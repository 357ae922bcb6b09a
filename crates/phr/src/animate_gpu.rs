//! `phr animate --device gpu`: the thesis's dynamic-scene pipeline with the GPU tracing the
//! frames. Per frame, on the CPU: pose, refit the auxiliary LBVH, rebuild with PHR straight to
//! the 8-wide tree, lay out the tree and the moved primitives; then upload them (timed apart,
//! waited for) and trace one sample per pixel on the GPU. The same command with `--device cpu` runs the CPU's pipeline on
//! the same motion, for the comparison.

use crate::animate::{prepare, AnimateArgs};
use anyhow::{bail, Result};
use phr_render::camera::CameraDesc;
use phr_render::Scene;

pub fn run(args: &AnimateArgs) -> Result<()> {
    if args.pipeline != crate::view::PipelineArg::Thesis {
        bail!("--device gpu animates with the thesis's pipeline (one tree over the scene): use --pipeline thesis");
    }
    let (scene, view) = prepare(args)?;
    imp::run(args, scene, &view)
}

#[cfg(not(feature = "gpu"))]
mod imp {
    use super::*;

    pub fn run(_: &AnimateArgs, _: Scene, _: &CameraDesc) -> Result<()> {
        Err(crate::render::without_gpu("animate"))
    }
}

#[cfg(feature = "gpu")]
mod imp {
    use super::*;
    use crate::animate::FRAME_DT;
    use anyhow::Context;
    use phr_bvh::dynamic::DynamicBvh;
    use phr_bvh::wide::WideBvh;
    use phr_bvh::Builder;
    use phr_gpu::scene::Packed;
    use phr_gpu::{Gpu, GpuScene, GpuTracer};
    use phr_render::animation::Animator;
    use phr_render::camera::Camera;
    use phr_render::geometry::Geometry;
    use phr_render::output::{write_atomically, write_image};
    use std::io::Write;
    use std::time::Instant;

    /// One frame's timings (ms) and rays.
    struct GpuFrame {
        pose: f64,
        refit: f64,
        build: f64,
        pack: f64,
        upload: f64,
        render: f64,
        frame: f64,
        rays: u64,
    }

    const CSV_HEADER: &str = "frame,time,pose_ms,refit_ms,build_ms,pack_ms,upload_ms,render_ms,frame_ms,rays";

    pub fn run(args: &AnimateArgs, mut scene: Scene, view: &CameraDesc) -> Result<()> {
        let Builder::Phr(options) = args.builder else { unreachable!("prepare checks the builder") };
        let gpu = Gpu::new()?;
        // The GPU traces one tree over every triangle where it is.
        scene.flatten_instanced();
        let mut geometry = Geometry::new(&scene);
        let mut animator = Animator::new(&scene);
        let mut dynamic = DynamicBvh::new(&geometry.boxes, options);
        // PHR straight to the 8-wide tree the GPU traces (its memory reused frame to frame).
        let mut tree = WideBvh::default();
        dynamic.update_wide(&geometry.boxes, &mut tree);
        let mut uploaded = GpuScene::upload_packed(
            &gpu,
            &Packed::with_tree(&scene, &geometry, &tree, None)?,
            scene.background.clone(),
        )?;
        let (w, h) = (args.width, args.height);
        let max_depth = scene.settings.max_depth.min(8);
        let mut tracer = GpuTracer::new(&gpu, &uploaded, &Camera::new(view, w, h), w, h, max_depth, 0)?;
        let progress = crate::progress::bar(args.frames as u64);
        let ms = |start: Instant| start.elapsed().as_secs_f64() * 1e3;
        let mut rows = Vec::new();
        for frame in 0..args.frames {
            let start = Instant::now();
            // The CPU's pipeline advances the clock before it poses: frame k shows (k + 1) dt.
            animator.pose(&mut geometry, (frame + 1) as f32 * FRAME_DT);
            let pose = ms(start);
            let timings = dynamic.update_wide(&geometry.boxes, &mut tree);
            let pack_start = Instant::now();
            let packed = Packed::moved(&scene, &geometry, &tree, None)?;
            let pack = ms(pack_start);
            let upload_start = Instant::now();
            uploaded.update(&gpu, &packed)?;
            gpu.wait()?;
            let upload = ms(upload_start);
            let render_start = Instant::now();
            tracer.clear();
            tracer.render(&uploaded, frame..frame + 1);
            tracer.wait()?;
            let render = ms(render_start);
            let frame_ms = ms(start);
            let rays = tracer.rays()?;
            if args.png {
                let path = args.out.join(format!("frame{frame:05}.png"));
                write_image(&path, w, h, &tracer.film()?.mean())
                    .with_context(|| format!("writing {}", path.display()))?;
            }
            rows.push(GpuFrame {
                pose,
                refit: timings.refit.as_secs_f64() * 1e3,
                build: timings.build.as_secs_f64() * 1e3,
                pack,
                upload,
                render,
                frame: frame_ms,
                rays,
            });
            progress.set_message(format!("{frame_ms:.1} ms/frame on {}", gpu.describe()));
            progress.inc(1);
        }
        progress.finish_and_clear();
        let csv = args.out.join("frames.csv");
        write_atomically(&csv, |tmp| {
            let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
            writeln!(f, "{CSV_HEADER}")?;
            for (k, r) in rows.iter().enumerate() {
                let time = (k + 1) as f32 * FRAME_DT;
                let cells = [r.pose, r.refit, r.build, r.pack, r.upload, r.render, r.frame].map(|x| format!("{x:.3}"));
                writeln!(f, "{k},{time:.4},{},{}", cells.join(","), r.rays)?;
            }
            f.flush()
        })
        .with_context(|| format!("writing {}", csv.display()))?;
        let median = |f: fn(&GpuFrame) -> f64| {
            let mut v: Vec<f64> = rows.iter().map(f).collect();
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 2).copied().unwrap_or(0.0)
        };
        let software = if gpu.is_software() { " (a software device: its times are the CPU's)" } else { "" };
        println!(
            "{} frames of {} ({} triangles, {w}x{h}, 1 spp) on {}{software}: median pose {:.2} ms, refit {:.2} ms, \
             {} build {:.2} ms, layout {:.2} ms, upload {:.2} ms ({:.1} MiB), render {:.2} ms, frame {:.2} ms ({:.1} fps)",
            rows.len(),
            args.scene,
            geometry.triangle_count(),
            gpu.describe(),
            median(|r| r.pose),
            median(|r| r.refit),
            args.builder,
            median(|r| r.build),
            median(|r| r.pack),
            median(|r| r.upload),
            uploaded.bytes as f64 / (1 << 20) as f64,
            median(|r| r.render),
            median(|r| r.frame),
            1e3 / median(|r| r.frame).max(1e-9)
        );
        println!("wrote {}", csv.display());
        Ok(())
    }
}
