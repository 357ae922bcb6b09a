//! `phr animate`: the dynamic-scene pipeline of thesis section 5.3, frame after frame, through
//! [`FramePipeline`] (the viewer's frame loop, so both report the same frame time): pose the
//! moving objects, refit the auxiliary LBVH, rebuild the render BVH with PHR (straight into
//! the wide BVH the renderer traces), render one sample per pixel. The motion is the scene's own animation or one
//! applied to every mesh. Writes a CSV of per-frame timings (the columns of `phr view
//! --headless`) and, if asked, the frames as PNG. With `--device gpu` the GPU traces the
//! frames (the viewer's `GpuFrames`: what changed uploaded, timed apart) and the CPU does the
//! rest, with any pipeline.

use crate::scene_arg::{open_scene, BUILTIN};
use crate::view::PipelineArg;
use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use phr_bvh::Builder;
use phr_render::camera::CameraDesc;
use phr_render::motion::{Animation, AnimationTarget, Motion as VertexMotion, ObjectAnimation};
use phr_render::output::{write_atomically, write_image};
use phr_render::pipeline::{FramePipeline, FrameReport, PipelineSettings, ViewMode};
use phr_render::Scene;
use std::io::Write;
use std::path::PathBuf;

/// Animation time per frame, in seconds.
const FRAME_DT: f32 = 1.0 / 30.0;

#[derive(Clone, Copy, ValueEnum)]
pub enum Motion {
    /// Every mesh turns about the vertical axis through the scene's centre (0.5 rad/s).
    Spin,
    /// A travelling wave displaces vertices vertically (a deformation).
    Wave,
    /// The scene's own animation (a scene file's `animate`, glTF animations).
    Scene,
}

#[derive(Args)]
pub struct AnimateArgs {
    /// A scene file (.json), a mesh (.obj, .ply, .gltf, .glb, optionally .gz), `builtin`, or a
    /// scene of scenes/suite by name (sponza, dragon, ...).
    #[arg(default_value = BUILTIN)]
    pub(crate) scene: String,
    #[arg(long, default_value_t = 100)]
    pub(crate) frames: u32,
    #[arg(long, value_enum, default_value = "spin")]
    pub(crate) motion: Motion,
    /// A PHR builder (phr-fast, phr-hq, phr:ALPHA,DELTA).
    #[arg(long, default_value = "phr-fast")]
    pub(crate) builder: Builder,
    #[arg(long, default_value_t = 256)]
    pub(crate) width: u32,
    #[arg(long, default_value_t = 256)]
    pub(crate) height: u32,
    #[arg(long)]
    pub(crate) view: Option<String>,
    /// Folder for `frames.csv` (and the frames as PNG with --png).
    #[arg(long, default_value = "animation")]
    pub(crate) out: PathBuf,
    /// Also write every frame as PNG.
    #[arg(long)]
    pub(crate) png: bool,
    /// How trees follow the motion: `thesis` (the default here: one tree over the whole scene,
    /// refitted and rebuilt with PHR every frame), `two-level` (rigid objects move by their
    /// transforms; only the deforming objects' tree is rebuilt) or `async` (two-level, the
    /// deforming objects' tree rebuilt on a worker thread and refitted meanwhile).
    #[arg(long, value_enum, default_value = "thesis")]
    pub(crate) pipeline: PipelineArg,
    /// Where to render: `cpu`, or `gpu` (pose, refit and PHR on the CPU, what changed
    /// uploaded, the frame traced on the GPU, with any pipeline; build with `--features
    /// gpu`).
    #[arg(long, value_enum, default_value = "cpu")]
    pub(crate) device: crate::render::Device,
}

/// Checks the builder, makes the output folder, opens the scene with its motion and picks the
/// view.
fn prepare(args: &AnimateArgs) -> Result<(Scene, CameraDesc)> {
    if !matches!(args.builder, Builder::Phr(_)) {
        bail!("animate rebuilds with PHR: use phr-fast, phr-hq or phr:ALPHA,DELTA")
    }
    let size = phr_render::scene::RenderSettings { width: args.width, height: args.height, spp: 1, max_depth: 1 };
    size.check().map_err(anyhow::Error::msg)?;
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let mut scene = open_scene(&args.scene)?;
    let view = scene.view(args.view.as_deref()).with_context(|| format!("no view {:?}", args.view))?;
    attach_motion(&mut scene, args.motion);
    if scene.animations.is_empty() {
        bail!("{}: nothing moves (the scene has no animation of its own; try --motion spin)", args.scene);
    }
    Ok((scene, view))
}

pub fn run(args: &AnimateArgs) -> Result<()> {
    let (scene, view) = prepare(args)?;
    let settings = PipelineSettings {
        builder: args.builder,
        pipeline: args.pipeline.into(),
        width: args.width,
        height: args.height,
        max_depth: scene.settings.max_depth.min(8),
        mode: ViewMode::Colour,
        explicit_lights: false,
        denoise: None,
    };
    let mut pipeline = FramePipeline::new(scene, settings, view);
    if args.device == crate::render::Device::Gpu {
        pipeline = crate::view::attach_gpu(pipeline, "animate")?.0;
    }
    // Without PNGs (one per frame), a GPU keeps the film: nothing is read back.
    pipeline.keep_film_on_device(!args.png);
    let progress = ProgressBar::new(args.frames as u64);
    progress.set_style(
        ProgressStyle::with_template("{spinner} animating [{bar:30}] {pos}/{len} frames {msg}")
            .expect("template")
            .progress_chars("=> "),
    );
    let mut rows = Vec::new();
    for frame in 0..args.frames {
        let report = pipeline.step(FRAME_DT);
        if let Some(image) = args.png.then(|| pipeline.image_to_save()).flatten() {
            let path = args.out.join(format!("frame{frame:05}.png"));
            write_image(&path, args.width, args.height, &image)
                .with_context(|| format!("writing {}", path.display()))?;
        }
        progress.set_message(format!("{:.1} ms/frame", report.frame_ms));
        progress.inc(1);
        rows.push(report);
    }
    progress.finish_and_clear();
    let csv = args.out.join("frames.csv");
    write_csv(&csv, &rows).with_context(|| format!("writing {}", csv.display()))?;
    print_summary(args, pipeline.geometry().triangle_count(), &rows);
    println!("wrote {}", csv.display());
    Ok(())
}

/// Attaches the motion to every mesh of `scene` (replacing the scene's own animation), or
/// keeps the scene's own.
pub(crate) fn attach_motion(scene: &mut Scene, motion: Motion) {
    let bounds = scene.bounds();
    let (centre, size) = (bounds.center(), bounds.extent().max_element().max(f32::MIN_POSITIVE));
    let motion = match motion {
        Motion::Scene => return,
        Motion::Spin => VertexMotion::Rotate { axis: Vec3::Y, pivot: centre, degrees_per_second: 0.5f32.to_degrees() },
        // 12 radians of phase across the scene's size, 3 radians per second: the wave moves
        // towards -x at a quarter of the scene per second.
        Motion::Wave => VertexMotion::Wave {
            amplitude: 0.03 * size,
            wavelength: std::f32::consts::TAU * size / 12.0,
            period: std::f32::consts::TAU / 3.0,
            direction: -Vec3::X,
            displacement: -Vec3::Y,
        },
    };
    // Every vertex moves, copies of instanced meshes included.
    scene.flatten_instanced();
    scene.animations = (0..scene.meshes.len())
        .map(|m| ObjectAnimation {
            target: AnimationTarget::Mesh(m),
            animation: Animation::Procedural(vec![motion.clone()]),
        })
        .collect();
}

fn print_summary(args: &AnimateArgs, triangles: usize, rows: &[FrameReport]) {
    let median = |f: fn(&FrameReport) -> f64| {
        let mut v: Vec<f64> = rows.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    // On another device the render includes moving what changed there.
    let device = rows.first().map_or("cpu", |r| r.device);
    let upload = match device {
        "cpu" => String::new(),
        _ => format!(
            " (upload {:.2} ms, {:.1} KiB)",
            median(|r| r.upload_ms),
            median(|r| r.upload_bytes as f64) / 1024.0
        ),
    };
    println!(
        "{} frames of {} ({} triangles, {}x{}, 1 spp): median pose {:.2} ms, refit {:.2} ms, {} build {:.2} ms, wide BVH {:.2} ms, render {:.2} ms on the {device}{upload}, frame {:.2} ms ({:.1} fps)",
        rows.len(),
        args.scene,
        triangles,
        args.width,
        args.height,
        median(|r| r.pose_ms),
        median(|r| r.refit_ms),
        args.builder,
        median(|r| r.build_ms),
        median(|r| r.wide_ms),
        median(|r| r.render_ms),
        median(|r| r.frame_ms),
        1e3 / median(|r| r.frame_ms).max(1e-9)
    );
}

fn write_csv(path: &std::path::Path, rows: &[FrameReport]) -> std::io::Result<()> {
    write_atomically(path, |tmp| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        writeln!(f, "{}", FrameReport::CSV_HEADER)?;
        for r in rows {
            writeln!(f, "{}", r.csv_row())?;
        }
        f.flush()
    })
}
