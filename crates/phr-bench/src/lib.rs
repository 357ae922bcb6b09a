//! The evaluation as a library: what the `phr bench*` commands measure, written once.
//!
//! - [`suite`]: the scene suite of `scenes/suite` and the thesis's benchmark setting;
//! - [`stats`]: medians and spreads of repeated measurements;
//! - [`frame`]: timed 1-spp frames of our renderer;
//! - [`mitsuba`]: the same frame rendered by Mitsuba 3 (the peer of the frame benchmark);
//! - [`rays`]: the ray sets (primary, diffuse bounces, incoherent, shadow), made one way;
//! - [`oracle`]: brute force and the binary reference traversal, which every hit is checked
//!   against;
//! - [`throughput`]: the one Mrays/s measurement and the one work-per-ray count;
//! - [`peer`]: exporting triangles and rays to a Python peer and reading its JSON;
//! - [`quality`], [`quality_bench`], [`quality_report`]: `phr bench-quality` (RMSE at equal
//!   time against a converged reference: our estimators and Mitsuba 3's `path`);
//! - [`reference_export`]: any scene in the reference renderer's format, for Mitsuba 3;
//! - [`ray_bench`], [`ray_report`]: `phr bench-rays` (our traversals against Embree);
//! - [`build_bench`]: `phr bench-build` (every builder: build time, tree quality, Mrays/s);
//! - [`cut_cost`]: `phr bench-cut-cost` (does PHR's `Σ |cut|` predict its build time?);
//! - [`tune_bench`]: `phr bench-tune` (BO against a dense grid; the tuners' frame times);
//! - [`thesis`]: `phr bench`, the thesis's chapter 7 (Table 7.1, its figures, the peers).
//!
//! The command-line front end parses arguments, calls these, and prints.

pub mod build_bench;
pub mod cut_cost;
pub mod device_report;
pub mod embree_build;
pub mod frame;
pub mod frame_report;
pub mod mitsuba;
pub mod oracle;
pub mod peer;
pub mod quality;
pub mod quality_bench;
pub mod quality_report;
pub mod ray_bench;
pub mod ray_report;
pub mod rays;
pub mod reference_export;
pub mod stats;
pub mod suite;
pub mod thesis;
pub mod throughput;
pub mod tune_bench;

pub use stats::Stat;

/// Where a long measurement tells what it is doing: a front end shows `status` (the current
/// step, replaced by the next) and keeps `note`s (warnings, skipped peers) in view.
pub trait Progress {
    fn status(&self, message: String);
    fn note(&self, message: String);
    /// One step of the run is done.
    fn advance(&self) {}
}
