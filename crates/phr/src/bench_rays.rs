//! `phr bench-rays`: closest-hit ray throughput of the binary reference traversal, the wide
//! BVHs (4 and 8 children, SIMD) and Intel Embree (via embreex, `bench/embree_rays.py`), on
//! the same triangles and the same ray batches, in one invocation.
//!
//! Per scene (default: bunny, sponza, sibenik, dragon and conference of `scenes/suite`):
//! - one binary tree (`--builder`, default PHR-HQ) over the triangles, collapsed to wide-4 and
//!   wide-8 (collapse times reported);
//! - three ray batches: `primary` (a `--res`² image of the scene's first view), `incoherent`
//!   (`--rays` rays from uniform points of the scene box in uniform directions) and `diffuse`
//!   (one cosine-distributed bounce from every primary hit, as in `bench-build`);
//! - a fourth batch, `shadow`: from each diffuse ray's origin to a uniform point of the scene
//!   box, over the interval (0, 1 − 10⁻⁴) of the unnormalised direction (as the renderer's
//!   light samples), traced as any-hit queries (ours `any_triangle`, Embree `rtcOccluded1`);
//! - Mrays/s, best of `--repeats`, on rayon pools of each `--threads` size, for `binary`
//!   (the scalar ordered traversal of `phr_bvh::traverse` with `intersect_triangle`: the
//!   renderer's path before the wide BVH), `wide4` and `wide8` (best SIMD level of this CPU,
//!   triangles packed in leaf order), wide-8 with 2 or 4 rays interleaved and in packets of 16
//!   (AVX-512, closest hits only), and Embree on the same rays;
//! - where the time goes: nodes visited, leaves visited and triangles tested per ray (wide-8
//!   and binary), and the share of a traversal-only pass: wide-8 with each ray's `tmax` set to
//!   its closest hit and leaves counted but not intersected (the traversal the real query does
//!   once it has found the hit: a lower bound of its traversal work).
//!
//! Every variant's hits are checked against the binary reference (same primitive and `t`);
//! a mismatch is an error. Output: `bench-rays.csv`, `bench-rays.md` (tables) in `--out`.
//! The measurement is [`phr_bench::ray_bench`]; this file parses arguments and prints.

use crate::progress::{bar, Bar};
use anyhow::{Context, Result};
use clap::Args;
use phr_bench::ray_bench::{measure_scene, validate, RayBenchOptions};
use phr_bench::ray_report::{markdown, write_csv};
use phr_bench::suite::{suite_files, THESIS_SCENES};
use phr_bvh::Builder;
use phr_render::output::write_atomically;
use std::path::PathBuf;

#[derive(Args)]
pub struct BenchRaysArgs {
    /// Scene files (JSON scenes or meshes); default: the five scenes of scenes/suite.
    #[arg(long = "scene", value_delimiter = ',')]
    pub scenes: Vec<PathBuf>,
    /// Side of the square image whose primary rays are traced.
    #[arg(long, default_value_t = 512)]
    pub res: u32,
    /// Number of incoherent rays.
    #[arg(long, default_value_t = 512 * 512)]
    pub rays: usize,
    /// Thread counts (rayon pools; Embree: that many processes, see bench/embree_rays.py).
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    pub threads: Vec<usize>,
    /// The builder of the binary tree the wide trees are collapsed from.
    #[arg(long, default_value = "phr-hq")]
    pub builder: Builder,
    /// Timed passes per measurement; the best is reported.
    #[arg(long, default_value_t = 3)]
    pub repeats: usize,
    /// Output folder.
    #[arg(long, default_value = "bench-rays")]
    pub out: PathBuf,
    /// Skip Embree.
    #[arg(long)]
    pub no_embree: bool,
    /// Keep each scene's triangles and ray sets in OUT/rays/SCENE/ (large: 250 MB for
    /// dragons8), for other tracers to replay; `docs/bench-rays/embree_packets.c` reads them.
    #[arg(long)]
    pub export_rays: bool,
}

impl BenchRaysArgs {
    fn options(&self) -> RayBenchOptions {
        RayBenchOptions {
            res: self.res,
            rays: self.rays,
            threads: self.threads.clone(),
            builder: self.builder,
            repeats: self.repeats,
            embree: !self.no_embree,
            out: self.out.clone(),
            export_rays: self.export_rays,
        }
    }
}

pub fn run(args: &BenchRaysArgs) -> Result<()> {
    let options = args.options();
    validate(&options)?;
    let scenes = if args.scenes.is_empty() { suite_files(THESIS_SCENES)? } else { args.scenes.clone() };
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let progress = bar(scenes.len() as u64);
    let (mut rows, mut infos) = (Vec::new(), Vec::new());
    for path in &scenes {
        let (info, scene_rows) = measure_scene(path, &options, &Bar(&progress))?;
        infos.push(info);
        rows.extend(scene_rows);
        progress.inc(1);
    }
    progress.finish_and_clear();
    let table = markdown(&infos, &rows, &options);
    println!("{table}");
    let csv = args.out.join("bench-rays.csv");
    write_csv(&csv, &rows, &args.threads).with_context(|| format!("writing {}", csv.display()))?;
    let md = args.out.join("bench-rays.md");
    write_atomically(&md, |tmp| std::fs::write(tmp, &table)).with_context(|| format!("writing {}", md.display()))?;
    println!("wrote {} and {}", csv.display(), md.display());
    Ok(())
}
