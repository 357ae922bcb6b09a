//! `phr bench --quick` runs end to end and writes every output; the suite's scene files load.

use std::path::PathBuf;

#[test]
fn quick_bench_writes_report_tables_and_plots() {
    let out = std::env::temp_dir().join(format!("phr-bench-quick-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let status = std::process::Command::new(env!("CARGO_BIN_EXE_phr"))
        .args(["bench", "--quick", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    for file in [
        "report.md",
        "results.csv",
        "results.json",
        "frame_time_vs_lbvh.svg",
        "tuning_frames.svg",
        "build_time_vs_cut.svg",
        "branching.svg",
        "heatmap_bunny.png",
    ] {
        assert!(out.join(file).is_file(), "missing {file}");
    }
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    for builder in ["| lbvh |", "| phr-fast |", "| phr-hq |", "| phr-grid |", "| phr-bo |"] {
        assert!(report.contains(builder), "report lacks the {builder} row");
    }
    let csv = std::fs::read_to_string(out.join("results.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 5, "header + one row per builder");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    assert_eq!(json["rows"].as_array().unwrap().len(), 5);
    std::fs::remove_dir_all(&out).unwrap();
}

#[test]
fn suite_scenes_load_with_three_views() {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/suite"));
    for name in ["bunny", "sponza", "sibenik", "dragon", "conference", "dragons8"] {
        let scene = phr_render::scene::json::load_scene_file(&dir.join(format!("{name}.json"))).unwrap();
        assert_eq!(scene.views.len(), 3, "{name}");
        assert_eq!(scene.settings.max_depth, 6, "{name}: 5 bounces");
        assert!(scene.triangle_count() > 60_000, "{name}");
        if name == "dragons8" {
            assert_eq!(scene.triangle_count(), 8 * 871_414);
        }
    }
}
