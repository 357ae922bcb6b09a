//! The viewer window under a virtual X server (Xvfb; Mesa's software OpenGL, or with
//! `--device gpu` the GPU's device, lavapipe in CI): it starts,
//! renders, and simulated input (xdotool: a mouse drag that orbits, the W key that flies)
//! changes what the window shows. Screenshots are the window's own framebuffer (F12).
//!
//! Needs `Xvfb` and `xdotool`, which a test cannot install, so it is ignored by the plain test
//! command and run on its own (`cargo test --release -p phr --test viewer_xvfb -- --ignored`,
//! as `.ci/run` does after installing them). Run so, it fails when they are missing: it never
//! passes without having looked at the window.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

struct Kill(Child);

impl Drop for Kill {
    fn drop(&mut self) {
        // SIGTERM first, so that Xvfb removes its lock file and socket (a killed server leaves
        // them behind, and a later run on the same display number would find a dead socket).
        let _ = Command::new("kill").arg(self.0.id().to_string()).status();
        for _ in 0..50 {
            if matches!(self.0.try_wait(), Ok(Some(_))) {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A display number with neither a lock file nor a socket (stale ones included), another for
/// each test of this process (they run in parallel).
fn free_display() -> u32 {
    static TAKEN: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
    let offset = 7 * TAKEN.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    (90 + std::process::id() % 100 + offset..600)
        .find(|n| {
            !Path::new(&format!("/tmp/.X{n}-lock")).exists() && !Path::new(&format!("/tmp/.X11-unix/X{n}")).exists()
        })
        .expect("a free X display number")
}

fn have(tool: &str) -> bool {
    Command::new("sh")
        .args(["-c", &format!("command -v {tool}")])
        .stdout(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

fn wait_for(what: &str, timeout: Duration, mut ready: impl FnMut() -> bool) {
    let start = Instant::now();
    while !ready() {
        assert!(start.elapsed() < timeout, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

fn xdotool(display: &str, args: &[&str]) -> String {
    let out = Command::new("xdotool").args(args).env("DISPLAY", display).output().expect("xdotool");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The rendered image's part of a window screenshot (right of the 280-pixel side panel), as
/// luminance values, and its width.
fn image_region(path: &Path) -> (usize, Vec<f32>) {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgb8();
    let (w, h) = img.dimensions();
    let mut out = Vec::new();
    for y in 0..h {
        for x in 300.min(w)..w {
            let p = img.get_pixel(x, y).0;
            out.push(0.2126 * p[0] as f32 + 0.7152 * p[1] as f32 + 0.0722 * p[2] as f32);
        }
    }
    ((w - 300.min(w)) as usize, out)
}

/// The means of the `size × size` blocks of an image of `width` columns (the partial blocks at
/// the right and bottom edges left out).
fn block_means(luminance: &[f32], width: usize, size: usize) -> Vec<f32> {
    let height = luminance.len() / width.max(1);
    let mut means = Vec::new();
    for by in 0..height / size {
        for bx in 0..width / size {
            let sum: f32 = (0..size)
                .flat_map(|y| (0..size).map(move |x| (by * size + y) * width + bx * size + x))
                .map(|i| luminance[i])
                .sum();
            means.push(sum / (size * size) as f32);
        }
    }
    means
}

fn mean_abs_diff(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum::<f32>() / a.len().max(1) as f32
}

fn std_dev(a: &[f32]) -> f32 {
    let mean = a.iter().sum::<f32>() / a.len() as f32;
    (a.iter().map(|x| (x - mean) * (x - mean)).sum::<f32>() / a.len() as f32).sqrt()
}

#[test]
#[ignore = "needs Xvfb and xdotool: run with --ignored (.ci/run does)"]
fn viewer_renders_and_follows_input_under_xvfb() {
    viewer_under_xvfb(&[]);
}

/// The same with the GPU tracing the frames (`--device gpu`; in CI, lavapipe:
/// `cargo test --release -p phr --features gpu --test viewer_xvfb -- --ignored gpu`).
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs Xvfb, xdotool and a GPU adapter (lavapipe): run with --ignored (.ci/run does)"]
fn the_gpu_viewer_renders_and_follows_input_under_xvfb() {
    viewer_under_xvfb(&["--device", "gpu"]);
}

/// The same without a denoiser, where the window draws the film the GPU keeps, from a texture
/// of the GPU's device, as bright as the render saved from that film.
#[cfg(feature = "gpu")]
#[test]
#[ignore = "needs Xvfb, xdotool and a GPU adapter (lavapipe): run with --ignored (.ci/run does)"]
fn the_gpu_viewer_shows_the_gpus_own_image_under_xvfb() {
    viewer_under_xvfb(&["--device", "gpu", "--denoiser", "none"]);
}

/// The mean luminance of the pixels of `path` right of `left` that are not black (in a
/// window screenshot, the image drawn on the black central panel).
fn lit_mean(path: &Path, left: u32) -> f32 {
    let img = image::open(path).unwrap_or_else(|e| panic!("{}: {e}", path.display())).to_rgb8();
    let lit: Vec<f32> = img
        .enumerate_pixels()
        .filter(|(x, _, p)| *x >= left && p.0.iter().any(|&c| c > 3))
        .map(|(_, _, p)| 0.2126 * p[0] as f32 + 0.7152 * p[1] as f32 + 0.0722 * p[2] as f32)
        .collect();
    lit.iter().sum::<f32>() / lit.len().max(1) as f32
}

/// Starts `phr view builtin` with `extra` arguments in a window of a virtual X server,
/// screenshots it twice while still and once after orbiting and flying.
fn viewer_under_xvfb(extra: &[&str]) {
    assert!(
        have("Xvfb") && have("xdotool"),
        "Xvfb and xdotool are not installed (apt-get install xvfb xdotool libgl1-mesa-dri; .ci/run does)"
    );
    let n = free_display();
    let display = format!(":{n}");
    let _xvfb = Kill(
        Command::new("Xvfb")
            // -noreset: by default the server resets when its last client leaves, and a
            // client connecting during the reset is refused (the viewer then fell back to
            // headless, about one run in five).
            .args([display.as_str(), "-screen", "0", "1280x1024x24", "-nolisten", "tcp", "-noreset"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start Xvfb"),
    );
    // Until it takes connections: its socket exists a moment before it listens, and a
    // loaded machine made the viewer try in that moment and fall back to headless.
    wait_for("Xvfb", Duration::from_secs(20), || {
        Path::new(&format!("/tmp/.X11-unix/X{n}")).exists()
            && Command::new("xdotool")
                .arg("getdisplaygeometry")
                .env("DISPLAY", &display)
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .status()
                .is_ok_and(|s| s.success())
    });

    let name = format!("phr-viewer-xvfb-{}{}", std::process::id(), extra.concat());
    let out: PathBuf = std::env::temp_dir().join(name);
    let _ = std::fs::remove_dir_all(&out);
    std::fs::create_dir_all(&out).expect("the output folder");
    let stderr = out.join("stderr.txt");
    let mut viewer = Kill(
        Command::new(env!("CARGO_BIN_EXE_phr"))
            .args(["view", "builtin", "--width", "128", "--height", "128"])
            .args(extra)
            .arg("--out")
            .arg(&out)
            .env("DISPLAY", &display)
            .env("LIBGL_ALWAYS_SOFTWARE", "1")
            .env_remove("WAYLAND_DISPLAY")
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&stderr).expect("the viewer's stderr file"))
            .spawn()
            .expect("start phr view"),
    );
    let mut window = String::new();
    wait_for("the viewer window", Duration::from_secs(60), || {
        if let Ok(Some(status)) = viewer.0.try_wait() {
            panic!("the viewer exited ({status}) before opening a window");
        }
        window = xdotool(&display, &["search", "--name", "^phr"]).lines().next().unwrap_or("").to_string();
        !window.is_empty()
    });
    // Let the window map and the worker start before giving it focus and keys.
    std::thread::sleep(Duration::from_secs(2));
    xdotool(&display, &["windowfocus", "--sync", &window]);
    let screenshot = |k: u32| {
        xdotool(&display, &["key", "F12"]);
        let path = out.join(format!("window-{k:03}.png"));
        wait_for(&format!("screenshot {k}"), Duration::from_secs(30), || path.is_file());
        path
    };
    // Let it accumulate, then two screenshots of the still view: their difference is noise.
    std::thread::sleep(Duration::from_secs(2));
    let (width, still_a) = image_region(&screenshot(0));
    std::thread::sleep(Duration::from_secs(1));
    let still_b_path = screenshot(1);
    let still_b = image_region(&still_b_path).1;
    assert!(std_dev(&still_a) > 10.0, "the image is blank (std dev {})", std_dev(&still_a));
    if extra.contains(&"none") {
        // The film as shown against the render saved from it (the same film a moment later):
        // alike in brightness (measured: 1.00). Drawn through an sRGB view, decoded once
        // more, it was about half as bright.
        xdotool(&display, &["key", "p"]);
        let saved = out.join("render-000.png");
        wait_for("the saved render", Duration::from_secs(30), || saved.is_file());
        std::thread::sleep(Duration::from_millis(200));
        let (shown, rendered) = (lit_mean(&still_b_path, 284), lit_mean(&saved, 0));
        println!("mean luminance: {shown} shown, {rendered} saved");
        assert!((0.85..1.25).contains(&(shown / rendered)), "shown {shown}, saved {rendered}");
    }

    // Orbit with a drag across the image, and fly forward with W.
    let geometry = xdotool(&display, &["getwindowgeometry", "--shell", &window]);
    let field = |name: &str| {
        geometry.lines().find_map(|l| l.strip_prefix(name)).and_then(|v| v.parse::<i32>().ok()).expect("geometry")
    };
    let (x, y, w, h) = (field("X="), field("Y="), field("WIDTH="), field("HEIGHT="));
    let (cx, cy) = (x + 300 + (w - 300) / 2, y + h / 2);
    let at = |dx: i32| format!("{}", cx + dx);
    let cy = format!("{cy}");
    xdotool(&display, &["mousemove", &at(-60), &cy, "mousedown", "1"]);
    for dx in [-30, 0, 30, 60, 90] {
        xdotool(&display, &["mousemove", &at(dx), &cy]);
        std::thread::sleep(Duration::from_millis(50));
    }
    xdotool(&display, &["mouseup", "1"]);
    xdotool(&display, &["keydown", "w"]);
    std::thread::sleep(Duration::from_millis(400));
    xdotool(&display, &["keyup", "w"]);
    std::thread::sleep(Duration::from_secs(2));
    let (moved_width, moved) = image_region(&screenshot(2));

    // Compared in 8×8-pixel blocks: a moved view moves whole edges and surfaces, while the
    // noise of a still one mostly averages out. Per pixel, on a slow device (lavapipe, 6
    // frames a second, where part of the input may fall between frames) the noise reached
    // 4.5 against changes of 10–13, under the 3× bar in one CI run of four; in blocks the
    // noise was at most 1.5 and the change 10–38 (twelve runs of the three tests).
    let lengths = [still_a.len(), still_b.len(), moved.len()];
    assert!(moved_width == width && lengths.iter().all(|&n| n == lengths[0]), "the window changed its size");
    let blocks = |luminance: &[f32]| block_means(luminance, width, 8);
    let noise = mean_abs_diff(&blocks(&still_a), &blocks(&still_b));
    let change = mean_abs_diff(&blocks(&still_b), &blocks(&moved));
    println!("change {change}, noise {noise}");
    assert!(std_dev(&moved) > 10.0, "the image went blank after input");
    assert!(change > 5.0 && change > 3.0 * noise, "input did not change the view: {change} vs noise {noise}");
    let said = std::fs::read_to_string(&stderr).unwrap_or_default();
    if extra.contains(&"gpu") {
        // The GPU traced the frames throughout (a failing device is dropped with a warning).
        assert!(said.contains("traced on the gpu") && !said.contains("failed"), "{said}");
        // Without a denoiser, the window draws the GPU's own image.
        assert_eq!(said.contains("shows the GPU's image"), extra.contains(&"none"), "{said}");
    }
    let _ = std::fs::remove_dir_all(&out);
}
