//! The static builder's trees for what never moves, built in the background
//! (`phr_render::static_rebuild`): once they land, the parts that never move have them, and
//! everything else is as without them. Every ray finds the same hit, bit for bit, so the
//! images of every frame are those of a pipeline without a static builder, before and after
//! the swap; the accumulation goes on.

use glam::Vec3;
use phr_bvh::{Builder, Ray};
use phr_render::pipeline::{FramePipeline, PipelineKind, PipelineSettings, ViewMode};
use phr_render::sampler::Pcg32;
use phr_render::scene::json::parse_scene;
use std::path::Path;

const SIZE: u32 = 24;

/// A `triangles` object: an `n` × `n` grid of squares of side `size / n` in the plane
/// y = `height`, centred on (`x`, `z`), bent a little so that its triangles are not all
/// coplanar, with `animate` (JSON, or empty).
fn grid(n: usize, size: f32, (x, height, z): (f32, f32, f32), animate: &str) -> String {
    let step = size / n as f32;
    let mut vertices = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            let (u, v) = (i as f32 * step - size / 2.0, j as f32 * step - size / 2.0);
            let y = height + 0.05 * (3.0 * u).sin() * (2.0 * v).cos();
            vertices.push(format!("[{}, {y}, {}]", x + u, z + v));
        }
    }
    let mut faces = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let k = i * (n + 1) + j;
            faces.push(format!("[{k}, {}, {}]", k + 1, k + n + 1));
            faces.push(format!("[{}, {}, {}]", k + 1, k + n + 2, k + n + 1));
        }
    }
    let animate = if animate.is_empty() { String::new() } else { format!(", \"animate\": {animate}") };
    format!(
        "{{\"type\": \"triangles\", \"material\": \"white\", \"vertices\": [{}], \"faces\": [{}]{animate}}}",
        vertices.join(", "),
        faces.join(", ")
    )
}

/// A floor that stays, a sphere, a light; with `animated`, a grid turning as a whole (a
/// rigid part) and one under a wave (the deforming part).
fn scene_json(animated: bool) -> String {
    let mut objects = vec![
        grid(24, 6.0, (0.0, 0.0, 0.0), ""),
        r#"{"type": "sphere", "center": [1.2, 0.5, 0.3], "radius": 0.5, "material": "white"}"#.to_string(),
        r#"{"type": "quad", "Q": [-0.5, 3, -0.5], "u": [1, 0, 0], "v": [0, 0, 1], "material": "lamp"}"#.to_string(),
    ];
    let (turning, waving) = match animated {
        true => (
            r#"{"type": "rotate", "axis": [0, 1, 0], "pivot": [-1, 0, 0], "degrees_per_second": 40}"#,
            r#"{"type": "wave", "amplitude": 0.1, "wavelength": 1.0, "period": 1.0, "direction": [1, 0, 0]}"#,
        ),
        false => ("", ""),
    };
    objects.push(grid(12, 1.5, (-1.0, 0.8, 0.0), turning));
    objects.push(grid(12, 1.5, (0.5, 1.2, -1.0), waving));
    format!(
        r#"{{"background": [0.2, 0.2, 0.2],
            "camera": {{"position": [0, 2.5, 5], "look_at": [0, 0.5, 0], "vfov": 50}},
            "materials": {{"white": {{"type": "lambertian", "albedo": 0.7}},
                           "lamp": {{"type": "emissive", "emit": [6, 6, 6], "two_sided": true}}}},
            "objects": [{}]}}"#,
        objects.join(",\n")
    )
}

fn pipeline(kind: PipelineKind, animated: bool, static_builder: Option<Builder>) -> FramePipeline {
    let scene = parse_scene(&scene_json(animated), Path::new("static_rebuild.json")).unwrap();
    let camera = scene.view(None).unwrap();
    let settings = PipelineSettings {
        builder: Builder::Lbvh(Default::default()),
        pipeline: kind,
        width: SIZE,
        height: SIZE,
        max_depth: 4,
        mode: ViewMode::Colour,
        explicit_lights: true,
        denoise: None,
    };
    let mut p = FramePipeline::new(scene, settings, camera);
    p.set_static_builder(static_builder);
    p
}

fn bits(v: &[Vec3]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

/// Rays from all around the scene through it.
fn rays(n: usize) -> Vec<Ray> {
    let mut rng = Pcg32::new(7, 1);
    let mut f = move || rng.next_f32();
    (0..n)
        .map(|_| {
            let o = Vec3::new(f() - 0.5, f() * 0.5, f() - 0.5) * 8.0;
            let target = Vec3::new(f() - 0.5, f() * 0.3, f() - 0.5) * 4.0;
            Ray::new(o, (target - o).normalize_or(Vec3::Y))
        })
        .collect()
}

/// Steps both pipelines `frames` times and checks that they show the same image.
fn step_both(rebuilt: &mut FramePipeline, plain: &mut FramePipeline, frames: usize, what: &str) {
    for frame in 0..frames {
        let (a, b) = (rebuilt.step(0.1), plain.step(0.1));
        assert_eq!((a.moved, a.samples), (b.moved, b.samples), "{what}: frame {frame}");
        assert_eq!(bits(&rebuilt.image()), bits(&plain.image()), "{what}: frame {frame} differs");
    }
}

/// The parts of `p` whose trees differ from those of `q`.
fn differing_parts(p: &FramePipeline, q: &FramePipeline) -> Vec<usize> {
    let (g, h) = (p.geometry(), q.geometry());
    (0..g.part_count())
        .filter(|&k| {
            let (a, b) = (g.part_wide(k), h.part_wide(k));
            a.nodes.len() != b.nodes.len() || a.prim_indices != b.prim_indices
        })
        .collect()
}

fn check(kind: PipelineKind, animated: bool, rebuilt_parts: usize) {
    let what = format!("{} pipeline, {}", kind.name(), if animated { "animated" } else { "static" });
    let sbvh: Builder = "sbvh".parse().unwrap();
    let mut rebuilt = pipeline(kind, animated, Some(sbvh));
    let mut plain = pipeline(kind, animated, None);
    step_both(&mut rebuilt, &mut plain, 2, &what);
    rebuilt.finish_static_rebuild();
    assert!(rebuilt.static_rebuilt(), "{what}: the static trees did not land");
    assert!(!plain.static_rebuilt());
    assert_eq!(differing_parts(&rebuilt, &plain).len(), rebuilt_parts, "{what}: parts rebuilt");
    let mut hits = 0;
    for ray in rays(3000) {
        let (a, b) = (rebuilt.geometry().intersect(&ray), plain.geometry().intersect(&ray));
        hits += usize::from(a.is_some());
        let key = |h: Option<phr_render::geometry::Hit>| {
            h.map(|h| (h.prim, h.part, h.t.to_bits(), h.u.to_bits(), h.v.to_bits()))
        };
        assert_eq!(key(a), key(b), "{what}: {ray:?}");
    }
    assert!(hits > 1000, "{what}: {hits} of the rays hit");
    step_both(&mut rebuilt, &mut plain, 3, &what);
    let report = rebuilt.step(0.1);
    assert_eq!(report.static_builder, Some(sbvh), "{what}: the report names the static builder");
    if !animated {
        // Accumulated over the swap: every sample is still there.
        assert_eq!(report.samples, 6, "{what}");
    }
    assert_eq!(plain.step(0.1).static_builder, None);
}

#[test]
fn a_static_scene_renders_as_before_the_swap_and_keeps_accumulating() {
    check(PipelineKind::Thesis, false, 1);
    check(PipelineKind::Async, false, 1);
}

#[test]
fn in_a_moving_scene_the_static_and_rigid_parts_are_rebuilt_and_the_deforming_one_is_not() {
    // Parts: the static floor, sphere and light; the deforming grid; the turning grid.
    check(PipelineKind::Async, true, 2);
    check(PipelineKind::TwoLevel, true, 2);
}

#[test]
fn the_thesis_pipeline_does_not_rebuild_an_animated_scene() {
    let mut p = pipeline(PipelineKind::Thesis, true, Some("sbvh".parse().unwrap()));
    for _ in 0..3 {
        p.step(0.1);
    }
    p.finish_static_rebuild();
    assert!(!p.static_rebuilt());
}

#[test]
fn the_builder_itself_as_static_builder_changes_nothing() {
    let mut p = pipeline(PipelineKind::Async, false, Some(Builder::Lbvh(Default::default())));
    p.step(0.1);
    p.finish_static_rebuild();
    assert!(!p.static_rebuilt());
    assert_eq!(p.step(0.1).static_builder, None);
}

/// A static rebuild under way when the layout changes is dropped: its trees were built for
/// the old layout's parts (here, the two-level layout's three, against the thesis pipeline's
/// one tree) and must not land in the new one.
#[test]
fn a_layout_change_drops_the_static_rebuild_under_way() {
    let sbvh: Builder = "sbvh".parse().unwrap();
    let mut rebuilt = pipeline(PipelineKind::Async, true, Some(sbvh));
    let mut plain = pipeline(PipelineKind::Thesis, true, None);
    rebuilt.step(0.1);
    let settings = PipelineSettings { pipeline: PipelineKind::Thesis, ..rebuilt.settings().clone() };
    rebuilt.set_settings(settings);
    // Time for the worker to finish the trees of the old layout.
    std::thread::sleep(std::time::Duration::from_millis(500));
    plain.step(0.1);
    step_both(&mut rebuilt, &mut plain, 3, "after the switch to the thesis pipeline");
    rebuilt.finish_static_rebuild();
    assert!(!rebuilt.static_rebuilt(), "the thesis pipeline rebuilds no animated scene");
}

/// The heatmap shows the steps through the builder's trees: switching to it brings them
/// back, and no static rebuild starts while it shows; `None` as static builder brings the
/// builder's trees back too.
#[test]
fn the_heatmap_and_no_static_builder_bring_the_builders_trees_back() {
    let sbvh: Builder = "sbvh".parse().unwrap();
    for kind in [PipelineKind::Thesis, PipelineKind::Async] {
        let mut plain = pipeline(kind, false, None);
        plain.step(0.1);
        let rebuilt_then = |change: &dyn Fn(&mut FramePipeline)| {
            let mut p = pipeline(kind, false, Some(sbvh));
            p.step(0.1);
            p.finish_static_rebuild();
            assert!(p.static_rebuilt() && differing_parts(&p, &plain).len() == 1, "{}", kind.name());
            change(&mut p);
            for _ in 0..3 {
                p.step(0.1);
            }
            p.finish_static_rebuild();
            p
        };
        let heatmap =
            rebuilt_then(&|p| p.set_settings(PipelineSettings { mode: ViewMode::Heatmap, ..p.settings().clone() }));
        assert!(!heatmap.static_rebuilt(), "{}: a static rebuild under the heatmap", kind.name());
        assert!(differing_parts(&heatmap, &plain).is_empty(), "{}: the heatmap is not the builder's", kind.name());
        let none = rebuilt_then(&|p| p.set_static_builder(None));
        assert!(!none.static_rebuilt());
        assert!(differing_parts(&none, &plain).is_empty(), "{}: without a static builder", kind.name());
    }
}
