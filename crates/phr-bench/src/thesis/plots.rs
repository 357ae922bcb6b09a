//! The figures of `phr bench` as SVG (plotters): frame time relative to LBVH (thesis Figure
//! 7.1), tuning time in frames (7.2), build time against `Σ |cut|` (6.1), branching factor.

use super::measure::Results;
use super::report::relative_frame_times;
use anyhow::{Context, Result};
use plotters::prelude::*;
use std::path::Path;

const SIZE: (u32, u32) = (760, 420);
const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

pub fn write_all(out: &Path, r: &Results) -> Result<()> {
    bars(
        &out.join("frame_time_vs_lbvh.svg"),
        "Frame time relative to LBVH (lower is faster)",
        &relative_frame_times(r),
    )?;
    let tuning: Vec<(String, f64)> = r
        .rows
        .iter()
        .filter_map(|x| {
            Some((format!("{} {} {}", x.scene, x.res, x.builder.trim_start_matches("phr-")), x.tune_frames?))
        })
        .collect();
    bars(&out.join("tuning_frames.svg"), "Tuning time in frames of the tuned configuration", &tuning)?;
    scatter_cut(&out.join("build_time_vs_cut.svg"), r)?;
    branching(&out.join("branching.svg"), r)?;
    Ok(())
}

fn bars(path: &Path, title: &str, data: &[(String, f64)]) -> Result<()> {
    let size = (SIZE.0.max(24 * data.len() as u32 + 120), SIZE.1 + 60);
    let root = SVGBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE)?;
    let max = data.iter().map(|d| d.1).fold(0.0f64, f64::max).max(1e-9) * 1.15;
    let n = data.len().max(1);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(150)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..n as f64, 0.0..max)
        .context("plot axes")?;
    let labels: Vec<String> = data.iter().map(|d| d.0.clone()).collect();
    chart
        .configure_mesh()
        .disable_x_mesh()
        .x_labels(n)
        .x_label_formatter(&|x| labels.get(x.floor() as usize).cloned().unwrap_or_default())
        .x_label_style(("sans-serif", 11).into_font().transform(FontTransform::Rotate90))
        .draw()?;
    chart.draw_series(data.iter().enumerate().map(|(i, d)| {
        Rectangle::new([(i as f64 + 0.15, 0.0), (i as f64 + 0.85, d.1)], COLORS[i % COLORS.len()].filled())
    }))?;
    root.present().with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

fn scenes_of<'a>(names: impl Iterator<Item = &'a String>) -> Vec<String> {
    let mut out: Vec<String> = Vec::new();
    for n in names {
        if !out.contains(n) {
            out.push(n.clone());
        }
    }
    out
}

fn scatter_cut(path: &Path, r: &Results) -> Result<()> {
    let root = SVGBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let max_x = r.cut.iter().map(|c| c.build_cost).fold(0.0, f64::max).max(1.0) * 1.05;
    let max_y = r.cut.iter().map(|c| c.build_ms).fold(0.0, f64::max).max(1e-3) * 1.05;
    let mut chart = ChartBuilder::on(&root)
        .caption("PHR build time against build cost Σ|cut|", ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..max_x, 0.0..max_y)?;
    chart.configure_mesh().x_desc("Σ|cut|").y_desc("build ms").draw()?;
    for (i, scene) in scenes_of(r.cut.iter().map(|c| &c.scene)).into_iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        chart
            .draw_series(
                r.cut
                    .iter()
                    .filter(|c| c.scene == scene)
                    .map(|c| Circle::new((c.build_cost, c.build_ms), 4, color.filled())),
            )?
            .label(scene)
            .legend(move |(x, y)| Circle::new((x, y), 4, color.filled()));
    }
    chart.configure_series_labels().background_style(WHITE).border_style(BLACK).draw()?;
    root.present().with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

fn branching(path: &Path, r: &Results) -> Result<()> {
    let root = SVGBackend::new(path, SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    // Build + render time relative to k = 2, per scene.
    let relative = |scene: &str, k: u32| {
        let base = r.branching.iter().find(|b| b.scene == scene && b.k == 2)?;
        let this = r.branching.iter().find(|b| b.scene == scene && b.k == k)?;
        Some((this.build_ms + this.render_ms) / (base.build_ms + base.render_ms))
    };
    let max = r.branching.iter().filter_map(|b| relative(&b.scene, b.k)).fold(1.0f64, f64::max) * 1.1;
    let mut chart = ChartBuilder::on(&root)
        .caption("PHR-HQ: build + render time relative to binary (k = 2)", ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(1.5f64..16.5, 0.0..max)?;
    chart.configure_mesh().x_desc("branching factor k").draw()?;
    for (i, scene) in scenes_of(r.branching.iter().map(|b| &b.scene)).into_iter().enumerate() {
        let color = COLORS[i % COLORS.len()];
        let pts: Vec<(f64, f64)> = r
            .branching
            .iter()
            .filter(|b| b.scene == scene)
            .filter_map(|b| Some((b.k as f64, relative(&scene, b.k)?)))
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))?
            .label(scene)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], color.stroke_width(2)));
        chart.draw_series(pts.into_iter().map(|p| Circle::new(p, 3, color.filled())))?;
    }
    chart.configure_series_labels().background_style(WHITE).border_style(BLACK).draw()?;
    root.present().with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
