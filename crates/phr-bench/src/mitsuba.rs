//! The peer of the frame benchmark: Mitsuba 3 rendering the thesis's frame with the same
//! estimator as ours, through `shared/reference/tools/render_reference.py`.
//!
//! The script reads our scene JSON format; it renders with the `rtiow` integrator (pure BSDF
//! sampling, implicit lights, no Russian roulette: our estimator) in the `llvm_ad_rgb`
//! variant, Mitsuba's fast CPU variant, which JIT-compiles the whole frame for the CPU's
//! SIMD width. Its first pass includes the compilation, so only the warm passes are timed
//! (one 1-spp pass per frame). The variant needs libLLVM ≥ 17: `apt-get install libllvm19`
//! and `DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so` (set here when that file
//! exists and the variable is not). Mitsuba itself: `python3 -m pip install mitsuba numpy`.
//!
//! A missing Python, package or library is not an error of the benchmark: the result says
//! it was skipped and why.

use anyhow::{bail, Context, Result};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The variant measured: the fast one. Anything else is reported as skipped, never
/// silently compared.
pub const VARIANT: &str = "llvm_ad_rgb";

/// How to get the peer, for reports that skipped it.
pub const INSTALL: &str = "install: `python3 -m pip install mitsuba numpy`, `apt-get install libllvm19`; \
    `DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so` is set automatically when present";

/// `tools/render_textured.py` of this repository: render_reference.py with MTL `map_Kd`
/// textures, which `phr bench-quality`'s textured scenes need.
pub const TEXTURED_TOOL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../../tools/render_textured.py");

/// Where Debian's `libllvm19` puts the library drjit needs.
pub const DEBIAN_LIBLLVM: &str = "/usr/lib/x86_64-linux-gnu/libLLVM-19.so";

/// Mitsuba's timing of one scene at one resolution.
#[derive(Clone, Debug, serde::Serialize)]
pub struct MitsubaFrame {
    pub variant: String,
    pub integrator: String,
    /// Mean wall-clock ms of the warm 1-spp passes.
    pub warm_ms: f64,
    /// The first pass (JIT compilation included), in ms.
    pub first_ms: f64,
    pub frames: usize,
}

/// Mitsuba's result, or why it did not run.
#[derive(Clone, Debug, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MitsubaRun {
    Ran(MitsubaFrame),
    Skipped(String),
}

/// The script and the folder its scenes' `{scenes}` paths point to.
#[derive(Clone, Debug)]
pub struct MitsubaPeer {
    pub python: String,
    pub tool: PathBuf,
    pub scenes_dir: PathBuf,
}

impl MitsubaPeer {
    /// The peer next to the shared scenes folder `scenes_dir` (`../reference/tools`).
    pub fn next_to(scenes_dir: &Path) -> Self {
        Self {
            python: std::env::var("PYTHON").unwrap_or_else(|_| "python3".into()),
            tool: scenes_dir.join("../reference/tools/render_reference.py"),
            scenes_dir: scenes_dir.to_path_buf(),
        }
    }

    /// Renders `frames` warm 1-spp frames (plus the JIT pass) of the scene file's first view
    /// in the thesis's setting at `res`², on `threads` threads; scratch files go to `work`.
    /// Anything that keeps Mitsuba from giving a warm timing is a skip, with its reason.
    pub fn thesis_frames(&self, scene_file: &Path, res: u32, frames: usize, threads: usize, work: &Path) -> MitsubaRun {
        match self.try_thesis_frames(scene_file, res, frames, threads, work) {
            Ok(frame) => MitsubaRun::Ran(frame),
            Err(e) => MitsubaRun::Skipped(format!("{e:#}")),
        }
    }

    fn try_thesis_frames(
        &self,
        scene_file: &Path,
        res: u32,
        frames: usize,
        threads: usize,
        work: &Path,
    ) -> Result<MitsubaFrame> {
        let text = std::fs::read_to_string(scene_file).with_context(|| format!("reading {}", scene_file.display()))?;
        let scene = thesis_frame_scene(serde_json::from_str(&text)?, res)
            .with_context(|| format!("{} has no view", scene_file.display()))?;
        std::fs::create_dir_all(work)?;
        let name = crate::suite::scene_name(scene_file);
        let local = work.join(format!("{name}_{res}_scene.json"));
        std::fs::write(&local, serde_json::to_string_pretty(&scene)?)?;
        let prefix = work.join(format!("{name}_{res}_mitsuba"));
        let passes = (frames + 1).to_string();
        let args = ["--integrator", "rtiow", "--spp", &passes, "--passes", &passes, "--res", &format!("{res}x{res}")];
        parse_meta(&self.run_script(&local, &prefix, &args, threads)?, frames)
    }

    /// Mitsuba 3's own `path` integrator (light sampling with MIS, Russian roulette: `--rr`)
    /// on `scene_file` as it is, `spp` samples in `passes` passes (the first includes the
    /// JIT, so at least two give a warm timing), on `threads` threads, written to `work`.
    pub fn path_render(
        &self,
        scene_file: &Path,
        spp: u32,
        passes: u32,
        threads: usize,
        work: &Path,
    ) -> Result<PathRender> {
        std::fs::create_dir_all(work)?;
        let prefix = work.join(format!("{}_path_{spp}spp", crate::suite::scene_name(scene_file)));
        let (spp_arg, passes_arg) = (spp.to_string(), passes.to_string());
        // Seeds from 10⁶: the references were rendered from seed 0 (and `shared/reference`
        // keeps 10⁶ for its own second renders), so ours must not replay their samples.
        let args = ["--integrator", "path", "--rr", "--spp", &spp_arg, "--passes", &passes_arg, "--seed", "1000000"];
        // Through the wrapper that gives render_reference.py the MTL's textures (the same
        // scene otherwise).
        let meta = self.run(
            &[TEXTURED_TOOL.as_ref(), "--reference-tool".as_ref(), self.tool.as_os_str()],
            scene_file,
            &prefix,
            &args,
            threads,
        )?;
        let variant = meta["variant"].as_str().unwrap_or("unknown");
        if variant != VARIANT {
            bail!("Mitsuba ran the {variant} variant, not {VARIANT}");
        }
        let warm_ms_per_spp =
            meta["timings"]["ms_per_spp_warm"].as_f64().context("render_reference.py wrote no warm timings")?;
        Ok(PathRender { spp, warm_ms_per_spp, exr: prefix.with_extension("exr") })
    }

    /// Runs the script on `scene_file` in the fast variant with `args`, writing `prefix.*`;
    /// returns the JSON side-car it wrote.
    fn run_script(&self, scene_file: &Path, prefix: &Path, args: &[&str], threads: usize) -> Result<Value> {
        self.run(&[self.tool.as_os_str()], scene_file, prefix, args, threads)
    }

    /// Runs `script` (the script and its own first arguments) as [`MitsubaPeer::run_script`]
    /// runs render_reference.py.
    fn run(
        &self,
        script: &[&std::ffi::OsStr],
        scene_file: &Path,
        prefix: &Path,
        args: &[&str],
        threads: usize,
    ) -> Result<Value> {
        for file in [script[0], self.tool.as_os_str()] {
            if !Path::new(file).is_file() {
                bail!("{} not found", Path::new(file).display());
            }
        }
        if threads < 2 {
            // Mitsuba 3.9.1 renders, then never returns from writing its EXR with a pool of
            // one thread.
            bail!("the script hangs writing its image on 1 thread (Mitsuba 3.9.1); run with --threads 2 or more");
        }
        let mut cmd = Command::new(&self.python);
        cmd.args(script).arg(scene_file).arg("-o").arg(prefix);
        cmd.args(["--variant", VARIANT]).args(args);
        cmd.args(["--threads", &threads.to_string(), "--quiet"]);
        cmd.arg("--scenes-dir").arg(&self.scenes_dir);
        if std::env::var_os("DRJIT_LIBLLVM_PATH").is_none() && Path::new(DEBIAN_LIBLLVM).is_file() {
            cmd.env("DRJIT_LIBLLVM_PATH", DEBIAN_LIBLLVM);
        }
        let out = cmd.output().with_context(|| format!("cannot run {}", self.python))?;
        if !out.status.success() {
            let err = String::from_utf8_lossy(&out.stderr);
            let last = err.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or("no message");
            bail!("render_reference.py failed: {}", last.trim());
        }
        let side_car = prefix.with_extension("json");
        let text = std::fs::read_to_string(&side_car).with_context(|| format!("reading {}", side_car.display()))?;
        Ok(serde_json::from_str(&text)?)
    }
}

/// An image of Mitsuba's `path` integrator ([`MitsubaPeer::path_render`]).
#[derive(Clone, Debug)]
pub struct PathRender {
    pub spp: u32,
    /// Mean wall-clock ms per sample of the warm passes (the first, with the JIT, left out).
    pub warm_ms_per_spp: f64,
    /// The mean image (linear OpenEXR).
    pub exr: PathBuf,
}

/// The scene JSON Mitsuba renders: the file's first view as its camera, `res`², and the
/// thesis's setting (every material diffuse 0.7, white sky, 6 segments, 1 spp). `None` if
/// the file has neither a camera nor views.
pub fn thesis_frame_scene(mut scene: Value, res: u32) -> Option<Value> {
    let obj = scene.as_object_mut()?;
    if !obj.contains_key("camera") {
        let first = obj.get("views")?.as_object()?.values().next()?.clone();
        obj.insert("camera".into(), first);
    }
    let albedo = crate::suite::THESIS_ALBEDO;
    if let Some(materials) = obj.get_mut("materials").and_then(Value::as_object_mut) {
        for m in materials.values_mut() {
            *m = json!({"type": "lambertian", "albedo": [albedo, albedo, albedo]});
        }
    }
    obj.insert("width".into(), json!(res));
    obj.insert("height".into(), json!(res));
    obj.insert("spp".into(), json!(1));
    obj.insert("max_depth".into(), json!(crate::suite::THESIS_MAX_DEPTH));
    obj.insert("background".into(), json!([1.0, 1.0, 1.0]));
    Some(scene)
}

/// Reads the timings the script wrote; anything but the fast variant is an error (never
/// compared).
fn parse_meta(meta: &Value, frames: usize) -> Result<MitsubaFrame> {
    let variant = meta["variant"].as_str().unwrap_or("unknown").to_string();
    if variant != VARIANT {
        bail!("Mitsuba ran the {variant} variant, not {VARIANT}");
    }
    let timings = &meta["timings"];
    match (timings["ms_per_spp_warm"].as_f64(), timings["first_pass_s"].as_f64()) {
        (Some(warm_ms), Some(first_s)) => Ok(MitsubaFrame {
            variant,
            integrator: meta["integrator"].as_str().unwrap_or("unknown").to_string(),
            warm_ms,
            first_ms: first_s * 1e3,
            frames,
        }),
        _ => bail!("render_reference.py wrote no warm timings"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thesis_scene_takes_the_first_view_and_the_thesis_setting() {
        let file = json!({
            "views": {"a": {"position": [1, 2, 3]}, "b": {"position": [4, 5, 6]}},
            "materials": {"red": {"type": "metal", "albedo": [1, 0, 0]}},
            "background": [0, 0, 0], "max_depth": 50, "width": 64, "height": 32
        });
        let s = thesis_frame_scene(file, 256).unwrap();
        assert_eq!(s["camera"]["position"], json!([1, 2, 3]));
        assert_eq!(s["materials"]["red"]["type"], "lambertian");
        assert_eq!((s["width"].as_u64(), s["height"].as_u64()), (Some(256), Some(256)));
        assert_eq!(s["max_depth"].as_u64(), Some(6));
        assert!(thesis_frame_scene(json!({"materials": {}}), 256).is_none());
    }

    #[test]
    fn only_the_llvm_variant_counts() {
        let meta = |variant: &str| {
            json!({"variant": variant, "integrator": "rtiow",
                   "timings": {"ms_per_spp_warm": 40.0, "first_pass_s": 0.5}})
        };
        match parse_meta(&meta("llvm_ad_rgb"), 8) {
            Ok(f) => assert_eq!((f.warm_ms, f.first_ms, f.frames), (40.0, 500.0, 8)),
            Err(why) => panic!("skipped: {why}"),
        }
        assert!(parse_meta(&meta("scalar_rgb"), 8).is_err());
    }
}
