//! `phr bench --peers`: Intel Embree (via the `embreex` Python package, `bench/peers.py`) on
//! exactly our triangles and rays, in the same run. We export the scene's triangles, the
//! primary and diffuse-bounce rays of its first view, and our closest hits; the script builds
//! Embree's BVH, traces the rays, and checks that the hits agree. embreex traces on one
//! thread, so our side is measured on one thread too.

use crate::bench_build::{throughput, RaySet};
use anyhow::{Context, Result};
use phr_bvh::{Builder, Ray};
use phr_render::camera::{Camera, CameraDesc};
use phr_render::geometry::Geometry;
use phr_render::output::write_atomically;
use phr_render::scene::RenderSettings;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

#[derive(Clone, Debug, Default)]
pub struct PeerRow {
    pub scene: String,
    pub rays: usize,
    pub ours_build_ms: f64,
    pub ours_primary: f64,
    pub ours_diffuse: f64,
    pub embree_build_ms: f64,
    pub embree_primary: f64,
    pub embree_diffuse: f64,
    pub hit_agreement: f64,
    /// Our 1-spp frame of the first view (PHR-HQ), and Mitsuba 3's (or why not).
    pub ours_frame_ms: f64,
    pub mitsuba: String,
}

/// The peer script `bench/NAME`, from the current directory or the checkout.
pub(crate) fn peer_script(name: &str) -> Option<PathBuf> {
    [PathBuf::from("bench").join(name), PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../bench")).join(name)]
        .into_iter()
        .find(|p| p.is_file())
}

/// Writes a count and then the floats, little-endian: the ray and triangle files the peer
/// scripts read.
pub(crate) fn write_counted(path: &Path, count: usize, floats: impl Iterator<Item = f32>) -> Result<()> {
    write_atomically(path, |tmp| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        f.write_all(&(count as u32).to_le_bytes())?;
        for x in floats {
            f.write_all(&x.to_le_bytes())?;
        }
        f.flush()
    })
    .with_context(|| format!("writing {}", path.display()))
}

fn write_rays(dir: &Path, kind: &str, geometry: &Geometry, rays: &[Ray]) -> Result<()> {
    let floats = rays.iter().flat_map(|r| [r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z]);
    write_counted(&dir.join(format!("rays_{kind}.bin")), rays.len(), floats)?;
    let hits = dir.join(format!("hits_{kind}.bin"));
    write_atomically(&hits, |tmp| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        for r in rays {
            let (prim, t) = geometry.intersect(r).map_or((-1i32, f32::INFINITY), |h| (h.prim as i32, h.t));
            f.write_all(&prim.to_le_bytes())?;
            f.write_all(&t.to_le_bytes())?;
        }
        f.flush()
    })
    .with_context(|| format!("writing {}", hits.display()))
}

/// Runs the peers for one scene; `Ok(None)` (with a message) when Python or embreex is missing.
pub fn run(
    scene: &str,
    scene_file: &Path,
    scene_data: &phr_render::Scene,
    geometry: &mut Geometry,
    view: &CameraDesc,
    res: u32,
    out: &Path,
) -> Result<Option<PeerRow>> {
    let Some(script) = peer_script("peers.py") else {
        println!("peers: skipped, bench/peers.py not found (run from the repository)");
        return Ok(None);
    };
    // The exported triangles and rays are large (250 MB for eight dragons): they go to a
    // temporary folder, and only the peers' results are kept in the report folder.
    let dir = std::env::temp_dir().join(format!("phr-peers-{}", std::process::id())).join(scene);
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let tris = &geometry.triangles;
    write_counted(
        &dir.join("triangles.bin"),
        tris.len(),
        tris.iter().flat_map(|t| t.iter().flat_map(|v| v.to_array())),
    )?;
    let report = Builder::PHR_HQ.build_timed(&geometry.boxes);
    let ours_build_ms = report.total_time().as_secs_f64() * 1e3;
    geometry.set_bvh(report.bvh);
    let rays = RaySet::new(geometry, &Camera::new(view, res, res), res);
    write_rays(&dir, "primary", geometry, &rays.primary)?;
    write_rays(&dir, "diffuse", geometry, &rays.diffuse)?;
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let (ours_primary, ours_diffuse) =
        one.install(|| (throughput(geometry, &rays.primary), throughput(geometry, &rays.diffuse)));
    let bvh = geometry.take_bvh();
    let size = RenderSettings { width: res, height: res, spp: 1, max_depth: scene_data.settings.max_depth };
    let (ours_frame_ms, _) = crate::tune::measure_frame(scene_data, geometry, bvh, view, &size);
    let mut command = Command::new("python3");
    command.arg(&script).arg(&dir).args(["--scene"]).arg(scene_file).args(["--res", &res.to_string()]);
    if let Some(scenes) = phr_render::scene::json::scenes_dir(scene_file) {
        let tool = scenes.join("../reference/tools/render_reference.py");
        command.arg("--reference-tool").arg(tool).arg("--scenes-dir").arg(&scenes);
    }
    let output = match command.output() {
        Ok(o) => o,
        Err(e) => {
            println!("peers: skipped, cannot run python3: {e}");
            return Ok(None);
        }
    };
    if !output.status.success() {
        let _ = std::fs::remove_dir_all(&dir);
        println!(
            "peers: skipped: {}{}",
            String::from_utf8_lossy(&output.stdout).trim(),
            String::from_utf8_lossy(&output.stderr).trim()
        );
        return Ok(None);
    }
    let text = std::fs::read_to_string(dir.join("peers.json"))?;
    let _ = std::fs::remove_dir_all(&dir);
    let kept = out.join("peers");
    std::fs::create_dir_all(&kept)?;
    std::fs::write(kept.join(format!("{scene}.json")), &text)?;
    let json: serde_json::Value = serde_json::from_str(&text)?;
    let f = |v: &serde_json::Value| v.as_f64().unwrap_or(f64::NAN);
    let m = &json["mitsuba"];
    let mitsuba = match (m["timings"]["render_s"].as_f64(), m["skipped"].as_str()) {
        (Some(s), _) => format!(
            "{:.1} ms ({}, {})",
            s * 1e3,
            m["variant"].as_str().unwrap_or("?"),
            m["integrator"].as_str().unwrap_or("?")
        ),
        (None, Some(why)) => format!("skipped: {why}"),
        _ => "not run".to_string(),
    };
    Ok(Some(PeerRow {
        scene: scene.to_string(),
        rays: rays.primary.len(),
        ours_build_ms,
        ours_primary,
        ours_diffuse,
        embree_build_ms: f(&json["build_ms"]),
        embree_primary: f(&json["primary"]["mrays_per_s"]),
        embree_diffuse: f(&json["diffuse"]["mrays_per_s"]),
        hit_agreement: f(&json["primary"]["hit_agreement"]).min(f(&json["diffuse"]["hit_agreement"])),
        ours_frame_ms,
        mitsuba,
    }))
}
