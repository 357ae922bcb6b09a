//! `phr bench-build`: LBVH build time and closest-hit throughput on every mesh of the shared
//! scenes, with 1 and 2 threads (or the list given), as a table and a CSV.
//!
//! Build: median of `--repeats` builds of the auxiliary-free LBVH (leaves of 4), from the
//! primitive boxes (computing the boxes is not counted). Trace: closest hit through the tree for
//! the primary rays of a `--res`² image from the scene's framing camera, and for one
//! diffuse bounce from each primary hit (cosine-distributed about the facing normal, from the
//! offset hit point): coherent and incoherent rays.

use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use phr_bvh::{sah_cost, Builder, Ray, SahConstants};
use phr_render::camera::Camera;
use phr_render::geometry::Geometry;
use phr_render::load::load_mesh;
use phr_render::output::write_atomically;
use phr_render::sampler::Pcg32;
use phr_render::scene::{Mesh, Scene};
use rayon::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The meshes of `shared/scenes`, by path below it.
const MESHES: &[&str] = &[
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
    scenes: Option<PathBuf>,
    /// Builds per measurement; the median is reported.
    #[arg(long, default_value_t = 7)]
    repeats: usize,
    /// Thread counts to measure.
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    threads: Vec<usize>,
    /// Side of the square image whose primary rays are traced.
    #[arg(long, default_value_t = 512)]
    res: u32,
    #[arg(long, default_value = "lbvh")]
    builder: Builder,
    /// Only meshes whose path contains this text.
    #[arg(long)]
    only: Option<String>,
    /// CSV output.
    #[arg(long, default_value = "bench-build.csv")]
    csv: PathBuf,
}

struct Row {
    mesh: String,
    triangles: usize,
    threads: usize,
    build_ms: f64,
    mtris_per_s: f64,
    sah: f64,
    primary_mrays: f64,
    diffuse_mrays: f64,
    diffuse_nodes_per_ray: f64,
    diffuse_prims_per_ray: f64,
}

pub fn run(args: &BenchBuildArgs) -> Result<()> {
    let dir = match &args.scenes {
        Some(d) => d.clone(),
        None => phr_render::scene::json::scenes_dir(Path::new("."))
            .context("cannot find the shared scenes folder; pass --scenes DIR or set PHR_SCENES_DIR")?,
    };
    if args.repeats == 0 || args.threads.contains(&0) {
        bail!("--repeats and --threads must be at least 1");
    }
    let meshes: Vec<&str> =
        MESHES.iter().copied().filter(|m| args.only.as_ref().is_none_or(|o| m.contains(o.as_str()))).collect();
    let progress = ProgressBar::new((meshes.len() * args.threads.len()) as u64);
    progress.set_style(
        ProgressStyle::with_template("{spinner} [{bar:30}] {pos}/{len} {msg}").expect("template").progress_chars("=> "),
    );
    let mut rows = Vec::new();
    for name in meshes {
        progress.set_message(name.to_string());
        let data = load_mesh(&dir.join(name))?;
        let n = data.triangles.len();
        let mut scene = Scene::default();
        scene.meshes.push(Mesh {
            name: name.into(),
            positions: data.positions,
            triangles: data.triangles,
            triangle_material: vec![0; n],
        });
        let mut geometry = Geometry::new(&scene);
        let camera = Camera::new(&scene.framing_camera(), args.res, args.res);
        for &threads in &args.threads {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
            let row = pool.install(|| measure(name, &mut geometry, &camera, args, threads));
            rows.push(row);
            progress.inc(1);
        }
    }
    progress.finish_and_clear();
    print_table(&rows);
    write_csv(&args.csv, &rows).with_context(|| format!("writing {}", args.csv.display()))?;
    println!("wrote {}", args.csv.display());
    Ok(())
}

fn measure(name: &str, geometry: &mut Geometry, camera: &Camera, args: &BenchBuildArgs, threads: usize) -> Row {
    let mut times: Vec<f64> = (0..args.repeats)
        .map(|_| {
            let start = Instant::now();
            geometry.build(|b| args.builder.build(b));
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    let build_ms = times[times.len() / 2];
    let res = args.res;
    let primary: Vec<Ray> =
        (0..res * res).map(|i| camera.ray((i % res) as f32 + 0.5, (i / res) as f32 + 0.5)).collect();
    let (primary_mrays, hits) = trace(geometry, &primary);
    let diffuse: Vec<Ray> = primary
        .iter()
        .zip(&hits)
        .enumerate()
        .filter_map(|(i, (ray, hit))| {
            let hit = hit.as_ref()?;
            let s = geometry.surface_point(ray, hit);
            let facing = if s.front { s.normal } else { -s.normal };
            let dir = (facing + Pcg32::for_pixel(1, 0, i as u32).unit_vector()).normalize_or(facing);
            Some(Ray::new(s.spawn_origin(dir), dir))
        })
        .collect();
    let (diffuse_mrays, _) = trace(geometry, &diffuse);
    let diffuse_work = traversal_work(geometry, &diffuse);
    let triangles = geometry.triangles.len();
    Row {
        mesh: name.into(),
        triangles,
        threads,
        build_ms,
        mtris_per_s: triangles as f64 / build_ms / 1e3,
        sah: sah_cost(&geometry.bvh, SahConstants::UNIT),
        primary_mrays,
        diffuse_mrays,
        diffuse_nodes_per_ray: diffuse_work.0,
        diffuse_prims_per_ray: diffuse_work.1,
    }
}

/// Mean nodes visited and primitives tested per ray.
fn traversal_work(geometry: &Geometry, rays: &[Ray]) -> (f64, f64) {
    let (nodes, prims) = rays
        .par_iter()
        .map(|r| {
            let mut s = phr_bvh::TraversalStats::default();
            geometry.intersect_counted(r, &mut s);
            (s.nodes as u64, s.prims as u64)
        })
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    let n = rays.len().max(1) as f64;
    (nodes as f64 / n, prims as f64 / n)
}

/// Closest hits of `rays` in parallel (chunks of 256 consecutive rays per task), best of 3.
fn trace(geometry: &Geometry, rays: &[Ray]) -> (f64, Vec<Option<phr_render::geometry::Hit>>) {
    let mut best = f64::INFINITY;
    let mut hits = Vec::new();
    for _ in 0..3 {
        let start = Instant::now();
        hits = rays.par_chunks(256).flat_map_iter(|c| c.iter().map(|r| geometry.intersect(r))).collect();
        best = best.min(start.elapsed().as_secs_f64());
    }
    (rays.len() as f64 / best / 1e6, hits)
}

fn print_table(rows: &[Row]) {
    println!(
        "{:<36} {:>8} {:>3} {:>9} {:>8} {:>7} {:>12} {:>12} {:>14}",
        "mesh",
        "tris",
        "thr",
        "build ms",
        "Mtris/s",
        "SAH",
        "primary Mr/s",
        "diffuse Mr/s",
        "diffuse nodes/prims per ray"
    );
    for r in rows {
        println!(
            "{:<36} {:>8} {:>3} {:>9.2} {:>8.2} {:>7.2} {:>12.2} {:>12.2} {:>8.1} / {:.1}",
            r.mesh,
            r.triangles,
            r.threads,
            r.build_ms,
            r.mtris_per_s,
            r.sah,
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
            "mesh,triangles,threads,build_ms,mtris_per_s,sah_cost,primary_mrays_per_s,diffuse_mrays_per_s,diffuse_nodes_per_ray,diffuse_prims_per_ray"
        )?;
        for r in rows {
            writeln!(
                f,
                "{},{},{},{:.3},{:.3},{:.4},{:.3},{:.3},{:.2},{:.2}",
                r.mesh,
                r.triangles,
                r.threads,
                r.build_ms,
                r.mtris_per_s,
                r.sah,
                r.primary_mrays,
                r.diffuse_mrays,
                r.diffuse_nodes_per_ray,
                r.diffuse_prims_per_ray
            )?;
        }
        f.flush()
    })
}
