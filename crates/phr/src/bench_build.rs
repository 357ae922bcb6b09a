//! `phr bench-build`: every builder on every mesh of the shared scenes (or on the scenes
//! given), with 1 and 2 threads
//! (or the lists given): build time (the auxiliary LBVH and PHR shown apart), SAH cost with the
//! constants (1, 1) and the thesis's (2, 1), PHR's `Σ |cut|`, and closest-hit throughput of
//! one fixed ray set per mesh, as a table and a CSV; native Embree's build next to them
//! ([`phr_bench::embree_build`]). What is measured and how: [`phr_bench::build_bench`].

use anyhow::{bail, Context, Result};
use clap::Args;
use phr_bench::build_bench::{embree_cells, measure_builder, table, write_csv};
use phr_bench::embree_build::measure_embree_build;
use phr_bench::rays::RaySet;
use phr_bench::suite::{open_mesh, open_scene, select, shared_scenes_dir, SHARED_MESHES};
use phr_bvh::Builder;
use phr_render::camera::Camera;
use phr_render::geometry::Geometry;
use std::path::PathBuf;

#[derive(Args)]
pub struct BenchBuildArgs {
    /// Scenes to measure instead of the shared meshes: scene files, meshes, or names of
    /// scenes/suite (`dragons8`: 7M triangles).
    pub scene: Vec<String>,
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
    #[arg(long, value_delimiter = ',', default_value = "lbvh,phr-fast,phr-hq,binned-sah,sweep-sah,sbvh")]
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
    /// Skip the peer, native Embree (build quality medium, through bench/embree_build.py;
    /// needs python3 with numpy and the embreex wheel's libembree4 or a system Embree).
    #[arg(long)]
    pub no_embree: bool,
}

pub fn run(args: &BenchBuildArgs) -> Result<()> {
    if args.repeats == 0 || args.threads.contains(&0) {
        bail!("--repeats and --threads must be at least 1");
    }
    // The branching factor applies to the PHR builders; the others stay binary.
    let builders: Vec<Builder> = args.builders.iter().map(|b| b.with_branching(args.branching).unwrap_or(*b)).collect();
    let meshes: Vec<String> = if args.scene.is_empty() {
        select(SHARED_MESHES, &args.only).into_iter().map(String::from).collect()
    } else {
        args.scene.clone()
    };
    let dir = if args.scene.is_empty() { Some(shared_scenes_dir(args.scenes.as_deref())?) } else { None };
    let progress = crate::progress::bar((meshes.len() * args.threads.len() * builders.len()) as u64);
    let mut rows = Vec::new();
    let mut skipped = None;
    for name in &meshes {
        let (mut geometry, scene) = match &dir {
            Some(dir) => open_mesh(dir, name)?,
            None => {
                let scene = open_scene(name)?;
                (Geometry::new(&scene), scene)
            }
        };
        let camera = Camera::new(&scene.framing_camera(), args.res, args.res);
        geometry.build(&Builder::default());
        let rays = RaySet::new(&geometry, &camera, args.res);
        for &threads in &args.threads {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
            for builder in &builders {
                progress.set_message(format!("{name}, {builder}, {threads} thread(s)"));
                let row = pool.install(|| measure_builder(name, &mut geometry, &rays, builder, args.repeats, threads));
                rows.push(row.cells());
                progress.inc(1);
            }
        }
        if !args.no_embree && skipped.is_none() {
            progress.set_message(format!("{name}, native Embree"));
            match measure_embree_build(name, &geometry.triangles, &args.threads, args.repeats) {
                Ok(embree) => rows.extend(embree_cells(name, geometry.triangle_count(), &embree)),
                Err(reason) => skipped = Some(reason),
            }
        }
    }
    progress.finish_and_clear();
    print!("{}", table(&rows));
    if let Some(reason) = skipped {
        println!("native Embree skipped: {reason}");
    }
    write_csv(&args.csv, &rows).with_context(|| format!("writing {}", args.csv.display()))?;
    println!("wrote {}", args.csv.display());
    Ok(())
}
