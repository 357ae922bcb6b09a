//! The scene suite (`scenes/suite`) and the thesis's benchmark setting.

use anyhow::{Context, Result};
use glam::Vec3;
use phr_render::geometry::Geometry;
use phr_render::material::Material;
use phr_render::scene::load_scene;
use phr_render::scene::Background;
use phr_render::Scene;
use std::path::{Path, PathBuf};

/// The suite, by file stem in `scenes/suite`: the thesis's scenes (Bunny, Sponza, Sibenik,
/// Dragon, Conference) and eight dragons for scaling. Each has three views.
pub const SUITE: &[&str] = &["bunny", "sponza", "sibenik", "dragon", "conference", "dragons8"];

/// The thesis's five scenes, by file stem in `scenes/suite`: the suite without the scaling
/// scene (what `phr bench-rays` measures by default).
pub const THESIS_SCENES: &[&str] = &["bunny", "sponza", "sibenik", "dragon", "conference"];

/// The meshes of the shared scenes folder, by path below it: the builder benchmarks
/// (`phr bench-build`, `bench-cut-cost`, `bench-tune`) measure the bare meshes, framed by
/// their default camera, rather than the suite's views.
pub const SHARED_MESHES: &[&str] = &[
    "cornell_box/CornellBox-Original.obj",
    "bunny/bun_zipper.ply",
    "sponza/sponza.obj",
    "sibenik/sibenik.obj",
    "sibenik/sibenik_75284_geometry.ply",
    "conference/conference_geometry.ply",
    "dragon/dragon_vrip.ply",
];

/// The entries of `list` whose name contains one of `only` (all of them if `only` is empty).
pub fn select<'a>(list: &[&'a str], only: &[String]) -> Vec<&'a str> {
    list.iter().copied().filter(|m| only.is_empty() || only.iter().any(|o| m.contains(o.as_str()))).collect()
}

/// The shared scenes folder: the one given, or the one `{scenes}` in scene files stands for
/// (`$PHR_SCENES_DIR`, or found above the current directory).
pub fn shared_scenes_dir(given: Option<&Path>) -> Result<PathBuf> {
    match given {
        Some(d) => Ok(d.to_path_buf()),
        None => phr_render::scene::json::scenes_dir(Path::new("."))
            .context("cannot find the shared scenes folder; pass --scenes DIR or set PHR_SCENES_DIR"),
    }
}

/// One mesh of the shared scenes (a path below `dir`), as a scene (its materials, a camera
/// framing it) and its geometry.
pub fn open_mesh(dir: &Path, name: &str) -> Result<(Geometry, Scene)> {
    let scene = load_scene(&dir.join(name))?;
    Ok((Geometry::new(&scene), scene))
}

/// The scene argument's word for the built-in scene.
pub const BUILTIN: &str = "builtin";

/// What a front end's scene argument names, opened: a scene file (.json), a mesh file,
/// [`BUILTIN`], or the name of a scene of `scenes/suite` (`sponza`, `dragon`, ...). The one
/// way the command line and the Python module open a scene; files go through
/// [`load_scene`].
pub fn open_scene(arg: &str) -> Result<Scene> {
    if arg == BUILTIN {
        return Ok(phr_render::scene::builtin::cornell_knot());
    }
    Ok(load_scene(&scene_path(arg))?)
}

/// The file `arg` names: itself if it exists or looks like a path, else the suite scene of
/// that name if there is one.
fn scene_path(arg: &str) -> PathBuf {
    let path = Path::new(arg);
    let bare_name = path.components().count() == 1 && path.extension().is_none();
    if !path.exists() && bare_name {
        if let Some(file) = suite_files(&[arg]).ok().and_then(|f| f.into_iter().next()) {
            if file.is_file() {
                return file;
            }
        }
    }
    path.to_path_buf()
}

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_suite_is_the_thesis_scenes_and_the_scaling_scene() {
        assert_eq!(&SUITE[..THESIS_SCENES.len()], THESIS_SCENES);
        assert_eq!(SUITE.len(), THESIS_SCENES.len() + 1);
    }

    #[test]
    fn select_filters_by_substring() {
        assert_eq!(select(SHARED_MESHES, &[]).len(), SHARED_MESHES.len());
        assert_eq!(select(SHARED_MESHES, &["sibenik".into()]).len(), 2);
        assert_eq!(
            select(SHARED_MESHES, &["bunny".into(), "dragon".into()]),
            ["bunny/bun_zipper.ply", "dragon/dragon_vrip.ply"]
        );
        assert!(select(SHARED_MESHES, &["nothing".into()]).is_empty());
    }

    #[test]
    fn suite_names_open_their_scene_files_and_paths_stay_paths() {
        assert!(scene_path("sponza").ends_with("scenes/suite/sponza.json"));
        assert_eq!(scene_path("no_such_scene"), PathBuf::from("no_such_scene"));
        assert_eq!(scene_path("dir/sponza"), PathBuf::from("dir/sponza"));
        let err = open_scene("no_such_scene").unwrap_err().to_string();
        assert!(err.contains("no_such_scene"), "{err}");
    }
}
