//! `phr view --headless`: the viewer's frame loop runs without a window, on a fixed clock, and
//! its frames.csv is right: time advances by exactly `--dt` per playing frame and stays put
//! when paused; rays match the image size; the SAH cost is finite, positive and follows the
//! motion; PHR's Σ|cut| is positive; the stages fit in the frame time; RSS and peak RSS are
//! sane. Animated objects change the image, a paused scene accumulates, and in the default
//! mode (colour, explicit light sampling) a moving light changes the lighting; all of it in
//! every pipeline (the thesis's one tree, the two-level layout, and the two-level layout with
//! asynchronous rebuilds).

mod common;

use common::{mean_abs_diff, phr, phr_ok, repo_path, Image, Table, TempDir};
use std::time::Duration;

/// Runs `phr --threads 2 view --headless --out OUT ARGS...` in `dir`.
fn run_headless(dir: &TempDir, out: &str, args: &[impl AsRef<str>]) -> Table {
    let mut all = vec!["--threads", "2", "view", "--headless", "--out", out];
    all.extend(args.iter().map(|a| a.as_ref()));
    phr_ok(&dir.0, &all, Duration::from_secs(300));
    Table::read(&dir.join(out).join("frames.csv"))
}

fn frame(dir: &TempDir, out: &str, i: usize) -> Vec<f32> {
    Image::png(&dir.join(out).join(format!("frame{i:05}.png"))).rgb
}

/// Checks that hold for every run: the clock, rays, SAH and build costs, stage times, memory.
/// `rays_per_pixel` bounds the rays of one frame, in units of width × height. `rebuilds`: a
/// tree is built with PHR every moving frame (the thesis pipeline, or a scene that deforms),
/// so its SAH cost and Σ|cut| are positive.
fn check_frames(csv: &Table, dt: f64, playing: bool, pixels: f64, rays_per_pixel: (f64, f64), rebuilds: bool) {
    for r in 0..csv.rows.len() {
        let n = |c: &str| csv.num(r, c);
        assert_eq!(n("frame"), r as f64);
        // The fixed clock: time advances before the frame is rendered.
        let time = if playing { (r + 1) as f64 * dt } else { 0.0 };
        assert!((n("time_s") - time).abs() < 2e-4, "frame {r}: time_s {} should be {time}", n("time_s"));
        if r > 0 && playing {
            let step = n("time_s") - csv.num(r - 1, "time_s");
            assert!((step - dt).abs() < 2e-4, "frame {r}: time advanced by {step}, not --dt {dt}");
        }
        let rays = n("rays");
        let (lo, hi) = (rays_per_pixel.0 * pixels, rays_per_pixel.1 * pixels);
        assert!(rays >= lo && rays <= hi, "frame {r}: {rays} rays, expected {lo} to {hi}");
        // Mrays/s from the rays and the render time, the latter rounded to 0.001 ms.
        let mrays = rays / n("render_ms") / 1e3;
        let tolerance = 1e-3 + mrays * 6e-4 / n("render_ms");
        assert!((n("mrays_per_s") - mrays).abs() <= tolerance, "frame {r}: Mrays/s {} vs {mrays}", n("mrays_per_s"));
        if rebuilds {
            assert!(n("sah_cost") > 0.0, "frame {r}: SAH cost {}", n("sah_cost"));
            // (Asynchronous rebuilds report the last landed tree's, none before the first.)
            assert!(n("build_cost") > 0.0 || n("tree_age") > 0.0, "frame {r}: PHR's Σ|cut| is {}", n("build_cost"));
        } else {
            // The frame in which the static builder's trees land packs their triangles.
            let static_builder = |r: usize| &csv.rows[r][csv.col("static_builder")];
            let landed = static_builder(r) != "-" && (r == 0 || static_builder(r - 1) == "-");
            assert!(
                n("refit_ms") == 0.0 && (n("wide_ms") == 0.0 || landed),
                "frame {r}: nothing deforms, nothing is refitted"
            );
        }
        let stages: f64 = ["pose_ms", "refit_ms", "build_ms", "wide_ms", "render_ms"].iter().map(|c| n(c)).sum();
        assert!(n("frame_ms") >= stages - 0.01, "frame {r}: stages {stages} ms exceed the frame {}", n("frame_ms"));
        let (rss, peak) = (n("rss_mib"), n("peak_rss_mib"));
        assert!(rss > 0.0 && peak >= rss, "frame {r}: RSS {rss} MiB, peak {peak} MiB");
    }
}

/// Carousel in normals mode at 48², `--dt 0.05`, and extra arguments.
fn carousel_args(extra: &[&str]) -> Vec<String> {
    let carousel = repo_path("scenes/dynamic/carousel.json").to_str().unwrap().to_string();
    let args = ["--frames", "100", "--width", "48", "--height", "48", "--dt", "0.05", "--mode", "normals"];
    args.iter().chain(extra).map(|s| s.to_string()).chain([carousel]).collect()
}

/// Distinct values of a column.
fn distinct(csv: &Table, column: &str) -> usize {
    let mut v = csv.nums(column);
    v.sort_by(f64::total_cmp);
    v.dedup();
    v.len()
}

#[test]
fn animated_frames_are_timed_and_change() {
    for pipeline in ["thesis", "two-level", "async"] {
        animated_frames_are_timed_and_change_in(pipeline);
    }
}

/// The carousel deforms (a waving floor, glTF node animation), so both pipelines rebuild a
/// tree with PHR every moving frame.
fn animated_frames_are_timed_and_change_in(pipeline: &str) {
    let dir = TempDir::new(&format!("view-headless-{pipeline}"));
    // Normals mode: the image depends on geometry only, up to anti-aliasing noise at edges,
    // and every pixel traces exactly one ray.
    let moving = run_headless(&dir, "animated", &carousel_args(&["--pipeline", pipeline]));
    let still = run_headless(&dir, "paused", &carousel_args(&["--pipeline", pipeline, "--paused"]));
    let pixels = 48.0 * 48.0;

    assert_eq!(moving.rows.len(), 100);
    check_frames(&moving, 0.05, true, pixels, (1.0, 1.0), true);
    let asynchronous = pipeline == "async";
    for r in 0..moving.rows.len() {
        let n = |c: &str| moving.num(r, c);
        assert_eq!(moving.str(r, "moved"), "1", "frame {r} did not move");
        // The asynchronous pipeline builds off the frame: the frame refits and packs.
        let built = asynchronous || n("build_ms") > 0.0;
        assert!(n("refit_ms") > 0.0 && built && n("render_ms") > 0.0, "frame {r} lacks timings");
        assert_eq!(n("samples"), 1.0, "an animated frame restarts accumulation");
        assert!(asynchronous || n("tree_age") == 0.0, "frame {r}: a tree built in the frame is of the frame");
    }
    if asynchronous {
        let ages = moving.nums("tree_age");
        assert!(ages[1..].iter().all(|&a| a >= 1.0), "later frames trace earlier trees: {ages:?}");
        assert!(moving.nums("build_cost").iter().any(|&c| c > 0.0), "no rebuilt tree landed");
    }
    assert!(distinct(&moving, "sah_cost") > 50, "the SAH cost follows the motion: {:?}", moving.nums("sah_cost"));

    check_frames(&still, 0.05, false, pixels, (1.0, 1.0), true);
    for r in 1..still.rows.len() {
        assert!(
            still.str(r, "moved") == "0" && still.num(r, "build_ms") == 0.0,
            "frame {r}: a paused scene keeps its tree"
        );
    }
    assert_eq!(still.num(99, "samples"), 100.0, "a paused scene accumulates");
    assert_eq!((distinct(&still, "sah_cost"), distinct(&still, "build_cost")), (1, 1), "a kept tree keeps its costs");

    let motion = mean_abs_diff(&frame(&dir, "animated", 0), &frame(&dir, "animated", 50));
    let noise = mean_abs_diff(&frame(&dir, "paused", 0), &frame(&dir, "paused", 50));
    assert!(motion > 8.0 && motion > 2.5 * noise, "moving objects change the image: {motion} vs noise {noise}");
    assert!(dir.join("animated/frame00099.png").is_file());
}

/// A floor lit by a small light (one-sided, facing down) that swings 1.5 units sideways with
/// a period of 2 s. The camera sits under the light looking down: it sees only the floor, so
/// the image changes only through the lighting. A ball swings high above, unlit and out of
/// sight: the scene is animated even if the light failed to move.
const SWINGING_LIGHT: &str = r#"{
  "max_depth": 2,
  "background": [0, 0, 0],
  "materials": {
    "floor": { "type": "lambertian", "albedo": 0.7 },
    "lamp": { "type": "emissive", "emit": 20 }
  },
  "camera": { "position": [0, 0.8, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "vfov": 90 },
  "objects": [
    { "type": "quad", "Q": [-3, 0, -3], "u": [0, 0, 6], "v": [6, 0, 0], "material": "floor" },
    { "type": "quad", "Q": [-0.2, 1, -0.2], "u": [0.4, 0, 0], "v": [0, 0, 0.4], "material": "lamp",
      "animate": { "type": "oscillate", "amplitude": [1.5, 0, 0], "period": 2 } },
    { "type": "sphere", "center": [0, 5, 0], "radius": 0.1, "material": "floor",
      "animate": { "type": "oscillate", "amplitude": [0, 0, 1], "period": 2 } }
  ]
}"#;

#[test]
fn moving_light_changes_the_lighting_in_the_default_mode() {
    for pipeline in ["thesis", "two-level", "async"] {
        moving_light_changes_the_lighting_in(pipeline);
    }
}

/// Everything here moves rigidly: the two-level pipeline moves the light and the ball by
/// their transforms and rebuilds nothing.
fn moving_light_changes_the_lighting_in(pipeline: &str) {
    let dir = TempDir::new(&format!("view-light-{pipeline}"));
    dir.write("light.json", SWINGING_LIGHT);
    // Default mode: colour with explicit light sampling. Frame 9 is at t = 0.5 s, a quarter period.
    let args =
        ["light.json", "--frames", "10", "--width", "32", "--height", "32", "--dt", "0.05", "--pipeline", pipeline];
    let moving = run_headless(&dir, "moving", &args);
    let still = run_headless(&dir, "paused", &[&args[..], &["--paused"]].concat());
    // Two segments per path (max_depth 2) and a shadow ray between them at most.
    let rebuilds = pipeline == "thesis";
    check_frames(&moving, 0.05, true, 32.0 * 32.0, (1.0, 3.0), rebuilds);
    check_frames(&still, 0.05, false, 32.0 * 32.0, (1.0, 3.0), rebuilds);

    let lit = |out: &str, i: usize| -> f32 {
        let f = frame(&dir, out, i);
        f.iter().sum::<f32>() / f.len() as f32
    };
    assert!(lit("paused", 0) > 20.0, "the floor under the light is lit: mean {}", lit("paused", 0));
    let motion = mean_abs_diff(&frame(&dir, "moving", 0), &frame(&dir, "moving", 9));
    // Paused frames 0 and 1 are 1 and 2 samples: their difference is half that of two 1-spp images.
    let noise = 2.0 * mean_abs_diff(&frame(&dir, "paused", 0), &frame(&dir, "paused", 1));
    assert!(motion > 5.0 && motion > 3.0 * noise, "the light moved: image change {motion}, 1-spp noise {noise}");
}

/// The peak RSS column is a peak: it never falls from one frame to the next.
/// (It fell before: the column was /proc's VmHWM as read each frame, which Linux lets fall.)
#[test]
fn peak_rss_never_falls() {
    let dir = TempDir::new("view-peak-rss");
    let csv = run_headless(&dir, "out", &carousel_args(&[]));
    let peaks = csv.nums("peak_rss_mib");
    for (r, pair) in peaks.windows(2).enumerate() {
        assert!(pair[1] >= pair[0], "frame {}: peak RSS fell from {} to {} MiB", r + 1, pair[0], pair[1]);
    }
}

fn expect_fallback(display: Option<&str>, frames: usize, message: &str) {
    let dir = TempDir::new(&format!("view-fallback-{frames}"));
    let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_phr"));
    command.args(["view", "--frames", &frames.to_string(), "--width", "16", "--height", "16", "--out", "out"]);
    command.current_dir(&dir.0).env_remove("WAYLAND_DISPLAY");
    match display {
        Some(d) => command.env("DISPLAY", d),
        None => command.env_remove("DISPLAY"),
    };
    let output = command.output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(stderr.contains(message), "{stderr}");
    assert_eq!(Table::read(&dir.join("out/frames.csv")).rows.len(), frames);
}

#[test]
fn no_display_falls_back_to_headless() {
    expect_fallback(None, 3, "no display");
}

#[test]
fn unusable_display_falls_back_to_headless() {
    expect_fallback(Some(":64999"), 2, "cannot open a window");
}

/// `--builder auto`: the moving frames try the LBVH, PHR-Fast, PHR-HQ and binned SAH in turn
/// (the CSV's `builder` column), then keep one of them, and the summary says which and why.
#[test]
fn the_auto_builder_tries_the_builders_then_keeps_one() {
    let dir = TempDir::new("view-auto");
    let scene = repo_path("scenes/dynamic/carousel.json");
    let args = [scene.to_str().unwrap(), "--builder", "auto", "--pipeline", "thesis", "--frames", "40"];
    let mut all = vec!["--threads", "2", "view", "--headless", "--out", "auto", "--png-every", "0", "--width", "48"];
    all.extend(["--height", "32"]);
    all.extend(args);
    let out = phr_ok(&dir.0, &all, Duration::from_secs(300));
    assert!(out.stdout.contains("auto: ") && out.stdout.contains("the fastest of"), "{}", out.stdout);
    let csv = Table::read(&dir.join("auto/frames.csv"));
    let builders: Vec<&str> = (0..csv.rows.len()).map(|r| csv.str(r, "builder")).collect();
    let mut distinct = builders.clone();
    distinct.dedup();
    // Four trials of 8 frames, then the choice for the rest.
    for (k, name) in ["phr-fast", "lbvh", "phr-hq", "binned-sah"].iter().enumerate() {
        assert!(builders[8 * k..8 * (k + 1)].iter().all(|b| b == name), "trial {k} is not {name}'s: {builders:?}");
    }
    assert!(distinct.len() >= 4, "{builders:?}");
    assert!(builders[32..].iter().all(|b| *b == builders[39]), "{builders:?}");
    assert!(out.stdout.contains(&format!("auto: {}", builders[39])), "{}", out.stdout);
}

/// `--static-builder`: the CSV names it from the frame its trees landed in on (never before
/// the first frame is out, never back); `none` keeps the builder's trees; a name that is no
/// builder is an error that says what is wrong.
#[test]
fn the_static_builder_is_reported_once_its_trees_landed() {
    let dir = TempDir::new("view-static-builder");
    // Nothing moves; its one tree is rebuilt in well under a millisecond, far less than the
    // 300 frames take.
    dir.write(
        "still.json",
        r#"{"camera": {"position": [0, 0.8, 0], "look_at": [0, 0, 0], "up": [0, 0, -1], "vfov": 90},
            "materials": {"floor": {"type": "lambertian", "albedo": 0.7}},
            "objects": [{"type": "quad", "Q": [-3, 0, -3], "u": [0, 0, 6], "v": [6, 0, 0], "material": "floor"},
                        {"type": "sphere", "center": [0, 0.2, 0], "radius": 0.1, "material": "floor"}]}"#,
    );
    let base = ["--threads", "2", "view", "still.json", "--headless", "--png-every", "0", "--width", "16"];
    let run = |out: &str, extra: &[&str]| {
        let args: Vec<&str> =
            base.iter().chain(&["--height", "16", "--out", out, "--frames", "300"]).chain(extra).copied().collect();
        phr_ok(&dir.0, &args, Duration::from_secs(300));
        let csv = Table::read(&dir.join(out).join("frames.csv"));
        (0..csv.rows.len()).map(|r| csv.str(r, "static_builder").to_string()).collect::<Vec<_>>()
    };
    let default = run("default", &[]);
    assert_eq!(default[0], "-", "the first frame traces the builder's trees");
    let first = default.iter().position(|b| b != "-").expect("the static builder's trees landed");
    assert!(default[first..].iter().all(|b| b == "sbvh"), "{default:?}");
    assert!(run("none", &["--static-builder", "none"]).iter().all(|b| b == "-"));
    let bad = phr(&dir.0, &[&base[..], &["--static-builder", "nonsense"]].concat());
    assert!(bad.code != Some(0) && bad.stderr.contains("--static-builder"), "{}", bad.stderr);
}
