//! `phr bench-build`: every builder on every mesh of the shared scenes, with 1 and 2 threads
//! (or the lists given): build time (the auxiliary LBVH and PHR shown apart), SAH cost with the
//! constants (1, 1) and the thesis's (2, 1), PHR's `Σ |cut|`, and closest-hit throughput of
//! one fixed ray set per mesh, as a table and a CSV.
//!
//! Build: median of `--repeats` builds from the primitive boxes. Rays: the primary rays of a
//! `--res`² image from the mesh's framing camera, and one diffuse bounce from each primary hit
//! (cosine-distributed about the facing normal): coherent and incoherent rays. The same rays
//! are traced through every builder's tree.

use anyhow::{bail, Context, Result};
use clap::Args;
use phr_bench::rays::RaySet;
use phr_bench::throughput::{mean_counts, throughput};
use phr_bvh::{sah_cost, Builder, Ray, SahConstants};
use phr_render::camera::Camera;
use phr_render::geometry::Geometry;
use phr_render::output::write_atomically;
use phr_render::scene::{load_scene, Scene};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The meshes of `shared/scenes`, by path below it.
pub const MESHES: &[&str] = &[
    "cornell_box/CornellBox-Original.obj",
    "bunny/bun_zipper.ply",
    "sponza/sponza.obj",
    "sibenik/sibenik.obj",
    "sibenik/sibenik_75284_geometry.ply",
    "conference/conference_geometry.ply",
    "dragon/dragon_vrip.ply",
];

#[derive(Args)]
pub struct BenchBuildArgs {
    /// The shared scenes folder (default: found above the current directory).
    #[arg(long)]
    pub scenes: Option<PathBuf>,
    /// Builds per measurement; the median is reported.
    #[arg(long, default_value_t = 5)]
    pub repeats: usize,
    /// Thread counts to measure.
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    pub threads: Vec<usize>,
    /// Side of the square image whose primary rays are traced.
    #[arg(long, default_value_t = 512)]
    pub res: u32,
    /// Builders to compare.
    #[arg(long, value_delimiter = ',', default_value = "lbvh,phr-fast,phr-hq,binned-sah,sweep-sah")]
    pub builders: Vec<Builder>,
    /// Branching factor for the PHR builders (2, 4, 8 or 16).
    #[arg(long, default_value_t = 2)]
    pub branching: u32,
    /// Only meshes whose path contains one of these texts.
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// CSV output.
    #[arg(long, default_value = "bench-build.csv")]
    pub csv: PathBuf,
}

struct Row {
    mesh: String,
    triangles: usize,
    threads: usize,
    builder: String,
    aux_ms: f64,
    build_ms: f64,
    total_ms: f64,
    sah_11: f64,
    sah_21: f64,
    build_cost: Option<u64>,
    primary_mrays: f64,
    diffuse_mrays: f64,
    diffuse_nodes_per_ray: f64,
    diffuse_prims_per_ray: f64,
}

/// The shared scenes folder: the one given, or the one found from here.
pub fn scenes_folder(given: &Option<PathBuf>) -> Result<PathBuf> {
    match given {
        Some(d) => Ok(d.clone()),
        None => phr_render::scene::json::scenes_dir(Path::new("."))
            .context("cannot find the shared scenes folder; pass --scenes DIR or set PHR_SCENES_DIR"),
    }
}

/// One mesh of the shared scenes, as a scene (its materials, a camera framing it) and its
/// geometry.
pub fn open_mesh(dir: &Path, name: &str) -> Result<(Geometry, Scene)> {
    let scene = load_scene(&dir.join(name))?;
    Ok((Geometry::new(&scene), scene))
}

pub fn run(args: &BenchBuildArgs) -> Result<()> {
    let dir = scenes_folder(&args.scenes)?;
    if args.repeats == 0 || args.threads.contains(&0) {
        bail!("--repeats and --threads must be at least 1");
    }
    // The branching factor applies to the PHR builders; the others stay binary.
    let builders: Vec<Builder> = args.builders.iter().map(|b| b.with_branching(args.branching).unwrap_or(*b)).collect();
    let meshes: Vec<&str> = MESHES
        .iter()
        .copied()
        .filter(|m| args.only.is_empty() || args.only.iter().any(|o| m.contains(o.as_str())))
        .collect();
    let progress = crate::progress::bar((meshes.len() * args.threads.len() * builders.len()) as u64);
    let mut rows = Vec::new();
    for name in meshes {
        let (mut geometry, scene) = open_mesh(&dir, name)?;
        let camera = Camera::new(&scene.framing_camera(), args.res, args.res);
        geometry.build(|b| Builder::default().build(b));
        let rays = RaySet::new(&geometry, &camera, args.res);
        for &threads in &args.threads {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
            for builder in &builders {
                progress.set_message(format!("{name}, {builder}, {threads} thread(s)"));
                rows.push(pool.install(|| measure(name, &mut geometry, &rays, builder, args.repeats, threads)));
                progress.inc(1);
            }
        }
    }
    progress.finish_and_clear();
    print_table(&rows);
    write_csv(&args.csv, &rows).with_context(|| format!("writing {}", args.csv.display()))?;
    println!("wrote {}", args.csv.display());
    Ok(())
}

fn measure(
    name: &str,
    geometry: &mut Geometry,
    rays: &RaySet,
    builder: &Builder,
    repeats: usize,
    threads: usize,
) -> Row {
    let mut reports: Vec<_> = (0..repeats)
        .map(|_| {
            let report = builder.build_timed(&geometry.boxes);
            (report.total_time(), report)
        })
        .collect();
    reports.sort_by_key(|r| r.0);
    let report = reports.swap_remove(reports.len() / 2).1;
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    let (aux_ms, build_ms, total_ms) = (ms(report.aux_time), ms(report.build_time), ms(report.total_time()));
    let build_cost = report.phr.map(|s| s.build_cost);
    geometry.set_bvh(report.bvh);
    let trace = |r: &Ray| geometry.intersect(r).is_some();
    let (primary_mrays, diffuse_mrays) = (throughput(&rays.primary, 3, trace), throughput(&rays.diffuse, 3, trace));
    let [diffuse_nodes_per_ray, diffuse_prims_per_ray] = mean_counts(&rays.diffuse, |r| {
        let mut s = phr_bvh::TraversalStats::default();
        geometry.intersect_counted(r, &mut s);
        [s.nodes as u64, s.prims as u64]
    });
    Row {
        mesh: name.into(),
        triangles: geometry.triangles.len(),
        threads,
        builder: builder.to_string(),
        aux_ms,
        build_ms,
        total_ms,
        sah_11: sah_cost(geometry.bvh(), SahConstants::UNIT),
        sah_21: sah_cost(geometry.bvh(), SahConstants::THESIS),
        build_cost,
        primary_mrays,
        diffuse_mrays,
        diffuse_nodes_per_ray,
        diffuse_prims_per_ray,
    }
}

/// The columns of the CSV, and the console table's headings and widths.
const COLUMNS: [(&str, &str, usize); 14] = [
    ("mesh", "mesh", 36),
    ("triangles", "tris", 8),
    ("threads", "thr", 3),
    ("builder", "builder", 12),
    ("aux_ms", "aux ms", 8),
    ("build_ms", "build ms", 9),
    ("total_ms", "total ms", 9),
    ("sah_cost_1_1", "SAH11", 7),
    ("sah_cost_2_1", "SAH21", 7),
    ("build_cost", "Σ|cut|", 9),
    ("primary_mrays_per_s", "prim Mr/s", 9),
    ("diffuse_mrays_per_s", "diff Mr/s", 9),
    ("diffuse_nodes_per_ray", "diff nodes", 10),
    ("diffuse_prims_per_ray", "diff prims", 10),
];

/// One row's values, in [`COLUMNS`] order.
fn cells(r: &Row) -> [String; 14] {
    [
        r.mesh.clone(),
        r.triangles.to_string(),
        r.threads.to_string(),
        r.builder.clone(),
        format!("{:.3}", r.aux_ms),
        format!("{:.3}", r.build_ms),
        format!("{:.3}", r.total_ms),
        format!("{:.4}", r.sah_11),
        format!("{:.4}", r.sah_21),
        r.build_cost.map_or(String::new(), |c| c.to_string()),
        format!("{:.3}", r.primary_mrays),
        format!("{:.3}", r.diffuse_mrays),
        format!("{:.2}", r.diffuse_nodes_per_ray),
        format!("{:.2}", r.diffuse_prims_per_ray),
    ]
}

fn print_table(rows: &[Row]) {
    let line = |cells: &mut dyn Iterator<Item = String>| {
        let padded: Vec<String> = cells.zip(COLUMNS).map(|(c, (_, _, w))| format!("{c:>w$}")).collect();
        println!("{}", padded.join(" "));
    };
    line(&mut COLUMNS.iter().map(|c| c.1.to_string()));
    for r in rows {
        line(&mut cells(r).into_iter());
    }
}

fn write_csv(path: &Path, rows: &[Row]) -> std::io::Result<()> {
    write_atomically(path, |tmp| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        writeln!(f, "{}", COLUMNS.map(|c| c.0).join(","))?;
        for r in rows {
            writeln!(f, "{}", cells(r).join(","))?;
        }
        f.flush()
    })
}
