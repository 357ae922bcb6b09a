//! `phr bench-device`: its files (CSV, JSON, Markdown) agree with each other and with what a
//! frame is; without the GPU the GPU's columns are empty and the report says why. With the
//! cargo feature `gpu` and an adapter (`.ci/run`: lavapipe), both devices trace the same
//! paths: the GPU's rays per frame equal the CPU's, up to the few paths rounding sends
//! elsewhere.

mod common;

use common::{phr_ok, repo_path, Table, TempDir};
use std::time::Duration;

/// Runs the benchmark on the bunny at 32² and 48²; returns the CSV and the Markdown report.
fn bench(dir: &TempDir, extra: &[&str]) -> (Table, String) {
    let scene = repo_path("scenes/suite/bunny.json");
    let mut args = vec!["--threads", "2", "bench-device", scene.to_str().unwrap(), "--resolutions", "32,48"];
    args.extend(["--frames", "3", "--warmup", "1", "--out", "out"]);
    args.extend_from_slice(extra);
    let out = phr_ok(&dir.0, &args, Duration::from_secs(300));
    let csv = Table::read(&dir.join("out/device.csv"));
    assert_eq!(csv.rows.len(), 2, "one row per resolution");
    for (row, res) in [32.0f64, 48.0].into_iter().enumerate() {
        assert_eq!(csv.str(row, "scene"), "bunny");
        assert_eq!(csv.num(row, "res"), res);
        assert!(csv.num(row, "build_ms") > 0.0);
        let (min, median) = (csv.num(row, "cpu_ms_min"), csv.num(row, "cpu_ms_median"));
        assert!(0.0 < min && min <= median, "row {row}");
        let rays = csv.num(row, "cpu_rays_per_frame");
        assert!(rays >= res * res && rays <= 6.0 * res * res, "row {row}: {rays} rays");
    }
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(dir.join("out/device.json")).unwrap())
        .expect("device.json parses");
    assert_eq!(json.as_array().map(Vec::len), Some(2));
    let report = std::fs::read_to_string(dir.join("out/device.md")).unwrap();
    assert!(report.contains("| bunny | 69451 | 48² |"), "{report}");
    assert_eq!(out.stdout.matches("| bunny |").count(), 2, "the table is printed too");
    (csv, report)
}

#[test]
fn without_the_gpu_its_columns_are_empty_and_the_report_says_why() {
    let dir = TempDir::new("bench-device-cpu");
    let (csv, report) = bench(&dir, &["--no-gpu"]);
    for row in 0..2 {
        assert_eq!(csv.opt(row, "gpu_ms_median"), None);
        assert_eq!(csv.opt(row, "cpu_over_gpu"), None);
    }
    assert!(report.contains("The GPU was skipped: --no-gpu"), "{report}");
}

#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn both_devices_trace_the_same_paths() {
    let dir = TempDir::new("bench-device-gpu");
    let (csv, report) = bench(&dir, &[]);
    for row in 0..2 {
        let (cpu, gpu) = (csv.num(row, "cpu_rays_per_frame"), csv.num(row, "gpu_rays_per_frame"));
        assert!((gpu - cpu).abs() <= 0.005 * cpu, "row {row}: {gpu} rays per frame on the GPU, {cpu} on the CPU");
        assert!(csv.num(row, "upload_ms") > 0.0 && csv.num(row, "gpu_ms_median") > 0.0);
        let ratio = csv.num(row, "cpu_over_gpu");
        let expected = csv.num(row, "cpu_ms_median") / csv.num(row, "gpu_ms_median");
        assert!((ratio - expected).abs() <= 0.01 * expected + 0.002, "row {row}: {ratio}, not {expected}");
    }
    assert!(!report.contains("skipped"), "{report}");
}
