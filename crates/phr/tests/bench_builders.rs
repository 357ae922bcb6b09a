//! The builder benchmarks end to end on the bunny: `phr bench-build`, `bench-cut-cost` and
//! `bench-tune` write their CSVs with one row per measured case, and the numbers mean what
//! their columns say (PHR builds report a `Σ |cut|`, the LBVH none; trees are traced; the
//! tuners pick points of the thesis's search box).

mod common;

use common::{phr_ok, repo_path, Table, TempDir};
use std::time::Duration;

fn shared_scenes() -> String {
    let dir = repo_path("../shared/scenes");
    assert!(dir.join("bunny/bun_zipper.ply").is_file(), "{} is missing: the shared scenes are needed", dir.display());
    dir.to_str().unwrap().to_string()
}

#[test]
fn bench_build_measures_every_builder_and_thread_count() {
    let dir = TempDir::new("bench-build");
    let scenes = shared_scenes();
    let args = ["bench-build", "--scenes", &scenes, "--only", "bunny", "--res", "48", "--repeats", "1"];
    let args = [&args[..], &["--threads", "1,2", "--builders", "lbvh,phr-fast,sweep-sah", "--csv", "b.csv"]].concat();
    let out = phr_ok(&dir.0, &args, Duration::from_secs(300));
    assert!(out.stdout.contains("diff Mr/s") && out.stdout.contains("wrote b.csv"), "{}", out.stdout);
    let csv = Table::read(&dir.join("b.csv"));
    // Native Embree is an optional peer: its rows, one per thread count, or a line saying why not.
    let embree: Vec<usize> = (0..csv.rows.len()).filter(|&r| csv.str(r, "builder").starts_with("embree ")).collect();
    if embree.is_empty() {
        assert!(out.stdout.contains("native Embree skipped: "), "{}", out.stdout);
    } else {
        assert_eq!(embree.len(), 2, "one Embree row per thread count");
        for &r in &embree {
            let ms = csv.num(r, "build_ms");
            assert!(ms > 0.0 && csv.num(r, "total_ms") == ms && csv.num(r, "renderable_ms") == ms);
            assert!(csv.opt(r, "sah_cost_1_1").is_none(), "Embree's tree is not ours to measure");
        }
    }
    let ours: Vec<usize> = (0..csv.rows.len()).filter(|r| !embree.contains(r)).collect();
    assert_eq!(ours.len(), 2 * 3, "thread counts × builders");
    for r in ours {
        assert_eq!(csv.str(r, "mesh"), "bunny/bun_zipper.ply");
        assert_eq!(csv.num(r, "triangles"), 69451.0);
        let builder = csv.str(r, "builder").to_string();
        assert_eq!(csv.opt(r, "build_cost").is_some(), builder.starts_with("phr"), "{builder}: Σ|cut| only for PHR");
        assert_eq!(csv.num(r, "aux_ms") > 0.0, builder.starts_with("phr"), "{builder}: an auxiliary LBVH only for PHR");
        let total = csv.num(r, "total_ms");
        assert!((total - csv.num(r, "aux_ms") - csv.num(r, "build_ms")).abs() < 0.01, "{builder}: total = aux + build");
        assert_eq!(csv.opt(r, "refit_ms").is_some(), builder.starts_with("phr"), "{builder}: a refit only for PHR");
        let direct = csv.opt(r, "direct_to_wide_ms");
        assert_eq!(direct.is_some(), builder.starts_with("phr"), "{builder}: a direct wide output only for PHR");
        assert!(direct.is_none_or(|ms| ms > 0.0), "{builder}: direct {direct:?}");
        let (wide, ready) = (csv.num(r, "wide_ms"), csv.num(r, "renderable_ms"));
        assert!(wide > 0.0 && (ready - total - wide).abs() < 0.01, "{builder}: renderable = total + wide");
        assert!(csv.num(r, "sah_cost_2_1") > csv.num(r, "sah_cost_1_1"), "{builder}: traversal counts twice");
        assert!(csv.num(r, "primary_mrays_per_s") > 0.0 && csv.num(r, "diffuse_mrays_per_s") > 0.0);
        assert!(csv.num(r, "diffuse_nodes_per_ray") >= 1.0);
    }
}

#[test]
fn bench_cut_cost_writes_every_grid_point_and_a_correlation() {
    let dir = TempDir::new("bench-cut-cost");
    let scenes = shared_scenes();
    let args = ["bench-cut-cost", "--scenes", &scenes, "--only", "bunny", "--alphas", "0.4,0.55"];
    let args = [&args[..], &["--deltas", "6,7,9", "--repeats", "1", "--csv", "c.csv"]].concat();
    let out = phr_ok(&dir.0, &args, Duration::from_secs(300));
    let line = out.stdout.lines().find(|l| l.starts_with("bunny/")).unwrap_or_else(|| panic!("{}", out.stdout));
    let correlation: f64 = line.split_whitespace().nth(2).unwrap().parse().unwrap();
    assert!((-1.0..=1.0).contains(&correlation), "{line}");
    let csv = Table::read(&dir.join("c.csv"));
    assert_eq!(csv.rows.len(), 2 * 3, "α × δ");
    // A larger δ cuts deeper: Σ|cut| grows with δ at a fixed α.
    for alpha in ["0.4", "0.55"] {
        let costs: Vec<f64> =
            (0..csv.rows.len()).filter(|&r| csv.str(r, "alpha") == alpha).map(|r| csv.num(r, "build_cost")).collect();
        assert!(costs.windows(2).all(|w| w[0] < w[1]), "α {alpha}: Σ|cut| over δ = 6, 7, 9: {costs:?}");
    }
}

#[test]
fn bench_tune_reports_gaps_and_frame_times_per_objective() {
    let dir = TempDir::new("bench-tune");
    let scenes = shared_scenes();
    let args = ["bench-tune", "--scenes", &scenes, "--only", "bunny", "--resolutions", "24", "--seeds", "2"];
    let args = [&args[..], &["--budget", "5", "--dense", "3", "--csv", "t.csv"]].concat();
    phr_ok(&dir.0, &args, Duration::from_secs(300));
    let csv = Table::read(&dir.join("t.csv"));
    assert_eq!(csv.rows.len(), 2, "one row per objective");
    assert_eq!([csv.str(0, "objective"), csv.str(1, "objective")], ["thesis", "frame-time"]);
    for r in 0..2 {
        assert!(csv.num(r, "max_gap_pct") >= csv.num(r, "median_gap_pct"));
        assert_eq!((csv.num(r, "bo_evals"), csv.num(r, "grid_evals")), (5.0, 9.0));
        for column in ["lbvh_ms", "fast_ms", "hq_ms", "grid_ms", "bo_thesis_ms", "bo_frametime_ms"] {
            assert!(csv.num(r, column) > 0.0, "{column}");
        }
        for (a, d) in [("grid_alpha", "grid_delta"), ("bo_alpha", "bo_delta"), ("bo_ft_alpha", "bo_ft_delta")] {
            let (alpha, delta) = (csv.num(r, a), csv.num(r, d));
            assert!((0.4..=0.55).contains(&alpha) && (6.0..=9.0).contains(&delta), "{a}: ({alpha}, {delta})");
        }
    }
}
