//! The SCENE argument shared by the subcommands: a scene file, a mesh file, `builtin`, or the
//! name of a scene of `scenes/suite` (`sponza`, `dragon`, ...). The one way the front end opens
//! a scene; files go through [`phr_render::scene::load_scene`].

use anyhow::Result;
use phr_render::scene::{builtin, load_scene};
use phr_render::Scene;
use std::path::{Path, PathBuf};

pub const BUILTIN: &str = "builtin";

pub fn open_scene(arg: &str) -> Result<Scene> {
    if arg == BUILTIN {
        return Ok(builtin::cornell_knot());
    }
    Ok(load_scene(&scene_path(arg))?)
}

/// The file `arg` names: itself if it exists or looks like a path, else the suite scene of
/// that name if there is one.
fn scene_path(arg: &str) -> PathBuf {
    let path = Path::new(arg);
    let bare_name = path.components().count() == 1 && path.extension().is_none();
    if !path.exists() && bare_name {
        if let Some(file) = phr_bench::suite::suite_files(&[arg]).ok().and_then(|f| f.into_iter().next()) {
            if file.is_file() {
                return file;
            }
        }
    }
    path.to_path_buf()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suite_names_open_their_scene_files_and_paths_stay_paths() {
        assert!(scene_path("sponza").ends_with("scenes/suite/sponza.json"));
        assert_eq!(scene_path("no_such_scene"), PathBuf::from("no_such_scene"));
        assert_eq!(scene_path("dir/sponza"), PathBuf::from("dir/sponza"));
        let err = open_scene("no_such_scene").unwrap_err().to_string();
        assert!(err.contains("no_such_scene"), "{err}");
    }
}
