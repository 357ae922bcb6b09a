//! `phr animate` on the built-in scene at a tiny size, for both motions: it writes the
//! frames.csv and the PNG frames it promises (one row and one image of the right size per
//! frame, nothing more), each row's frame time is the sum of its stage columns, PHR's costs
//! are positive and finite and the SAH cost follows the motion.

mod common;

use common::{files_in, phr_ok, Image, Table, TempDir};
use std::time::Duration;

const FRAMES: usize = 4;

fn check_animation(motion: &str) {
    let dir = TempDir::new(&format!("animate-{motion}"));
    let frames = FRAMES.to_string();
    let args = ["--threads", "2", "animate", "builtin", "--motion", motion, "--frames", &frames];
    let out = phr_ok(
        &dir.0,
        &[&args[..], &["--width", "32", "--height", "24", "--png", "--out", "anim"]].concat(),
        Duration::from_secs(120),
    );
    assert!(out.stdout.contains(&format!("{FRAMES} frames of builtin")), "{}", out.stdout);

    let expected: std::collections::BTreeSet<String> =
        (0..FRAMES).map(|i| format!("frame{i:05}.png")).chain(["frames.csv".to_string()]).collect();
    let anim = dir.join("anim");
    assert_eq!(files_in(&anim), expected, "{motion}: the files written");
    for i in 0..FRAMES {
        let png = Image::png(&anim.join(format!("frame{i:05}.png")));
        assert_eq!((png.width, png.height), (32, 24), "{motion}: frame {i} size");
        assert!(png.mean() > 1.0, "{motion}: frame {i} is black");
    }

    let csv = Table::read(&anim.join("frames.csv"));
    assert_eq!(csv.rows.len(), FRAMES, "{motion}: one row per frame");
    for r in 0..FRAMES {
        let n = |c: &str| csv.num(r, c);
        assert_eq!(n("frame"), r as f64);
        // The frame is the viewer's (FramePipeline's): its stages, plus the bookkeeping
        // between them (the tree's SAH cost, the film).
        let stages: f64 = ["pose_ms", "refit_ms", "build_ms", "wide_ms", "render_ms"].iter().map(|c| n(c)).sum();
        assert!(
            n("frame_ms") >= stages - 0.01,
            "{motion} frame {r}: the stages ({stages} ms) exceed the frame ({} ms)",
            n("frame_ms")
        );
        for column in ["build_ms", "render_ms", "build_cost", "sah_cost", "mrays_per_s"] {
            assert!(n(column) > 0.0, "{motion} frame {r}: {column} = {}", n(column));
        }
    }
    let sah = csv.nums("sah_cost");
    assert!(sah.windows(2).any(|p| p[0] != p[1]), "{motion}: the SAH cost does not follow the motion: {sah:?}");
}

#[test]
fn spin_writes_its_frames_and_timings() {
    check_animation("spin");
}

#[test]
fn wave_writes_its_frames_and_timings() {
    check_animation("wave");
}

/// A scene without animation of its own has nothing to show with `--motion scene`: a clear
/// error, not a film of a still scene.
#[test]
fn scene_motion_on_a_still_scene_is_an_error() {
    let dir = TempDir::new("animate-still");
    let out = common::phr(&dir.0, &["animate", "builtin", "--motion", "scene", "--frames", "2", "--out", "anim"]);
    assert!(out.code == Some(1) && out.stderr.contains("nothing moves"), "{}", out.stderr);
}
