//! `phr bench-frame`: the files it promises (CSV, JSON, Markdown) agree with each other and
//! with what a frame is (at least one camera ray per pixel, at most six segments per path;
//! min ≤ median ≤ max), and a missing peer is reported as skipped, with the reason, without
//! failing the benchmark.

mod common;

use common::{phr_ok, phr_within, repo_path, Table, TempDir};
use std::time::Duration;

#[test]
fn frame_benchmark_writes_consistent_tables() {
    let dir = TempDir::new("bench-frame");
    let scene = repo_path("scenes/suite/bunny.json");
    let args = ["bench-frame", scene.to_str().unwrap(), "--resolutions", "32,48", "--frames", "3", "--warmup", "1"];
    let mut args = args.to_vec();
    args.extend(["--no-mitsuba", "--out", "out"]);
    let out = phr_ok(&dir.0, &args, Duration::from_secs(300));
    let csv = Table::read(&dir.join("out/frame.csv"));
    assert_eq!(csv.rows.len(), 2, "one row per resolution");
    for (row, res) in [32.0f64, 48.0].into_iter().enumerate() {
        assert_eq!(csv.str(row, "scene"), "bunny");
        assert_eq!(csv.num(row, "res"), res);
        assert_eq!(csv.num(row, "frames"), 3.0);
        let (min, median, max, mean) = (
            csv.num(row, "ours_ms_min"),
            csv.num(row, "ours_ms_median"),
            csv.num(row, "ours_ms_max"),
            csv.num(row, "ours_ms_mean"),
        );
        assert!(0.0 < min && min <= median && median <= max && min <= mean && mean <= max, "row {row}");
        let rays = csv.num(row, "rays_per_frame");
        assert!(rays >= res * res && rays <= 6.0 * res * res, "row {row}: {rays} rays");
        let mrays = csv.num(row, "mrays_per_s");
        // The CSV rounds ms and Mrays/s to 3 decimals; these frames take a fraction of a ms.
        let expected = rays / median / 1e3;
        assert!((mrays - expected).abs() <= 0.01 * expected + 0.002, "row {row}: {mrays} Mrays/s, not {expected}");
        assert_eq!(csv.opt(row, "mitsuba_warm_ms"), None, "Mitsuba was left out");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out/frame.json")).unwrap()).expect("frame.json parses");
    assert_eq!(json.as_array().map(Vec::len), Some(2));
    assert_eq!(json[1]["ours"]["frames"], 3);
    assert_eq!(json[1]["mitsuba"]["skipped"], "--no-mitsuba");
    let report = std::fs::read_to_string(dir.join("out/frame.md")).unwrap();
    assert!(report.contains("| bunny | 69451 | 48² |"), "{report}");
    assert!(report.contains("- bunny 32²: --no-mitsuba"), "{report}");
    assert_eq!(out.stdout.matches("| bunny |").count(), 2, "the table is printed too");
}

#[test]
fn a_peer_that_cannot_run_is_skipped_with_its_reason() {
    let dir = TempDir::new("bench-frame-peer");
    let scene = repo_path("scenes/suite/bunny.json");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_phr"))
        .args(["bench-frame", scene.to_str().unwrap(), "--resolutions", "16", "--frames", "1", "--out", "out"])
        .current_dir(&dir.0)
        .env("PYTHON", "/nonexistent/python3")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let csv = Table::read(&dir.join("out/frame.csv"));
    assert_eq!(csv.opt(0, "mitsuba_over_ours"), None);
    let report = std::fs::read_to_string(dir.join("out/frame.md")).unwrap();
    assert!(report.contains("| skipped | – |"), "{report}");
    // Either the script was found and Python could not start, or the script is missing.
    assert!(
        report.contains("cannot run /nonexistent/python3") || report.contains("render_reference.py not found"),
        "{report}"
    );
}

#[test]
fn zero_frames_is_an_error() {
    let dir = TempDir::new("bench-frame-zero");
    let out = phr_within(&dir.0, &["bench-frame", "--frames", "0", "--no-mitsuba"], Duration::from_secs(60));
    assert_ne!(out.code, Some(0));
    assert!(out.stderr.contains("at least one frame"), "{}", out.stderr);
}
