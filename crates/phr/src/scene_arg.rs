//! The SCENE argument shared by the subcommands: a scene file, a mesh file, or `builtin`.

use anyhow::Result;
use phr_render::scene::{builtin, load_scene};
use phr_render::Scene;
use std::path::Path;

pub const BUILTIN: &str = "builtin";

pub fn open_scene(arg: &str) -> Result<Scene> {
    if arg == BUILTIN {
        return Ok(builtin::cornell_knot());
    }
    Ok(load_scene(Path::new(arg))?)
}
