//! `phr bench-rays`' report: `bench-rays.md` (tables) and `bench-rays.csv`.

use crate::ray_bench::{RayBenchOptions, Row, SceneInfo, VARIANTS};
use phr_render::output::write_atomically;
use std::io::Write;
use std::path::Path;

/// One Markdown table row of `cells`.
fn table_row(cells: impl IntoIterator<Item = String>) -> String {
    format!("| {} |\n", cells.into_iter().collect::<Vec<_>>().join(" | "))
}

fn fmt(x: Option<f64>) -> String {
    x.map_or("-".into(), |x| format!("{x:.2}"))
}

/// The report: scene table, one throughput table per thread count, the work per ray.
pub fn markdown(infos: &[SceneInfo], rows: &[Row], options: &RayBenchOptions) -> String {
    let threads = &options.threads;
    let mut s = String::new();
    let command: Vec<String> = std::env::args().collect();
    s += &format!(
        "# phr bench-rays\n\nCommand: `{}` (release build).\n\nClosest-hit Mrays/s (best of {}), builder {}, primary rays {}², {} incoherent rays. \
         `binary`: scalar binary traversal (the reference); `wide4`/`wide8`: wide BVH, SIMD level `{}`, \
         one ray at a time; `wide8 ×2`/`×4`: 2 or 4 rays interleaved (each steps one node or leaf in turn), \
         chunks of 256 rays, as the renderer traces a tile; `wide8 packets`: packets of 16 consecutive rays \
         (primary rays: 16 × 1 strips of the image) through AVX-512 registers, closest hits only, lanes whose rays \
         part ways idling (`-`: shadow rays, or no AVX-512); \
         Embree: embreex `rtcIntersect1` loop, T threads = T processes, default scene flags and \
         `robust=True` (conservative traversal, like ours). Ratios: best of wide4/wide8 (ours), and \
         best of ×2/×4/packets (batched), over each Embree. \
         `shadow`: rays from the diffuse rays' origins to uniform points of the scene box, interval (0, 1 − 10⁻⁴) \
         of the unnormalised direction, traced as any-hit queries (ours `any_triangle`, Embree \
         `rtcOccluded1`); their work-per-ray row counts the closest-hit query on the same rays.\n\n",
        command.join(" "),
        options.repeats,
        options.builder,
        options.res,
        options.rays,
        infos.first().map_or("-", |i| i.simd.name())
    );
    s += "| scene | triangles | build ms | collapse-4 ms | collapse-8 ms | Embree build ms | wide-8 nodes MB | triangles MB | block fill |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for i in infos {
        s += &table_row([
            i.scene.clone(),
            i.triangles.to_string(),
            format!("{:.1}", i.build_ms),
            format!("{:.1}", i.collapse4_ms),
            format!("{:.1}", i.collapse8_ms),
            i.embree_build_ms.map_or("-".into(), |x| format!("{x:.1}")),
            format!("{:.1}", i.wide8_mb),
            format!("{:.1}", i.packed8_mb),
            format!("{:.2}", i.block_fill),
        ]);
    }
    for &t in threads {
        s += &format!(
            "\n## {t} thread(s)\n\n| scene | rays | binary | wide4 | wide8 | wide8 ×2 | wide8 ×4 | wide8 packets | Embree | Embree robust | ours/Embree | ours/Embree robust | batched/Embree | batched/Embree robust | wide8/binary |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n"
        );
        for r in rows {
            let best = r.get("wide4", t).unwrap_or(0.0).max(r.get("wide8", t).unwrap_or(0.0));
            let ratio = r.get("embree", t).map(|e| best / e);
            let ratio_robust = r.get("embree-robust", t).map(|e| best / e);
            let batched = ["wide8-x2", "wide8-x4", "wide8-packets"].iter().filter_map(|v| r.get(v, t)).reduce(f64::max);
            let batched_ratio = batched.zip(r.get("embree", t)).map(|(i, e)| i / e);
            let batched_robust = batched.zip(r.get("embree-robust", t)).map(|(i, e)| i / e);
            let speedup = r.get("binary", t).map(|b| r.get("wide8", t).unwrap_or(0.0) / b);
            let [b, w4, w8, x2, x4, p, e, er] =
                ["binary", "wide4", "wide8", "wide8-x2", "wide8-x4", "wide8-packets", "embree", "embree-robust"]
                    .map(|v| fmt(r.get(v, t)));
            s += &table_row([
                r.scene.clone(),
                r.kind.clone(),
                b,
                w4,
                w8,
                x2,
                x4,
                p,
                e,
                er,
                fmt(ratio),
                fmt(ratio_robust),
                fmt(batched_ratio),
                fmt(batched_robust),
                fmt(speedup),
            ]);
        }
    }
    s += "\n## Work per ray (1 thread)\n\nbinary: nodes visited, triangles tested; wide8: nodes, leaves, triangles; \
          traversal share: time of a wide-8 pass with `tmax` preset to the closest hit and leaves not intersected, \
          over the full wide-8 time.\n\n| scene | rays | hit rate | binary nodes | binary tris | wide8 nodes | wide8 leaves | wide8 tris | traversal share | Embree hit agreement |\n|---|---|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for r in rows {
        let per_ray =
            [r.binary_nodes, r.binary_tris, r.wide_nodes, r.wide_leaves, r.wide_tris].map(|x| format!("{x:.1}"));
        s += &table_row(
            [r.scene.clone(), r.kind.clone(), format!("{:.2}", r.hit_rate)].into_iter().chain(per_ray).chain([
                format!("{:.0}%", 100.0 * r.traversal_share),
                r.embree_agreement.map_or("-".into(), |a| format!("{a:.4}")),
            ]),
        );
    }
    s
}

/// One line per scene, kind, thread count and variant.
pub fn write_csv(path: &Path, rows: &[Row], threads: &[usize]) -> std::io::Result<()> {
    write_atomically(path, |tmp| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        writeln!(
            f,
            "scene,triangles,kind,rays,threads,variant,mrays_per_s,hit_rate,binary_nodes_per_ray,binary_tris_per_ray,wide8_nodes_per_ray,wide8_leaves_per_ray,wide8_tris_per_ray,wide8_traversal_share,embree_hit_agreement"
        )?;
        for r in rows {
            for &t in threads {
                for v in VARIANTS.iter().copied().chain(["embree", "embree-robust"]) {
                    let Some(m) = r.get(v, t) else { continue };
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
