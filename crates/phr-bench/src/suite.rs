//! The scene suite (`scenes/suite`) and the thesis's benchmark setting.

use anyhow::{Context, Result};
use glam::Vec3;
use phr_render::material::Material;
use phr_render::scene::load_scene;
use phr_render::scene::Background;
use phr_render::Scene;
use std::path::{Path, PathBuf};

/// The suite, by file stem in `scenes/suite`: the thesis's scenes (Bunny, Sponza, Sibenik,
/// Dragon, Conference) and eight dragons for scaling. Each has three views.
pub const SUITE: &[&str] = &["bunny", "sponza", "sibenik", "dragon", "conference", "dragons8"];

/// Path segments of the thesis's frame (camera ray and five bounces).
pub const THESIS_MAX_DEPTH: u32 = 6;

/// Albedo of every surface in the thesis's frame.
pub const THESIS_ALBEDO: f32 = 0.7;

/// The `scenes/suite` folder: from the current directory, or from the checkout this crate
/// was built in.
pub fn suite_dir() -> Result<PathBuf> {
    let candidates =
        [PathBuf::from("scenes/suite"), PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/suite"))];
    candidates
        .into_iter()
        .find(|p| p.is_dir())
        .context("cannot find scenes/suite; run from the repository or pass scene files")
}

/// The files of the named suite scenes.
pub fn suite_files(names: &[&str]) -> Result<Vec<PathBuf>> {
    let dir = suite_dir()?;
    Ok(names.iter().map(|n| dir.join(format!("{n}.json"))).collect())
}

/// A scene's short name: its file stem.
pub fn scene_name(path: &Path) -> String {
    path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
}

/// Turns `scene` into the thesis's benchmark setting: white sky, every surface diffuse
/// (albedo [`THESIS_ALBEDO`]), at most [`THESIS_MAX_DEPTH`] path segments, whatever the file
/// says.
pub fn apply_thesis_setting(scene: &mut Scene) {
    let diffuse = Material::Lambertian { albedo: Vec3::splat(THESIS_ALBEDO) };
    scene.materials.iter_mut().for_each(|m| *m = diffuse.clone());
    scene.background = Background::Constant(Vec3::ONE);
    scene.settings.max_depth = THESIS_MAX_DEPTH;
}

/// Loads a suite scene file in the thesis's setting.
pub fn load_thesis_scene(path: &Path) -> Result<Scene> {
    let mut scene = load_scene(path).with_context(|| format!("loading {}", path.display()))?;
    apply_thesis_setting(&mut scene);
    Ok(scene)
}
