//! `phr bench-build`: one builder on one mesh: build time (the auxiliary tree and PHR shown
//! apart; for PHR also the refit of the auxiliary tree, what a dynamic scene pays instead of
//! its build), the time to make the tree renderable (the collapse to the renderer's 8-wide
//! BVH and the packing of its triangles), SAH cost with the constants (1, 1) and the thesis's (2, 1), PHR's `Σ |cut|`, and
//! closest-hit throughput of one fixed ray set per mesh.
//!
//! Build: median of `repeats` builds from the primitive boxes. Rays: the primary rays of a
//! square image from the mesh's framing camera, and one diffuse bounce from each primary hit
//! ([`RaySet`]): coherent and incoherent rays. The same rays are traced through every
//! builder's tree.

use crate::rays::RaySet;
use crate::throughput::{mean_counts, throughput};
use phr_bvh::binned_sah::build_binned_sah_wide;
use phr_bvh::phr::{build_phr_wide, AuxTree};
use phr_bvh::{sah_cost, Builder, PackedTriangles, Ray, SahConstants, TraversalStats, WideBvh};
use phr_render::geometry::{Geometry, WIDTH};
use phr_render::output::write_atomically;
use std::io::Write;
use std::path::Path;
use std::time::{Duration, Instant};

/// One builder on one mesh with one thread count.
#[derive(Clone, Debug)]
pub struct BuildRow {
    pub mesh: String,
    pub triangles: usize,
    pub threads: usize,
    pub builder: String,
    pub aux_ms: f64,
    /// Refit of the auxiliary tree (PHR builders only).
    pub refit_ms: Option<f64>,
    pub build_ms: f64,
    pub total_ms: f64,
    /// The collapse to the renderer's 8-wide BVH and the triangle packing.
    pub wide_ms: f64,
    /// PHR and binned SAH: the builder straight to the 8-wide BVH (no binary tree, no
    /// collapse) and the triangle packing; what `build_ms + wide_ms` become with the direct
    /// output.
    pub direct_ms: Option<f64>,
    pub sah_11: f64,
    pub sah_21: f64,
    /// PHR's `Σ |cut|` (PHR builders only).
    pub build_cost: Option<u64>,
    pub primary_mrays: f64,
    pub diffuse_mrays: f64,
    pub diffuse_nodes_per_ray: f64,
    pub diffuse_prims_per_ray: f64,
}

/// Builds `geometry`'s tree with `builder` `repeats` times (in the current rayon pool,
/// which has `threads` threads), keeps the median build, and traces `rays` through it.
pub fn measure_builder(
    mesh: &str,
    geometry: &mut Geometry,
    rays: &RaySet,
    builder: &Builder,
    repeats: usize,
    threads: usize,
) -> BuildRow {
    let mut reports: Vec<_> = (0..repeats.max(1))
        .map(|_| {
            let report = geometry.build_report(builder);
            (report.total_time(), report)
        })
        .collect();
    reports.sort_by_key(|r| r.0);
    let report = reports.swap_remove(reports.len() / 2).1;
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    let (aux_ms, build_ms, total_ms) = (ms(report.aux_time), ms(report.build_time), ms(report.total_time()));
    let build_cost = report.phr.map(|s| s.build_cost);
    let (refit_ms, direct_ms) = match builder {
        Builder::Phr(options) => {
            let mut aux = AuxTree::build(&geometry.boxes);
            let refit = median_ms(repeats, || {
                let start = Instant::now();
                aux.refit(&geometry.boxes);
                start.elapsed()
            });
            let direct = direct_ms(repeats, geometry, |wide| {
                build_phr_wide(&aux, options, wide);
            });
            (Some(refit), Some(direct))
        }
        Builder::BinnedSah(options) => {
            (None, Some(direct_ms(repeats, geometry, |wide| build_binned_sah_wide(&geometry.boxes, options, wide))))
        }
        _ => (None, None),
    };
    // Into the previous build's memory, as a dynamic scene does every frame.
    let wide_ms = median_ms(repeats, || geometry.set_bvh(report.bvh.clone()));
    geometry.set_bvh(report.bvh);
    let trace = |r: &Ray| geometry.intersect(r).is_some();
    let (primary_mrays, diffuse_mrays) = (throughput(&rays.primary, 3, trace), throughput(&rays.diffuse, 3, trace));
    let [diffuse_nodes_per_ray, diffuse_prims_per_ray] = mean_counts(&rays.diffuse, |r| {
        let mut s = TraversalStats::default();
        geometry.intersect_counted(r, &mut s);
        [s.nodes as u64, s.prims as u64]
    });
    BuildRow {
        mesh: mesh.into(),
        triangles: geometry.triangle_count(),
        threads,
        builder: builder.to_string(),
        aux_ms,
        refit_ms,
        build_ms,
        total_ms,
        wide_ms,
        direct_ms,
        sah_11: sah_cost(geometry.bvh(), SahConstants::UNIT),
        sah_21: sah_cost(geometry.bvh(), SahConstants::THESIS),
        build_cost,
        primary_mrays,
        diffuse_mrays,
        diffuse_nodes_per_ray,
        diffuse_prims_per_ray,
    }
}

/// The median time of a builder's direct wide output (`build`, into the previous build's
/// memory, as a dynamic scene builds every frame) with the triangle packing after it.
fn direct_ms(repeats: usize, geometry: &Geometry, mut build: impl FnMut(&mut WideBvh<WIDTH>)) -> f64 {
    let (mut wide, mut packed) = (WideBvh::<WIDTH>::default(), PackedTriangles::default());
    median_ms(repeats, || {
        let start = Instant::now();
        build(&mut wide);
        packed.repack(&wide.prim_indices, &geometry.triangles);
        start.elapsed()
    })
}

/// The median of `repeats` (at least 1) timings, in milliseconds.
fn median_ms(repeats: usize, mut run: impl FnMut() -> Duration) -> f64 {
    let mut times: Vec<Duration> = (0..repeats.max(1)).map(|_| run()).collect();
    times.sort();
    times[times.len() / 2].as_secs_f64() * 1e3
}

/// One row of the table: a value (or nothing) per column of [`COLUMNS`].
pub type Cells = [String; COLUMNS.len()];

/// The columns: CSV name, console heading, console width.
pub const COLUMNS: [(&str, &str, usize); 18] = [
    ("mesh", "mesh", 36),
    ("triangles", "tris", 8),
    ("threads", "thr", 3),
    ("builder", "builder", 22),
    ("aux_ms", "aux ms", 8),
    ("refit_ms", "refit ms", 8),
    ("build_ms", "build ms", 9),
    ("total_ms", "total ms", 9),
    ("wide_ms", "wide ms", 8),
    ("renderable_ms", "ready ms", 9),
    ("direct_to_wide_ms", "direct ms", 9),
    ("sah_cost_1_1", "SAH11", 7),
    ("sah_cost_2_1", "SAH21", 7),
    ("build_cost", "Σ|cut|", 9),
    ("primary_mrays_per_s", "prim Mr/s", 9),
    ("diffuse_mrays_per_s", "diff Mr/s", 9),
    ("diffuse_nodes_per_ray", "diff nodes", 10),
    ("diffuse_prims_per_ray", "diff prims", 10),
];

impl BuildRow {
    /// The row's values, in [`COLUMNS`] order.
    pub fn cells(&self) -> Cells {
        [
            self.mesh.clone(),
            self.triangles.to_string(),
            self.threads.to_string(),
            self.builder.clone(),
            format!("{:.3}", self.aux_ms),
            self.refit_ms.map_or(String::new(), |ms| format!("{ms:.3}")),
            format!("{:.3}", self.build_ms),
            format!("{:.3}", self.total_ms),
            format!("{:.3}", self.wide_ms),
            format!("{:.3}", self.total_ms + self.wide_ms),
            self.direct_ms.map_or(String::new(), |ms| format!("{ms:.3}")),
            format!("{:.4}", self.sah_11),
            format!("{:.4}", self.sah_21),
            self.build_cost.map_or(String::new(), |c| c.to_string()),
            format!("{:.3}", self.primary_mrays),
            format!("{:.3}", self.diffuse_mrays),
            format!("{:.2}", self.diffuse_nodes_per_ray),
            format!("{:.2}", self.diffuse_prims_per_ray),
        ]
    }
}

/// One row per thread count for native Embree's build of a mesh: build = total = ready to
/// trace (its commit makes the BVH8 with triangle leaves); what it does not report is empty.
pub fn embree_cells(mesh: &str, triangles: usize, embree: &crate::embree_build::EmbreeBuild) -> Vec<Cells> {
    embree
        .median_ms
        .iter()
        .map(|&(threads, ms)| {
            let ms = format!("{ms:.3}");
            let values = [
                ("mesh", mesh.to_string()),
                ("triangles", triangles.to_string()),
                ("threads", threads.to_string()),
                ("builder", embree.name.clone()),
                ("build_ms", ms.clone()),
                ("total_ms", ms.clone()),
                ("renderable_ms", ms),
            ];
            COLUMNS.map(|(name, _, _)| values.iter().find(|v| v.0 == name).map_or(String::new(), |v| v.1.clone()))
        })
        .collect()
}

/// The rows (cells in [`COLUMNS`] order) as a console table, right-aligned.
pub fn table(rows: &[Cells]) -> String {
    let line = |cells: &mut dyn Iterator<Item = String>| {
        let padded: Vec<String> = cells.zip(COLUMNS).map(|(c, (_, _, w))| format!("{c:>w$}")).collect();
        padded.join(" ") + "\n"
    };
    let mut out = line(&mut COLUMNS.iter().map(|c| c.1.to_string()));
    for r in rows {
        out += &line(&mut r.iter().cloned());
    }
    out
}

/// Writes the rows (cells in [`COLUMNS`] order) as CSV (all or nothing).
pub fn write_csv(path: &Path, rows: &[Cells]) -> std::io::Result<()> {
    write_atomically(path, |tmp| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        writeln!(f, "{}", COLUMNS.map(|c| c.0).join(","))?;
        for r in rows {
            writeln!(f, "{}", r.join(","))?;
        }
        f.flush()
    })
}
