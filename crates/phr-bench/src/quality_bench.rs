//! `phr bench-quality`: per scene and time budget, the RMSE against the scene's converged
//! reference of our outputs ([`Method::ours`]) and of Mitsuba 3's `path` integrator,
//! with the images, as CSV, JSON and a Markdown table.
//!
//! A scene file `DIR/scenes/NAME.json` has its reference at `DIR/images/NAME.exr`, the
//! layout of `shared/reference` (rendered by Mitsuba 3 at 4096–16384 spp) and of this crate's
//! `references` (textured Sponza, and the built-in scene, which the benchmark writes out in
//! the reference renderer's format first: [`builtin_scene_file`]).

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

/// This crate's references (`references/make_references.py` renders them): its scenes in
/// `scenes/`, their images in `images/`.
pub const OWN_REFERENCES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/references");

/// The scenes of [`OWN_REFERENCES`], by name; `builtin` is phr's built-in scene.
pub const OWN_SCENES: &[&str] = &["sponza_textured", "builtin"];

/// The size of the built-in scene's reference.
const BUILTIN_SIZE: u32 = 256;

/// A scene to score and its converged reference.
#[derive(Clone, Debug)]
pub struct ScoredScene {
    pub file: PathBuf,
    pub reference: PathBuf,
}

impl ScoredScene {
    /// A scene file with its reference at `../images/STEM.exr` from its folder.
    pub fn with_reference_beside(file: PathBuf) -> Self {
        let stem = crate::suite::scene_name(&file);
        let reference = file.parent().unwrap_or(Path::new(".")).join("../images").join(format!("{stem}.exr"));
        Self { file, reference }
    }

    /// The scene `name` of `shared/reference`, of [`OWN_SCENES`], or `builtin` (written out to
    /// `work` by [`builtin_scene_file`]); else a scene file.
    pub fn named(name: &str, work: &Path) -> Result<Self> {
        if name == crate::suite::BUILTIN {
            let reference = Path::new(OWN_REFERENCES).join("images/builtin.exr");
            return Ok(Self { file: builtin_scene_file(work)?, reference });
        }
        if OWN_SCENES.contains(&name) {
            return Ok(Self::with_reference_beside(Path::new(OWN_REFERENCES).join(format!("scenes/{name}.json"))));
        }
        if REFERENCE_SCENES.contains(&name) {
            let dir = crate::suite::shared_scenes_dir(None)?;
            return Ok(Self::with_reference_beside(dir.join(format!("../reference/scenes/{name}.json"))));
        }
        Ok(Self::with_reference_beside(PathBuf::from(name)))
    }
}

/// phr's built-in scene in the reference renderer's format (`work/scenes/builtin.json` and its
/// PLY files), as `references/make_references.py` renders it, so that Mitsuba 3 renders it
/// too.
pub fn builtin_scene_file(work: &Path) -> Result<PathBuf> {
    let mut scene = crate::suite::open_scene(crate::suite::BUILTIN)?;
    let view = scene.view(None).context("the built-in scene has no view")?;
    (scene.settings.width, scene.settings.height) = (BUILTIN_SIZE, BUILTIN_SIZE);
    crate::reference_export::export_reference_scene(&scene, &view, "builtin", &work.join("scenes"))
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
pub fn open_scene_with_reference(scored: &ScoredScene) -> Result<(Scene, CameraDesc, Vec<Vec3>)> {
    let (scene_file, reference_file) = (&scored.file, &scored.reference);
    if !reference_file.is_file() {
        bail!("{}: no reference image at {}", scene_file.display(), reference_file.display());
    }
    let (rw, rh, reference) = read_linear_image(reference_file)?;
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
pub fn measure_scene(
    scored: &ScoredScene,
    options: &QualityOptions,
    progress: &dyn Progress,
) -> Result<Vec<QualityRow>> {
    let scene_file = &scored.file;
    let name = crate::suite::scene_name(scene_file);
    let (scene, view, reference) = open_scene_with_reference(scored)?;
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
