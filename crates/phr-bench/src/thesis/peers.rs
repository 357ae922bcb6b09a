//! `phr bench --peers`: Intel Embree (via the `embreex` Python package, `bench/peers.py`) on
//! exactly our triangles and rays, in the same run. We export the scene's triangles, the
//! primary and diffuse-bounce rays of its first view, and our closest hits; the script builds
//! Embree's BVH, traces the rays, and checks that the hits agree. embreex traces on one
//! thread, so our side is measured on one thread too.

use crate::oracle::Hit;
use crate::peer::{export_dir, peer_script, run_script, write_rays, write_triangles};
use crate::rays::RaySet;
use crate::throughput::throughput;
use anyhow::Result;
use phr_bvh::{Builder, Ray};
use phr_render::camera::{Camera, CameraDesc};
use phr_render::geometry::Geometry;
use phr_render::scene::RenderSettings;
use std::ffi::OsString;
use std::path::Path;

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

/// Runs the peers for one scene; `Ok(None)` (with a message) when Python or embreex is missing.
#[allow(clippy::too_many_arguments)]
pub fn run(
    scene: &str,
    scene_file: &Path,
    scene_data: &phr_render::Scene,
    geometry: &mut Geometry,
    view: &CameraDesc,
    res: u32,
    out: &Path,
    progress: &dyn crate::Progress,
) -> Result<Option<PeerRow>> {
    let Some(script) = peer_script("peers.py") else {
        progress.note("peers: skipped, bench/peers.py not found (run from the repository)".into());
        return Ok(None);
    };
    let dir = export_dir("peers", scene)?;
    write_triangles(&dir, &geometry.triangles)?;
    let report = Builder::PHR_HQ.build_timed(&geometry.boxes);
    let ours_build_ms = report.total_time().as_secs_f64() * 1e3;
    geometry.set_bvh(report.bvh);
    let rays = RaySet::new(geometry, &Camera::new(view, res, res), res);
    for (kind, rays) in [("primary", &rays.primary), ("diffuse", &rays.diffuse)] {
        let hits: Vec<Hit> = rays.iter().map(|r| geometry.intersect(r).map(|h| (h.prim, h.t))).collect();
        write_rays(&dir, kind, rays, &hits)?;
    }
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let trace = |r: &Ray| geometry.intersect(r).is_some();
    let (ours_primary, ours_diffuse) =
        one.install(|| (throughput(&rays.primary, 3, trace), throughput(&rays.diffuse, 3, trace)));
    let bvh = geometry.take_bvh();
    let size = RenderSettings { width: res, height: res, spp: 1, max_depth: scene_data.settings.max_depth };
    let (ours_frame_ms, _) = crate::frame::median_frame(scene_data, geometry, bvh, view, &size);
    let mut script_args: Vec<OsString> =
        [dir.as_os_str(), "--scene".as_ref(), scene_file.as_os_str(), "--res".as_ref()].map(OsString::from).into();
    script_args.push(res.to_string().into());
    if let Some(scenes) = phr_render::scene::json::scenes_dir(scene_file) {
        let tool = scenes.join("../reference/tools/render_reference.py");
        script_args.extend(["--reference-tool".into(), tool.into(), "--scenes-dir".into(), scenes.into()]);
    }
    let result = run_script(&script, &script_args, &dir.join("peers.json"));
    let _ = std::fs::remove_dir_all(&dir);
    let json = match result {
        Ok(json) => json,
        Err(why) => {
            progress.note(format!("peers: skipped: {why}"));
            return Ok(None);
        }
    };
    let kept = out.join("peers");
    std::fs::create_dir_all(&kept)?;
    std::fs::write(kept.join(format!("{scene}.json")), serde_json::to_string_pretty(&json)?)?;
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
