//! `phr view --headless`: the viewer's frame loop runs without a window, records per-frame
//! timings and writes frames; animated objects change the image, a paused scene accumulates.

use std::path::{Path, PathBuf};
use std::process::Command;

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/dynamic").join(name)
}

fn run_headless(out: &Path, extra: &[&str]) {
    let _ = std::fs::remove_dir_all(out);
    let output = Command::new(env!("CARGO_BIN_EXE_phr"))
        .args(["--threads", "2", "view", "--headless", "--frames", "100", "--width", "48", "--height", "48"])
        .arg(scene("carousel.json"))
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
}

fn pixels(path: &Path) -> Vec<f32> {
    image::open(path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .to_rgb8()
        .into_raw()
        .into_iter()
        .map(f32::from)
        .collect()
}

fn mean_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.len() as f32
}

struct Row {
    moved: bool,
    refit_ms: f64,
    build_ms: f64,
    render_ms: f64,
    frame_ms: f64,
    samples: u32,
}

fn rows(out: &Path) -> Vec<Row> {
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            Row {
                moved: f[col("moved")] == "1",
                refit_ms: f[col("refit_ms")].parse().unwrap(),
                build_ms: f[col("build_ms")].parse().unwrap(),
                render_ms: f[col("render_ms")].parse().unwrap(),
                frame_ms: f[col("frame_ms")].parse().unwrap(),
                samples: f[col("samples")].parse().unwrap(),
            }
        })
        .collect()
}

#[test]
fn animated_frames_are_timed_and_change() {
    let base = std::env::temp_dir().join(format!("phr-view-headless-{}", std::process::id()));
    let animated = base.join("animated");
    let paused = base.join("paused");
    // Normals mode: the image depends on geometry only, up to anti-aliasing noise at edges.
    run_headless(&animated, &["--mode", "normals"]);
    run_headless(&paused, &["--mode", "normals", "--paused"]);

    let moving = rows(&animated);
    assert_eq!(moving.len(), 100);
    for (i, r) in moving.iter().enumerate() {
        assert!(r.moved, "frame {i} did not move");
        assert!(r.refit_ms > 0.0 && r.build_ms > 0.0 && r.render_ms > 0.0, "frame {i} lacks timings");
        assert!(r.frame_ms >= r.refit_ms + r.build_ms + r.render_ms - 0.01, "frame {i}: stages exceed the frame");
        assert_eq!(r.samples, 1, "an animated frame restarts accumulation");
    }
    let still = rows(&paused);
    assert!(still.iter().skip(1).all(|r| !r.moved && r.build_ms == 0.0), "a paused scene keeps its tree");
    assert_eq!(still.last().unwrap().samples, 100, "a paused scene accumulates");
    assert!(animated.join("frame00099.png").is_file());

    let motion = mean_abs_diff(&pixels(&animated.join("frame00000.png")), &pixels(&animated.join("frame00050.png")));
    let noise = mean_abs_diff(&pixels(&paused.join("frame00000.png")), &pixels(&paused.join("frame00050.png")));
    assert!(motion > 8.0 && motion > 2.5 * noise, "moving objects change the image: {motion} vs noise {noise}");
    std::fs::remove_dir_all(&base).unwrap();
}

#[test]
fn no_display_falls_back_to_headless() {
    let out = std::env::temp_dir().join(format!("phr-view-nodisplay-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let output = Command::new(env!("CARGO_BIN_EXE_phr"))
        .args(["view", "--frames", "3", "--width", "16", "--height", "16", "--out"])
        .arg(&out)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    assert!(String::from_utf8_lossy(&output.stderr).contains("no display"));
    assert_eq!(rows(&out).len(), 3);
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn unusable_display_falls_back_to_headless() {
    let out = std::env::temp_dir().join(format!("phr-view-baddisplay-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let output = Command::new(env!("CARGO_BIN_EXE_phr"))
        .args(["view", "--frames", "2", "--width", "16", "--height", "16", "--out"])
        .arg(&out)
        .env("DISPLAY", ":64999")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(stderr.contains("cannot open a window"), "{stderr}");
    assert_eq!(rows(&out).len(), 2);
    std::fs::remove_dir_all(&out).unwrap();
}
