//! `phr render`: load, build, trace progressively, write images, print a summary.

use crate::scene_arg::{open_scene, BUILTIN};
use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use phr_bvh::builder::BuildReport;
use phr_bvh::{sah_cost, Builder, SahConstants};
use phr_render::camera::CameraDesc;
use phr_render::denoise::{oidn, Atrous, Filter, Guide, GUIDE_SAMPLES};
use phr_render::film::Film;
use phr_render::geometry::Geometry;
use phr_render::lights::LightSet;
use phr_render::output::{write_heatmap, write_image};
use phr_render::render::{Renderer, Tracing};
use phr_render::scene::{RenderSettings, Scene};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args, Clone)]
pub struct RenderArgs {
    /// A scene file (.json), a mesh (.obj, .ply, .gltf, .glb, optionally .gz), `builtin`, or a
    /// scene of scenes/suite by name (sponza, dragon, ...).
    #[arg(default_value = BUILTIN)]
    pub scene: String,
    /// Named view of the scene (default: its first).
    #[arg(long)]
    pub view: Option<String>,
    #[arg(long)]
    pub width: Option<u32>,
    #[arg(long)]
    pub height: Option<u32>,
    /// Samples per pixel (frames of 1 sample each, accumulated).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Maximum ray segments per path, camera ray included.
    #[arg(long)]
    pub max_depth: Option<u32>,
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// BVH builder: lbvh, phr-fast, phr-hq, phr:ALPHA,DELTA, sweep-sah, binned-sah, sbvh (the
    /// default: spatial splits, the tree that traces fastest; a static render builds it once).
    #[arg(long, default_value = "sbvh")]
    pub builder: Builder,
    /// Children per node (PHR builders: 2, 4, 8 or 16).
    #[arg(long, default_value_t = 2)]
    pub branching: u32,
    /// Output image: .png (sRGB), .exr or .pfm (linear); denoised unless `--denoiser none`.
    #[arg(long, short, default_value = "render.png")]
    pub out: PathBuf,
    /// Also write the film's linear mean to this .exr or .pfm, never denoised: the unbiased
    /// estimate that image comparisons want.
    #[arg(long)]
    pub linear: Option<PathBuf>,
    /// Also write the denoiser's guides: the first hits' albedo (PATH) and normals (PATH with
    /// `_normal` before its extension), .exr or .pfm.
    #[arg(long)]
    pub albedo: Option<PathBuf>,
    /// Also write the per-pixel variance of the mean (.exr or .pfm), for compare_images.py --test-var.
    #[arg(long)]
    pub variance: Option<PathBuf>,
    /// Also write a heatmap of traversal steps per primary ray (.png).
    #[arg(long)]
    pub heatmap: Option<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// The estimator. `path`: at diffuse hits one light (emissive triangle or sphere, the
    /// sky) is sampled through a shadow ray, weighed against the path's own bounce by multiple
    /// importance sampling, with Russian roulette. `implicit`: lights only count where paths
    /// hit them, the thesis's estimator (and `phr bench`'s). Both converge to the same image.
    #[arg(long, value_enum, default_value = "path")]
    pub integrator: Integrator,
    /// `atrous`: the edge-avoiding à-trous filter guided by the first hits' albedo, normals
    /// and positions, and by the film's variance (`crates/phr-render/src/denoise/atrous.rs`).
    /// `oidn`: Intel Open Image Denoise, guided by the albedo and normals (builds with the
    /// cargo feature `oidn`, see `tools/setup-oidn.sh`). With either, the pixels the filter
    /// leaves alone (lights and the sky seen directly) that are noisy or at an edge are
    /// sampled again, 15 times the spp (at most a quarter of the render's samples).
    #[arg(long, value_enum, default_value = "atrous")]
    pub denoiser: Denoiser,
    /// How a frame's paths are traced: `wavefront` (a tile's rays intersected as one batch,
    /// several rays traversed at once) or `single` (each path to its end, one after the
    /// other: the reference). The same image either way.
    #[arg(long, default_value = "wavefront")]
    pub tracing: Tracing,
    /// Where to trace: `cpu`, or `gpu` (the WGSL path tracer of crates/phr-gpu on any Vulkan,
    /// Metal or DX12 adapter, Mesa's lavapipe included; build with `--features gpu`). The GPU
    /// traces the CPU's 8-wide tree with either estimator; the denoiser then runs on the CPU.
    #[arg(long, value_enum, default_value = "cpu")]
    pub device: Device,
}

/// The devices of `phr render --device`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Device {
    Cpu,
    Gpu,
}

/// The error of `phr COMMAND --device gpu` in a `phr` built without the cargo feature `gpu`.
#[cfg(not(feature = "gpu"))]
pub fn without_gpu(command: &str) -> anyhow::Error {
    anyhow::anyhow!(
        "this phr was built without the GPU tracer: build it with `cargo build --release --features gpu` \
         (or run `cargo run --release --features gpu -- {command} ... --device gpu`)"
    )
}

/// The denoisers of `phr render --denoiser`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Denoiser {
    Atrous,
    Oidn,
    None,
}

impl Denoiser {
    pub fn filter(self) -> Option<Filter> {
        match self {
            Denoiser::Atrous => Some(Filter::Atrous),
            Denoiser::Oidn => Some(Filter::Oidn),
            Denoiser::None => None,
        }
    }
}

/// The estimators of `phr render --integrator`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Integrator {
    Path,
    Implicit,
}

impl Default for RenderArgs {
    fn default() -> Self {
        Self {
            scene: BUILTIN.into(),
            view: None,
            width: None,
            height: None,
            spp: None,
            max_depth: None,
            seed: 0,
            builder: Builder::Sbvh(Default::default()),
            branching: 2,
            out: "render.png".into(),
            linear: None,
            variance: None,
            heatmap: None,
            quiet: false,
            integrator: Integrator::Path,
            denoiser: Denoiser::Atrous,
            tracing: Tracing::default(),
            albedo: None,
            device: Device::Cpu,
        }
    }
}

/// Fails before any work if an output could not be written (bad folder or extension).
pub fn check_output(path: &Path, allowed: &[&str]) -> Result<()> {
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
    if !allowed.contains(&ext.as_str()) {
        bail!("{}: unsupported output format (use {})", path.display(), allowed.join(", "));
    }
    let dir = path.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.is_dir() {
        bail!("{}: folder {} does not exist", path.display(), dir.display());
    }
    Ok(())
}

/// What both devices do first: check the outputs, load the scene, pick the view and settle the
/// settings.
pub fn prepare(args: &RenderArgs) -> Result<(Scene, CameraDesc, RenderSettings)> {
    check_output(&args.out, &["png", "exr", "pfm"])?;
    for p in [&args.linear, &args.variance, &args.albedo].into_iter().flatten() {
        check_output(p, &["exr", "pfm"])?;
    }
    if let Some(p) = &args.heatmap {
        check_output(p, &["png"])?;
    }
    if args.denoiser == Denoiser::Oidn && !oidn::AVAILABLE {
        bail!("--denoiser oidn: {}", oidn::MISSING);
    }
    let scene = open_scene(&args.scene)?;
    let view = scene.view(args.view.as_deref()).with_context(|| {
        format!(
            "no view \"{}\" in {} (views: {})",
            args.view.as_deref().unwrap_or(""),
            args.scene,
            scene.view_names().join(", ")
        )
    })?;
    let settings = RenderSettings {
        width: args.width.unwrap_or(scene.settings.width),
        height: args.height.unwrap_or(scene.settings.height),
        spp: args.spp.unwrap_or(scene.settings.spp),
        max_depth: args.max_depth.unwrap_or(scene.settings.max_depth),
    };
    settings.check().map_err(anyhow::Error::msg)?;
    Ok((scene, view, settings))
}

/// `phr render` on the CPU (`--device gpu` is `crate::render_gpu`'s).
pub fn run(args: &RenderArgs) -> Result<()> {
    let (scene, view, settings) = prepare(args)?;
    let RenderSettings { width, height, spp, .. } = settings;

    let builder = args.builder.with_branching(args.branching).map_err(anyhow::Error::msg)?;
    let mut geometry = Geometry::new(&scene);
    let report = geometry.build_report(&builder);
    let mut build = describe_build(&builder, &report);
    geometry.set_bvh(report.bvh);
    build += &describe_copies(&scene, geometry.build_copies(&builder));
    // A still render never rebuilds: the packed triangles it traces become the only copy.
    geometry.release_triangles();
    let lights =
        (args.integrator == Integrator::Path).then(|| LightSet::new(&geometry, &scene.materials, &scene.background));

    let renderer = Renderer::new(&scene, &geometry, &view, &settings, lights.as_ref())
        .with_seed(args.seed)
        .with_tracing(args.tracing);
    let progress = if args.quiet { ProgressBar::hidden() } else { ProgressBar::new(spp as u64) };
    progress.set_style(
        ProgressStyle::with_template("{spinner} rendering [{bar:30}] {pos}/{len} spp  {elapsed} (eta {eta})  {msg}")
            .expect("valid template")
            .progress_chars("=> "),
    );
    let mut film = Film::new(width, height);
    let mut rays = 0u64;
    let render_start = Instant::now();
    for frame in 0..spp {
        let (pixels, stats) = renderer.render_frame(frame);
        film.add_frame(&pixels);
        rays += stats.rays;
        progress.inc(1);
        progress.set_message(format!("{:.1} Mrays/s", rays as f64 / render_start.elapsed().as_secs_f64() / 1e6));
    }
    let render_ms = render_start.elapsed().as_secs_f64() * 1e3;
    progress.finish_and_clear();

    let notes = finish(args, &renderer, &film)?;
    let sah = sah_cost(geometry.bvh(), SahConstants::UNIT);
    println!(
        "{}: {} triangles, {} spheres | {build} | render {:.0} ms ({width}x{height}, {spp} spp) | {:.2} Mrays/s | SAH cost {:.2}",
        args.scene,
        geometry.triangle_count(),
        geometry.spheres.len(),
        render_ms,
        rays as f64 / (render_ms / 1e3) / 1e6,
        sah
    );
    notes.iter().for_each(|line| println!("{line}"));
    println!("wrote {}", args.out.display());
    Ok(())
}

/// What follows the frames on either device: the denoiser, whose guide and extra samples
/// `renderer` traces on the CPU, then every output file. Returns what to print after the
/// render's summary.
pub fn finish(args: &RenderArgs, renderer: &Renderer, film: &Film) -> Result<Vec<String>> {
    let (width, height, spp) = (film.width, film.height, film.samples);
    let mut notes = Vec::new();
    let mean = film.mean();
    let start = Instant::now();
    let (denoised, guide) = match args.denoiser.filter() {
        Some(filter) => {
            let finished = filter.finish(renderer, film).map_err(anyhow::Error::msg)?;
            let ms = start.elapsed().as_secs_f64() * 1e3;
            let refined = (finished.refined_pixels, finished.extra_samples);
            (Some((finished.image, ms, refined)), Some(finished.guide))
        }
        None => (None, args.albedo.is_some().then(|| Guide::render(renderer, spp.min(GUIDE_SAMPLES)))),
    };
    let image = denoised.as_ref().map_or(&mean, |(image, _, _)| image);
    write_image(&args.out, width, height, image).with_context(|| format!("writing {}", args.out.display()))?;
    if let (Some(p), Some(guide)) = (&args.albedo, &guide) {
        write_image(p, width, height, &guide.albedo).with_context(|| format!("writing {}", p.display()))?;
        let normal_path = with_suffix(p, "_normal");
        // Normals in [-1, 1] as they are (linear formats keep the sign).
        write_image(&normal_path, width, height, &guide.normal)
            .with_context(|| format!("writing {}", normal_path.display()))?;
    }
    if let Some(p) = &args.linear {
        write_image(p, width, height, &mean).with_context(|| format!("writing {}", p.display()))?;
    }
    if let Some(p) = &args.variance {
        write_image(p, width, height, &film.variance_of_mean()).with_context(|| format!("writing {}", p.display()))?;
    }
    if let Some(p) = &args.heatmap {
        let steps: Vec<u32> = renderer.primary_ray_stats().iter().map(|s| s.nodes).collect();
        let max = write_heatmap(p, width, height, &steps, None).with_context(|| format!("writing {}", p.display()))?;
        let mean = steps.iter().map(|&s| s as f64).sum::<f64>() / steps.len() as f64;
        notes.push(format!("heatmap: {} (mean {mean:.1} traversal steps per primary ray, red = {max})", p.display()));
    }
    if let Some((_, ms, (pixels, samples))) = denoised {
        let filter = match args.denoiser {
            Denoiser::Oidn => "Open Image Denoise".to_string(),
            _ => format!("à-trous, {} passes", Atrous::default().passes),
        };
        notes.push(format!(
            "denoised ({filter}) in {ms:.0} ms: the guide, {pixels} unfiltered noisy pixels (light and sky edges) \
             sampled {samples} more times each, the filter"
        ));
    }
    Ok(notes)
}

/// `dir/name.ext` → `dir/name{suffix}.ext`.
fn with_suffix(path: &Path, suffix: &str) -> PathBuf {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let ext = path.extension().map(|e| format!(".{}", e.to_string_lossy())).unwrap_or_default();
    path.with_file_name(format!("{stem}{suffix}{ext}"))
}

/// What the copies of meshes placed many times add to a build, after its description
/// (nothing when there are none).
pub fn describe_copies(scene: &phr_render::scene::Scene, time: std::time::Duration) -> String {
    let (placed, stored) = scene.instanced_triangle_count();
    if scene.instanced.is_empty() {
        return String::new();
    }
    let copies: usize = scene.instanced.iter().map(|i| i.copies.len()).sum();
    format!(
        " + {copies} copies of {} meshes ({stored} triangles stored, {placed} placed) {:.1} ms",
        scene.instanced.len(),
        time.as_secs_f64() * 1e3
    )
}

/// "phr-fast build 12.3 ms (LBVH 4.1 + PHR 8.2, Σ|cut| 185317)" or "lbvh build 4.0 ms".
pub fn describe_build(builder: &Builder, report: &BuildReport) -> String {
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    match report.phr {
        Some(stats) => format!(
            "{builder} build {:.1} ms (LBVH {:.1} + PHR {:.1}, Σ|cut| {})",
            ms(report.total_time()),
            ms(report.aux_time),
            ms(report.build_time),
            stats.build_cost
        ),
        None => format!("{builder} build {:.1} ms", ms(report.total_time())),
    }
}
