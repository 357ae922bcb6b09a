//! `phr render --device gpu` and `phr animate --device gpu`: with the cargo feature `gpu` and
//! an adapter (`.ci/run` installs lavapipe and runs the ignored tests), the GPU renders the
//! built-in scene with the CPU's random numbers, so its linear mean equals the CPU's pixel by
//! pixel (but where rounding sent a path elsewhere), with either estimator, denoises with the
//! default filter, and animates a deforming mesh frame by frame; without the feature either
//! flag is an error that says how to get it, and what the GPU lacks (the CPU's traversal
//! heatmap) is refused either way, before any output is written.

mod common;

use common::{phr_within, TempDir};
use std::time::Duration;

#[test]
fn the_gpu_refuses_what_it_lacks_before_writing_anything() {
    let dir = TempDir::new("gpu-refuses");
    let args = ["render", "--device", "gpu", "--out", "x.png", "--heatmap", "h.png"];
    let out = phr_within(&dir.0, &args, Duration::from_secs(60));
    assert_ne!(out.code, Some(0));
    assert!(out.stderr.contains("render it with --device cpu"), "{}", out.stderr);
    assert!(!dir.join("x.png").exists() && !dir.join("h.png").exists(), "no output");
}

#[cfg(not(feature = "gpu"))]
#[test]
fn without_the_feature_the_gpu_is_an_error_that_says_how_to_get_it() {
    let dir = TempDir::new("gpu-missing");
    let args = ["render", "--device", "gpu", "--out", "x.png"];
    let out = phr_within(&dir.0, &args, Duration::from_secs(60));
    assert_ne!(out.code, Some(0));
    assert!(out.stderr.contains("--features gpu"), "{}", out.stderr);
    assert!(!dir.join("x.png").exists(), "no output");
    let args = ["animate", "--device", "gpu", "--frames", "2", "--out", "anim"];
    let out = phr_within(&dir.0, &args, Duration::from_secs(60));
    assert_ne!(out.code, Some(0));
    assert!(out.stderr.contains("--features gpu"), "{}", out.stderr);
    assert!(!dir.join("anim/frames.csv").exists(), "no output");
    let args = ["view", "--headless", "--device", "gpu", "--frames", "2", "--out", "view"];
    let out = phr_within(&dir.0, &args, Duration::from_secs(60));
    assert_ne!(out.code, Some(0));
    assert!(out.stderr.contains("--features gpu"), "{}", out.stderr);
    assert!(!dir.join("view/frames.csv").exists(), "no output");
}

/// `phr view --device gpu`, headless: the moving bunny of a scene file, with the viewer's
/// light sampling and denoiser, its colour frames traced on the GPU (the CSV's `device`), the
/// scene's moved parts' instances uploaded when it moves and nothing when it is paused, the
/// frames as PNGs.
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn the_viewer_traces_its_frames_on_the_gpu() {
    use common::Table;
    let dir = TempDir::new("gpu-view");
    let scene = common::repo_path("scenes/dynamic/bunny_in_sponza.json");
    for (out, paused) in [("moving", false), ("paused", true)] {
        let mut args = vec!["--threads", "2", "view", scene.to_str().unwrap(), "--headless", "--device", "gpu"];
        args.extend(["--frames", "3", "--width", "48", "--height", "32", "--out", out]);
        if paused {
            args.push("--paused");
        }
        let out_dir = dir.join(out);
        let out = phr_within(&dir.0, &args, Duration::from_secs(300));
        assert_eq!(out.code, Some(0), "{}", out.stderr);
        assert!(out.stdout.contains("colour frames traced on the gpu"), "{}", out.stdout);
        let csv = Table::read(&out_dir.join("frames.csv"));
        assert_eq!(csv.rows.len(), 3);
        for row in 0..3 {
            assert_eq!(csv.str(row, "device"), "gpu");
            assert!(csv.num(row, "rays") >= 48.0 * 32.0, "row {row}: {} rays", csv.num(row, "rays"));
            assert!(csv.num(row, "render_ms") >= csv.num(row, "upload_ms"));
            assert!(out_dir.join(format!("frame{row:05}.png")).is_file());
        }
        // The scene goes up once; then, each frame it moves, what moved: the turning bunny's
        // instance and the emitters, not Sponza's or the bunny's triangles.
        let uploads = (1..3).filter(|&row| csv.num(row, "upload_ms") > 0.0).count();
        assert_eq!(uploads, if paused { 0 } else { 2 }, "{out_dir:?}");
        assert!(csv.num(0, "upload_bytes") > 4e6, "{out_dir:?}: {} bytes", csv.num(0, "upload_bytes"));
        for row in 1..3 {
            let bytes = csv.num(row, "upload_bytes");
            assert!(bytes < 65536.0 && (bytes > 0.0) != paused, "{out_dir:?}, row {row}: {bytes} bytes");
        }
    }
}

/// Headless without a denoiser the GPU keeps the film, read back for the PNGs only: a still
/// view's PNGs are the CPU's (the same samples: 98 % of the 8-bit values within 2 of the
/// CPU's), and each frame's rays are the CPU's.
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn the_headless_viewer_reads_the_gpus_film_for_its_pngs_only() {
    use common::Table;
    let dir = TempDir::new("gpu-kept");
    for device in ["cpu", "gpu"] {
        let mut args = vec!["--threads", "2", "view", "builtin", "--headless", "--paused", "--denoiser", "none"];
        args.extend(["--frames", "4", "--png-every", "3", "--width", "48", "--height", "32"]);
        args.extend(["--device", device, "--out", device]);
        let out = phr_within(&dir.0, &args, Duration::from_secs(300));
        assert_eq!(out.code, Some(0), "{}", out.stderr);
        assert_eq!(out.stdout.contains("the gpu keeps the film"), device == "gpu", "{}", out.stdout);
    }
    let (cpu, gpu) = (Table::read(&dir.join("cpu/frames.csv")), Table::read(&dir.join("gpu/frames.csv")));
    for row in 0..4 {
        assert_eq!(gpu.str(row, "device"), "gpu");
        assert_eq!(gpu.num(row, "rays"), cpu.num(row, "rays"), "frame {row}");
    }
    for frame in [0, 3] {
        let png = |d: &str| image::open(dir.join(&format!("{d}/frame{frame:05}.png"))).unwrap().to_rgb8().into_raw();
        let (c, g) = (png("cpu"), png("gpu"));
        assert_eq!(c.len(), 48 * 32 * 3);
        let close = c.iter().zip(&g).filter(|(a, b)| a.abs_diff(**b) <= 2).count();
        assert!(close * 100 >= c.len() * 98, "frame {frame}: {close} of {} values within 2", c.len());
    }
    assert!(!dir.join("gpu/frame00001.png").exists(), "only every third frame is written");
}

/// `phr view --device gpu` on 1,000 turning copies of the bunny: the copies go up as one
/// bunny's tree and 1,000 instances (not 69M flattened triangles), and a moving frame writes
/// only the instances and the tree over them.
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn the_gpu_traces_copies_of_a_mesh_placed_many_times() {
    use common::Table;
    let dir = TempDir::new("gpu-copies");
    let scene = common::repo_path("scenes/instances/bunnies_1000_moving.json");
    let mut args = vec!["--threads", "2", "view", scene.to_str().unwrap(), "--headless", "--device", "gpu"];
    args.extend(["--frames", "3", "--width", "48", "--height", "32", "--png-every", "0", "--out", "copies"]);
    let out = phr_within(&dir.0, &args, Duration::from_secs(300));
    assert_eq!(out.code, Some(0), "{}", out.stderr);
    assert!(out.stdout.contains("colour frames traced on the gpu"), "{}", out.stdout);
    let csv = Table::read(&dir.join("copies/frames.csv"));
    assert_eq!(csv.str(0, "device"), "gpu");
    let whole = csv.num(0, "upload_bytes");
    // One bunny (69,451 triangles) with its tree, and the floor: not 69M triangles.
    assert!(whole > 2e6 && whole < 2e7, "{whole} bytes uploaded");
    for row in 1..3 {
        let bytes = csv.num(row, "upload_bytes");
        // 1,000 instances of 208 bytes and the tree over them.
        assert!(bytes > 208e3 && bytes < 1e6, "row {row}: {bytes} bytes");
    }
}

/// A wave through the bunny, then the bunny spinning, four frames each on the GPU with each
/// pipeline: every frame moved, uploaded and traced, each frame's image a PNG; every frame
/// traces at least its camera rays. Spinning with the two-level pipelines moves the bunny's
/// instance only: those frames write a few hundred bytes.
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn the_gpu_animates_with_every_pipeline() {
    use common::Table;
    let dir = TempDir::new("gpu-animate");
    for pipeline in ["thesis", "two-level", "async"] {
        for motion in ["wave", "spin"] {
            let mut args = vec!["--threads", "2", "animate", "bunny", "--motion", motion, "--frames", "4"];
            args.extend(["--device", "gpu", "--pipeline", pipeline]);
            let folder = format!("anim-{pipeline}-{motion}");
            args.extend(["--width", "40", "--height", "30", "--png", "--out", &folder]);
            let what = format!("{pipeline}, {motion}");
            let out = phr_within(&dir.0, &args, Duration::from_secs(300));
            assert_eq!(out.code, Some(0), "{what}: {}", out.stderr);
            assert!(
                out.stdout.contains("on the gpu (upload") && out.stdout.contains("4 frames of bunny"),
                "{}",
                out.stdout
            );
            let csv = Table::read(&dir.join(&folder).join("frames.csv"));
            assert_eq!(csv.rows.len(), 4);
            for row in 0..4 {
                assert_eq!(csv.str(row, "device"), "gpu", "{what}");
                for column in ["pose_ms", "refit_ms", "build_ms", "wide_ms", "upload_ms", "render_ms"] {
                    assert!(csv.num(row, column) >= 0.0, "{what}: {column}");
                }
                assert!(csv.num(row, "frame_ms") >= csv.num(row, "render_ms") + csv.num(row, "build_ms"));
                assert!(csv.num(row, "rays") >= 40.0 * 30.0, "{what}, row {row}: {} rays", csv.num(row, "rays"));
                assert!(dir.join(&folder).join(format!("frame{row:05}.png")).is_file());
                let bytes = csv.num(row, "upload_bytes");
                if row > 0 && motion == "spin" && pipeline != "thesis" {
                    assert!(bytes > 0.0 && bytes < 4096.0, "{what}, row {row}: {bytes} bytes");
                } else {
                    // The bunny's triangles and tree (69,451 triangles).
                    assert!(bytes > 3e6, "{what}, row {row}: {bytes} bytes");
                }
            }
        }
    }
}

#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn the_gpu_renders_the_cpu_s_samples() {
    use common::Image;
    let dir = TempDir::new("gpu-render");
    for integrator in ["implicit", "path"] {
        let render = |device: &str| {
            let mean = format!("{device}-{integrator}.pfm");
            let mut args =
                vec!["--threads", "2", "render", "builtin", "--quiet", "--device", device, "--out", "out.png"];
            args.extend(["--integrator", integrator, "--denoiser", "none"]);
            args.extend(["--width", "48", "--height", "32", "--spp", "4", "--seed", "5", "--linear", &mean]);
            let out = phr_within(&dir.0, &args, Duration::from_secs(300));
            assert_eq!(out.code, Some(0), "{}", out.stderr);
            (Image::pfm(&dir.join(&mean)), out.stdout)
        };
        let ((gpu, summary), (cpu, _)) = (render("gpu"), render("cpu"));
        assert!(summary.contains("GPU ") && summary.contains("Mrays/s"), "{summary}");
        assert_eq!((gpu.width, gpu.height), (48, 32));
        assert!(gpu.rgb.iter().all(|v| v.is_finite() && *v >= 0.0));
        let pixels: Vec<(&[f32], &[f32])> = cpu.rgb.chunks(3).zip(gpu.rgb.chunks(3)).collect();
        let lit: Vec<_> = pixels.iter().filter(|(c, g)| c.iter().chain(g.iter()).any(|&v| v > 0.0)).collect();
        let close = |a: f32, b: f32| (a - b).abs() <= 1e-3 * (1.0 + a.abs());
        let alike = lit.iter().filter(|(c, g)| c.iter().zip(g.iter()).all(|(a, b)| close(*a, *b))).count();
        println!("{integrator}: {alike} of {} lit pixels alike", lit.len());
        assert!(lit.len() > pixels.len() / 10, "{integrator}: {} lit pixels of {}", lit.len(), pixels.len());
        assert!(alike as f64 >= 0.95 * lit.len() as f64, "{integrator}: {alike} of {} lit pixels alike", lit.len());
    }
    // The defaults (light sampling, the à-trous filter): denoised, the guide traced on the CPU.
    let args = ["--threads", "2", "render", "builtin", "--quiet", "--device", "gpu", "--spp", "4", "--out", "d.png"];
    let out = phr_within(&dir.0, &args, Duration::from_secs(300));
    assert_eq!(out.code, Some(0), "{}", out.stderr);
    assert!(out.stdout.contains("denoised (à-trous") && out.stdout.contains("(on the CPU)"), "{}", out.stdout);
    assert_eq!((Image::png(&dir.join("d.png")).width, Image::png(&dir.join("d.png")).height), (512, 512));
}
