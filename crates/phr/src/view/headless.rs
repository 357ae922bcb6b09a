//! `phr view --headless`: the viewer's frame loop without a window, on a fixed clock (`--dt`
//! seconds of animation per frame), writing the frames as PNG and one CSV row of timings
//! per frame, so runs can be scripted and compared. A GPU tracing the frames keeps the film,
//! as for the window, unless a PNG is written every frame: it is read back for the PNGs only.

use super::{memory_mib, ViewArgs};
use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use phr_render::output::{write_atomically, write_image};
use phr_render::pipeline::{FramePipeline, FrameReport};
use std::io::Write;

pub fn run(args: &ViewArgs, mut pipeline: FramePipeline) -> Result<()> {
    // Unless every frame is written: reading the whole film back (sums and squares) would
    // then cost twice what reading each frame does.
    pipeline.keep_film_on_device(args.png_every != 1);
    std::fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let csv_path = args.out.join("frames.csv");
    // Rows stream to a temporary file renamed into place at the end (no partial CSV on
    // failure), so a long soak holds no per-frame data beyond a few floats.
    write_atomically(&csv_path, |tmp| {
        let mut csv = std::io::BufWriter::new(std::fs::File::create(tmp)?);
        let summary = frames(args, &mut pipeline, &mut csv).map_err(std::io::Error::other)?;
        csv.flush()?;
        print_summary(args, &pipeline, &summary);
        Ok(())
    })
    .with_context(|| format!("writing {}", csv_path.display()))?;
    println!("wrote {}", csv_path.display());
    Ok(())
}

/// What the summary needs of each frame: pose, refit, build, wide, render, frame ms, Mrays/s,
/// upload ms.
type Times = [f32; 8];

struct Summary {
    times: Vec<Times>,
    peak_rss_at_100: f64,
    peak_rss_at_end: f64,
}

fn frames(args: &ViewArgs, pipeline: &mut FramePipeline, csv: &mut impl Write) -> Result<Summary> {
    let progress = ProgressBar::new(args.frames);
    progress.set_style(
        ProgressStyle::with_template("{spinner} {msg} [{bar:30}] {pos}/{len} frames, {per_sec}")
            .expect("template")
            .progress_chars("=> "),
    );
    let (width, height) = (pipeline.settings().width, pipeline.settings().height);
    writeln!(csv, "{},rss_mib,peak_rss_mib", FrameReport::CSV_HEADER)?;
    let mut summary =
        Summary { times: Vec::with_capacity(args.frames as usize), peak_rss_at_100: 0.0, peak_rss_at_end: 0.0 };
    for frame in 0..args.frames {
        let r = pipeline.step(args.dt);
        if frame == 0 && pipeline.film_on_device() {
            println!("phr view: the {} keeps the film; it is read back for the PNGs only", r.device);
        }
        if args.png_every > 0 && frame % args.png_every == 0 {
            let path = args.out.join(format!("frame{frame:05}.png"));
            if let Some(image) = pipeline.image_to_save() {
                write_image(&path, width, height, &image).with_context(|| format!("writing {}", path.display()))?;
            }
        }
        // The kernel's high-water mark (VmHWM) can fall between reads (seen: 17.6 -> 17.4
        // MiB), so the peak column is the running maximum of what was read.
        let (rss, hwm) = memory_mib();
        let peak = hwm.max(rss).max(summary.peak_rss_at_end);
        writeln!(csv, "{},{rss:.1},{peak:.1}", r.csv_row())?;
        summary.times.push(
            [r.pose_ms, r.refit_ms, r.build_ms, r.wide_ms, r.render_ms, r.frame_ms, r.mrays_per_s(), r.upload_ms]
                .map(|x| x as f32),
        );
        if frame < 100 {
            summary.peak_rss_at_100 = peak;
        }
        summary.peak_rss_at_end = peak;
        progress.set_message(format!("{:.1} ms/frame, {rss:.0} MiB", r.frame_ms));
        progress.inc(1);
    }
    progress.finish_and_clear();
    Ok(summary)
}

fn print_summary(args: &ViewArgs, pipeline: &FramePipeline, summary: &Summary) {
    // The first frame builds the auxiliary tree from scratch; the steady state is the rest.
    let steady = if summary.times.len() > 1 { &summary.times[1..] } else { &summary.times[..] };
    let median = |k: usize| {
        let mut v: Vec<f32> = steady.iter().map(|t| t[k]).collect();
        v.sort_by(f32::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    let frame_ms = median(5);
    println!(
        "{} frames of {} ({} triangles, {}x{}, 1 spp, {}): median pose {:.2} ms + refit {:.2} ms + build {:.2} ms + wide tree and packing {:.2} ms + render {:.2} ms = frame {:.2} ms ({:.1} fps), {:.1} Mrays/s",
        summary.times.len(),
        args.scene,
        pipeline.geometry().triangle_count(),
        pipeline.settings().width,
        pipeline.settings().height,
        pipeline.settings().builder,
        median(0),
        median(1),
        median(2),
        median(3),
        median(4),
        frame_ms,
        1e3 / frame_ms.max(1e-9),
        median(6),
    );
    if let Some(auto) = pipeline.auto() {
        println!("{}", auto.describe());
    }
    match pipeline.tracer() {
        Some(device) => {
            println!("colour frames traced on the {device}; median upload {:.2} ms (in the render time)", median(7))
        }
        None => println!("traced on the CPU"),
    }
    println!(
        "peak RSS: {:.1} MiB after {} frames, {:.1} MiB after {}",
        summary.peak_rss_at_100,
        summary.times.len().min(100),
        summary.peak_rss_at_end,
        summary.times.len()
    );
}
