//! Native Embree's build time, the peer of `phr bench-build`: `bench/embree_build.py` calls
//! Embree's own library through ctypes (the libembree4 the embreex wheel ships, or a system
//! one) on our triangles and times `rtcCommitScene` alone. embreex's own scene build would
//! add Python-side conversion and triple the time.

use crate::peer::{export_dir, peer_script, run_script, write_triangles};
use glam::Vec3;
use std::ffi::OsString;

/// Embree's build of one mesh: its BVH8 with triangle leaves, ready to trace.
#[derive(Clone, Debug, PartialEq)]
pub struct EmbreeBuild {
    /// E.g. `embree 4.4.0 (medium)`.
    pub name: String,
    /// The library that ran.
    pub library: String,
    /// Per thread count, the median commit time in ms.
    pub median_ms: Vec<(usize, f64)>,
}

/// Builds `triangles` with native Embree (build quality medium, its default) `repeats` times
/// per thread count. `Err` says why the peer did not run (no script, numpy or library).
pub fn measure_embree_build(
    mesh: &str,
    triangles: &[[Vec3; 3]],
    threads: &[usize],
    repeats: usize,
) -> Result<EmbreeBuild, String> {
    let script = peer_script("embree_build.py").ok_or("bench/embree_build.py not found")?;
    let dir = export_dir("bench-build", &mesh.replace('/', "_")).map_err(|e| format!("{e:#}"))?;
    let result = (|| {
        write_triangles(&dir, triangles).map_err(|e| format!("{e:#}"))?;
        let list = threads.iter().map(usize::to_string).collect::<Vec<_>>().join(",");
        let args: Vec<OsString> = vec![
            dir.clone().into(),
            "--threads".into(),
            list.into(),
            "--repeats".into(),
            repeats.max(1).to_string().into(),
        ];
        let json = run_script(&script, &args, &dir.join("embree_build.json"))?;
        let text = |key: &str| json[key].as_str().unwrap_or("?").to_string();
        let median_ms = threads
            .iter()
            .map(|t| {
                json["builds"][t.to_string()]["median_ms"]
                    .as_f64()
                    .map(|ms| (*t, ms))
                    .ok_or(format!("embree_build.json lacks {t} threads"))
            })
            .collect::<Result<Vec<_>, String>>()?;
        Ok(EmbreeBuild {
            name: format!("embree {} ({})", text("version"), text("quality")),
            library: text("library"),
            median_ms,
        })
    })();
    let _ = std::fs::remove_dir_all(&dir);
    result
}
