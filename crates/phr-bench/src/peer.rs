//! The one way the benchmarks run a Python peer (Embree through embreex, Mitsuba 3): export
//! our triangles and rays as little-endian binary files to a folder, run `python3 SCRIPT`
//! on it, and read the JSON the script writes there.

use crate::oracle::Hit;
use anyhow::{Context, Result};
use glam::Vec3;
use phr_bvh::Ray;
use phr_render::output::write_atomically;
use serde_json::Value;
use std::ffi::OsString;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The peer script `bench/NAME`, from the current directory or the checkout.
pub fn peer_script(name: &str) -> Option<PathBuf> {
    [PathBuf::from("bench").join(name), PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../bench")).join(name)]
        .into_iter()
        .find(|p| p.is_file())
}

/// Writes a count and then the floats, little-endian.
pub fn write_counted(path: &Path, count: usize, floats: impl Iterator<Item = f32>) -> Result<()> {
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

/// `triangles.bin`: the count, then `v0, v1, v2` of each triangle.
pub fn write_triangles(dir: &Path, tris: &[[Vec3; 3]]) -> Result<()> {
    write_counted(&dir.join("triangles.bin"), tris.len(), tris.iter().flat_map(|t| t.iter().flat_map(|v| v.to_array())))
}

/// `rays_KIND.bin` (origin, direction), `tfar_KIND.bin` (each ray's `tmax`) and
/// `hits_KIND.bin` (our closest hit per ray: primitive as i32, -1 for none, and `t`).
pub fn write_rays(dir: &Path, kind: &str, rays: &[Ray], hits: &[Hit]) -> Result<()> {
    let floats = rays.iter().flat_map(|r| [r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z]);
    write_counted(&dir.join(format!("rays_{kind}.bin")), rays.len(), floats)?;
    write_counted(&dir.join(format!("tfar_{kind}.bin")), rays.len(), rays.iter().map(|r| r.tmax))?;
    let path = dir.join(format!("hits_{kind}.bin"));
    write_atomically(&path, |tmp| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        for h in hits {
            let (prim, t) = h.map_or((-1i32, f32::INFINITY), |(p, t)| (p as i32, t));
            f.write_all(&prim.to_le_bytes())?;
            f.write_all(&t.to_le_bytes())?;
        }
        f.flush()
    })
    .with_context(|| format!("writing {}", path.display()))
}

/// A fresh temporary folder for one scene's exported files (large: 250 MB for eight dragons),
/// so only the peers' results are kept.
pub fn export_dir(purpose: &str, scene: &str) -> Result<PathBuf> {
    let dir = std::env::temp_dir().join(format!("phr-{purpose}-{}", std::process::id())).join(scene);
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    Ok(dir)
}

/// Runs `python3 script args` and reads the JSON file `result` it writes. `Err` is the reason
/// the peer did not run (no python3, a missing package, a failure), for the report to say.
pub fn run_script(script: &Path, args: &[OsString], result: &Path) -> Result<Value, String> {
    let output =
        Command::new("python3").arg(script).args(args).output().map_err(|e| format!("cannot run python3: {e}"))?;
    if !output.status.success() {
        return Err(format!(
            "{}{}",
            String::from_utf8_lossy(&output.stdout).trim(),
            String::from_utf8_lossy(&output.stderr).trim()
        ));
    }
    let text = std::fs::read_to_string(result).map_err(|e| format!("{}: {e}", result.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: {e}", result.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rays_and_hits_are_written_as_counted_little_endian_arrays() {
        let dir = std::env::temp_dir().join(format!("phr-peer-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let rays = [Ray::with_interval(Vec3::new(1.0, 2.0, 3.0), Vec3::X, 0.0, 0.5)];
        write_rays(&dir, "k", &rays, &[Some((7, 0.25))]).unwrap();
        let floats = |name: &str| -> Vec<f32> {
            let b = std::fs::read(dir.join(name)).unwrap();
            assert_eq!(u32::from_le_bytes(b[..4].try_into().unwrap()), 1);
            b[4..].chunks(4).map(|c| f32::from_le_bytes(c.try_into().unwrap())).collect()
        };
        assert_eq!(floats("rays_k.bin"), [1.0, 2.0, 3.0, 1.0, 0.0, 0.0]);
        assert_eq!(floats("tfar_k.bin"), [0.5]);
        let hits = std::fs::read(dir.join("hits_k.bin")).unwrap();
        assert_eq!(i32::from_le_bytes(hits[..4].try_into().unwrap()), 7);
        assert_eq!(f32::from_le_bytes(hits[4..8].try_into().unwrap()), 0.25);
        let err = run_script(&dir.join("missing.py"), &[], &dir.join("none.json")).unwrap_err();
        assert!(!err.is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
