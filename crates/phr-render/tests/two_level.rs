//! The two-level layout (a tree per rigidly moving object, placed by its transform under a
//! top-level tree) against things it does not use: the thesis pipeline, which moves every
//! vertex and builds one tree, and brute force over the placed triangles. Hits, surface
//! points and light samples must agree, through rotations, non-uniform scales and mirrors.

use glam::{Affine3A, Quat, Vec3};
use phr_bvh::dynamic::DynamicBvh;
use phr_bvh::phr::PhrOptions;
use phr_bvh::triangle::{intersect_triangle, triangle_normal};
use phr_bvh::{Builder, Ray, TraversalStats};
use phr_render::animation::Animator;
use phr_render::geometry::Geometry;
use phr_render::lights::LightSet;
use phr_render::motion::{Animation, AnimationTarget, Motion, ObjectAnimation};
use phr_render::pipeline::{FramePipeline, PipelineKind, PipelineSettings, ViewMode};
use phr_render::sampler::Pcg32;
use phr_render::scene::json::parse_scene;
use std::path::Path;

/// A static floor and sphere; a block that turns and bobs, a sphere that swings and a lamp
/// that turns (rigid); a strip that waves (a deformation).
const SCENE: &str = r#"{
  "background": [0.05, 0.05, 0.05],
  "camera": { "position": [0, 2, 6], "look_at": [0, 0.5, 0], "vfov": 50 },
  "materials": {
    "white": { "type": "lambertian", "albedo": 0.7 },
    "lamp": { "type": "emissive", "emit": [8, 8, 8] }
  },
  "objects": [
    { "type": "quad", "Q": [-4, 0, -4], "u": [8, 0, 0], "v": [0, 0, 8], "material": "white" },
    { "type": "sphere", "center": [-2, 0.5, -1], "radius": 0.5, "material": "white" },
    { "type": "triangles", "material": "white",
      "vertices": [[0, 0.2, 0], [1, 0.2, 0], [0, 1.4, 0], [0, 0.2, 1], [1, 1.4, 1], [0.3, 0.9, -0.6]],
      "faces": [[0, 1, 2], [0, 3, 1], [1, 3, 4], [2, 4, 3], [0, 2, 5], [1, 5, 2], [2, 5, 4]],
      "animate": [ { "type": "rotate", "axis": [0.2, 1, 0.1], "pivot": [0.5, 0.5, 0.5], "degrees_per_second": 70 },
                   { "type": "oscillate", "amplitude": [0, 0.3, 0.2], "period": 1.3 } ] },
    { "type": "sphere", "center": [1.5, 1.2, -1], "radius": 0.4, "material": "white",
      "animate": { "type": "oscillate", "amplitude": [-1.2, 0, 0.5], "period": 2 } },
    { "type": "quad", "Q": [-0.5, 2.5, -0.5], "u": [1, 0, 0], "v": [0, 0, 1], "material": "lamp",
      "animate": { "type": "rotate", "axis": [1, 0, 0], "pivot": [0, 2.5, 0], "degrees_per_second": 40 } },
    { "type": "triangles", "material": "white",
      "vertices": [[-3, 0.1, 2], [-1, 0.1, 2], [-3, 0.1, 3], [-1, 0.1, 3], [1, 0.1, 2], [1, 0.1, 3]],
      "faces": [[0, 2, 1], [1, 2, 3], [1, 3, 4], [4, 3, 5]],
      "animate": { "type": "wave", "amplitude": 0.3, "wavelength": 2.0, "period": 1.5, "direction": [1, 0, 0] } }
  ]
}"#;

fn pipeline(kind: PipelineKind) -> FramePipeline {
    pipeline_of(parse_scene(SCENE, Path::new("two_level.json")).unwrap(), kind)
}

/// The scene's first view at 16², PHR-Fast, paths of 3 segments, explicit light sampling.
fn pipeline_of(scene: phr_render::Scene, kind: PipelineKind) -> FramePipeline {
    let camera = scene.view(None).unwrap();
    let settings = PipelineSettings {
        builder: Builder::PHR_FAST,
        pipeline: kind,
        width: 16,
        height: 16,
        max_depth: 3,
        mode: ViewMode::Colour,
        explicit_lights: true,
        denoise: None,
    };
    FramePipeline::new(scene, settings, camera)
}

/// Rays from all over the scene's box towards all over it.
fn rays(n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Pcg32::for_pixel(seed, 0, 0);
    let mut point = |scale: f32| {
        Vec3::new(rng.next_f32() - 0.5, rng.next_f32() * 0.5, rng.next_f32() - 0.5) * Vec3::new(8.0, 6.0, 8.0) * scale
    };
    (0..n)
        .map(|_| {
            let o = point(1.2);
            let target = point(0.8);
            Ray::new(o, (target - o).normalize_or(Vec3::Y))
        })
        .collect()
}

/// Closest triangle hit over every triangle where it is in the world, lowest index on ties
/// (the scene's spheres are handled by the callers).
fn brute_force_triangles(g: &Geometry, ray: &Ray) -> Option<(f32, u32)> {
    let mut best: Option<(f32, u32)> = None;
    for i in 0..g.triangles.len() {
        let [a, b, c] = g.world_triangle(i);
        if let Some(h) = intersect_triangle(ray, a, b, c) {
            if best.is_none_or(|(t, _)| h.t < t) {
                best = Some((h.t, i as u32));
            }
        }
    }
    best
}

fn close(a: f32, b: f32) -> bool {
    (a - b).abs() <= 1e-4 * (1.0 + a.abs().max(b.abs()))
}

#[test]
fn two_level_frames_hit_what_the_thesis_pipeline_hits() {
    let mut thesis = pipeline(PipelineKind::Thesis);
    let mut two = pipeline(PipelineKind::TwoLevel);
    for frame in 0..5 {
        let (a, b) = (thesis.step(0.37), two.step(0.37));
        assert!(a.moved && b.moved);
        assert_eq!(thesis.time, two.time);
        let (gt, g2) = (thesis.geometry(), two.geometry());
        assert!(g2.part_count() >= 5, "static, deforming and three rigid parts: {}", g2.part_count());
        same_hits(gt, g2, frame);
    }
}

/// `two` (two-level) hits what `thesis` (one tree, moved vertices) hits, with the same surface
/// points; its counting traversal and shadow queries agree with its closest hits.
fn same_hits(gt: &Geometry, g2: &Geometry, frame: u64) {
    let mut differ = 0;
    let all = rays(2000, frame);
    for (i, ray) in all.iter().enumerate() {
        let (want, got) = (gt.intersect(ray), g2.intersect(ray));
        match (want, got) {
            (None, None) => {}
            (Some(w), Some(h)) if w.prim == h.prim && close(w.t, h.t) => {
                let (sw, sh) = (gt.surface_point(ray, &w), g2.surface_point(ray, &h));
                assert!((sw.position - sh.position).length() < 1e-3, "frame {frame}, ray {i}: position");
                assert!(sw.normal.dot(sh.normal) > 0.9999, "frame {frame}, ray {i}: normal");
                assert_eq!(sw.front, sh.front, "frame {frame}, ray {i}: side");
                assert_eq!(sw.material, sh.material);
            }
            // Rays grazing an edge may fall on either side of it in the two layouts.
            _ => differ += 1,
        }
    }
    assert!(differ <= all.len() / 200, "frame {frame}: {differ} of {} rays differ", all.len());
    // The heatmap's counting traversal finds the same hits.
    for ray in &all[..200] {
        let counted = g2.intersect_counted(ray, &mut TraversalStats::default()).map(|h| (h.t, h.prim));
        assert_eq!(counted, g2.intersect(ray).map(|h| (h.t, h.prim)));
    }
    // Shadow queries agree with closest hits.
    for ray in &all[..500] {
        assert_eq!(g2.occluded(ray), g2.intersect(ray).is_some());
    }
}

/// A glTF whose nodes animate, given a second animation in code (scene files refuse this): two
/// animations of one mesh, which no single transform describes, so it deforms.
#[test]
fn an_object_with_two_animations_deforms() {
    let scene = r#"{
      "camera": { "position": [0, 2.2, 6.5], "look_at": [0, 0.9, 0], "vfov": 45 },
      "materials": {},
      "objects": [ { "type": "gltf", "file": "carousel.gltf" }, { "type": "gltf", "file": "floor.gltf" } ]
    }"#;
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/dynamic/twice_animated.json");
    let make = |kind| {
        let mut scene = parse_scene(scene, &path).unwrap();
        let turn = Motion::Rotate { axis: Vec3::Y, pivot: Vec3::ZERO, degrees_per_second: 50.0 };
        let target = scene.animations[0].target;
        assert_eq!(target, AnimationTarget::Mesh(0));
        scene.animations.push(ObjectAnimation { target, animation: Animation::Procedural(vec![turn]) });
        pipeline_of(scene, kind)
    };
    let (mut thesis, mut two) = (make(PipelineKind::Thesis), make(PipelineKind::TwoLevel));
    for frame in 0..3 {
        thesis.step(0.3);
        two.step(0.3);
        assert_eq!(two.geometry().part_count(), 2, "the floor stands still, the carousel deforms");
        assert_eq!(thesis.geometry().triangles, two.geometry().triangles, "frame {frame}: posed alike");
        same_hits(thesis.geometry(), two.geometry(), frame);
    }
}

/// A glTF moved by its nodes alone moves each node's triangles as a rigid part, placed by the
/// node's world matrix: the carousel's platform and riders are parts of their own, moved by
/// transforms, and only the floor's wave deforms; every frame hits what the thesis pipeline
/// (every vertex posed) hits, with either two-level pipeline. (The carousel's parts are
/// smaller than `NODE_PART_MIN_TRIANGLES`, so the viewer deforms them; the test splits parts
/// of any size.)
#[test]
fn gltf_nodes_move_as_rigid_parts() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/dynamic/carousel.json");
    let load = || phr_render::scene::load_scene(&path).unwrap();
    let scene = load();
    let triangles = Geometry::new(&scene).triangle_count();
    let default = Animator::new(&scene).objects(triangles);
    assert_eq!(default.iter().filter(|o| !o.rigid).count(), 2, "below the minimum, the carousel deforms");
    let objects = Animator::with_node_part_minimum(&scene, 0).objects(triangles);
    let rigid = objects.iter().filter(|o| o.rigid).count();
    let deforming: Vec<_> = objects.iter().filter(|o| !o.rigid).collect();
    // The floor deforms; the platform, the riders and the swinging ball are rigid.
    assert_eq!(deforming.len(), 1, "only the floor deforms");
    assert!(rigid >= 4, "the carousel's nodes are rigid parts: {rigid} rigid objects");
    for kind in [PipelineKind::TwoLevel, PipelineKind::Async] {
        let split = |pipeline: FramePipeline| {
            let scene = load();
            let animator = Animator::with_node_part_minimum(&scene, 0);
            FramePipeline::with_animator(scene, pipeline.settings().clone(), pipeline.camera().clone(), animator)
        };
        let (mut thesis, mut two) = (pipeline_of(load(), PipelineKind::Thesis), split(pipeline_of(load(), kind)));
        for frame in 0..4 {
            thesis.step(0.37);
            two.step(0.37);
            assert!(two.geometry().part_count() >= rigid + 2, "static, deforming and rigid parts");
            same_hits(thesis.geometry(), two.geometry(), frame);
        }
    }
}

#[test]
fn light_samples_lie_on_the_moved_lamp() {
    let mut thesis = pipeline(PipelineKind::Thesis);
    let mut two = pipeline(PipelineKind::TwoLevel);
    for _ in 0..3 {
        thesis.step(0.61);
        two.step(0.61);
        let (materials, background) = (&thesis.scene().materials, &thesis.scene().background);
        let lt = LightSet::new(thesis.geometry(), materials, background);
        let l2 = LightSet::new(two.geometry(), materials, background);
        assert_eq!(lt.len(), 2);
        // From below the lamp, looking up.
        let (from, facing) = (Vec3::new(0.1, -0.9, 0.2), Vec3::Y);
        for seed in 0..50 {
            let mut r1 = Pcg32::for_pixel(seed, 1, 2);
            let mut r2 = r1.clone();
            let a = lt.sample(thesis.geometry(), from, facing, &mut r1).unwrap();
            let b = l2.sample(two.geometry(), from, facing, &mut r2).unwrap();
            match (a.point, b.point) {
                (Some(pa), Some(pb)) => assert!((pa - pb).length() < 1e-4, "{pa} vs {pb}"),
                (None, None) => {} // both chose the sky
                (pa, pb) => panic!("one chose the sky, the other not: {pa:?} vs {pb:?}"),
            }
            assert!(a.dir.dot(b.dir) > 0.9999);
            assert!(close(a.pdf, b.pdf), "{} vs {}", a.pdf, b.pdf);
        }
    }
}

/// Parts placed by arbitrary invertible maps (non-uniform scales, shears, mirrors) hit what
/// brute force over the placed triangles hits, with the placed triangles' normals.
#[test]
fn placed_parts_equal_brute_force() {
    let scene = parse_scene(SCENE, Path::new("two_level.json")).unwrap();
    let mut g = Geometry::new(&scene);
    let n = g.triangles.len() as u32;
    // Triangles in three parts, the two spheres in a fourth.
    let groups = vec![(0..2).collect(), (2..9).collect(), (9..n).collect(), vec![n, n + 1]];
    g.split(groups, &Builder::PHR_HQ);
    assert_eq!(g.part_count(), 4);
    // What a device keeping the parts reads to know which ones to upload again.
    let generations = |g: &Geometry| (0..g.part_count()).map(|k| g.part_generation(k)).collect::<Vec<_>>();
    let split = generations(&g);
    assert!(split.windows(2).all(|w| w[0] != w[1]), "each part packed on its own: {split:?}");
    let maps = [
        Affine3A::from_scale_rotation_translation(Vec3::new(1.5, 0.5, 2.0), Quat::from_rotation_y(0.8), Vec3::X),
        Affine3A::from_mat3_translation(
            glam::Mat3::from_cols(Vec3::new(-1.0, 0.2, 0.0), Vec3::new(0.0, 1.0, 0.3), Vec3::new(0.1, 0.0, 0.9)),
            Vec3::new(0.5, 0.2, -0.4),
        ),
        Affine3A::from_scale(Vec3::new(1.0, -1.0, 1.0)) * Affine3A::from_translation(Vec3::new(0.0, -1.0, 0.0)),
    ];
    let shift = Vec3::new(0.3, 0.4, -0.2);
    let id = Affine3A::IDENTITY;
    // All four parts moved (through the top-level tree), then two (searched directly).
    let layouts = [
        [maps[0], maps[1], maps[2], Affine3A::from_translation(shift)],
        [id, maps[1], id, Affine3A::from_translation(shift)],
    ];
    for (layout, m) in layouts.iter().enumerate() {
        g.place(&[(0, m[0]), (1, m[1]), (2, m[2]), (3, m[3])]);
        check_placed(&g, n, shift, layout);
    }
    assert_eq!(generations(&g), split, "placing parts changes none of their trees");
    // Part 2 (in place) deforms: its new tree alone, without placing again, must be found
    // where its triangles now are (rays skip a part whose box they miss).
    for t in &mut g.triangles[9..] {
        *t = t.map(|v| v * Vec3::new(1.0, 1.6, 1.0) + Vec3::new(1.5, 0.7, 0.0));
    }
    let boxes = g.part_boxes(2);
    g.set_part_bvh(2, Builder::PHR_HQ.build(&boxes));
    check_placed(&g, n, shift, 2);
    let rebuilt = generations(&g);
    let changed = |a: &[u64], b: &[u64]| (0..a.len()).filter(|&k| a[k] != b[k]).collect::<Vec<_>>();
    assert_eq!(changed(&split, &rebuilt), [2], "a new tree for part 2 alone");
    // Refitted after its triangles moved, the part keeps no binary tree (the counting
    // traversal would walk it, boxes and all, instead of the refitted wide tree).
    for t in &mut g.triangles[9..] {
        *t = t.map(|v| v + Vec3::new(0.3, -0.2, 0.1));
    }
    g.refit_part(2, None);
    assert!(g.part_bvh(2).nodes.is_empty(), "the refit dropped the binary tree");
    for ray in rays(500, 12) {
        let counted = g.intersect_counted(&ray, &mut TraversalStats::default()).map(|h| (h.t, h.prim));
        assert_eq!(counted, g.intersect(&ray).map(|h| (h.t, h.prim)), "counting traversal, refitted part");
    }
    check_placed(&g, n, shift, 4);
    // And again, its wide tree built straight by PHR, without a binary tree: the counting
    // traversal then walks the wide tree.
    for t in &mut g.triangles[9..] {
        *t = t.map(|v| v * Vec3::new(0.8, 1.0, 1.2) - Vec3::new(0.5, 0.2, 0.0));
    }
    let boxes = g.part_boxes(2);
    let mut dynamic = DynamicBvh::new(&boxes, PhrOptions::HQ);
    g.set_part_wide(2, |wide| dynamic.update_wide(&boxes, wide));
    assert!(g.part_bvh(2).nodes.is_empty() && !g.part_wide(2).nodes.is_empty());
    check_placed(&g, n, shift, 3);
    let built = generations(&g);
    assert_eq!(changed(&rebuilt, &built), [2]);
    g.refit_part(2, None);
    assert_eq!(changed(&built, &generations(&g)), [2], "a refit changes the part");
    for ray in rays(500, 11) {
        let counted = g.intersect_counted(&ray, &mut TraversalStats::default()).map(|h| (h.t, h.prim));
        assert_eq!(counted, g.intersect(&ray).map(|h| (h.t, h.prim)), "counting traversal, direct wide part");
    }
    // Back to one tree over everything, in place.
    let tree = Builder::PHR_FAST.build(&g.boxes);
    let nodes = tree.nodes.len();
    g.set_bvh(tree);
    assert_eq!(g.part_count(), 1);
    assert!(!split.contains(&g.part_generation(0)) && g.part_generation(0) > built[2], "never a generation again");
    assert_eq!(g.world_triangle(3), g.triangles[3]);
    assert!(rays(100, 3).iter().any(|r| g.intersect(r).is_some()));
    // The benchmarks take the tree out to set it again: they must get it back, not an empty one.
    assert_eq!(g.take_bvh().nodes.len(), nodes, "take_bvh hands the tree back");
    assert!(rays(100, 3).iter().all(|r| g.intersect(r).is_none()), "nothing is hit after take_bvh");
}

/// [`placed_parts_equal_brute_force`] for one placement: the spheres (primitives `n`, `n + 1`)
/// moved by `shift`.
fn check_placed(g: &Geometry, n: u32, shift: Vec3, layout: usize) {
    let spheres: Vec<_> =
        g.spheres.iter().map(|s| phr_bvh::sphere::Sphere { center: s.sphere.center + shift, ..s.sphere }).collect();
    let mut hits = 0;
    for (i, ray) in rays(3000, 7).iter().enumerate() {
        let mut want = brute_force_triangles(g, ray);
        for (k, s) in spheres.iter().enumerate() {
            if let Some(t) = s.intersect(ray) {
                if want.is_none_or(|(bt, _)| t < bt) {
                    want = Some((t, n + k as u32));
                }
            }
        }
        let got = g.intersect(ray);
        assert_eq!(g.occluded(ray), want.is_some(), "layout {layout}, ray {i}: shadow query");
        match (want, got) {
            (None, None) => {}
            (Some((t, prim)), Some(h)) => {
                assert!(
                    prim == h.prim && close(t, h.t),
                    "layout {layout}, ray {i}: want {t} on {prim}, got {} on {}",
                    h.t,
                    h.prim
                );
                hits += 1;
                if prim < n {
                    let [a, b, c] = g.world_triangle(prim as usize);
                    let normal = triangle_normal(a, b, c).normalize();
                    let sp = g.surface_point(ray, &h);
                    assert!(
                        sp.normal.dot(normal) > 0.9999,
                        "layout {layout}, ray {i}: normal {} vs {normal}",
                        sp.normal
                    );
                    assert!((sp.position - ray.at(h.t)).length() < 1e-3, "layout {layout}, ray {i}: position");
                }
            }
            _ => panic!("layout {layout}, ray {i}: want {want:?}, got {:?}", got.map(|h| (h.t, h.prim))),
        }
    }
    assert!(hits > 500, "layout {layout}: too few hits to prove anything: {hits}");
}

/// The asynchronous pipeline traces the deforming part's tree refitted while the worker
/// rebuilds it: every frame must still hit what the thesis pipeline (everything rebuilt in
/// the frame) hits, so the traced tree encloses the moved triangles whether or not a new tree
/// has landed; and new trees do land (here the policy is told to rebuild all the time).
#[test]
fn async_frames_hit_what_the_thesis_pipeline_hits() {
    let mut thesis = pipeline(PipelineKind::Thesis);
    let mut late = pipeline(PipelineKind::Async);
    late.rebuild_sah_growth = 0.0;
    let mut ages = Vec::new();
    for frame in 0..12 {
        let (a, b) = (thesis.step(0.21), late.step(0.21));
        assert!(a.moved && b.moved);
        ages.push(b.tree_age);
        same_hits(thesis.geometry(), late.geometry(), frame);
        // Some frames land a tree, some trace the refitted one.
        std::thread::sleep(std::time::Duration::from_millis(if frame % 3 == 0 { 60 } else { 0 }));
    }
    assert_eq!(ages[0], 0, "the first frame traces the tree built for it");
    assert!(ages[1..].iter().all(|&a| a >= 1), "later frames trace a tree built earlier: {ages:?}");
    // Without landings the age would grow by one a frame.
    assert!(ages[1..].windows(2).any(|w| w[1] <= w[0]), "no rebuilt tree landed: {ages:?}");
}

/// The rebuild policy: a tree is rebuilt when the refitted one's SAH cost has grown by the
/// factor. On the carousel (its riders deform), an unreachable factor keeps refitting the
/// first tree, which stays right; a factor of 1 rebuilds as soon as the cost grows at all.
#[test]
fn async_rebuilds_follow_the_sah_growth() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/dynamic/carousel.json");
    let ages = |growth: f64| {
        let mut p = pipeline_of(phr_render::scene::load_scene(&path).unwrap(), PipelineKind::Async);
        let mut thesis = pipeline_of(phr_render::scene::load_scene(&path).unwrap(), PipelineKind::Thesis);
        p.rebuild_sah_growth = growth;
        (0..10u64)
            .map(|frame| {
                let (r, _) = (p.step(0.1), thesis.step(0.1));
                same_hits(thesis.geometry(), p.geometry(), frame);
                std::thread::sleep(std::time::Duration::from_millis(50));
                r.tree_age
            })
            .collect::<Vec<_>>()
    };
    let kept = ages(f64::INFINITY);
    assert_eq!(kept, (0..10).collect::<Vec<u64>>(), "never rebuilt");
    let eager = ages(1.0);
    assert!(eager.windows(2).any(|w| w[1] <= w[0]), "a growing cost rebuilds: {eager:?}");
}
