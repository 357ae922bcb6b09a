//! `phr export-reference`: a scene in the reference renderer's JSON, with its meshes as PLY
//! files, so Mitsuba 3 renders what phr renders (`shared/reference/tools/render_reference.py
//! DIR/NAME.json -o PREFIX`). The writing lives in `phr_bench::reference_export`.

use crate::scene_arg::open_scene;
use anyhow::{Context, Result};
use clap::Args;
use phr_bench::reference_export::export_reference_scene;
use std::path::PathBuf;

#[derive(Args)]
pub struct ExportReferenceArgs {
    /// A scene file (.json), a mesh (.obj, .ply, .gltf, .glb), `builtin`, or a suite scene.
    scene: String,
    /// Output folder (NAME.json and NAME_*.ply).
    #[arg(long)]
    out: PathBuf,
    /// The name of the files (default: the scene's file name, or `builtin`).
    #[arg(long)]
    name: Option<String>,
    /// The scene's named view (default: its first).
    #[arg(long)]
    view: Option<String>,
    /// Image size and samples per pixel written into the file (default: the scene's).
    #[arg(long)]
    width: Option<u32>,
    #[arg(long)]
    height: Option<u32>,
    #[arg(long)]
    spp: Option<u32>,
    /// Maximum ray segments per path (default: the scene's).
    #[arg(long)]
    max_depth: Option<u32>,
}

pub fn run(args: &ExportReferenceArgs) -> Result<()> {
    let mut scene = open_scene(&args.scene)?;
    let view = scene
        .view(args.view.as_deref())
        .with_context(|| format!("no view {:?} (the scene has: {})", args.view, scene.view_names().join(", ")))?;
    let s = &mut scene.settings;
    s.width = args.width.unwrap_or(s.width);
    s.height = args.height.unwrap_or(s.height);
    s.spp = args.spp.unwrap_or(s.spp);
    s.max_depth = args.max_depth.unwrap_or(s.max_depth);
    s.check().map_err(anyhow::Error::msg)?;
    let name = match &args.name {
        Some(n) => n.clone(),
        None => phr_bench::suite::scene_name(std::path::Path::new(&args.scene)),
    };
    let path = export_reference_scene(&scene, &view, &name, &args.out).with_context(|| args.scene.clone())?;
    println!("wrote {}", path.display());
    Ok(())
}
