//! `phr view`: the interactive viewer ([`window`]) and its headless twin ([`headless`]). Both
//! drive the same [`FramePipeline`] (pose → update the trees → render → accumulate), so a
//! scripted headless run measures what the window shows.

mod camera_control;
mod device;
pub(crate) use device::attach_gpu;
mod headless;
mod window;

use crate::render::{Denoiser, Device};
use crate::scene_arg::{open_scene, BUILTIN};
use anyhow::{Context, Result};
use clap::{Args, ValueEnum};
use phr_bvh::Builder;
use phr_render::auto_builder::AutoBuilder;
use phr_render::pipeline::{FramePipeline, PipelineKind, PipelineSettings, ViewMode};
use phr_render::scene::RenderSettings;
use std::path::PathBuf;

#[derive(Args)]
pub struct ViewArgs {
    /// A scene file (.json), a mesh (.obj, .ply, .gltf, .glb, optionally .gz), `builtin`, or a
    /// scene of scenes/suite by name (sponza, dragon, ...).
    #[arg(default_value = BUILTIN)]
    scene: String,
    /// Run without a window: render --frames frames and write PNGs and frames.csv to --out.
    #[arg(long)]
    headless: bool,
    /// Frames to render (headless mode).
    #[arg(long, default_value_t = 100)]
    frames: u64,
    /// Output folder: headless frames and CSV, and the window's screenshots.
    #[arg(long, default_value = "view")]
    out: PathBuf,
    /// Write every Nth headless frame as PNG (0: none).
    #[arg(long, default_value_t = 1)]
    png_every: u64,
    /// Animation time step per headless frame, in seconds.
    #[arg(long, default_value_t = 1.0 / 30.0)]
    dt: f32,
    #[arg(long, default_value_t = 256)]
    width: u32,
    #[arg(long, default_value_t = 256)]
    height: u32,
    /// lbvh, phr-fast, phr-hq, phr:ALPHA,DELTA, sweep-sah, binned-sah or sbvh; or `auto`: the
    /// builder whose moving frames are fastest, found by trying each (LBVH, PHR-Fast, PHR-HQ,
    /// binned SAH) for a few moving frames, and again when the frame time drifts.
    #[arg(long, default_value = "phr-fast")]
    builder: BuilderArg,
    /// Children per node for PHR builders (2 to 16).
    #[arg(long, default_value_t = 2)]
    branching: u32,
    /// A builder for the trees of what never moves (the static scene, and the rigid objects,
    /// which move by their transforms alone): once the first frame is out, they are built
    /// again with it on a worker thread and swapped in without restarting the accumulation
    /// (the hits, and so the image, stay the same); `none`: keep --builder's trees. The
    /// thesis pipeline rebuilds only scenes without animation; nothing is rebuilt with
    /// `--device gpu` or in the heatmap mode (which shows --builder's trees).
    #[arg(long, default_value = "sbvh")]
    static_builder: StaticBuilderArg,
    /// How trees follow a moving scene: `two-level` builds a tree per rigidly moving object
    /// once and moves it by its transform under a small top-level tree, rebuilding only the
    /// deforming objects' tree; `async` does so too, but rebuilds the deforming objects'
    /// tree with PHR on a worker thread while frames trace it refitted; `thesis` refits and
    /// rebuilds one tree over the whole scene every moving frame (thesis section 5.3).
    /// Default: `async` on the CPU, `thesis` on the GPU (the one it traces).
    #[arg(long, value_enum)]
    pipeline: Option<PipelineArg>,
    /// Maximum path length (default: the scene's, at most 8).
    #[arg(long)]
    max_depth: Option<u32>,
    #[arg(long, value_enum, default_value = "colour")]
    mode: ModeArg,
    /// The scene's named view to start from.
    #[arg(long)]
    view: Option<String>,
    /// Start with the animation paused.
    #[arg(long)]
    paused: bool,
    /// How lights are found: `explicit` samples one light (emissive triangle or sphere, the
    /// sky) at every diffuse hit, weighed against the path's own bounce by multiple importance
    /// sampling, with Russian roulette (the same expected image, far less noise; the viewer's
    /// default); `implicit` only counts lights that paths happen to hit, the thesis's estimator.
    #[arg(long, value_enum, default_value = "explicit")]
    light_sampling: LightSampling,
    /// `atrous`: every frame is shown denoised: while the view or the scene moves (and for
    /// the first 15 still frames) each frame's samples through SVGF's temporal filter, whose
    /// history follows the surfaces; from 16 samples on, the accumulated image at each power
    /// of two (then every 64); `oidn`: the same, with Intel Open Image Denoise on the
    /// accumulated image (builds with the cargo feature `oidn`); `none`: the raw mean.
    #[arg(long, value_enum, default_value = "atrous")]
    denoiser: Denoiser,
    /// `gpu` (a `phr` built with `--features gpu`): the GPU traces the colour frames, with any
    /// pipeline, meshes placed many times as copies of one tree, as on the CPU; the CPU poses,
    /// builds the trees, denoises and traces the other modes. The window draws with the GPU's
    /// device; without a denoiser the GPU keeps the film and the window shows it there.
    #[arg(long, value_enum, default_value = "cpu")]
    device: Device,
}

/// `--static-builder`: a builder, or `none`.
#[derive(Clone, Copy, Debug)]
pub struct StaticBuilderArg(Option<Builder>);

impl std::str::FromStr for StaticBuilderArg {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "none" => Ok(StaticBuilderArg(None)),
            _ => s.parse().map(|b| StaticBuilderArg(Some(b))),
        }
    }
}

/// `--builder`: a builder, or `auto` (online tuning).
#[derive(Clone, Copy, Debug)]
pub enum BuilderArg {
    Auto,
    Fixed(Builder),
}

impl std::str::FromStr for BuilderArg {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "auto" => Ok(BuilderArg::Auto),
            _ => s.parse().map(BuilderArg::Fixed),
        }
    }
}

#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
enum LightSampling {
    Explicit,
    Implicit,
}

/// [`PipelineKind`] on the command line (`phr view`, `phr animate`).
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum PipelineArg {
    Thesis,
    TwoLevel,
    Async,
}

impl From<PipelineArg> for PipelineKind {
    fn from(p: PipelineArg) -> Self {
        match p {
            PipelineArg::Thesis => PipelineKind::Thesis,
            PipelineArg::TwoLevel => PipelineKind::TwoLevel,
            PipelineArg::Async => PipelineKind::Async,
        }
    }
}

#[derive(Clone, Copy, ValueEnum)]
enum ModeArg {
    Colour,
    Normals,
    Albedo,
    Heatmap,
}

impl From<ModeArg> for ViewMode {
    fn from(m: ModeArg) -> Self {
        match m {
            ModeArg::Colour => ViewMode::Colour,
            ModeArg::Normals => ViewMode::Normals,
            ModeArg::Albedo => ViewMode::Albedo,
            ModeArg::Heatmap => ViewMode::Heatmap,
        }
    }
}

pub fn run(args: &ViewArgs) -> Result<()> {
    let (pipeline, on_gpu) = open(args)?;
    if let Some(device) = pipeline.tracer() {
        eprintln!("phr view: colour frames traced on the {device}");
    }
    if args.headless {
        return headless::run(args, pipeline);
    }
    if !has_display() {
        eprintln!(
            "phr view: no display (DISPLAY and WAYLAND_DISPLAY are unset); running headless: {} frames to {}",
            args.frames,
            args.out.display()
        );
        return headless::run(args, pipeline);
    }
    match window::run(args, pipeline, on_gpu) {
        Err(window::WindowError::Start(e)) => {
            // (One window per process: the event loop cannot be made again for OpenGL.)
            let hint = if args.device == Device::Gpu { " (--device cpu draws through OpenGL)" } else { "" };
            eprintln!(
                "phr view: cannot open a window ({e}){hint}; running headless: {} frames to {}",
                args.frames,
                args.out.display()
            );
            headless::run(args, open(args)?.0)
        }
        Err(window::WindowError::Other(e)) => Err(e),
        Ok(()) => Ok(()),
    }
}

/// Loads the scene and sets the pipeline up as the arguments say; with `--device gpu`, also
/// gives the GPU, for the window to draw with.
fn open(args: &ViewArgs) -> Result<(FramePipeline, Option<device::OnGpu>)> {
    if args.denoiser == Denoiser::Oidn && !phr_render::denoise::oidn::AVAILABLE {
        anyhow::bail!("--denoiser oidn: {}", phr_render::denoise::oidn::MISSING);
    }
    let on_gpu = args.device == Device::Gpu;
    let pipeline_kind = args.pipeline.unwrap_or(PipelineArg::Async);
    let scene = open_scene(&args.scene)?;
    let camera = scene
        .view(args.view.as_deref())
        .with_context(|| format!("no view {:?} (the scene has: {})", args.view, scene.view_names().join(", ")))?;
    let (builder, auto) = match args.builder {
        BuilderArg::Fixed(b) => (b.with_branching(args.branching).map_err(anyhow::Error::msg)?, None),
        BuilderArg::Auto if args.branching != 2 => {
            anyhow::bail!("--builder auto tries binary builders: leave --branching at 2")
        }
        BuilderArg::Auto => {
            let tuner = AutoBuilder::default();
            (tuner.current(), Some(tuner))
        }
    };
    let max_depth = args.max_depth.unwrap_or(scene.settings.max_depth.min(8));
    let size = RenderSettings { width: args.width, height: args.height, spp: 1, max_depth };
    size.check().map_err(anyhow::Error::msg)?;
    let settings = PipelineSettings {
        builder,
        pipeline: pipeline_kind.into(),
        width: args.width,
        height: args.height,
        max_depth,
        mode: args.mode.into(),
        explicit_lights: args.light_sampling == LightSampling::Explicit,
        denoise: args.denoiser.filter(),
    };
    let mut pipeline = FramePipeline::new(scene, settings, camera);
    let mut gpu = None;
    if on_gpu {
        let (attached, device) = device::attach_gpu(pipeline, "view")?;
        (pipeline, gpu) = (attached, Some(device));
    }
    pipeline.set_auto(auto);
    pipeline.set_static_builder(args.static_builder.0);
    pipeline.playing = !args.paused;
    Ok((pipeline, gpu))
}

fn has_display() -> bool {
    ["DISPLAY", "WAYLAND_DISPLAY"].iter().any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
}

/// Resident set size now and at its peak, in MiB, from `/proc/self/status` (Linux; zeros
/// elsewhere).
pub fn memory_mib() -> (f64, f64) {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.split_whitespace().next()?.parse::<f64>().ok())
            .map_or(0.0, |kib| kib / 1024.0)
    };
    (field("VmRSS:"), field("VmHWM:"))
}
