//! `phr bench-quality`: per scene and time budget, the RMSE against the scene's converged
//! reference of our outputs ([`Method::ours`]) and of Mitsuba 3's `path` integrator,
//! with the images, as CSV, JSON and a Markdown table.
//!
//! A scene file `DIR/scenes/NAME.json` has its reference at `DIR/images/NAME.exr`, the
//! layout of `shared/reference` (rendered by Mitsuba 3 at 4096–16384 spp).

use crate::mitsuba::MitsubaPeer;
use crate::quality::{read_linear_image, render_within, rmse, DenoiseCost, Method};
use crate::Progress;
use anyhow::{bail, Context, Result};
use glam::Vec3;
use phr_bvh::Builder;
use phr_render::camera::CameraDesc;
use phr_render::geometry::Geometry;
use phr_render::lights::LightSet;
use phr_render::output::write_image;
use phr_render::render::Renderer;
use phr_render::scene::load_scene;
use phr_render::Scene;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The reference scenes of `shared/reference`, by name.
pub const REFERENCE_SCENES: &[&str] = &["cornell_obj", "bunny_sky", "cornell_glass_mirror", "spheres_sky"];

/// The reference image of a scene file: `../images/STEM.exr` from its folder.
pub fn reference_for(scene_file: &Path) -> PathBuf {
    let stem = crate::suite::scene_name(scene_file);
    scene_file.parent().unwrap_or(Path::new(".")).join("../images").join(format!("{stem}.exr"))
}

pub struct QualityOptions {
    /// Budgets, in seconds of wall-clock time.
    pub budgets: Vec<f64>,
    pub builder: Builder,
    /// The peer, or why it does not run.
    pub mitsuba: Result<MitsubaPeer, String>,
    pub threads: usize,
    /// Where the images and Mitsuba's scratch files go.
    pub out: PathBuf,
}

/// What one method made of one budget.
#[derive(Clone, Debug, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    Ran { spp: u32, ms: f64, rmse: f64 },
    Skipped(String),
}

#[derive(Clone, Debug, serde::Serialize)]
pub struct QualityRow {
    pub scene: String,
    pub budget_s: f64,
    pub method: Method,
    pub outcome: Outcome,
}

impl QualityRow {
    pub fn rmse(&self) -> Option<f64> {
        match self.outcome {
            Outcome::Ran { rmse, .. } => Some(rmse),
            Outcome::Skipped(_) => None,
        }
    }
}

/// A scene file that [`measure_scene`] can score: readable, with a camera, and a reference
/// image of its size. Returns the scene, its view and the reference's pixels. Checked for
/// every scene before any is rendered, so that a bad one leaves no partial output.
pub fn open_scene_with_reference(scene_file: &Path) -> Result<(Scene, CameraDesc, Vec<Vec3>)> {
    let reference_file = reference_for(scene_file);
    if !reference_file.is_file() {
        bail!("{}: no reference image at {}", scene_file.display(), reference_file.display());
    }
    let (rw, rh, reference) = read_linear_image(&reference_file)?;
    let scene = load_scene(scene_file)?;
    let view = scene.view(None).with_context(|| format!("{} has no camera", scene_file.display()))?;
    let settings = scene.settings;
    if (settings.width, settings.height) != (rw, rh) {
        bail!(
            "{} is {}×{}, its reference {} is {rw}×{rh}",
            scene_file.display(),
            settings.width,
            settings.height,
            reference_file.display()
        );
    }
    Ok((scene, view, reference))
}

/// Measures one scene at every budget; each image goes to `out/images/SCENE_BUDGETs_METHOD.png`.
pub fn measure_scene(scene_file: &Path, options: &QualityOptions, progress: &dyn Progress) -> Result<Vec<QualityRow>> {
    let name = crate::suite::scene_name(scene_file);
    let (scene, view, reference) = open_scene_with_reference(scene_file)?;
    let settings = scene.settings;
    progress.status(format!("{name}: building ({})", options.builder));
    let mut geometry = Geometry::new(&scene);
    geometry.build(&options.builder);
    let lights = LightSet::new(&geometry, &scene.materials, &scene.background);
    let implicit = Renderer::new(&scene, &geometry, &view, &settings, None);
    let path = Renderer::new(&scene, &geometry, &view, &settings, Some(&lights));
    let mut costs = Vec::new();
    for filter in Method::ours().into_iter().filter_map(Method::filter) {
        costs.push(DenoiseCost::measure(&path, filter).map_err(anyhow::Error::msg)?);
    }
    let images = options.out.join("images");
    std::fs::create_dir_all(&images).with_context(|| format!("creating {}", images.display()))?;
    let save = |budget: f64, method: Method, pixels: &[Vec3]| -> Result<()> {
        let file = images.join(format!("{name}_{budget}s_{}.png", method.slug()));
        write_image(&file, settings.width, settings.height, pixels)
            .with_context(|| format!("writing {}", file.display()))
    };

    let mut rows = Vec::new();
    for &budget in &options.budgets {
        for method in Method::ours() {
            progress.status(format!("{name}, {budget} s: {}", method.label()));
            let renderer = if method == Method::Implicit { &implicit } else { &path };
            let cost = method.filter().and_then(|f| costs.iter().find(|c| c.filter == f));
            let r = render_within(renderer, Duration::from_secs_f64(budget), cost).map_err(anyhow::Error::msg)?;
            save(budget, method, &r.image)?;
            let outcome = Outcome::Ran { spp: r.spp, ms: r.ms, rmse: rmse(&r.image, &reference) };
            rows.push(QualityRow { scene: name.clone(), budget_s: budget, method, outcome });
        }
    }
    progress.status(format!("{name}: Mitsuba 3"));
    for (budget, outcome) in mitsuba_outcomes(scene_file, &reference, options, &save) {
        if let Outcome::Skipped(why) = &outcome {
            progress.note(format!("{name}, {budget} s: Mitsuba 3 skipped: {why}"));
        }
        rows.push(QualityRow { scene: name.clone(), budget_s: budget, method: Method::MitsubaPath, outcome });
    }
    // Grouped by budget, in the order of the methods.
    rows.sort_by(|a, b| a.budget_s.total_cmp(&b.budget_s).then(a.method.cmp(&b.method)));
    progress.advance();
    Ok(rows)
}

/// Writes the image one method made of one budget.
type SaveImage<'a> = &'a dyn Fn(f64, Method, &[Vec3]) -> Result<()>;

/// Mitsuba's `path` at each budget. Its samples: those its warm rate fits into the budget,
/// the rate measured first on 8 samples in 4 passes, then on the run itself; when the run's
/// warm time misses the budget by more than 10 %, it runs again with the samples its own
/// rate gives (at least 2 samples, in up to 16 passes). Its time is that warm rate times the
/// samples (the JIT pass is left out, as the frame benchmark does). Its seeds start at 10⁶,
/// away from the references' own.
fn mitsuba_outcomes(
    scene_file: &Path,
    reference: &[Vec3],
    options: &QualityOptions,
    save: SaveImage,
) -> Vec<(f64, Outcome)> {
    let peer = match &options.mitsuba {
        Ok(peer) => peer,
        Err(why) => return options.budgets.iter().map(|&b| (b, Outcome::Skipped(why.clone()))).collect(),
    };
    let work = options.out.join("mitsuba");
    let run = |spp: u32| peer.path_render(scene_file, spp, spp.min(16), options.threads, &work);
    let spp_for = |budget: f64, rate: f64| -> Result<u32> {
        if !(rate.is_finite() && rate > 0.0) {
            bail!("Mitsuba reported a warm rate of {rate} ms per sample");
        }
        Ok((budget * 1e3 / rate).round().clamp(2.0, 1e6) as u32)
    };
    let calibration = peer.path_render(scene_file, 8, 4, options.threads, &work).map(|c| c.warm_ms_per_spp);
    let within = |budget: f64| -> Result<Outcome> {
        let rate = *calibration.as_ref().map_err(|e| anyhow::anyhow!("{e:#}"))?;
        let mut render = run(spp_for(budget, rate)?)?;
        let ms = |r: &crate::mitsuba::PathRender| r.warm_ms_per_spp * f64::from(r.spp);
        if (ms(&render) - budget * 1e3).abs() > 0.1 * budget * 1e3 {
            render = run(spp_for(budget, render.warm_ms_per_spp)?)?;
        }
        let (w, h, image) = read_linear_image(&render.exr)?;
        if w as usize * h as usize != reference.len() || image.len() != reference.len() {
            bail!("Mitsuba's image is {w}×{h}, not the reference's size");
        }
        save(budget, Method::MitsubaPath, &image)?;
        Ok(Outcome::Ran { spp: render.spp, ms: ms(&render), rmse: rmse(&image, reference) })
    };
    options
        .budgets
        .iter()
        .map(|&budget| (budget, within(budget).unwrap_or_else(|e| Outcome::Skipped(format!("{e:#}")))))
        .collect()
}
