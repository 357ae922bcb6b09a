//! The equal-time quality benchmark's results as files people open: `quality.csv`,
//! `quality.json` and `quality.md` (per scene and budget, each method's spp, time and RMSE,
//! and its RMSE over the implicit estimator's and over Mitsuba's).

use crate::frame_report::write_report_files;
use crate::quality::Method;
use crate::quality_bench::{Outcome, QualityRow};
use anyhow::Result;
use std::fmt::Write as _;
use std::path::Path;

/// What the run was, printed above the table.
pub struct QualityRunInfo<'a> {
    pub command: &'a str,
    pub threads: usize,
    pub builder: String,
}

/// Writes `quality.csv`, `quality.json` and `quality.md` to `dir`.
pub fn write_quality_report(dir: &Path, info: &QualityRunInfo, rows: &[QualityRow]) -> Result<()> {
    let json = serde_json::to_string_pretty(rows)?;
    write_report_files(dir, &[("quality.csv", csv(rows)), ("quality.json", json), ("quality.md", markdown(info, rows))])
}

/// The RMSE of the row of `method` for the same scene and budget as `row`.
fn rmse_of(rows: &[QualityRow], row: &QualityRow, method: Method) -> Option<f64> {
    rows.iter().find(|r| r.scene == row.scene && r.budget_s == row.budget_s && r.method == method)?.rmse()
}

/// `row`'s RMSE over that of `method` (same scene and budget), if both ran.
fn ratio(rows: &[QualityRow], row: &QualityRow, method: Method) -> Option<f64> {
    Some(row.rmse()? / rmse_of(rows, row, method)?)
}

fn csv(rows: &[QualityRow]) -> String {
    let mut s = String::from("scene,budget_s,method,spp,ms,rmse,over_implicit,over_mitsuba,skipped\n");
    for r in rows {
        let fmt = |x: Option<f64>| x.map(|x| format!("{x:.5}")).unwrap_or_default();
        let mut cells = vec![r.scene.clone(), r.budget_s.to_string(), r.method.slug().to_string()];
        match &r.outcome {
            Outcome::Ran { spp, ms, rmse } => {
                cells.extend([spp.to_string(), format!("{ms:.1}"), format!("{rmse:.6}")]);
                cells.push(fmt(ratio(rows, r, Method::Implicit)));
                cells.push(fmt(ratio(rows, r, Method::MitsubaPath)));
                cells.push(String::new());
            }
            Outcome::Skipped(why) => {
                cells.extend([String::new(), String::new(), String::new(), String::new(), String::new()]);
                // One field without separators or quotes, so that any CSV reader splits it right.
                cells.push(why.replace([',', '"', '\n'], ";"));
            }
        }
        s.push_str(&cells.join(","));
        s.push('\n');
    }
    s
}

/// The Markdown report: one table, then why any peer was skipped.
pub fn markdown(info: &QualityRunInfo, rows: &[QualityRow]) -> String {
    let mut s = String::from("# Image quality at equal time: phr against Mitsuba 3\n\n");
    let _ = writeln!(
        s,
        "Command: `{}` (release build), {} thread(s), our BVH: {}.\n",
        info.command, info.threads, info.builder
    );
    s.push_str(
        "Each method gets the same wall-clock budget per scene. Ours renders 1-spp frames until the \
         budget is spent (the denoised output reserves and counts the time of its guide and filter); \
         loading and building are not counted. Mitsuba 3 (`llvm_ad_rgb`, its `path` integrator with \
         Russian roulette) gets the samples its warm rate fits into the budget; its time is that rate \
         times the samples (the JIT pass is left out). RMSE against the scene's converged reference, \
         over all pixels and channels. Below 1 in the ratio columns: less error than that method.\n\n",
    );
    s.push_str("| scene | budget | method | spp | ms | RMSE | ÷ implicit | ÷ Mitsuba |\n");
    s.push_str("|---|---:|---|---:|---:|---:|---:|---:|\n");
    let fmt = |x: Option<f64>| x.map_or_else(|| "–".to_string(), |x| format!("{x:.3}"));
    for r in rows {
        let cells = match &r.outcome {
            Outcome::Ran { spp, ms, rmse } => format!(
                "{spp} | {ms:.0} | {rmse:.4} | {} | {}",
                fmt(ratio(rows, r, Method::Implicit)),
                fmt(ratio(rows, r, Method::MitsubaPath))
            ),
            Outcome::Skipped(_) => "skipped | | | |".to_string(),
        };
        let _ = writeln!(s, "| {} | {} s | {} | {cells} |", r.scene, r.budget_s, r.method.label());
    }
    let skipped: Vec<String> = rows
        .iter()
        .filter_map(|r| match &r.outcome {
            Outcome::Skipped(why) => Some(format!("- {} at {} s: {why}", r.scene, r.budget_s)),
            Outcome::Ran { .. } => None,
        })
        .collect();
    if !skipped.is_empty() {
        let _ = writeln!(s, "\nMitsuba 3 skipped ({}):", crate::mitsuba::INSTALL);
        s.push_str(&skipped.join("\n"));
        s.push('\n');
    }
    s
}
