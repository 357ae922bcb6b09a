//! `phr bench-rays`' measurement: closest-hit and any-hit ray throughput of the binary
//! reference traversal, the wide BVHs (4 and 8 children, SIMD) and Intel Embree (via
//! embreex, `bench/embree_rays.py`), on the same triangles and the same ray batches.
//!
//! Per scene:
//! - one binary tree (the options' builder) over the triangles, collapsed to wide-4 and
//!   wide-8 (collapse times reported);
//! - ray batches ([`crate::rays`]): `primary` (a `res`² image of the scene's first view),
//!   `incoherent` (uniform in the scene box), `diffuse` (one bounce from each primary hit)
//!   and `shadow` (from the diffuse origins to points of the box, traced as any-hit queries:
//!   ours `any_triangle`, Embree `rtcOccluded1`);
//! - Mrays/s, best of `repeats`, on rayon pools of each thread count, for `binary` (the
//!   scalar reference traversal), `wide4` and `wide8` (best SIMD level of this CPU), wide-8
//!   with 2 or 4 rays interleaved and in packets of 16 ([`VARIANTS`]), and Embree on the same
//!   rays;
//! - where the time goes: nodes, leaves and triangles per ray, and the share of a
//!   traversal-only pass (wide-8 with `tmax` preset to the closest hit, leaves not
//!   intersected).
//!
//! Every variant's hits are checked against the reference ([`crate::oracle`]); a mismatch is an
//! error.

use crate::oracle::{agrees, binary_hit, binary_occluded, binary_work, brute_force, wide_hit, Hit};
use crate::peer::{export_dir, peer_script, run_script, write_rays, write_triangles};
use crate::rays::{incoherent_rays, shadow_rays, RaySet};
use crate::throughput::{mean_counts, throughput};
use crate::Progress;
use anyhow::{bail, Context, Result};
use glam::Vec3;
use phr_bvh::wide::triangles::{TriangleBlock, LANES};
use phr_bvh::wide::{WideNode, WideStats};
use phr_bvh::{Aabb, Builder, Bvh, PackedTriangles, Ray, SimdLevel, WideBvh};
use phr_render::camera::Camera;
use phr_render::geometry::Geometry;
use phr_render::scene::load_scene;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub const KINDS: [&str; 4] = ["primary", "incoherent", "diffuse", "shadow"];
/// The kind traced as any-hit (occlusion) queries.
pub const SHADOW: &str = "shadow";
/// Our traversals: the binary reference, wide-4 and wide-8 one ray at a time, wide-8 with
/// 2 and 4 rays interleaved (in chunks of 256 rays, as the renderer's tiles), and wide-8 in
/// packets of 16 rays (closest hits only, where the CPU has AVX-512).
pub const VARIANTS: [&str; 6] = ["binary", "wide4", "wide8", "wide8-x2", "wide8-x4", "wide8-packets"];

/// What to measure.
#[derive(Clone, Debug)]
pub struct RayBenchOptions {
    /// Side of the square image whose primary rays are traced.
    pub res: u32,
    /// Number of incoherent rays.
    pub rays: usize,
    /// Thread counts (rayon pools; Embree: that many processes).
    pub threads: Vec<usize>,
    /// The builder of the binary tree the wide trees are collapsed from.
    pub builder: Builder,
    /// Timed passes per measurement; the best is reported.
    pub repeats: usize,
    /// Run Embree (when its script and Python packages are there).
    pub embree: bool,
    /// Where Embree's JSON results are kept (`DIR/embree/SCENE.json`).
    pub out: PathBuf,
    /// Keep the triangles and ray sets in `DIR/rays/SCENE/` (the format of
    /// `bench/embree_rays.py`), for other tracers to replay.
    pub export_rays: bool,
}

/// The measurements of one scene and ray kind.
#[derive(Default)]
pub struct Row {
    pub scene: String,
    pub triangles: usize,
    pub kind: String,
    pub rays: usize,
    pub hit_rate: f64,
    /// (variant, threads) → Mrays/s; the variants of [`VARIANTS`], embree, embree-robust.
    pub mrays: BTreeMap<(String, usize), f64>,
    pub binary_nodes: f64,
    pub binary_tris: f64,
    pub wide_nodes: f64,
    pub wide_leaves: f64,
    pub wide_tris: f64,
    /// Traversal-only wide-8 pass time over the full wide-8 time (1 thread).
    pub traversal_share: f64,
    pub embree_agreement: Option<f64>,
}

impl Row {
    pub fn get(&self, variant: &str, threads: usize) -> Option<f64> {
        self.mrays.get(&(variant.to_string(), threads)).copied()
    }
}

/// One scene's trees and their sizes.
pub struct SceneInfo {
    pub scene: String,
    pub triangles: usize,
    pub build_ms: f64,
    pub collapse4_ms: f64,
    pub collapse8_ms: f64,
    pub embree_build_ms: Option<f64>,
    pub simd: SimdLevel,
    /// Wide-8 nodes and packed triangles, MB; and the triangle blocks' fill.
    pub wide8_mb: f64,
    pub packed8_mb: f64,
    pub block_fill: f64,
}

/// The trees one scene is traced with, all over the same triangles.
struct Trees {
    tris: Vec<[Vec3; 3]>,
    bvh: Bvh,
    wide4: WideBvh<4>,
    packed4: PackedTriangles,
    wide8: WideBvh<8>,
    packed8: PackedTriangles,
}

/// Checks that `options` can be measured.
pub fn validate(options: &RayBenchOptions) -> Result<()> {
    if options.repeats == 0 || options.threads.is_empty() || options.threads.contains(&0) || options.res == 0 {
        bail!("--repeats, --threads and --res must be at least 1");
    }
    Ok(())
}

/// Measures one scene file.
pub fn measure_scene(path: &Path, options: &RayBenchOptions, progress: &dyn Progress) -> Result<(SceneInfo, Vec<Row>)> {
    let name = crate::suite::scene_name(path);
    progress.status(format!("{name}: loading"));
    let scene = load_scene(path).with_context(|| format!("loading {}", path.display()))?;
    let view = scene.views.first().map(|(_, c)| c.clone()).unwrap_or_else(|| scene.framing_camera());
    let mut geometry = Geometry::new(&scene);
    if !geometry.spheres.is_empty() {
        progress.note(format!("{name}: {} spheres are left out (triangles only)", geometry.spheres.len()));
    }
    progress.status(format!("{name}: building"));
    let (trees, mut info) = build_trees(&name, &geometry, &options.builder);

    progress.status(format!("{name}: rays"));
    // The diffuse bounces come from the scene's own geometry (with its spheres, if any).
    geometry.build(&options.builder);
    let set = RaySet::new(&geometry, &Camera::new(&view, options.res, options.res), options.res);
    let bounds = geometry.boxes[..trees.tris.len()].iter().fold(Aabb::EMPTY, |b, x| b.union(*x));
    let shadow = shadow_rays(&set.diffuse, bounds);
    let batches = [set.primary, incoherent_rays(bounds, options.rays), set.diffuse, shadow];

    let script = peer_script("embree_rays.py").filter(|_| options.embree);
    if options.embree && script.is_none() {
        progress.note("Embree skipped: bench/embree_rays.py not found (run from the repository)".into());
    }
    let export = if options.export_rays {
        let dir = options.out.join("rays").join(&name);
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Some(dir)
    } else if script.is_some() {
        Some(export_dir("bench-rays", &name)?)
    } else {
        None
    };
    if let Some(dir) = &export {
        write_triangles(dir, &trees.tris)?;
    }
    let mut rows = Vec::new();
    for (kind, rays) in KINDS.iter().zip(&batches) {
        progress.status(format!("{name}: {kind} rays, checking hits"));
        let reference: Vec<Hit> = rays.par_iter().map(|r| binary_hit(&trees.bvh, &trees.tris, r)).collect();
        check_hits(&name, kind, rays, &reference, &trees, progress)?;
        if let Some(dir) = &export {
            write_rays(dir, kind, rays, &reference)?;
        }
        rows.push(measure_kind(&name, kind, rays, &reference, &trees, options, progress)?);
    }
    if let (Some(script), Some(dir)) = (script, &export) {
        progress.status(format!("{name}: Embree"));
        info.embree_build_ms = add_embree(&name, &script, dir, &mut rows, options, progress)?;
    }
    if let Some(dir) = export.filter(|_| !options.export_rays) {
        let _ = std::fs::remove_dir_all(&dir);
    }
    Ok((info, rows))
}

/// The binary tree, its wide collapses and packed triangles, with their times and sizes.
fn build_trees(name: &str, geometry: &Geometry, builder: &Builder) -> (Trees, SceneInfo) {
    let tris = geometry.triangles.clone();
    let report = builder.build_timed_with_triangles(&geometry.boxes[..tris.len()], &tris);
    let build_ms = report.total_time().as_secs_f64() * 1e3;
    let bvh = report.bvh;
    let start = Instant::now();
    let wide4 = WideBvh::<4>::from_bvh(&bvh);
    let packed4 = PackedTriangles::new(&wide4.prim_indices, &tris);
    let collapse4_ms = start.elapsed().as_secs_f64() * 1e3;
    let start = Instant::now();
    let wide8 = WideBvh::<8>::from_bvh(&bvh);
    let packed8 = PackedTriangles::new(&wide8.prim_indices, &tris);
    let collapse8_ms = start.elapsed().as_secs_f64() * 1e3;
    let info = SceneInfo {
        scene: name.to_string(),
        triangles: tris.len(),
        build_ms,
        collapse4_ms,
        collapse8_ms,
        embree_build_ms: None,
        simd: wide8.simd(),
        wide8_mb: (wide8.nodes.len() * std::mem::size_of::<WideNode<8>>()) as f64 / 1e6,
        packed8_mb: (packed8.blocks.len() * std::mem::size_of::<TriangleBlock>()) as f64 / 1e6,
        block_fill: tris.len() as f64 / (packed8.blocks.len() * LANES).max(1) as f64,
    };
    (Trees { tris, bvh, wide4, packed4, wide8, packed8 }, info)
}

/// Every variant's hits against the reference; any-hit queries (shadow rays) too.
fn check_hits(
    name: &str,
    kind: &str,
    rays: &[Ray],
    reference: &[Hit],
    trees: &Trees,
    progress: &dyn Progress,
) -> Result<()> {
    let t = trees;
    let interleaved = |m: usize| -> Vec<Hit> {
        let mut hits = vec![None; rays.len()];
        match m {
            2 => t.wide8.closest_triangles_interleaved::<2>(&t.packed8, rays, &mut hits),
            _ => t.wide8.closest_triangles_interleaved::<4>(&t.packed8, rays, &mut hits),
        }
        hits.into_iter().map(|h| h.map(|h| (h.prim, h.hit.t))).collect()
    };
    let packets = {
        let mut hits = vec![None; rays.len()];
        t.wide8.closest_triangles_packets(&t.packed8, rays, &mut hits);
        hits.into_iter().map(|h| h.map(|h| (h.prim, h.hit.t))).collect()
    };
    let variants: [(&str, Vec<Hit>); 5] = [
        ("wide4", rays.par_iter().map(|r| wide_hit(&t.wide4, &t.packed4, r)).collect()),
        ("wide8", rays.par_iter().map(|r| wide_hit(&t.wide8, &t.packed8, r)).collect()),
        ("wide8-x2", interleaved(2)),
        ("wide8-x4", interleaved(4)),
        ("wide8-packets", packets),
    ];
    for (variant, got) in variants {
        for i in (0..got.len()).filter(|&i| got[i] != reference[i]) {
            match agrees(got[i], reference[i], &t.tris, &rays[i]) {
                Ok(()) => progress.note(format!(
                    "{name} {kind}: {variant} finds the brute-force hit {:?} that the binary reference misses ({:?}), ray {:?}",
                    got[i], reference[i], rays[i]
                )),
                Err(brute) => bail!(
                    "{name} {kind}: {variant} differs from the binary reference and from brute force, ray {:?}: {:?}, reference {:?}, brute force {brute:?}",
                    rays[i],
                    got[i],
                    reference[i]
                ),
            }
        }
    }
    if kind == SHADOW {
        // Occluded exactly when the closest-hit reference (or brute force) hits something.
        let interleaved = |m: usize| {
            let mut occluded = vec![false; rays.len()];
            match m {
                2 => t.wide8.any_triangles_interleaved::<2>(&t.packed8, rays, &mut occluded),
                _ => t.wide8.any_triangles_interleaved::<4>(&t.packed8, rays, &mut occluded),
            }
            occluded
        };
        let (x2, x4) = (interleaved(2), interleaved(4));
        let wrong = rays.par_iter().zip(reference).enumerate().position_any(|(i, (r, h))| {
            let got = [
                binary_occluded(&t.bvh, &t.tris, r),
                t.wide4.any_triangle(&t.packed4, r),
                t.wide8.any_triangle(&t.packed8, r),
                x2[i],
                x4[i],
            ];
            got.iter().any(|&g| g != h.is_some() && g != brute_force(&t.tris, r).is_some())
        });
        if let Some(i) = wrong {
            bail!("{name} {SHADOW}: an any-hit query disagrees with the reference, ray {:?}", rays[i]);
        }
    }
    Ok(())
}

/// Throughput on every pool size, and the work per ray, of one batch.
fn measure_kind(
    name: &str,
    kind: &str,
    rays: &[Ray],
    reference: &[Hit],
    trees: &Trees,
    options: &RayBenchOptions,
    progress: &dyn Progress,
) -> Result<Row> {
    let hits = reference.iter().filter(|h| h.is_some()).count();
    let mut row = Row {
        scene: name.to_string(),
        triangles: trees.tris.len(),
        kind: kind.to_string(),
        rays: rays.len(),
        hit_rate: hits as f64 / rays.len().max(1) as f64,
        ..Row::default()
    };
    for &threads in &options.threads {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
        progress.status(format!("{name}: {kind} rays, {threads} thread(s)"));
        for (i, v) in VARIANTS.iter().enumerate() {
            let Some(m) = pool.install(|| variant_throughput(i, kind == SHADOW, rays, trees, options.repeats)) else {
                continue;
            };
            row.mrays.insert((v.to_string(), threads), m);
        }
    }
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    one.install(|| work_per_ray(&mut row, rays, reference, trees, options.repeats));
    Ok(row)
}

/// Mrays/s of `VARIANTS[variant]`, as any-hit queries for shadow rays (`None`: packets on
/// shadow rays, which have no any-hit query, or on a CPU without AVX-512).
fn variant_throughput(variant: usize, any: bool, rays: &[Ray], t: &Trees, repeats: usize) -> Option<f64> {
    Some(match (variant, any) {
        (0, true) => throughput(rays, repeats, |ray| binary_occluded(&t.bvh, &t.tris, ray)),
        (1, true) => throughput(rays, repeats, |ray| t.wide4.any_triangle(&t.packed4, ray)),
        (2, true) => throughput(rays, repeats, |ray| t.wide8.any_triangle(&t.packed8, ray)),
        (3, true) => interleaved_any::<2>(rays, repeats, t),
        (4, true) => interleaved_any::<4>(rays, repeats, t),
        (_, true) => return None,
        (0, false) => throughput(rays, repeats, |ray| binary_hit(&t.bvh, &t.tris, ray).is_some()),
        (1, false) => throughput(rays, repeats, |ray| wide_hit(&t.wide4, &t.packed4, ray).is_some()),
        (2, false) => throughput(rays, repeats, |ray| wide_hit(&t.wide8, &t.packed8, ray).is_some()),
        (3, false) => interleaved::<2>(rays, repeats, t),
        (4, false) => interleaved::<4>(rays, repeats, t),
        (_, false) if phr_bvh::wide::packet::available() => packets(rays, repeats, t),
        _ => return None,
    })
}

/// Mrays/s of the wide-8 closest-hit traversal with `M` rays interleaved.
fn interleaved<const M: usize>(rays: &[Ray], repeats: usize, t: &Trees) -> f64 {
    crate::throughput::throughput_batched(rays, repeats, |chunk| {
        let mut hits = vec![None; chunk.len()];
        t.wide8.closest_triangles_interleaved::<M>(&t.packed8, chunk, &mut hits);
        hits.iter().filter(|h| h.is_some()).count()
    })
}

/// Mrays/s of the wide-8 closest-hit traversal in packets of 16 rays.
fn packets(rays: &[Ray], repeats: usize, t: &Trees) -> f64 {
    crate::throughput::throughput_batched(rays, repeats, |chunk| {
        let mut hits = vec![None; chunk.len()];
        t.wide8.closest_triangles_packets(&t.packed8, chunk, &mut hits);
        hits.iter().filter(|h| h.is_some()).count()
    })
}

/// Mrays/s of the wide-8 any-hit traversal with `M` rays interleaved.
fn interleaved_any<const M: usize>(rays: &[Ray], repeats: usize, t: &Trees) -> f64 {
    crate::throughput::throughput_batched(rays, repeats, |chunk| {
        let mut occluded = vec![false; chunk.len()];
        t.wide8.any_triangles_interleaved::<M>(&t.packed8, chunk, &mut occluded);
        occluded.iter().filter(|&&o| o).count()
    })
}

/// Where the time goes (on the current pool, one thread): nodes, leaves and triangles per
/// ray of the closest-hit query, and the share of a traversal-only pass.
fn work_per_ray(row: &mut Row, rays: &[Ray], reference: &[Hit], t: &Trees, repeats: usize) {
    [row.binary_nodes, row.binary_tris] = mean_counts(rays, |r| binary_work(&t.bvh, &t.tris, r));
    [row.wide_nodes, row.wide_leaves, row.wide_tris] = mean_counts(rays, |r| {
        let mut s = WideStats::default();
        let mut ray = *r;
        let mut best = None;
        t.wide8.closest_hit_leaves_counted(
            &mut ray,
            |first, count, r| {
                t.packed8.leaf_hits(first, count, r, |i, h, r| {
                    let p = t.wide8.prim_indices[i as usize];
                    let keep = h.t < r.tmax || best.is_none_or(|bp| p < bp);
                    if keep {
                        r.tmax = h.t;
                        best = Some(p);
                    }
                    keep
                })
            },
            &mut s,
        );
        [s.nodes as u64, s.leaves as u64, s.prims as u64]
    });
    // Traversal only: tmax at the closest hit, leaves counted, not intersected.
    let clipped: Vec<Ray> =
        rays.iter().zip(reference).map(|(r, h)| Ray { tmax: h.map_or(r.tmax, |(_, t)| t), ..*r }).collect();
    let traversal = throughput(&clipped, repeats, |ray| {
        let mut r = *ray;
        let mut leaves = 0u32;
        t.wide8.closest_hit_leaves(&mut r, |_, count, _| {
            leaves += count;
            false
        });
        std::hint::black_box(leaves) > 0
    });
    let full = row.get("wide8", 1).or_else(|| variant_throughput(2, row.kind == SHADOW, rays, t, repeats));
    let full = full.expect("wide8 runs every query");
    row.traversal_share = full / traversal;
}

/// Runs Embree on the exported scene and adds its columns to `rows`; returns its build time.
/// A peer that cannot run is reported, not an error.
fn add_embree(
    name: &str,
    script: &Path,
    dir: &Path,
    rows: &mut [Row],
    options: &RayBenchOptions,
    progress: &dyn Progress,
) -> Result<Option<f64>> {
    let threads: Vec<String> = options.threads.iter().map(|t| t.to_string()).collect();
    let args: Vec<OsString> = [dir.as_os_str().to_owned()]
        .into_iter()
        .chain(["--kinds", &KINDS.join(","), "--threads", &threads.join(","), "--repeats"].map(OsString::from))
        .chain([OsString::from(options.repeats.to_string())])
        .collect();
    let json = match run_script(script, &args, &dir.join("embree.json")) {
        Ok(json) => json,
        Err(why) => {
            progress.note(format!("{name}: Embree skipped: {why}"));
            return Ok(None);
        }
    };
    let kept = options.out.join("embree");
    std::fs::create_dir_all(&kept).with_context(|| format!("creating {}", kept.display()))?;
    std::fs::write(kept.join(format!("{name}.json")), serde_json::to_string_pretty(&json)?)?;
    for row in rows {
        let k = &json["kinds"][&row.kind];
        for &t in &options.threads {
            for (column, key) in [("embree", "mrays_per_s"), ("embree-robust", "robust_mrays_per_s")] {
                if let Some(m) = k[key][t.to_string()].as_f64() {
                    row.mrays.insert((column.to_string(), t), m);
                }
            }
        }
        row.embree_agreement = k["hit_agreement"].as_f64();
    }
    Ok(json["build_ms"].as_f64())
}
