//! The frame benchmark's results as files people open: CSV, JSON and a Markdown table of
//! ours against Mitsuba 3 per scene and resolution.

use crate::frame::FrameTiming;
use crate::mitsuba::MitsubaRun;
use anyhow::{Context, Result};
use phr_render::output::write_atomically;
use std::fmt::Write as _;
use std::path::Path;

/// One scene at one resolution.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FrameRow {
    pub scene: String,
    pub triangles: usize,
    pub res: u32,
    pub builder: String,
    pub ours: FrameTiming,
    pub mitsuba: MitsubaRun,
}

impl FrameRow {
    /// Mitsuba's warm frame time over ours (mean over mean: Mitsuba reports the mean). Above
    /// 1: we are faster.
    pub fn speedup(&self) -> Option<f64> {
        match &self.mitsuba {
            MitsubaRun::Ran(m) => Some(m.warm_ms / self.ours.ms.mean),
            MitsubaRun::Skipped(_) => None,
        }
    }
}

/// What the run was: its command and thread count, printed above the table.
pub struct FrameRunInfo<'a> {
    pub command: &'a str,
    pub threads: usize,
}

/// Writes `frame.csv`, `frame.json` and `frame.md` to `dir`.
pub fn write_frame_report(dir: &Path, info: &FrameRunInfo, rows: &[FrameRow]) -> Result<()> {
    write_report_files(
        dir,
        &[
            ("frame.csv", csv(rows)),
            ("frame.json", serde_json::to_string_pretty(rows)?),
            ("frame.md", markdown(info, rows)),
        ],
    )
}

/// Writes each `(name, text)` to `dir/name` (each file whole or not at all), creating `dir`.
pub fn write_report_files(dir: &Path, files: &[(&str, String)]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (name, text) in files {
        let path = dir.join(name);
        write_atomically(&path, |tmp| std::fs::write(tmp, text))
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

fn mitsuba_ms(run: &MitsubaRun) -> String {
    match run {
        MitsubaRun::Ran(m) => format!("{:.2}", m.warm_ms),
        MitsubaRun::Skipped(_) => String::new(),
    }
}

fn csv(rows: &[FrameRow]) -> String {
    let mut s = String::from(
        "scene,triangles,res,builder,frames,ours_ms_median,ours_ms_min,ours_ms_max,ours_ms_mean,rays_per_frame,mrays_per_s,mitsuba_warm_ms,mitsuba_over_ours\n",
    );
    for r in rows {
        let o = &r.ours;
        let ms = [o.ms.median, o.ms.min, o.ms.max, o.ms.mean].map(|x| format!("{x:.3}"));
        let mut cells = vec![r.scene.clone(), r.triangles.to_string(), r.res.to_string(), r.builder.clone()];
        cells.push(o.frames.to_string());
        cells.extend(ms);
        cells.push(format!("{:.0}", o.rays));
        cells.push(format!("{:.3}", o.mrays_per_s()));
        cells.push(mitsuba_ms(&r.mitsuba));
        cells.push(r.speedup().map(|x| format!("{x:.3}")).unwrap_or_default());
        s.push_str(&cells.join(","));
        s.push('\n');
    }
    s
}

/// The Markdown report: the table, then why any peer was skipped.
pub fn markdown(info: &FrameRunInfo, rows: &[FrameRow]) -> String {
    let mut s = String::from("# The thesis's frame: phr against Mitsuba 3\n\n");
    let _ = writeln!(s, "Command: `{}` (release build), {} thread(s).\n", info.command, info.threads);
    s.push_str(
        "One frame: first view, 1 sample per pixel, at most 6 segments, white sky, every surface diffuse 0.7. \
         Ours: median [min–max] and mean wall-clock ms per frame after warm-up frames. Mitsuba 3: \
         `llvm_ad_rgb` variant, `rtiow` integrator (the same estimator), mean of the warm passes (the \
         first pass, which includes the JIT, is left out), same thread count. Ratio: Mitsuba ms / ours \
         (mean over mean); above 1 we are faster.\n\n",
    );
    s.push_str("| scene | triangles | res | ours ms | ours mean | Mrays/s | Mitsuba ms | Mitsuba/ours |\n");
    s.push_str("|---|---:|---:|---:|---:|---:|---:|---:|\n");
    for r in rows {
        let o = &r.ours;
        let _ = writeln!(
            s,
            "| {} | {} | {}² | {:.1} [{:.1}–{:.1}] | {:.1} | {:.2} | {} | {} |",
            r.scene,
            r.triangles,
            r.res,
            o.ms.median,
            o.ms.min,
            o.ms.max,
            o.ms.mean,
            o.mrays_per_s(),
            match &r.mitsuba {
                MitsubaRun::Ran(m) => format!("{:.1}", m.warm_ms),
                MitsubaRun::Skipped(_) => "skipped".into(),
            },
            r.speedup().map(|x| format!("{x:.2}")).unwrap_or_else(|| "–".into())
        );
    }
    let skipped: Vec<String> = rows
        .iter()
        .filter_map(|r| match &r.mitsuba {
            MitsubaRun::Skipped(why) => Some(format!("- {} {}²: {why}", r.scene, r.res)),
            MitsubaRun::Ran(_) => None,
        })
        .collect();
    if !skipped.is_empty() {
        let _ = writeln!(s, "\nMitsuba 3 skipped ({}):", crate::mitsuba::INSTALL);
        s.push_str(&skipped.join("\n"));
        s.push('\n');
    }
    s
}
