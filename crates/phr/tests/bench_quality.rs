//! `phr bench-quality`: every method gets a row per budget, the files agree, the ratios are
//! those of the RMSE column, light sampling beats the implicit estimator by far on a scene
//! lit by a small lamp (which a misaligned reference or a wrong image would not show), a
//! skipped peer gives its reason, and a scene without a reference is an error naming where
//! the reference was looked for.

mod common;

use common::{phr_ok, phr_within, repo_path, Table, TempDir};
use std::time::Duration;

fn cornell_obj() -> String {
    let scene = repo_path("../shared/reference/scenes/cornell_obj.json");
    assert!(scene.is_file(), "{} is missing: the shared references are needed", scene.display());
    scene.to_str().unwrap().to_string()
}

#[test]
fn each_method_is_scored_at_each_budget() {
    let dir = TempDir::new("bench-quality");
    let scene = cornell_obj();
    let args = ["--threads", "2", "bench-quality", &scene, "--seconds", "0.2,0.4", "--no-mitsuba", "--out", "out"];
    let out = phr_ok(&dir.0, &args, Duration::from_secs(300));
    let csv = Table::read(&dir.join("out/quality.csv"));
    // Path + OIDN too in builds with the feature.
    let mut methods = vec!["implicit", "path", "path-atrous", "mitsuba-path"];
    if csv.rows.len() == 10 {
        methods.insert(3, "path-oidn");
    }
    let m = methods.len();
    assert_eq!(csv.rows.len(), 2 * m, "each method at two budgets");
    for (row, (budget, method)) in [0.2, 0.4].iter().flat_map(|b| methods.iter().map(|m| (*b, *m))).enumerate() {
        assert_eq!(csv.str(row, "scene"), "cornell_obj");
        assert_eq!(csv.num(row, "budget_s"), budget);
        assert_eq!(csv.str(row, "method"), method);
        if method == "mitsuba-path" {
            assert_eq!(csv.opt(row, "rmse"), None);
            assert_eq!(csv.str(row, "skipped"), "--no-mitsuba");
            continue;
        }
        assert!(csv.num(row, "spp") >= 1.0 && csv.num(row, "ms") > 0.0, "row {row}");
        let ratio = csv.num(row, "rmse") / csv.num(row - row % m, "rmse");
        assert!((csv.num(row, "over_implicit") - ratio).abs() < 1e-4, "row {row}: {ratio}");
        assert!(dir.join(&format!("out/images/cornell_obj_{budget}s_{method}.png")).is_file(), "row {row}");
    }
    for implicit in [0, m] {
        // The lamp is 2 % of the ceiling: implicit paths rarely find it (RMSE 0.2–0.3 at
        // these budgets), light sampling does (0.04–0.07).
        let (rmse_implicit, rmse_path) = (csv.num(implicit, "rmse"), csv.num(implicit + 1, "rmse"));
        assert!(rmse_path < 0.5 * rmse_implicit, "path {rmse_path} against implicit {rmse_implicit}");
        assert!(csv.num(implicit + 2, "rmse") < 0.5 * rmse_implicit, "the denoised output");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("out/quality.json")).unwrap()).expect("parses");
    assert_eq!(json.as_array().map(Vec::len), Some(2 * m));
    assert_eq!(json[m - 1]["outcome"]["skipped"], "--no-mitsuba");
    let report = std::fs::read_to_string(dir.join("out/quality.md")).unwrap();
    assert!(report.contains("- cornell_obj at 0.2 s: --no-mitsuba"), "{report}");
    assert_eq!(out.stdout.matches("| cornell_obj |").count(), 2 * m, "the table is printed too");
}

#[test]
fn a_scene_without_a_reference_is_an_error() {
    let dir = TempDir::new("bench-quality-no-reference");
    let scene = repo_path("scenes/suite/bunny.json");
    let args = ["bench-quality", scene.to_str().unwrap(), "--seconds", "0.1", "--no-mitsuba", "--out", "out"];
    let out = phr_within(&dir.0, &args, Duration::from_secs(60));
    assert_ne!(out.code, Some(0));
    assert!(out.stderr.contains("no reference image at") && out.stderr.contains("images/bunny.exr"), "{}", out.stderr);
    assert!(!dir.join("out/quality.csv").exists(), "no partial report");
}

#[test]
fn budgets_must_be_positive() {
    let dir = TempDir::new("bench-quality-budget");
    for bad in ["0", "-1", "nan"] {
        let seconds = format!("--seconds={bad}");
        let out = phr_within(&dir.0, &["bench-quality", &seconds, "--no-mitsuba"], Duration::from_secs(60));
        assert_ne!(out.code, Some(0), "{bad}");
        assert!(out.stderr.contains("budgets must lie in"), "{bad}: {}", out.stderr);
    }
}

/// The image-quality issue's goal on cornell_obj at 16 spp: `phr render`'s default output
/// (light sampling with MIS, à-trous, the unfiltered edges sampled more) has at most 0.10
/// times the RMSE of the thesis's implicit estimator. Measured: 0.072–0.074 (seeds 0–2).
#[test]
fn the_default_output_at_16_spp_is_ten_times_closer_than_the_implicit_estimator() {
    use phr_bench::quality::{read_linear_image, rmse};
    let dir = TempDir::new("quality-16spp");
    let scene = cornell_obj();
    let (_, _, reference) =
        read_linear_image(&repo_path("../shared/reference/images/cornell_obj.exr")).expect("the reference");
    let render = |name: &str, extra: &[&str]| {
        let out = dir.join(&format!("{name}.exr"));
        let mut args =
            vec!["--threads", "2", "render", &scene, "--spp", "16", "--quiet", "--out", out.to_str().unwrap()];
        args.extend(extra);
        phr_ok(&dir.0, &args, Duration::from_secs(120));
        rmse(&read_linear_image(&out).unwrap().2, &reference)
    };
    let default = render("default", &[]);
    let implicit = render("implicit", &["--integrator", "implicit", "--denoiser", "none"]);
    assert!(default <= 0.10 * implicit, "RMSE {default} against the implicit estimator's {implicit}");
}
