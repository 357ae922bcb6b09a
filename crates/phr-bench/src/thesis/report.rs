//! The report files of `phr bench`: `results.csv`, `results.json`, `report.md`.

use super::measure::Results;
use super::{Materials, Plan};
use anyhow::{Context, Result};
use phr_render::output::write_atomically;
use std::fmt::Write as _;
use std::io::Write;
use std::path::Path;

/// Figures the thesis publishes for our setting (its Go code, 6-core desktop), by (scene,
/// builder): build time in ms, without the auxiliary LBVH for PHR. Only those the issues
/// quote; the thesis's bunny had 144k triangles (ours: 69k).
const THESIS_BUILD_MS: &[(&str, &str, f64)] =
    &[("bunny", "lbvh", 148.0), ("dragon", "lbvh", 874.0), ("dragon", "phr-fast", 143.0), ("dragon", "phr-hq", 1110.0)];

fn thesis_build(scene: &str, builder: &str) -> Option<f64> {
    THESIS_BUILD_MS.iter().find(|(s, b, _)| *s == scene && *b == builder).map(|t| t.2)
}

fn save(path: &Path, text: &str) -> Result<()> {
    write_atomically(path, |tmp| std::fs::File::create(tmp)?.write_all(text.as_bytes()))
        .with_context(|| format!("writing {}", path.display()))
}

pub fn write_all(out: &Path, plan: &Plan, results: &Results) -> Result<()> {
    save(&out.join("results.csv"), &csv(results))?;
    save(&out.join("results.json"), &json(results))?;
    save(&out.join("report.md"), &markdown(plan, results))?;
    Ok(())
}

fn csv(r: &Results) -> String {
    let mut s = String::from(
        "scene,triangles,res,builder,alpha,delta,aux_ms,aux_ms_min,aux_ms_max,build_ms,build_ms_min,build_ms_max,total_ms,total_ms_min,total_ms_max,sah_cost_2_1,sah_cost_1_1,build_cost,render_ms,mrays_per_s,collapse_ms,frame_ms,tune_ms,tune_frames\n",
    );
    for x in &r.rows {
        let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v:.3}"));
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{:.4},{:.4},{},{:.3},{:.3},{:.3},{:.3},{},{}",
            x.scene,
            x.triangles,
            x.res,
            x.builder,
            opt(x.params.map(|p| p.0)),
            opt(x.params.map(|p| p.1)),
            x.aux_ms.median,
            x.aux_ms.min,
            x.aux_ms.max,
            x.build_ms.median,
            x.build_ms.min,
            x.build_ms.max,
            x.total_ms.median,
            x.total_ms.min,
            x.total_ms.max,
            x.sah_21,
            x.sah_11,
            x.build_cost.map_or(String::new(), |c| c.to_string()),
            x.render_ms,
            x.mrays,
            x.collapse_ms,
            x.frame_ms,
            opt(x.tune_ms),
            opt(x.tune_frames)
        );
    }
    s
}

fn json(r: &Results) -> String {
    use serde_json::json;
    let stat = |s: &crate::Stat| json!({"median": s.median, "min": s.min, "max": s.max});
    let rows: Vec<_> = r
        .rows
        .iter()
        .map(|x| {
            json!({
                "scene": x.scene, "triangles": x.triangles, "res": x.res, "builder": x.builder,
                "alpha": x.params.map(|p| p.0), "delta": x.params.map(|p| p.1),
                "aux_ms": stat(&x.aux_ms), "build_ms": stat(&x.build_ms), "total_ms": stat(&x.total_ms),
                "sah_cost_2_1": x.sah_21, "sah_cost_1_1": x.sah_11, "build_cost": x.build_cost,
                "render_ms": x.render_ms, "mrays_per_s": x.mrays, "collapse_ms": x.collapse_ms, "frame_ms": x.frame_ms,
                "tune_ms": x.tune_ms, "tune_frames": x.tune_frames,
            })
        })
        .collect();
    let branching: Vec<_> = r
        .branching
        .iter()
        .map(|b| json!({"scene": b.scene, "k": b.k, "build_ms": b.build_ms, "sah_cost_2_1": b.sah_21, "render_ms": b.render_ms}))
        .collect();
    let cut: Vec<_> =
        r.cut.iter().map(|c| json!({"scene": c.scene, "build_cost": c.build_cost, "build_ms": c.build_ms})).collect();
    serde_json::to_string_pretty(&json!({"rows": rows, "branching": branching, "build_cost_study": cut}))
        .unwrap_or_default()
}

/// Frame time relative to the LBVH's for one scene, per builder, averaged over resolutions.
pub fn relative_frame_times_of(r: &Results, scene: &str) -> Vec<(String, f64)> {
    let rows = Results { rows: r.rows.iter().filter(|x| x.scene == scene).cloned().collect(), ..Default::default() };
    relative_frame_times(&rows)
}

/// Scene names in order of appearance.
pub fn scene_names(r: &Results) -> Vec<String> {
    let mut scenes: Vec<String> = Vec::new();
    for x in &r.rows {
        if !scenes.contains(&x.scene) {
            scenes.push(x.scene.clone());
        }
    }
    scenes
}

/// Frame time relative to the LBVH's, per builder, averaged over scenes and resolutions.
pub fn relative_frame_times(r: &Results) -> Vec<(String, f64)> {
    let mut builders: Vec<String> = Vec::new();
    for x in &r.rows {
        if !builders.contains(&x.builder) {
            builders.push(x.builder.clone());
        }
    }
    builders
        .into_iter()
        .filter_map(|b| {
            let ratios: Vec<f64> = r
                .rows
                .iter()
                .filter(|x| x.builder == b)
                .filter_map(|x| {
                    let lbvh = r.rows.iter().find(|y| y.builder == "lbvh" && y.scene == x.scene && y.res == x.res)?;
                    Some(x.frame_ms / lbvh.frame_ms)
                })
                .collect();
            (!ratios.is_empty()).then(|| (b, ratios.iter().sum::<f64>() / ratios.len() as f64))
        })
        .collect()
}

pub fn summary(r: &Results) -> String {
    let mut s = String::from("frame time relative to LBVH (mean over scenes and resolutions):\n");
    for (b, ratio) in relative_frame_times(r) {
        let _ = writeln!(s, "  {b:<12} {ratio:.3}");
    }
    s
}

fn markdown(plan: &Plan, r: &Results) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# phr bench report\n");
    let command: Vec<String> = std::env::args().skip(1).collect();
    let _ =
        writeln!(s, "Command: `phr {}` (regenerate with the same command; do not edit by hand).\n", command.join(" "));
    let _ = writeln!(
        s,
        "Made by `phr bench` ({} repeats; resolutions {:?}; builders {}). Machine: {} cores. Setting: {}, 1 spp, 60° \
         field of view, up to {} views per scene, render \
         times are the mean over the views of the median 1-spp frame; frame time = build + collapse to the renderer's \
         wide BVH (`collapse_ms` in the CSV) + render. Build times are medians; `[min–max]` is the spread. \
         PHR times are shown as auxiliary LBVH + PHR. SAH costs use traversal 2, intersection 1 (the thesis's). The \
         thesis column gives the thesis's published figure where one exists (Go, 6-core desktop; its bunny had 144k \
         triangles).\n",
        plan.repeats,
        plan.resolutions,
        plan.builders.join(", "),
        rayon::current_num_threads(),
        match plan.materials {
            Materials::Thesis => "the thesis's (white sky, every surface diffuse, up to 6 path segments)",
            Materials::Own => "the scene files' own materials, background and depth",
        },
        plan.max_views
    );
    let mut scenes: Vec<&str> = Vec::new();
    for x in &r.rows {
        if !scenes.contains(&x.scene.as_str()) {
            scenes.push(&x.scene);
        }
    }
    let _ = writeln!(s, "## Table 7.1: build, render and frame time\n");
    for scene in &scenes {
        let rows: Vec<_> = r.rows.iter().filter(|x| x.scene == *scene).collect();
        let _ = writeln!(s, "### {} ({} triangles)\n", scene, rows[0].triangles);
        let mut header = String::from("| builder | α, δ | build ms [min–max] | thesis build ms | SAH | Σ\\|cut\\| |");
        let mut rule = String::from("|---|---|---|---|---|---|");
        for res in &plan.resolutions {
            let _ = write!(header, " render {res}² ms | frame {res}² ms | Mrays/s {res}² |");
            rule.push_str("---|---|---|");
        }
        let _ = writeln!(s, "{header}\n{rule}");
        let mut builders: Vec<&str> = Vec::new();
        for x in &rows {
            if !builders.contains(&x.builder.as_str()) {
                builders.push(&x.builder);
            }
        }
        for b in builders {
            let first = rows.iter().find(|x| x.builder == b).expect("row");
            let params = first.params.map_or("".into(), |(a, d)| format!("{a:.3}, {d:.2}"));
            let build = if first.aux_ms.median > 0.0 {
                format!(
                    "{:.1} + {:.1} = {:.1} [{:.1}–{:.1}]",
                    first.aux_ms.median,
                    first.build_ms.median,
                    first.total_ms.median,
                    first.total_ms.min,
                    first.total_ms.max
                )
            } else {
                format!("{:.1} [{:.1}–{:.1}]", first.total_ms.median, first.total_ms.min, first.total_ms.max)
            };
            let thesis = thesis_build(scene, b).map_or("".into(), |t| format!("{t:.0}"));
            let cost = first.build_cost.map_or("".into(), |c| c.to_string());
            let _ = write!(s, "| {b} | {params} | {build} | {thesis} | {:.2} | {cost} |", first.sah_21);
            for res in &plan.resolutions {
                match rows.iter().find(|x| x.builder == b && x.res == *res) {
                    Some(x) => {
                        let _ = write!(s, " {:.1} | {:.1} | {:.2} |", x.render_ms, x.frame_ms, x.mrays);
                    }
                    None => s.push_str(" | | |"),
                }
            }
            s.push('\n');
        }
        s.push('\n');
    }
    let _ = writeln!(s, "## Frame time relative to LBVH (Figure 7.1)\n");
    let _ = writeln!(s, "Per scene (mean over the resolutions) and over all scenes; below 1 is faster than the LBVH. The thesis reported PHR-Grid and PHR-BO about 50 % and PHR-Fast about 33 % faster than its LBVH.\n");
    let all = relative_frame_times(r);
    let mut header = String::from("| builder |");
    let mut rule = String::from("|---|");
    for scene in scene_names(r) {
        let _ = write!(header, " {scene} |");
        rule.push_str("---|");
    }
    let _ = writeln!(s, "{header} all scenes |\n{rule}---|");
    for (b, ratio) in &all {
        let _ = write!(s, "| {b} |");
        for scene in scene_names(r) {
            let v = relative_frame_times_of(r, &scene).into_iter().find(|(x, _)| x == b).map(|x| x.1);
            let _ = write!(s, " {} |", v.map_or(String::new(), |v| format!("{v:.3}")));
        }
        let _ = writeln!(s, " {ratio:.3} |");
    }
    let _ = writeln!(s, "\n![frame time relative to LBVH](frame_time_vs_lbvh.svg)\n");
    let _ = writeln!(s, "## Tuning time in frames (Figure 7.2)\n");
    let _ = writeln!(s, "| scene | res | method | α, δ | tuning ms | frames |\n|---|---|---|---|---|---|");
    for x in r.rows.iter().filter(|x| x.tune_ms.is_some()) {
        let (a, d) = x.params.unwrap_or_default();
        let _ = writeln!(
            s,
            "| {} | {}² | {} | {a:.3}, {d:.2} | {:.0} | {:.1} |",
            x.scene,
            x.res,
            x.builder,
            x.tune_ms.unwrap_or_default(),
            x.tune_frames.unwrap_or_default()
        );
    }
    let _ = writeln!(s, "\n![tuning time in frames](tuning_frames.svg)\n");
    let _ = writeln!(s, "## Build time against Σ|cut| (Figure 6.1)\n");
    let _ = writeln!(s, "| scene | points | correlation |\n|---|---|---|");
    for scene in &scenes {
        let pts: Vec<_> = r.cut.iter().filter(|c| c.scene == *scene).collect();
        let xs: Vec<f64> = pts.iter().map(|c| c.build_cost).collect();
        let ys: Vec<f64> = pts.iter().map(|c| c.build_ms).collect();
        let _ = writeln!(s, "| {scene} | {} | {:.3} |", pts.len(), crate::stats::correlation(&xs, &ys));
    }
    let _ = writeln!(s, "\n![build time against build cost](build_time_vs_cut.svg)\n");
    let _ = writeln!(s, "## Branching factor (section 7.1): PHR-HQ, {}²\n", plan.resolutions[0]);
    let _ = writeln!(s, "| scene | k | build ms | SAH(2,1) | render ms |\n|---|---|---|---|---|");
    for b in &r.branching {
        let _ = writeln!(s, "| {} | {} | {:.1} | {:.2} | {:.1} |", b.scene, b.k, b.build_ms, b.sah_21, b.render_ms);
    }
    let _ = writeln!(s, "\n![branching factor](branching.svg)\n");
    if !r.peers.is_empty() {
        let _ = writeln!(s, "## Peers: Embree on the same triangles and rays (`--peers`)\n");
        let _ = writeln!(
            s,
            "One thread on both sides (embreex traces on one thread). Ours: PHR-HQ, build = LBVH + PHR. Embree: its default BVH, build = scene commit. Rays: the primary rays of the first view at {}² and one diffuse bounce from each hit.\n",
            plan.resolutions[0]
        );
        let _ = writeln!(s, "| scene | rays | build ms ours / Embree | primary Mrays/s ours / Embree | diffuse Mrays/s ours / Embree | hit agreement | 1-spp frame ours | Mitsuba 3 |\n|---|---|---|---|---|---|---|---|");
        for p in &r.peers {
            let _ = writeln!(
                s,
                "| {} | {} | {:.1} / {:.1} | {:.2} / {:.2} | {:.2} / {:.2} | {:.4} | {:.1} ms | {} |",
                p.scene,
                p.rays,
                p.ours_build_ms,
                p.embree_build_ms,
                p.ours_primary,
                p.embree_primary,
                p.ours_diffuse,
                p.embree_diffuse,
                p.hit_agreement,
                p.ours_frame_ms,
                p.mitsuba
            );
        }
        s.push('\n');
    }
    let _ = writeln!(s, "## Traversal steps per primary ray: LBVH (left) and PHR-HQ (right) (Figure 5.3)\n");
    for (scene, file) in &r.heatmaps {
        let _ = writeln!(s, "{scene}:\n\n![{scene} heatmaps]({file})\n");
    }
    s
}
