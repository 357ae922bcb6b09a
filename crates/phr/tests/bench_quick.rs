//! `phr bench --quick` runs end to end and writes every output, and the outputs agree: no NaN
//! or infinity anywhere, each row's frame time is its build (auxiliary LBVH + PHR) + collapse +
//! render time, the JSON and every number of the Markdown report equal the CSV's (to their
//! rounding), and PHR-HQ's SAH cost beats the LBVH's. Also: the suite's scene files load.

mod common;

use common::{assert_no_nan_or_inf, phr_ok, repo_path, Table, TempDir};
use serde_json::Value;
use std::time::Duration;

/// `printed` is `expected` printed with `decimals` decimals, up to the CSV's own rounding (3
/// decimals) and float noise.
fn assert_rounds_to(what: &str, printed: f64, expected: f64, decimals: i32) {
    let tolerance = 0.5 * 10f64.powi(-decimals) + 6e-4;
    assert!((printed - expected).abs() <= tolerance, "{what}: printed {printed}, should be {expected}");
}

/// The numbers in a Markdown cell, e.g. `4.7 + 10.0 = 14.7 [14.7–14.7]` → 4.7, 10.0, 14.7, 14.7, 14.7.
fn numbers(cell: &str) -> Vec<f64> {
    cell.split(|c: char| !(c.is_ascii_digit() || c == '.'))
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().unwrap_or_else(|_| panic!("{s:?} in {cell:?}")))
        .collect()
}

fn number(cell: &str) -> f64 {
    match numbers(cell)[..] {
        [x] => x,
        _ => panic!("expected one number in {cell:?}"),
    }
}

/// The body rows (cells trimmed) of the first table after the line starting with `heading`.
fn markdown_table(report: &str, heading: &str) -> Vec<Vec<String>> {
    let mut lines = report.lines().skip_while(|l| !l.starts_with(heading));
    assert!(lines.next().is_some(), "report.md has no {heading:?}");
    let table: Vec<&str> = lines.skip_while(|l| !l.starts_with('|')).take_while(|l| l.starts_with('|')).collect();
    assert!(table.len() > 2, "{heading}: no table rows");
    table[2..].iter().map(|l| l.trim().trim_matches('|').split('|').map(|c| c.trim().to_string()).collect()).collect()
}

/// The Markdown row whose first cell is `key`.
fn row_for<'a>(rows: &'a [Vec<String>], key: &str, table: &str) -> &'a [String] {
    rows.iter().find(|r| r[0] == key).unwrap_or_else(|| panic!("{table}: no row {key}"))
}

fn csv_row(csv: &Table, builder: &str) -> usize {
    (0..csv.rows.len()).find(|&r| csv.str(r, "builder") == builder).unwrap_or_else(|| panic!("no CSV row {builder}"))
}

/// Every number parses and is finite; the optional ones are empty exactly where they should be.
fn check_csv_fields(csv: &Table) {
    let optional = ["alpha", "delta", "build_cost", "tune_ms", "tune_frames"];
    for r in 0..csv.rows.len() {
        let builder = csv.str(r, "builder").to_string();
        for column in csv.header.iter().filter(|c| !["scene", "builder"].contains(&c.as_str())) {
            if !optional.contains(&column.as_str()) {
                csv.num(r, column);
            }
        }
        let phr = builder != "lbvh";
        let tuned = builder == "phr-grid" || builder == "phr-bo";
        for (column, present) in
            [("alpha", phr), ("delta", phr), ("build_cost", phr), ("tune_ms", tuned), ("tune_frames", tuned)]
        {
            assert_eq!(csv.opt(r, column).is_some(), present, "{builder}: {column} = {:?}", csv.str(r, column));
        }
    }
}

/// frame = total + collapse + render, total = aux + build (medians of one repeat), and the
/// tuning time in frames is the tuning time over the frame time.
fn check_frame_times(csv: &Table) {
    for r in 0..csv.rows.len() {
        let n = |c: &str| csv.num(r, c);
        let b = csv.str(r, "builder");
        let stages = n("total_ms") + n("collapse_ms") + n("render_ms");
        assert!(
            (n("frame_ms") - stages).abs() <= 2e-3,
            "{b}: frame_ms {} ≠ total + collapse + render = {stages}",
            n("frame_ms")
        );
        let build = n("aux_ms") + n("build_ms");
        assert!((n("total_ms") - build).abs() <= 1.5e-3, "{b}: total_ms {} ≠ aux + build = {build}", n("total_ms"));
        for stage in ["total_ms", "collapse_ms", "render_ms"] {
            assert!(n(stage) > 0.0, "{b}: {stage} = {}", n(stage));
        }
        for stat in ["aux_ms", "build_ms", "total_ms"] {
            let (lo, mid, hi) = (n(&format!("{stat}_min")), n(stat), n(&format!("{stat}_max")));
            assert!(lo <= mid && mid <= hi, "{b}: {stat} median {mid} outside [{lo}, {hi}]");
        }
        if let (Some(ms), Some(frames)) = (csv.opt(r, "tune_ms"), csv.opt(r, "tune_frames")) {
            assert_rounds_to(&format!("{b} tune_frames"), frames, ms / n("frame_ms"), 3);
        }
    }
}

/// The JSON rows carry the CSV's values, unrounded; a number the CSV has is never null there.
fn check_json_matches_csv(csv: &Table, json: &Value) {
    let rows = json["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), csv.rows.len());
    for (r, row) in rows.iter().enumerate() {
        for column in &csv.header {
            let (key, stat) = match column.rsplit_once('_') {
                Some((k, s)) if ["min", "max"].contains(&s) => (k.to_string(), s),
                _ if row[column.as_str()].is_object() => (column.clone(), "median"),
                _ => (column.clone(), ""),
            };
            let value = if stat.is_empty() { &row[key.as_str()] } else { &row[key.as_str()][stat] };
            let what = format!("results.json row {r} {column} = {value}");
            match csv.str(r, column) {
                "" => assert!(value.is_null(), "{what}, the CSV's is empty"),
                text => match text.parse::<f64>() {
                    Ok(x) => assert_rounds_to(&what, value.as_f64().unwrap_or(f64::NAN), x, 3),
                    Err(_) => assert_eq!(value.as_str(), Some(text), "{what}"),
                },
            }
        }
    }
}

/// Table 7.1, the relative frame times and the tuning table show the CSV's numbers.
fn check_markdown_matches_csv(report: &str, csv: &Table) {
    let scene = csv.str(0, "scene");
    let res = csv.str(0, "res");
    let table = markdown_table(report, &format!("### {scene} ("));
    let lbvh_frame = csv.num(csv_row(csv, "lbvh"), "frame_ms");
    let relative = markdown_table(report, "## Frame time relative to LBVH");
    let tuning = markdown_table(report, "## Tuning time in frames");
    assert_eq!(table.len(), csv.rows.len(), "Table 7.1 has one row per builder");
    for r in 0..csv.rows.len() {
        let n = |c: &str| csv.num(r, c);
        let b = csv.str(r, "builder");
        let cells = row_for(&table, b, "Table 7.1");
        let check = |cell: &str, exact: f64, decimals: i32, what: &str| {
            assert_rounds_to(&format!("Table 7.1 {b} {what}"), number(cell), exact, decimals)
        };
        // builder | α, δ | build [min–max] | thesis | SAH | Σ|cut| | render | frame | Mrays/s
        if let (Some(a), Some(d)) = (csv.opt(r, "alpha"), csv.opt(r, "delta")) {
            let ad = numbers(&cells[1]);
            assert_rounds_to(&format!("{b} α"), ad[0], a, 3);
            assert_rounds_to(&format!("{b} δ"), ad[1], d, 2);
        }
        let mut build = vec![n("total_ms"), n("total_ms_min"), n("total_ms_max")];
        if n("aux_ms") > 0.0 {
            build.splice(0..0, [n("aux_ms"), n("build_ms")]);
        }
        let shown = numbers(&cells[2]);
        assert_eq!(shown.len(), build.len(), "{b}: build cell {:?}", cells[2]);
        for (s, x) in shown.iter().zip(&build) {
            assert_rounds_to(&format!("Table 7.1 {b} build {:?}", cells[2]), *s, *x, 1);
        }
        check(&cells[4], n("sah_cost_2_1"), 2, "SAH");
        assert_eq!(cells[5], csv.str(r, "build_cost"), "Table 7.1 {b} Σ|cut|");
        check(&cells[6], n("render_ms"), 1, "render ms");
        check(&cells[7], n("frame_ms"), 1, "frame ms");
        check(&cells[8], n("mrays_per_s"), 2, "Mrays/s");
        let ratio = n("frame_ms") / lbvh_frame;
        for cell in &row_for(&relative, b, "relative frame times")[1..] {
            assert_rounds_to(&format!("relative frame time of {b}"), number(cell), ratio, 3);
        }
        if let (Some(ms), Some(frames)) = (csv.opt(r, "tune_ms"), csv.opt(r, "tune_frames")) {
            let row = tuning.iter().find(|t| t[2] == b).unwrap_or_else(|| panic!("no tuning row for {b}"));
            assert_eq!((row[0].as_str(), row[1].as_str()), (scene, format!("{res}²").as_str()));
            assert_eq!(row[3], cells[1], "{b}: tuned α, δ");
            assert_rounds_to(&format!("{b} tuning ms"), number(&row[4]), ms, 0);
            assert_rounds_to(&format!("{b} tuning frames"), number(&row[5]), frames, 1);
        }
    }
    assert_eq!(tuning.len(), (0..csv.rows.len()).filter(|&r| csv.opt(r, "tune_ms").is_some()).count());
}

/// The branching and Σ|cut| tables show the JSON's numbers (the CSV does not have them).
fn check_markdown_matches_json(report: &str, json: &Value) {
    let branching = markdown_table(report, "## Branching factor");
    let rows = json["branching"].as_array().expect("branching");
    assert_eq!(branching.len(), rows.len());
    for (cells, row) in branching.iter().zip(rows) {
        let k = row["k"].as_u64().expect("k");
        assert_eq!((cells[0].as_str(), number(&cells[1])), (row["scene"].as_str().unwrap(), k as f64));
        for (cell, key, decimals) in
            [(&cells[2], "build_ms", 1), (&cells[3], "sah_cost_2_1", 2), (&cells[4], "render_ms", 1)]
        {
            let exact = row[key].as_f64().unwrap_or_else(|| panic!("branching k={k}: {key} = {}", row[key]));
            assert_rounds_to(&format!("branching k={k} {key}"), number(cell), exact, decimals);
        }
    }
    let study = json["build_cost_study"].as_array().expect("build_cost_study");
    let field = |key: &str| -> Vec<f64> { study.iter().map(|p| p[key].as_f64().expect(key)).collect() };
    let cut = markdown_table(report, "## Build time against");
    assert_eq!(number(&cut[0][1]) as usize, study.len(), "Σ|cut| study points");
    assert_rounds_to(
        "Σ|cut| correlation",
        number(&cut[0][2]),
        correlation(&field("build_cost"), &field("build_ms")),
        3,
    );
}

fn correlation(x: &[f64], y: &[f64]) -> f64 {
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (mx, my) = (mean(x), mean(y));
    let cov: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let var = |v: &[f64], m: f64| v.iter().map(|a| (a - m).powi(2)).sum::<f64>();
    cov / (var(x, mx) * var(y, my)).sqrt()
}

#[test]
fn quick_bench_writes_consistent_report_tables_and_plots() {
    let dir = TempDir::new("bench-quick");
    phr_ok(&dir.0, &["bench", "--quick", "--out", "out"], Duration::from_secs(300));
    let out = dir.join("out");
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
    let text = |name: &str| std::fs::read_to_string(out.join(name)).unwrap();
    let (report, csv_text, json_text) = (text("report.md"), text("results.csv"), text("results.json"));
    for (name, text) in [("report.md", &report), ("results.csv", &csv_text), ("results.json", &json_text)] {
        assert_no_nan_or_inf(name, text);
    }
    for builder in ["| lbvh |", "| phr-fast |", "| phr-hq |", "| phr-grid |", "| phr-bo |"] {
        assert!(report.contains(builder), "report lacks the {builder} row");
    }
    let csv = Table::parse("results.csv", &csv_text);
    assert_eq!(csv.rows.len(), 5, "one row per builder");
    let json: Value = serde_json::from_str(&json_text).unwrap();

    check_csv_fields(&csv);
    check_frame_times(&csv);
    check_json_matches_csv(&csv, &json);
    check_markdown_matches_csv(&report, &csv);
    check_markdown_matches_json(&report, &json);

    // The high-quality PHR tree is a better tree than the LBVH, by both SAH costs.
    let (hq, lbvh) = (csv_row(&csv, "phr-hq"), csv_row(&csv, "lbvh"));
    for sah in ["sah_cost_2_1", "sah_cost_1_1"] {
        let (a, b) = (csv.num(hq, sah), csv.num(lbvh, sah));
        assert!(a > 0.0 && a < b, "PHR-HQ's {sah} {a} should be below the LBVH's {b}");
    }
}

#[test]
fn suite_scenes_load_with_three_views() {
    let dir = repo_path("scenes/suite");
    for name in ["bunny", "sponza", "sibenik", "dragon", "conference", "dragons8"] {
        let scene = phr_render::scene::load_scene(&dir.join(format!("{name}.json"))).unwrap();
        assert_eq!(scene.views.len(), 3, "{name}");
        assert_eq!(scene.settings.max_depth, 6, "{name}: 5 bounces");
        assert!(scene.triangle_count() > 60_000, "{name}");
        if name == "dragons8" {
            assert_eq!(scene.triangle_count(), 8 * 871_414);
        }
    }
}
