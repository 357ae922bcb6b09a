//! `phr animate`: the dynamic-scene pipeline of thesis section 5.3, frame after frame: move
//! the vertices, refit the auxiliary LBVH, rebuild the render BVH with PHR, render one sample
//! per pixel. Writes a CSV of per-frame timings and, if asked, the frames as PNG.

use crate::scene_arg::{open_scene, BUILTIN};
use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use glam::{Quat, Vec3};
use indicatif::{ProgressBar, ProgressStyle};
use phr_bvh::dynamic::DynamicBvh;
use phr_bvh::{sah_cost, Builder, SahConstants};
use phr_render::camera::Camera;
use phr_render::geometry::Geometry;
use phr_render::integrator::PathTracer;
use phr_render::output::{write_atomically, write_image};
use phr_render::render::Renderer;
use rayon::prelude::*;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

#[derive(Clone, Copy, ValueEnum)]
pub enum Motion {
    /// Every triangle turns about the vertical axis through the scene's centre.
    Spin,
    /// A travelling wave displaces vertices vertically (a deformation).
    Wave,
}

#[derive(Args)]
pub struct AnimateArgs {
    /// A scene file (.json), a mesh file, or `builtin`.
    #[arg(default_value = BUILTIN)]
    scene: String,
    #[arg(long, default_value_t = 100)]
    frames: u32,
    #[arg(long, value_enum, default_value = "spin")]
    motion: Motion,
    /// A PHR builder (phr-fast, phr-hq, phr:ALPHA,DELTA).
    #[arg(long, default_value = "phr-fast")]
    builder: Builder,
    #[arg(long, default_value_t = 256)]
    width: u32,
    #[arg(long, default_value_t = 256)]
    height: u32,
    #[arg(long)]
    view: Option<String>,
    /// Folder for `frames.csv` (and the frames as PNG with --png).
    #[arg(long, default_value = "animation")]
    out: PathBuf,
    /// Also write every frame as PNG.
    #[arg(long)]
    png: bool,
}

pub fn run(args: &AnimateArgs) -> Result<()> {
    let Builder::Phr(options) = args.builder else {
        bail!("animate rebuilds with PHR: use phr-fast, phr-hq or phr:ALPHA,DELTA")
    };
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let scene = open_scene(&args.scene)?;
    let view = scene.view(args.view.as_deref()).with_context(|| format!("no view {:?}", args.view))?;
    let mut geometry = Geometry::new(&scene);
    let rest = geometry.triangles.clone();
    let centre = scene.bounds().center();
    let size = scene.bounds().extent().max_element();
    let mut dynamic = DynamicBvh::new(&geometry.boxes, options);
    let camera = Camera::new(&view, args.width, args.height);
    let progress = ProgressBar::new(args.frames as u64);
    progress.set_style(
        ProgressStyle::with_template("{spinner} animating [{bar:30}] {pos}/{len} frames {msg}")
            .expect("template")
            .progress_chars("=> "),
    );
    let mut rows = Vec::new();
    for frame in 0..args.frames {
        let time = frame as f32 / 30.0;
        let start = Instant::now();
        let motion = args.motion;
        geometry.triangles.par_iter_mut().zip(rest.par_iter()).for_each(|(t, r)| {
            *t = r.map(|v| move_vertex(motion, v, centre, size, time));
        });
        geometry.update_boxes();
        let animate_ms = start.elapsed().as_secs_f64() * 1e3;
        let (bvh, timings) = dynamic.update(&geometry.boxes);
        geometry.set_bvh(bvh);
        let render_start = Instant::now();
        let renderer = Renderer {
            tracer: PathTracer {
                geometry: &geometry,
                materials: &scene.materials,
                background: &scene.background,
                max_depth: scene.settings.max_depth.min(8),
                lights: None,
            },
            camera: camera.clone(),
            width: args.width,
            height: args.height,
            seed: frame as u64,
        };
        let (pixels, stats) = renderer.render_frame(0);
        let render_ms = render_start.elapsed().as_secs_f64() * 1e3;
        if args.png {
            let path = args.out.join(format!("frame{frame:05}.png"));
            write_image(&path, args.width, args.height, &pixels)
                .with_context(|| format!("writing {}", path.display()))?;
        }
        let refit_ms = timings.refit.as_secs_f64() * 1e3;
        let build_ms = timings.build.as_secs_f64() * 1e3;
        let row = FrameRow {
            frame,
            animate_ms,
            refit_ms,
            build_ms,
            render_ms,
            frame_ms: animate_ms + refit_ms + build_ms + render_ms,
            build_cost: timings.build_cost,
            sah: sah_cost(geometry.bvh(), SahConstants::UNIT),
            mrays: stats.rays as f64 / render_ms / 1e3,
        };
        progress.set_message(format!("{:.1} ms/frame", row.frame_ms));
        progress.inc(1);
        rows.push(row);
    }
    progress.finish_and_clear();
    let csv = args.out.join("frames.csv");
    write_csv(&csv, &rows).with_context(|| format!("writing {}", csv.display()))?;
    let median = |f: fn(&FrameRow) -> f64| {
        let mut v: Vec<f64> = rows.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    println!(
        "{} frames of {} ({} triangles, {}x{}, 1 spp): median refit {:.2} ms, {} build {:.2} ms, render {:.2} ms, frame {:.2} ms ({:.1} fps)",
        rows.len(),
        args.scene,
        geometry.triangles.len(),
        args.width,
        args.height,
        median(|r| r.refit_ms),
        args.builder,
        median(|r| r.build_ms),
        median(|r| r.render_ms),
        median(|r| r.frame_ms),
        1e3 / median(|r| r.frame_ms).max(1e-9)
    );
    println!("wrote {}", csv.display());
    Ok(())
}

fn move_vertex(motion: Motion, v: Vec3, centre: Vec3, size: f32, time: f32) -> Vec3 {
    match motion {
        Motion::Spin => centre + Quat::from_rotation_y(0.5 * time) * (v - centre),
        Motion::Wave => v + Vec3::Y * (0.03 * size) * ((v.x - centre.x) / size * 12.0 + 3.0 * time).sin(),
    }
}

struct FrameRow {
    frame: u32,
    animate_ms: f64,
    refit_ms: f64,
    build_ms: f64,
    render_ms: f64,
    frame_ms: f64,
    build_cost: u64,
    sah: f64,
    mrays: f64,
}

fn write_csv(path: &std::path::Path, rows: &[FrameRow]) -> std::io::Result<()> {
    write_atomically(path, |tmp| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        writeln!(f, "frame,animate_ms,refit_ms,build_ms,render_ms,frame_ms,build_cost,sah_cost,mrays_per_s")?;
        for r in rows {
            writeln!(
                f,
                "{},{:.3},{:.3},{:.3},{:.3},{:.3},{},{:.4},{:.3}",
                r.frame, r.animate_ms, r.refit_ms, r.build_ms, r.render_ms, r.frame_ms, r.build_cost, r.sah, r.mrays
            )?;
        }
        f.flush()
    })
}
