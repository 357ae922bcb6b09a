//! The `phr` binary on bad input: every failure is a non-zero exit with one `error:` line on
//! stderr naming the offending file (and line, for text formats), no panic, and no image (nor
//! a stray partial file) left behind. Plus the happy path on a tiny OBJ, for `render` and `info`.

mod common;

use common::{phr, TempDir};
use std::collections::BTreeSet;
use std::time::Duration;

/// A quad: 4 vertices, 2 triangles.
const QUAD_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n";

/// Runs `phr render SCENE --out out.png EXTRA...` in a folder holding only `inputs`, and checks
/// the failure contract. Returns the one error line.
fn expect_render_failure(test: &str, inputs: &[(&str, &[u8])], scene: &str, extra: &[&str]) -> String {
    let dir = TempDir::new(test);
    for (name, bytes) in inputs {
        dir.write(name, bytes);
    }
    let before = dir.files();
    let mut args = vec!["render", scene, "--out", "out.png"];
    args.extend_from_slice(extra);
    let out = phr(&dir.0, &args);
    let what = format!("{test}: phr {args:?}\nstdout:\n{}\nstderr:\n{}", out.stdout, out.stderr);
    assert!(out.code.is_some_and(|c| c != 0), "{what}\nexpected a non-zero exit code, got {:?}", out.code);
    assert!(!out.stderr.contains("panicked"), "{what}\npanicked");
    let errors: Vec<&str> = out.stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{what}\nexpected exactly one `error:` line");
    assert!(!out.stdout.contains("wrote"), "{what}\nclaims to have written something");
    // Nothing written: no image, no temporary `.out.png.*.partial.png`, nothing else.
    assert_eq!(dir.files(), before, "{what}\nfiles left in the folder");
    errors[0].to_string()
}

fn assert_names(line: &str, needles: &[&str]) {
    for n in needles {
        assert!(line.contains(n), "error line {line:?} should contain {n:?}");
    }
}

/// A binary little-endian PLY of a quad: 4 float vertices, 2 triangle faces.
fn binary_ply() -> Vec<u8> {
    let mut bytes = b"ply\nformat binary_little_endian 1.0\ncomment made by cli_errors.rs\nelement vertex 4\n\
        property float x\nproperty float y\nproperty float z\nelement face 2\n\
        property list uchar int vertex_indices\nend_header\n"
        .to_vec();
    for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]] {
        for c in p {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    for face in [[0i32, 1, 2], [0, 2, 3]] {
        bytes.push(3);
        for i in face {
            bytes.extend_from_slice(&i.to_le_bytes());
        }
    }
    bytes
}

#[test]
fn missing_scene_file() {
    let line = expect_render_failure("missing", &[], "missing.obj", &[]);
    assert_names(&line, &["missing.obj"]);
}

#[test]
fn truncated_binary_ply() {
    let full = binary_ply();
    // The intact file renders: the failure below is the truncation, not the writer of this test.
    {
        let dir = TempDir::new("ply-intact");
        dir.write("quad.ply", &full);
        let out = phr(
            &dir.0,
            &["render", "quad.ply", "--out", "out.png", "--width", "8", "--height", "8", "--spp", "1", "--quiet"],
        );
        assert_eq!(out.code, Some(0), "intact PLY: {}", out.stderr);
        assert!(out.stdout.contains("2 triangles"), "{}", out.stdout);
    }
    // Cut inside the second face, and inside the vertices.
    for (test, cut) in [("ply-cut-faces", full.len() - 7), ("ply-cut-vertices", full.len() - 2 * 13 - 20)] {
        let line = expect_render_failure(test, &[("quad.ply", &full[..cut])], "quad.ply", &[]);
        assert_names(&line, &["quad.ply"]);
        assert!(line.contains("ends") || line.contains("truncated"), "{line}");
    }
}

#[test]
fn obj_face_index_out_of_range() {
    let obj = "# a triangle\nv 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 3\nf 1 2 9\n";
    let line = expect_render_failure("obj-range", &[("bad.obj", obj.as_bytes())], "bad.obj", &[]);
    assert_names(&line, &["bad.obj:6:", "out of range"]);
}

#[test]
fn obj_nan_coordinate() {
    let obj = "v 0 0 0\nv 1 0 0\nv nan 0 0\nf 1 2 3\n";
    let line = expect_render_failure("obj-nan", &[("nan.obj", obj.as_bytes())], "nan.obj", &[]);
    assert_names(&line, &["nan.obj:3:", "not finite"]);
}

#[test]
fn obj_without_faces() {
    let obj = "v 0 0 0\nv 1 0 0\nv 1 1 0\n";
    let line = expect_render_failure("obj-empty", &[("empty.obj", obj.as_bytes())], "empty.obj", &[]);
    assert_names(&line, &["empty.obj", "no triangles"]);
}

/// A 60×60 grid of valid triangles spanning `extent` units: big enough for a real tree.
fn grid_obj(extent: f64) -> String {
    let n = 60;
    let mut obj = String::new();
    for i in 0..n {
        for j in 0..n {
            let (x, y) = (i as f64 * extent / n as f64, j as f64 * extent / n as f64);
            obj += &format!("v {x:e} {y:e} {:e}\n", 0.1 * extent * (0.3 * i as f64 + 0.2 * j as f64).sin());
        }
    }
    for i in 0..n - 1 {
        for j in 0..n - 1 {
            let a = i * n + j + 1;
            obj += &format!("f {a} {} {}\nf {} {} {}\n", a + 1, a + n, a + 1, a + n + 1, a + n);
        }
    }
    obj
}

/// Meshes far beyond f32's comfortable range used to crash the wide traversal (the framing
/// camera's squared extent overflowed, its rays were infinite): now one clear error.
#[test]
fn coordinates_beyond_float_range_are_an_error() {
    for (test, extent) in [("far-1e19", 1e19), ("far-1e30", 1e30), ("far-1e37", 1e37)] {
        let obj = grid_obj(extent);
        let line = expect_render_failure(test, &[("far.obj", obj.as_bytes())], "far.obj", &["--spp", "1"]);
        assert_names(&line, &["far.obj", "coordinates beyond"]);
    }
    // A scene file's camera far out, and a transform that scales a valid mesh out of range.
    let near = grid_obj(10.0);
    let camera = r#"{ "camera": { "position": [0, 0, 1e38], "look_at": [0, 0, 0], "up": [0, 1, 0], "vfov": 40 },
  "materials": { "white": { "type": "lambertian", "albedo": 0.7 } },
  "objects": [ { "type": "mesh", "file": "near.obj", "material": "white" } ] }"#;
    let line = expect_render_failure(
        "far-camera",
        &[("near.obj", near.as_bytes()), ("scene.json", camera.as_bytes())],
        "scene.json",
        &["--spp", "1"],
    );
    assert_names(&line, &["scene.json", "camera position"]);
    let scaled = r#"{ "materials": { "white": { "type": "lambertian", "albedo": 0.7 } },
  "objects": [ { "type": "mesh", "file": "near.obj", "material": "white", "transform": { "scale": 1e30 } } ] }"#;
    let line = expect_render_failure(
        "far-scaled",
        &[("near.obj", near.as_bytes()), ("scene.json", scaled.as_bytes())],
        "scene.json",
        &["--spp", "1"],
    );
    assert_names(&line, &["scene.json", "coordinates beyond"]);
    // The same mesh at a sane size renders.
    let dir = TempDir::new("near-grid");
    dir.write("near.obj", &near);
    let out = phr(&dir.0, &["render", "near.obj", "--out", "out.png", "--width", "16", "--height", "16", "--spp", "1"]);
    assert_eq!(out.code, Some(0), "{}", out.stderr);
}

/// Sizes and depths that used to wrap `width * height` in u32 (65536² rendered for 30 s and
/// aborted on allocation) or loop for ever (a depth of 2³²−1): one clear error, at once.
#[test]
fn image_size_and_depth_limits() {
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    let cases: [(&str, &[&str], &[&str]); 4] = [
        ("size-wrap", &["--width", "65536", "--height", "65536"], &["65536x65536", "too large"]),
        ("size-empty", &["--width", "0"], &["empty"]),
        ("depth-huge", &["--max-depth", "4294967295"], &["max_depth", "1024"]),
        ("spp-zero", &["--spp", "0"], &["spp"]),
    ];
    for (test, extra, needles) in cases {
        let line = expect_render_failure(test, &[("tri.obj", obj.as_bytes())], "tri.obj", extra);
        assert_names(&line, needles);
    }
    for (key, needle) in
        [(r#""spp": 0"#, "spp"), (r#""max_depth": 0"#, "max_depth"), (r#""width": 100000"#, "too large")]
    {
        let json = format!(
            r#"{{ {key}, "materials": {{ "w": {{ "type": "lambertian", "albedo": 0.5 }} }},
  "objects": [ {{ "type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "w" }} ] }}"#
        );
        let line = expect_render_failure("json-settings", &[("s.json", json.as_bytes())], "s.json", &[]);
        assert_names(&line, &["s.json", needle]);
    }
}

/// Scene values that cannot make an image, and keys that mean nothing, used to be accepted
/// without a word (a `fov` key ignored, a sphere's transform dropped, a period of 1e-45 s
/// posing NaN vertices). Each is one clear error naming the file and the place.
#[test]
fn nonsense_scene_values_are_errors() {
    let scene = |camera: &str, material: &str, object: &str| {
        format!(
            r#"{{ "camera": {{ {camera} }},
  "materials": {{ "m": {material} }},
  "objects": [ {object} ] }}"#
        )
    };
    let cam = r#""position": [0, 0, 5], "look_at": [0, 0, 0], "vfov": 40"#;
    let white = r#"{ "type": "lambertian", "albedo": 0.7 }"#;
    let ball = r#"{ "type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m" }"#;
    let moving = |motion: &str| {
        format!(r#"{{ "type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m", "animate": {motion} }}"#)
    };
    let cases: Vec<(&str, String, &[&str])> = vec![
        (
            "fov",
            scene(r#""position": [0, 0, 5], "look_at": [0, 0, 0], "fov": 40"#, white, ball),
            &["camera", "unknown key \"fov\""],
        ),
        (
            "sphere-transform",
            scene(
                cam,
                white,
                r#"{ "type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "m", "transform": { "scale": 2 } }"#,
            ),
            &["object 0 (sphere)", "unknown key \"transform\""],
        ),
        (
            "top-level",
            scene(cam, white, ball).replacen('{', r#"{ "sample_count": 4,"#, 1),
            &["top level", "sample_count"],
        ),
        (
            "albedo",
            scene(cam, r#"{ "type": "lambertian", "albedo": [0.5, -0.1, 0.5] }"#, ball),
            &["material \"m\"", "albedo"],
        ),
        ("emit-nan", scene(cam, r#"{ "type": "emissive", "emit": 1e39 }"#, ball), &["material \"m\"", "emit"]),
        ("ior", scene(cam, r#"{ "type": "dielectric", "ior": 0 }"#, ball), &["material \"m\"", "ior 0"]),
        (
            "vfov-0",
            scene(r#""position": [0, 0, 5], "look_at": [0, 0, 0], "vfov": 0"#, white, ball),
            &["camera", "vfov 0"],
        ),
        (
            "vfov-180",
            scene(r#""position": [0, 0, 5], "look_at": [0, 0, 0], "vfov": 180"#, white, ball),
            &["camera", "vfov 180"],
        ),
        (
            "look-at",
            scene(r#""position": [1, 2, 3], "look_at": [1, 2, 3]"#, white, ball),
            &["camera", "look_at equals position"],
        ),
        (
            "up",
            scene(r#""position": [0, 5, 0], "look_at": [0, 0, 0], "up": [0, 1, 0]"#, white, ball),
            &["camera", "parallel"],
        ),
        (
            "period",
            scene(cam, white, &moving(r#"{ "type": "oscillate", "amplitude": [1, 0, 0], "period": 1e-45 }"#)),
            &["object 0", "period"],
        ),
        (
            "rotation",
            scene(cam, white, &moving(r#"{ "type": "rotate", "degrees_per_second": 1e39 }"#)),
            &["object 0", "degrees_per_second"],
        ),
    ];
    for (test, json, needles) in cases {
        let line = expect_render_failure(
            &format!("nonsense-{test}"),
            &[("s.json", json.as_bytes())],
            "s.json",
            &["--spp", "1"],
        );
        assert_names(&line, &[&["s.json"], needles].concat());
    }
    // The same scene without the nonsense renders.
    let dir = TempDir::new("nonsense-ok");
    dir.write("s.json", scene(cam, white, &moving(r#"{ "type": "oscillate", "amplitude": [1, 0, 0], "period": 2 }"#)));
    let out = phr(&dir.0, &["render", "s.json", "--out", "out.png", "--width", "8", "--height", "8", "--spp", "1"]);
    assert_eq!(out.code, Some(0), "{}", out.stderr);
}

#[test]
fn json_unknown_material_name() {
    let json = r#"{
  "materials": { "white": { "type": "lambertian", "albedo": 0.7 } },
  "objects": [
    { "type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white" },
    { "type": "sphere", "center": [0, 3, 0], "radius": 1, "material": "red" }
  ]
}
"#;
    let line = expect_render_failure("json-name", &[("scene.json", json.as_bytes())], "scene.json", &[]);
    assert_names(&line, &["scene.json", "unknown material", "red"]);
}

#[test]
fn json_unknown_material_type() {
    let json = r#"{
  "materials": {
    "white": {
      "type": "plastic",
      "albedo": 0.7
    }
  },
  "objects": [
    { "type": "sphere", "center": [0, 0, 0], "radius": 1, "material": "white" }
  ]
}
"#;
    let line = expect_render_failure("json-type", &[("scene.json", json.as_bytes())], "scene.json", &[]);
    assert_names(&line, &["scene.json:4:", "plastic"]);
}

#[test]
fn output_folder_does_not_exist() {
    let dir = TempDir::new("out-dir");
    dir.write("quad.obj", QUAD_OBJ);
    let before = dir.files();
    // A render this size would take minutes: failing fast shows the check comes first.
    let args =
        ["render", "quad.obj", "--out", "nowhere/out.png", "--width", "4000", "--height", "4000", "--spp", "100000"];
    let out = phr(&dir.0, &args);
    assert!(out.code.is_some_and(|c| c != 0), "exit {:?}: {}", out.code, out.stderr);
    assert!(!out.stderr.contains("panicked"), "{}", out.stderr);
    let errors: Vec<&str> = out.stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{}", out.stderr);
    assert_names(errors[0], &["nowhere/out.png", "does not exist"]);
    assert!(out.stdout.is_empty(), "rendered before failing: {}", out.stdout);
    assert!(out.elapsed < Duration::from_secs(20), "took {:?}: rendered before failing?", out.elapsed);
    assert_eq!(dir.files(), before);
    assert!(!dir.0.join("nowhere").exists());
}

#[test]
fn unknown_builder() {
    let line =
        expect_render_failure("builder", &[("quad.obj", QUAD_OBJ.as_bytes())], "quad.obj", &["--builder", "octree"]);
    assert_names(&line, &["--builder", "octree"]);
}

#[test]
fn unknown_view() {
    let line = expect_render_failure("view", &[("quad.obj", QUAD_OBJ.as_bytes())], "quad.obj", &["--view", "sideways"]);
    assert_names(&line, &["quad.obj", "sideways"]);
}

#[test]
fn tiny_obj_renders_and_validates() {
    let dir = TempDir::new("ok");
    dir.write("quad.obj", QUAD_OBJ);
    let out = phr(
        &dir.0,
        &["render", "quad.obj", "--width", "16", "--height", "16", "--spp", "2", "--quiet", "--out", "out.png"],
    );
    assert_eq!(out.code, Some(0), "stdout:\n{}\nstderr:\n{}", out.stdout, out.stderr);
    assert!(!out.stderr.contains("panicked"), "{}", out.stderr);
    let summary = out.stdout.lines().find(|l| l.starts_with("quad.obj:")).unwrap_or_else(|| panic!("{}", out.stdout));
    assert!(summary.contains("2 triangles"), "{summary}");
    assert!(summary.contains("16x16, 2 spp"), "{summary}");
    let png = std::fs::read(dir.0.join("out.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");
    // IHDR: width and height, big-endian, right after the chunk header.
    assert_eq!(&png[12..16], b"IHDR");
    assert_eq!(u32::from_be_bytes(png[16..20].try_into().unwrap()), 16);
    assert_eq!(u32::from_be_bytes(png[20..24].try_into().unwrap()), 16);
    let expected: BTreeSet<String> = ["quad.obj", "out.png"].map(String::from).into();
    assert_eq!(dir.files(), expected, "stray files");

    let info = phr(&dir.0, &["info", "quad.obj"]);
    assert_eq!(info.code, Some(0), "{}", info.stderr);
    assert!(info.stdout.contains("triangles   2"), "{}", info.stdout);
    assert!(info.stdout.contains("invariants  ok"), "{}", info.stdout);
}

/// `phr tune` runs both methods end to end on a tiny mesh and reports its choice.
#[test]
fn tune_runs_grid_and_bayes() {
    let dir = TempDir::new("tune");
    dir.write("box.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nf 1 2 3\nf 1 3 4\nf 1 2 6\nf 1 6 5\n");
    let mesh = dir.0.join("box.obj");
    let cache = dir.0.join("cache.json");
    for method in ["grid", "bo"] {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_phr"))
            .args([
                "tune",
                mesh.to_str().unwrap(),
                "--width",
                "16",
                "--height",
                "16",
                "--budget",
                "5",
                "--method",
                method,
            ])
            .arg("--cache")
            .arg(&cache)
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{method}: {}", String::from_utf8_lossy(&out.stderr));
        assert!(stdout.contains("chosen α"), "{method}: {stdout}");
    }
    assert!(cache.is_file(), "the Bayesian run caches its normalisation maxima");
}

/// Output into a closed pipe (`phr render … | head -1` once `head` has exited) ends `phr`
/// quietly, like other command-line tools: no panic message on stderr.
#[test]
fn a_closed_stdout_is_no_panic() {
    use std::process::{Command, Stdio};
    let dir = TempDir::new("closed-stdout");
    let mut child = Command::new(env!("CARGO_BIN_EXE_phr"))
        .current_dir(&dir.0)
        .args(["render", "builtin", "--spp", "1", "--width", "8", "--height", "8", "--quiet", "--out", "x.png"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("runs phr");
    // Close the reading end before phr prints its summary.
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("phr ends");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
}
