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
use phr_render::geometry::Geometry;
use phr_render::lights::LightSet;
use phr_render::output::write_image;
use phr_render::render::Renderer;
use phr_render::scene::load_scene;
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

/// Measures one scene at every budget; each image goes to `out/images/SCENE_BUDGETs_METHOD.png`.
pub fn measure_scene(scene_file: &Path, options: &QualityOptions, progress: &dyn Progress) -> Result<Vec<QualityRow>> {
    let name = crate::suite::scene_name(scene_file);
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

/// Mitsuba's `path` at each budget: its warm rate measured on 8 samples, then the samples
/// that rate fits into the budget (at least 2), in up to 16 passes; its time is its warm
/// rate times the samples (its JIT compilation left out, as the frame benchmark does).
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
    let rate = peer.path_render(scene_file, 8, 4, options.threads, &work).map(|c| c.warm_ms_per_spp);
    let within = |budget: f64| -> Result<Outcome> {
        let rate = rate.as_ref().map_err(|e| anyhow::anyhow!("{e:#}"))?;
        let spp = ((budget * 1e3 / rate).round() as u32).max(2);
        let run = peer.path_render(scene_file, spp, spp.min(16), options.threads, &work)?;
        let (_, _, image) = read_linear_image(&run.exr)?;
        if image.len() != reference.len() {
            bail!("Mitsuba's image has {} pixels, the reference {}", image.len(), reference.len());
        }
        save(budget, Method::MitsubaPath, &image)?;
        Ok(Outcome::Ran { spp, ms: run.warm_ms_per_spp * f64::from(spp), rmse: rmse(&image, reference) })
    };
    options
        .budgets
        .iter()
        .map(|&budget| (budget, within(budget).unwrap_or_else(|e| Outcome::Skipped(format!("{e:#}")))))
        .collect()
}
