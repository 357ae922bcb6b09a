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
//!   triangles packed in leaf order), and Embree on the same rays;
//! - where the time goes: nodes visited, leaves visited and triangles tested per ray (wide-8
//!   and binary), and the share of a traversal-only pass: wide-8 with each ray's `tmax` set to
//!   its closest hit and leaves counted but not intersected (the traversal the real query does
//!   once it has found the hit: a lower bound of its traversal work).
//!
//! Every variant's hits are checked against the binary reference (same primitive and `t`);
//! a mismatch is an error. Output: `bench-rays.csv`, `bench-rays.md` (tables) in `--out`.

use crate::bench::peers::{peer_script, write_counted};
use crate::bench_build::RaySet;
use anyhow::{bail, Context, Result};
use clap::Args;
use glam::Vec3;
use indicatif::{ProgressBar, ProgressStyle};
use phr_bvh::triangle::intersect_triangle;
use phr_bvh::wide::{Lanes, WideStats, Width};
use phr_bvh::{
    any_hit, closest_hit, closest_hit_counted, Aabb, Builder, Bvh, PackedTriangles, Ray, SimdLevel, WideBvh,
};
use phr_render::camera::Camera;
use phr_render::geometry::Geometry;
use phr_render::output::write_atomically;
use phr_render::sampler::Pcg32;
use phr_render::scene::load_scene;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// The scenes measured by default, by file stem in `scenes/suite`.
pub const SCENES: &[&str] = &["bunny", "sponza", "sibenik", "dragon", "conference"];
const KINDS: [&str; 4] = ["primary", "incoherent", "diffuse", "shadow"];
/// The kind traced as any-hit (occlusion) queries.
const SHADOW: &str = "shadow";
const VARIANTS: [&str; 3] = ["binary", "wide4", "wide8"];

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
}

/// The measurements of one scene and ray kind.
#[derive(Default)]
struct Row {
    scene: String,
    triangles: usize,
    kind: String,
    rays: usize,
    hit_rate: f64,
    /// (variant, threads) → Mrays/s; variants binary, wide4, wide8, embree.
    mrays: BTreeMap<(String, usize), f64>,
    binary_nodes: f64,
    binary_tris: f64,
    wide_nodes: f64,
    wide_leaves: f64,
    wide_tris: f64,
    /// Traversal-only wide-8 pass time over the full wide-8 time (1 thread).
    traversal_share: f64,
    embree_agreement: Option<f64>,
}

struct SceneInfo {
    scene: String,
    triangles: usize,
    build_ms: f64,
    collapse4_ms: f64,
    collapse8_ms: f64,
    embree_build_ms: Option<f64>,
    simd: SimdLevel,
    /// Wide-8 nodes and packed triangles, MB; and the triangle blocks' fill.
    wide8_mb: f64,
    packed8_mb: f64,
    block_fill: f64,
}

fn script() -> Option<PathBuf> {
    peer_script("embree_rays.py")
}

pub fn run(args: &BenchRaysArgs) -> Result<()> {
    if args.repeats == 0 || args.threads.is_empty() || args.threads.contains(&0) || args.res == 0 {
        bail!("--repeats, --threads and --res must be at least 1");
    }
    let scenes = if args.scenes.is_empty() { phr_bench::suite::suite_files(SCENES)? } else { args.scenes.clone() };
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let progress = ProgressBar::new(scenes.len() as u64);
    progress.set_style(
        ProgressStyle::with_template("{spinner} [{bar:30}] {pos}/{len} {msg} (eta {eta})")
            .expect("template")
            .progress_chars("=> "),
    );
    let mut rows = Vec::new();
    let mut infos = Vec::new();
    for path in &scenes {
        let (info, scene_rows) = measure_scene(path, args, &progress)?;
        infos.push(info);
        rows.extend(scene_rows);
        progress.inc(1);
    }
    progress.finish_and_clear();
    let threads = &args.threads;
    let table = markdown(&infos, &rows, threads, args);
    println!("{table}");
    let csv = args.out.join("bench-rays.csv");
    write_csv(&csv, &rows, threads).with_context(|| format!("writing {}", csv.display()))?;
    let md = args.out.join("bench-rays.md");
    write_atomically(&md, |tmp| std::fs::write(tmp, &table)).with_context(|| format!("writing {}", md.display()))?;
    println!("wrote {} and {}", csv.display(), md.display());
    Ok(())
}

/// Incoherent rays: uniform origins in the scene box, uniform directions.
fn incoherent_rays(bounds: Aabb, count: usize) -> Vec<Ray> {
    (0..count)
        .into_par_iter()
        .map(|i| {
            let mut rng = Pcg32::new(0x5eed, i as u64);
            let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            Ray::new(bounds.min + u * bounds.extent(), rng.unit_vector())
        })
        .collect()
}

/// Shadow rays: from each diffuse ray's origin to a uniform point of the scene box, over the
/// interval (0, 1 − 10⁻⁴) of the unnormalised direction (the renderer's light-sample rays).
fn shadow_rays(diffuse: &[Ray], bounds: Aabb) -> Vec<Ray> {
    diffuse
        .par_iter()
        .enumerate()
        .map(|(i, r)| {
            let mut rng = Pcg32::new(0x5ad0, i as u64);
            let target = bounds.min + Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * bounds.extent();
            Ray::with_interval(r.origin, target - r.origin, 0.0, 1.0 - 1e-4)
        })
        .collect()
}

/// Any hit by the binary reference traversal.
#[inline]
fn binary_occluded(bvh: &Bvh, tris: &[[Vec3; 3]], ray: &Ray) -> bool {
    any_hit(bvh, ray, |p, r| {
        let [a, b, c] = tris[p as usize];
        intersect_triangle(r, a, b, c).is_some()
    })
}

/// Every any-hit query agrees with the closest-hit reference (occluded exactly when
/// something is hit), or with brute force where the reference misses a tolerance hit.
#[allow(clippy::too_many_arguments)]
fn check_occlusion(
    name: &str,
    rays: &[Ray],
    reference: &[Option<(u32, f32)>],
    tris: &[[Vec3; 3]],
    bvh: &Bvh,
    wide4: &WideBvh<4>,
    packed4: &PackedTriangles,
    wide8: &WideBvh<8>,
    packed8: &PackedTriangles,
) -> Result<()> {
    let wrong = rays.par_iter().zip(reference).position_any(|(r, h)| {
        let got = [binary_occluded(bvh, tris, r), wide4.any_triangle(packed4, r), wide8.any_triangle(packed8, r)];
        got.iter().any(|&g| g != h.is_some() && g != brute_force(tris, r).is_some())
    });
    match wrong {
        Some(i) => bail!("{name} {SHADOW}: an any-hit query disagrees with the reference, ray {:?}", rays[i]),
        None => Ok(()),
    }
}

/// Closest hit over every triangle (lowest index wins ties).
fn brute_force(tris: &[[Vec3; 3]], ray: &Ray) -> Option<(u32, f32)> {
    let mut best: Option<(u32, f32)> = None;
    for (i, [a, b, c]) in tris.iter().enumerate() {
        if let Some(h) = intersect_triangle(ray, *a, *b, *c) {
            if best.is_none_or(|(_, t)| h.t < t) {
                best = Some((i as u32, h.t));
            }
        }
    }
    best
}

/// The reference: binary ordered traversal, scalar Möller–Trumbore, lowest index wins ties.
#[inline]
fn binary_hit(bvh: &Bvh, tris: &[[Vec3; 3]], ray: &Ray) -> Option<(u32, f32)> {
    let mut r = *ray;
    let mut best: Option<(u32, f32)> = None;
    closest_hit(bvh, &mut r, |p, r| binary_test(tris, p, r, &mut best));
    best
}

#[inline(always)]
fn binary_test(tris: &[[Vec3; 3]], p: u32, r: &mut Ray, best: &mut Option<(u32, f32)>) -> bool {
    let [a, b, c] = tris[p as usize];
    match intersect_triangle(r, a, b, c) {
        Some(h) if h.t < r.tmax || best.is_none_or(|(bp, _)| p < bp) => {
            r.tmax = h.t;
            *best = Some((p, h.t));
            true
        }
        _ => false,
    }
}

#[inline]
fn wide_hit<const N: usize>(wide: &WideBvh<N>, packed: &PackedTriangles, ray: &Ray) -> Option<(u32, f32)>
where
    Lanes<N>: Width<N>,
{
    wide.closest_triangle(packed, ray).map(|(p, h)| (p, h.t))
}

/// Mrays/s of `trace` over `rays` on the current rayon pool, best of `repeats`.
fn throughput(rays: &[Ray], repeats: usize, trace: impl Fn(&Ray) -> bool + Sync) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..repeats {
        let start = Instant::now();
        let hits: usize = rays.par_chunks(256).map(|c| c.iter().filter(|r| trace(r)).count()).sum();
        std::hint::black_box(hits);
        best = best.min(start.elapsed().as_secs_f64());
    }
    rays.len() as f64 / best / 1e6
}

fn measure_scene(path: &Path, args: &BenchRaysArgs, progress: &ProgressBar) -> Result<(SceneInfo, Vec<Row>)> {
    let name = phr_bench::suite::scene_name(path);
    progress.set_message(format!("{name}: loading"));
    let scene = load_scene(path).with_context(|| format!("loading {}", path.display()))?;
    let view = scene.views.first().map(|(_, c)| c.clone()).unwrap_or_else(|| scene.framing_camera());
    let camera = Camera::new(&view, args.res, args.res);
    let mut geometry = Geometry::new(&scene);
    if !geometry.spheres.is_empty() {
        note(progress, format!("{name}: {} spheres are left out (triangles only)", geometry.spheres.len()));
    }
    let tris = geometry.triangles.clone();
    let boxes: Vec<Aabb> = geometry.boxes[..tris.len()].to_vec();

    progress.set_message(format!("{name}: building"));
    let report = args.builder.build_timed(&boxes);
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

    progress.set_message(format!("{name}: rays"));
    // The diffuse bounces come from the scene's own geometry (with its spheres, if any).
    geometry.build(|b| args.builder.build(b));
    let set = RaySet::new(&geometry, &camera, args.res);
    let bounds = boxes.iter().fold(Aabb::EMPTY, |b, x| b.union(*x));
    let shadow = shadow_rays(&set.diffuse, bounds);
    let batches = [set.primary, incoherent_rays(bounds, args.rays), set.diffuse, shadow];

    let dir = std::env::temp_dir().join(format!("phr-bench-rays-{}", std::process::id())).join(&name);
    let export = !args.no_embree && script().is_some();
    if export {
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        write_counted(
            &dir.join("triangles.bin"),
            tris.len(),
            tris.iter().flat_map(|t| t.iter().flat_map(|v| v.to_array())),
        )?;
    }

    let mut rows = Vec::new();
    for (kind, rays) in KINDS.iter().zip(&batches) {
        progress.set_message(format!("{name}: {kind} rays, checking hits"));
        let reference: Vec<Option<(u32, f32)>> = rays.par_iter().map(|r| binary_hit(&bvh, &tris, r)).collect();
        let check = |variant: &str, got: Vec<Option<(u32, f32)>>| -> Result<()> {
            // A difference is only allowed where the binary reference itself misses the
            // brute-force hit: a hit accepted by the triangle test's edge tolerance just
            // outside the triangle's box, which a merged leaf's larger box may contain.
            for i in (0..got.len()).filter(|&i| got[i] != reference[i]) {
                let brute = brute_force(&tris, &rays[i]);
                if got[i] != brute {
                    bail!(
                        "{name} {kind}: {variant} differs from the binary reference and from brute force, \
                         ray {:?}: {:?}, reference {:?}, brute force {:?}",
                        rays[i],
                        got[i],
                        reference[i],
                        brute
                    );
                }
                note(
                    progress,
                    format!(
                        "{name} {kind}: {variant} finds the brute-force hit {:?} that the binary reference misses \
                     ({:?}), ray {:?}",
                        brute, reference[i], rays[i]
                    ),
                );
            }
            Ok(())
        };
        check("wide4", rays.par_iter().map(|r| wide_hit(&wide4, &packed4, r)).collect())?;
        check("wide8", rays.par_iter().map(|r| wide_hit(&wide8, &packed8, r)).collect())?;
        let any = *kind == SHADOW;
        if any {
            check_occlusion(&name, rays, &reference, &tris, &bvh, &wide4, &packed4, &wide8, &packed8)?;
        }
        let hits = reference.iter().filter(|h| h.is_some()).count();
        if export {
            write_rays(&dir, kind, rays, &reference)?;
        }

        let mut row = Row {
            scene: name.clone(),
            triangles: tris.len(),
            kind: kind.to_string(),
            rays: rays.len(),
            hit_rate: hits as f64 / rays.len().max(1) as f64,
            ..Row::default()
        };
        for &threads in &args.threads {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
            progress.set_message(format!("{name}: {kind} rays, {threads} thread(s)"));
            let r = args.repeats;
            let (b, w4, w8) = pool.install(|| match any {
                true => (
                    throughput(rays, r, |ray| binary_occluded(&bvh, &tris, ray)),
                    throughput(rays, r, |ray| wide4.any_triangle(&packed4, ray)),
                    throughput(rays, r, |ray| wide8.any_triangle(&packed8, ray)),
                ),
                false => (
                    throughput(rays, r, |ray| binary_hit(&bvh, &tris, ray).is_some()),
                    throughput(rays, r, |ray| wide_hit(&wide4, &packed4, ray).is_some()),
                    throughput(rays, r, |ray| wide_hit(&wide8, &packed8, ray).is_some()),
                ),
            });
            for (v, m) in VARIANTS.iter().zip([b, w4, w8]) {
                row.mrays.insert((v.to_string(), threads), m);
            }
        }
        // Where the time goes (one thread).
        let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
        let traversal = one.install(|| {
            let n = rays.len().max(1) as f64;
            let (nodes, prims) = rays
                .par_iter()
                .map(|r| {
                    let mut s = phr_bvh::TraversalStats::default();
                    let mut ray = *r;
                    let mut best = None;
                    closest_hit_counted(&bvh, &mut ray, |p, r| binary_test(&tris, p, r, &mut best), &mut s);
                    (s.nodes as u64, s.prims as u64)
                })
                .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
            row.binary_nodes = nodes as f64 / n;
            row.binary_tris = prims as f64 / n;
            let w = rays
                .par_iter()
                .map(|r| {
                    let mut s = WideStats::default();
                    let mut ray = *r;
                    let mut best = None;
                    wide8.closest_hit_leaves_counted(
                        &mut ray,
                        |first, count, r| {
                            packed8.leaf_hits(first, count, r, |i, h, r| {
                                let p = wide8.prim_indices[i as usize];
                                if h.t < r.tmax || best.is_none_or(|bp| p < bp) {
                                    r.tmax = h.t;
                                    best = Some(p);
                                    true
                                } else {
                                    false
                                }
                            })
                        },
                        &mut s,
                    );
                    [s.nodes as u64, s.leaves as u64, s.prims as u64]
                })
                .reduce(|| [0; 3], |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2]]);
            row.wide_nodes = w[0] as f64 / n;
            row.wide_leaves = w[1] as f64 / n;
            row.wide_tris = w[2] as f64 / n;
            // Traversal only: tmax at the closest hit, leaves counted, not intersected.
            let clipped: Vec<Ray> =
                rays.iter().zip(&reference).map(|(r, h)| Ray { tmax: h.map_or(r.tmax, |(_, t)| t), ..*r }).collect();
            throughput(&clipped, args.repeats, |ray| {
                let mut r = *ray;
                let mut leaves = 0u32;
                wide8.closest_hit_leaves(&mut r, |_, count, _| {
                    leaves += count;
                    false
                });
                std::hint::black_box(leaves) > 0
            })
        });
        // The share needs the 1-thread full time; measure it if 1 was not among --threads.
        let full_1 = match row.mrays.get(&("wide8".to_string(), 1)) {
            Some(&m) => m,
            None if any => one.install(|| throughput(rays, args.repeats, |ray| wide8.any_triangle(&packed8, ray))),
            None => one.install(|| throughput(rays, args.repeats, |ray| wide_hit(&wide8, &packed8, ray).is_some())),
        };
        row.traversal_share = full_1 / traversal;
        rows.push(row);
    }

    let mut embree_build_ms = None;
    if export {
        progress.set_message(format!("{name}: Embree"));
        let threads: Vec<String> = args.threads.iter().map(|t| t.to_string()).collect();
        let output = Command::new("python3")
            .arg(script().expect("checked above"))
            .arg(&dir)
            .args(["--kinds", &KINDS.join(","), "--threads", &threads.join(","), "--repeats"])
            .arg(args.repeats.to_string())
            .output();
        match output {
            Ok(o) if o.status.success() => {
                let text = std::fs::read_to_string(dir.join("embree.json"))?;
                let kept = args.out.join("embree");
                std::fs::create_dir_all(&kept)?;
                std::fs::write(kept.join(format!("{name}.json")), &text)?;
                let json: serde_json::Value = serde_json::from_str(&text)?;
                embree_build_ms = json["build_ms"].as_f64();
                for row in &mut rows {
                    let k = &json["kinds"][&row.kind];
                    for &t in &args.threads {
                        if let Some(m) = k["mrays_per_s"][t.to_string()].as_f64() {
                            row.mrays.insert(("embree".to_string(), t), m);
                        }
                        if let Some(m) = k["robust_mrays_per_s"][t.to_string()].as_f64() {
                            row.mrays.insert(("embree-robust".to_string(), t), m);
                        }
                    }
                    row.embree_agreement = k["hit_agreement"].as_f64();
                }
            }
            Ok(o) => note(
                progress,
                format!(
                    "{name}: Embree skipped: {}{}",
                    String::from_utf8_lossy(&o.stdout).trim(),
                    String::from_utf8_lossy(&o.stderr).trim()
                ),
            ),
            Err(e) => note(progress, format!("{name}: Embree skipped, cannot run python3: {e}")),
        }
        let _ = std::fs::remove_dir_all(&dir);
    } else if !args.no_embree {
        note(progress, "Embree skipped: bench/embree_rays.py not found (run from the repository)".into());
    }
    let info = SceneInfo {
        scene: name,
        triangles: tris.len(),
        build_ms,
        collapse4_ms,
        collapse8_ms,
        embree_build_ms,
        simd: wide8.simd(),
        wide8_mb: (wide8.nodes.len() * std::mem::size_of::<phr_bvh::wide::WideNode<8>>()) as f64 / 1e6,
        packed8_mb: (packed8.blocks.len() * std::mem::size_of::<phr_bvh::wide::triangles::TriangleBlock>()) as f64
            / 1e6,
        block_fill: tris.len() as f64 / (packed8.blocks.len() * phr_bvh::wide::triangles::LANES).max(1) as f64,
    };
    Ok((info, rows))
}

/// A message above the progress bar (also when it is hidden, as in a pipe).
fn note(progress: &ProgressBar, message: String) {
    progress.suspend(|| eprintln!("{message}"));
}

fn write_rays(dir: &Path, kind: &str, rays: &[Ray], hits: &[Option<(u32, f32)>]) -> Result<()> {
    let floats = rays.iter().flat_map(|r| [r.origin.x, r.origin.y, r.origin.z, r.dir.x, r.dir.y, r.dir.z]);
    write_counted(&dir.join(format!("rays_{kind}.bin")), rays.len(), floats)?;
    write_counted(&dir.join(format!("tfar_{kind}.bin")), rays.len(), rays.iter().map(|r| r.tmax))?;
    let path = dir.join(format!("hits_{kind}.bin"));
    write_atomically(&path, |tmp| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        for h in hits {
            let (prim, t) = h.map_or((-1i32, f32::INFINITY), |(p, t)| (p as i32, t));
            f.write_all(&prim.to_le_bytes())?;
            f.write_all(&t.to_le_bytes())?;
        }
        f.flush()
    })
    .with_context(|| format!("writing {}", path.display()))
}

fn get(row: &Row, v: &str, t: usize) -> Option<f64> {
    row.mrays.get(&(v.to_string(), t)).copied()
}

fn fmt(x: Option<f64>) -> String {
    x.map_or("-".into(), |x| format!("{x:.2}"))
}

fn markdown(infos: &[SceneInfo], rows: &[Row], threads: &[usize], args: &BenchRaysArgs) -> String {
    let mut s = String::new();
    let command: Vec<String> = std::env::args().collect();
    s += &format!(
        "# phr bench-rays\n\nCommand: `{}` (release build).\n\nClosest-hit Mrays/s (best of {}), builder {}, primary rays {}², {} incoherent rays. \
         `binary`: scalar binary traversal (the reference); `wide4`/`wide8`: wide BVH, SIMD level `{}`; \
         Embree: embreex `rtcIntersect1` loop, T threads = T processes, default scene flags and \
         `robust=True` (conservative traversal, like ours). Ratio: best of wide4/wide8 over Embree. \
         `shadow`: rays from the diffuse rays' origins to uniform points of the scene box, interval (0, 1 − 10⁻⁴) \
         of the unnormalised direction, traced as any-hit queries (ours `any_triangle`, Embree \
         `rtcOccluded1`); their work-per-ray row counts the closest-hit query on the same rays.\n\n",
        command.join(" "),
        args.repeats,
        args.builder,
        args.res,
        args.rays,
        infos.first().map_or("-", |i| i.simd.name())
    );
    s += "| scene | triangles | build ms | collapse-4 ms | collapse-8 ms | Embree build ms | wide-8 nodes MB | triangles MB | block fill |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for i in infos {
        s += &format!(
            "| {} | {} | {:.1} | {:.1} | {:.1} | {} | {:.1} | {:.1} | {:.2} |\n",
            i.scene,
            i.triangles,
            i.build_ms,
            i.collapse4_ms,
            i.collapse8_ms,
            i.embree_build_ms.map_or("-".into(), |x| format!("{x:.1}")),
            i.wide8_mb,
            i.packed8_mb,
            i.block_fill
        );
    }
    for &t in threads {
        s += &format!(
            "\n## {t} thread(s)\n\n| scene | rays | binary | wide4 | wide8 | Embree | Embree robust | ours/Embree | ours/Embree robust | wide8/binary |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n"
        );
        for r in rows {
            let best = get(r, "wide4", t).unwrap_or(0.0).max(get(r, "wide8", t).unwrap_or(0.0));
            let ratio = get(r, "embree", t).map(|e| best / e);
            let ratio_robust = get(r, "embree-robust", t).map(|e| best / e);
            let speedup = get(r, "binary", t).map(|b| get(r, "wide8", t).unwrap_or(0.0) / b);
            s += &format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                r.scene,
                r.kind,
                fmt(get(r, "binary", t)),
                fmt(get(r, "wide4", t)),
                fmt(get(r, "wide8", t)),
                fmt(get(r, "embree", t)),
                fmt(get(r, "embree-robust", t)),
                fmt(ratio),
                fmt(ratio_robust),
                fmt(speedup)
            );
        }
    }
    s += "\n## Work per ray (1 thread)\n\nbinary: nodes visited, triangles tested; wide8: nodes, leaves, triangles; \
          traversal share: time of a wide-8 pass with `tmax` preset to the closest hit and leaves not intersected, \
          over the full wide-8 time.\n\n| scene | rays | hit rate | binary nodes | binary tris | wide8 nodes | wide8 leaves | wide8 tris | traversal share | Embree hit agreement |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for r in rows {
        s += &format!(
            "| {} | {} | {:.2} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.0}% | {} |\n",
            r.scene,
            r.kind,
            r.hit_rate,
            r.binary_nodes,
            r.binary_tris,
            r.wide_nodes,
            r.wide_leaves,
            r.wide_tris,
            100.0 * r.traversal_share,
            r.embree_agreement.map_or("-".into(), |a| format!("{:.4}", a))
        );
    }
    s
}

fn write_csv(path: &Path, rows: &[Row], threads: &[usize]) -> std::io::Result<()> {
    write_atomically(path, |tmp| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        writeln!(
            f,
            "scene,triangles,kind,rays,threads,variant,mrays_per_s,hit_rate,binary_nodes_per_ray,binary_tris_per_ray,wide8_nodes_per_ray,wide8_leaves_per_ray,wide8_tris_per_ray,wide8_traversal_share,embree_hit_agreement"
        )?;
        for r in rows {
            for &t in threads {
                for v in VARIANTS.iter().copied().chain(["embree", "embree-robust"]) {
                    let Some(m) = get(r, v, t) else { continue };
                    writeln!(
                        f,
                        "{},{},{},{},{},{},{:.4},{:.4},{:.2},{:.2},{:.2},{:.2},{:.2},{:.4},{}",
                        r.scene,
                        r.triangles,
                        r.kind,
                        r.rays,
                        t,
                        v,
                        m,
                        r.hit_rate,
                        r.binary_nodes,
                        r.binary_tris,
                        r.wide_nodes,
                        r.wide_leaves,
                        r.wide_tris,
                        r.traversal_share,
                        r.embree_agreement.map_or(String::new(), |a| format!("{a:.5}"))
                    )?;
                }
            }
        }
        f.flush()
    })
}
