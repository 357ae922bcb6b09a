//! `phr view --headless`: the viewer's frame loop without a window, on a fixed clock (`--dt`
//! seconds of animation per frame), writing the frames as PNG and one CSV row of timings
//! per frame, so runs can be scripted and compared.

use super::{memory_mib, ViewArgs};
use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use phr_render::output::{write_atomically, write_image};
use phr_render::pipeline::{FramePipeline, FrameReport};
use std::io::Write;
use std::path::Path;

pub fn run(args: &ViewArgs, mut pipeline: FramePipeline) -> Result<()> {
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let csv_path = args.out.join("frames.csv");
    let progress = ProgressBar::new(args.frames);
    progress.set_style(
        ProgressStyle::with_template("{spinner} {msg} [{bar:30}] {pos}/{len} frames, {per_sec}")
            .expect("template")
            .progress_chars("=> "),
    );
    let (width, height) = (pipeline.settings().width, pipeline.settings().height);
    let mut rows = Vec::with_capacity(args.frames as usize);
    for frame in 0..args.frames {
        let report = pipeline.step(args.dt);
        if args.png_every > 0 && frame % args.png_every == 0 {
            let path = args.out.join(format!("frame{frame:05}.png"));
            write_image(&path, width, height, &pipeline.image())
                .with_context(|| format!("writing {}", path.display()))?;
        }
        let (rss, peak) = memory_mib();
        progress.set_message(format!("{:.1} ms/frame, {rss:.0} MiB", report.frame_ms));
        progress.inc(1);
        rows.push((report, rss, peak));
    }
    progress.finish_and_clear();
    write_csv(&csv_path, &rows).with_context(|| format!("writing {}", csv_path.display()))?;
    print_summary(args, &pipeline, &rows);
    println!("wrote {}", csv_path.display());
    Ok(())
}

fn print_summary(args: &ViewArgs, pipeline: &FramePipeline, rows: &[(FrameReport, f64, f64)]) {
    // The first frame builds the auxiliary tree from scratch; the steady state is the rest.
    let steady: Vec<&FrameReport> = rows.iter().skip(1).map(|(r, _, _)| r).collect();
    let steady = if steady.is_empty() { rows.iter().map(|(r, _, _)| r).collect() } else { steady };
    let median = |f: fn(&FrameReport) -> f64| {
        let mut v: Vec<f64> = steady.iter().map(|r| f(r)).collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    let frame_ms = median(|r| r.frame_ms);
    println!(
        "{} frames of {} ({} triangles, {}x{}, 1 spp, {}): median pose {:.2} ms + refit {:.2} ms + build {:.2} ms + render {:.2} ms = frame {:.2} ms ({:.1} fps), {:.1} Mrays/s",
        rows.len(),
        args.scene,
        pipeline.geometry().triangles.len(),
        pipeline.settings().width,
        pipeline.settings().height,
        pipeline.settings().builder,
        median(|r| r.pose_ms),
        median(|r| r.refit_ms),
        median(|r| r.build_ms),
        median(|r| r.render_ms),
        frame_ms,
        1e3 / frame_ms.max(1e-9),
        median(FrameReport::mrays_per_s),
    );
    if let (Some(first), Some(last)) = (rows.get(99.min(rows.len() - 1)), rows.last()) {
        println!(
            "peak RSS: {:.1} MiB at frame {}, {:.1} MiB at frame {}",
            first.2,
            first.0.frame + 1,
            last.2,
            last.0.frame + 1
        );
    }
}

fn write_csv(path: &Path, rows: &[(FrameReport, f64, f64)]) -> std::io::Result<()> {
    write_atomically(path, |tmp| {
        let mut f = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        writeln!(
            f,
            "frame,time_s,moved,pose_ms,refit_ms,build_ms,render_ms,frame_ms,rays,mrays_per_s,sah_cost,build_cost,samples,rss_mib,peak_rss_mib"
        )?;
        for (r, rss, peak) in rows {
            writeln!(
                f,
                "{},{:.4},{},{:.3},{:.3},{:.3},{:.3},{:.3},{},{:.3},{:.4},{},{},{:.1},{:.1}",
                r.frame,
                r.time,
                r.moved as u8,
                r.pose_ms,
                r.refit_ms,
                r.build_ms,
                r.render_ms,
                r.frame_ms,
                r.rays,
                r.mrays_per_s(),
                r.sah_cost,
                r.build_cost,
                r.samples,
                rss,
                peak
            )?;
        }
        f.flush()
    })
}
