//! `phr bench`'s measurement: the thesis's evaluation (chapter 7) reproduced by one command, on the scene
//! suite in `scenes/suite` (Bunny, Sponza, Sibenik, Dragon, Conference, and eight dragons for
//! scaling; each with three views, white sky, diffuse, 5 bounces, 60° field of view).
//!
//! For every scene, resolution and builder it measures build time (auxiliary LBVH and PHR
//! apart), SAH cost, `Σ |cut|`, render time (1 spp, mean over the views), frame time and
//! Mrays/s, with median and spread over repeats; PHR-Grid and PHR-BO are tuned per scene and
//! resolution, and their tuning time is given in frames. Results go to `DIR` as CSV, JSON, a
//! Markdown report in the layout of the thesis's Table 7.1, and SVG plots; with
//! `--peers`, Embree on the same triangles and rays (`bench/peers.py`).

mod measure;
mod peers;
mod plots;
mod report;

pub use measure::{BranchRow, CutPoint, Results, Row};
pub use peers::PeerRow;

use crate::Progress;
use anyhow::{Context, Result};
use std::path::{Path, PathBuf};

/// Builders measured by default, by name (`phr-grid` and `phr-bo` are tuned per scene).
pub const BUILDERS: &[&str] = &["lbvh", "phr-fast", "phr-hq", "phr-grid", "phr-bo", "binned-sah", "sweep-sah"];

/// The materials, background and depth the frames are rendered with.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Materials {
    /// Every surface diffuse (albedo 0.7), white sky, up to 6 path segments, whatever the
    /// scene file says: the thesis's benchmark setting.
    Thesis,
    /// The scene files' own materials, background and depth.
    Own,
}

/// What the measurement needs to know, after `--quick` is applied.
pub struct Plan {
    pub scenes: Vec<PathBuf>,
    pub resolutions: Vec<u32>,
    pub builders: Vec<String>,
    pub repeats: usize,
    pub max_views: usize,
    pub branching: Vec<u32>,
    pub cut_grid: (Vec<f64>, Vec<f64>),
    pub sweep_limit: usize,
    pub peers: bool,
    pub materials: Materials,
}

impl Plan {
    /// Progress steps of the whole run (for a bar's length).
    pub fn steps(&self) -> usize {
        self.scenes.len() * (self.resolutions.len() * self.builders.len() + self.branching.len() + 1)
    }
}

/// Measures every scene of `plan`, writes the report files (CSV, JSON, Markdown, plots) to
/// `out`, and returns the results.
pub fn run(plan: &Plan, out: &Path, progress: &dyn Progress) -> Result<Results> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut results = Results::default();
    for scene in &plan.scenes {
        measure::measure_scene(scene, plan, out, progress, &mut results)
            .with_context(|| format!("benchmarking {}", scene.display()))?;
    }
    report::write_all(out, plan, &results)?;
    plots::write_all(out, &results)?;
    Ok(results)
}

/// The lines printed after a run.
pub fn summary(results: &Results) -> String {
    report::summary(results)
}

/// Where the report is.
pub fn report_path(out: &Path) -> PathBuf {
    out.join("report.md")
}
