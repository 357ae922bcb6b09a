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

fn print_table(rows: &[Row]) {
    println!(
        "{:<36} {:>8} {:>3} {:<12} {:>8} {:>9} {:>9} {:>7} {:>7} {:>9} {:>8} {:>8} {:>13}",
        "mesh",
        "tris",
        "thr",
        "builder",
        "aux ms",
        "build ms",
        "total ms",
        "SAH11",
        "SAH21",
        "Σ|cut|",
        "prim Mr/s",
        "diff Mr/s",
        "diff node/prim"
    );
    for r in rows {
        println!(
            "{:<36} {:>8} {:>3} {:<12} {:>8.2} {:>9.2} {:>9.2} {:>7.2} {:>7.2} {:>9} {:>8.2} {:>8.2} {:>7.1}/{:<5.1}",
            r.mesh,
            r.triangles,
            r.threads,
            r.builder,
            r.aux_ms,
            r.build_ms,
            r.total_ms,
            r.sah_11,
            r.sah_21,
            r.build_cost.map_or("-".into(), |c| c.to_string()),
            r.primary_mrays,
            r.diffuse_mrays,
            r.diffuse_nodes_per_ray,
            r.diffuse_prims_per_ray
        );
    }
}

fn write_csv(path: &Path, rows: &[Row]) -> std::io::Result<()> {
    write_atomically(path, |tmp| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        writeln!(
            f,
            "mesh,triangles,threads,builder,aux_ms,build_ms,total_ms,sah_cost_1_1,sah_cost_2_1,build_cost,primary_mrays_per_s,diffuse_mrays_per_s,diffuse_nodes_per_ray,diffuse_prims_per_ray"
        )?;
        for r in rows {
            writeln!(
                f,
                "{},{},{},{},{:.3},{:.3},{:.3},{:.4},{:.4},{},{:.3},{:.3},{:.2},{:.2}",
                r.mesh,
                r.triangles,
                r.threads,
                r.builder,
                r.aux_ms,
                r.build_ms,
                r.total_ms,
                r.sah_11,
                r.sah_21,
                r.build_cost.map_or(String::new(), |c| c.to_string()),
                r.primary_mrays,
                r.diffuse_mrays,
                r.diffuse_nodes_per_ray,
                r.diffuse_prims_per_ray
            )?;
        }
        f.flush()
    })
}
