//! The same seed gives the same image for any thread count (README), bit for bit, with implicit
//! lights and with explicit light sampling: each pixel's random numbers depend only on (seed,
//! frame, pixel), and closest-hit ties do not depend on the tree, so every builder and
//! branching factor gives the same image too. A different seed gives a different image.

use glam::Vec3;
use phr_bvh::Builder;
use phr_render::film::Film;
use phr_render::geometry::Geometry;
use phr_render::lights::LightSet;
use phr_render::render::Renderer;
use phr_render::scene::builtin;
use phr_render::scene::RenderSettings;
use phr_render::Scene;

const WIDTH: u32 = 48;
const HEIGHT: u32 = 48;
const FRAMES: u32 = 4;
const MAX_DEPTH: u32 = 8;

/// Builds and renders `scene` as `phr render` does, on a pool of `threads` threads; returns the
/// film mean and the number of rays traced.
fn render(scene: &Scene, threads: usize, seed: u64) -> (Vec<Vec3>, u64) {
    render_with(scene, threads, seed, Builder::default(), false)
}

/// [`render`] with a builder, and with explicit light sampling if `nee`.
fn render_with(scene: &Scene, threads: usize, seed: u64, builder: Builder, nee: bool) -> (Vec<Vec3>, u64) {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let mut geometry = Geometry::new(scene);
        geometry.build(&builder);
        let lights = nee.then(|| LightSet::new(&geometry, &scene.materials, &scene.background));
        assert!(lights.as_ref().is_none_or(|l| !l.is_empty()), "no emissive triangles to sample");
        let view = scene.view(None).expect("default view");
        let settings = RenderSettings { width: WIDTH, height: HEIGHT, spp: FRAMES, max_depth: MAX_DEPTH };
        let renderer = Renderer::new(scene, &geometry, &view, &settings, lights.as_ref()).with_seed(seed);
        let mut film = Film::new(WIDTH, HEIGHT);
        let mut rays = 0;
        for frame in 0..FRAMES {
            let (pixels, stats) = renderer.render_frame(frame);
            film.add_frame(&pixels);
            rays += stats.rays;
        }
        assert_eq!(film.samples, FRAMES);
        (film.mean(), rays)
    })
}

fn bits(image: &[Vec3]) -> Vec<[u32; 3]> {
    image.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

#[test]
fn same_seed_same_image_for_any_thread_count() {
    let scene = builtin::cornell_knot();
    let (one, rays_one) = render(&scene, 1, 7);
    let (two, rays_two) = render(&scene, 2, 7);
    assert_eq!(one.len(), (WIDTH * HEIGHT) as usize);
    // Not vacuous: a lit image with finite values (at 4 spp about a third of the pixels have
    // found the light yet; the open front of the box shows black).
    assert!(one.iter().all(|p| p.is_finite()), "non-finite pixel");
    let lit = one.iter().filter(|p| p.max_element() > 0.0).count();
    assert!(lit > one.len() / 5, "only {lit} of {} pixels are lit", one.len());
    assert_eq!(rays_one, rays_two, "different number of rays traced");
    let differing = bits(&one).iter().zip(&bits(&two)).filter(|(a, b)| a != b).count();
    assert_eq!(differing, 0, "{differing} pixels differ between 1 and 2 threads");

    let (other, _) = render(&scene, 2, 8);
    let differing = bits(&one).iter().zip(&bits(&other)).filter(|(a, b)| a != b).count();
    assert!(differing > one.len() / 4, "seed 8 vs 7: only {differing} pixels differ");
}

#[test]
fn every_builder_gives_the_same_image() {
    let scene = builtin::cornell_knot();
    let (reference, _) = render(&scene, 2, 3);
    let mut builders: Vec<Builder> = ["phr-fast", "phr-hq", "phr:0.4,7", "sweep-sah", "binned-sah", "sbvh"]
        .iter()
        .map(|s| s.parse().unwrap())
        .collect();
    builders.extend([4, 8, 16].map(|k| Builder::PHR_HQ.with_branching(k).unwrap()));
    for builder in builders {
        let (image, _) = render_with(&scene, 2, 3, builder, false);
        assert!(bits(&image) == bits(&reference), "{builder} renders a different image than the LBVH");
    }
}

#[test]
fn explicit_light_sampling_is_deterministic_too() {
    let scene = builtin::cornell_knot();
    let (one, rays_one) = render_with(&scene, 1, 7, Builder::default(), true);
    let (implicit, rays_implicit) = render(&scene, 1, 7);
    // Not vacuous: light sampling traces shadow rays and lights more pixels at 4 spp.
    assert!(rays_one > rays_implicit, "{rays_one} rays with light sampling, {rays_implicit} without");
    let lit = |image: &[Vec3]| image.iter().filter(|p| p.max_element() > 0.0).count();
    assert!(lit(&one) > lit(&implicit), "light sampling lit {} pixels, implicit {}", lit(&one), lit(&implicit));
    for (threads, builder) in [(2, Builder::default()), (3, Builder::PHR_HQ.with_branching(8).unwrap())] {
        let (image, rays) = render_with(&scene, threads, 7, builder, true);
        assert_eq!(rays, rays_one, "{threads} threads, {builder}: different number of rays");
        let differing = bits(&one).iter().zip(&bits(&image)).filter(|(a, b)| a != b).count();
        assert_eq!(differing, 0, "{threads} threads, {builder}: {differing} pixels differ");
    }
}

/// The wavefront (a tile's rays intersected as a batch) and the single-ray loop give the same
/// image, bit for bit, and trace the same rays: on a scene of triangles alone (the packed
/// triangle test) and on the built-in scene (spheres among the triangles, the part's own leaf
/// test), both through the interleaved traversal; with each estimator; and the guided frames'
/// first hits agree too.
#[test]
fn wavefront_and_single_ray_tracing_give_the_same_image() {
    use phr_render::render::Tracing;
    let cornell = concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/reference/scenes/cornell_obj.json");
    let scenes = [
        ("cornell_obj", phr_render::scene::load_scene(std::path::Path::new(cornell)).expect("shared cornell_obj.json")),
        ("builtin", builtin::cornell_knot()),
    ];
    for (name, scene) in &scenes {
        let mut geometry = Geometry::new(scene);
        geometry.build(&Builder::default());
        let lights = LightSet::new(&geometry, &scene.materials, &scene.background);
        let view = scene.view(None).expect("default view");
        let settings = RenderSettings { width: WIDTH, height: HEIGHT, spp: 1, max_depth: MAX_DEPTH };
        for nee in [false, true] {
            let renderer = |tracing| {
                Renderer::new(scene, &geometry, &view, &settings, nee.then_some(&lights))
                    .with_seed(5)
                    .with_tracing(tracing)
            };
            let (single, wavefront) = (renderer(Tracing::Single), renderer(Tracing::Wavefront));
            let what = format!("{name}, light sampling {nee}");
            for frame in 0..2 {
                let (a, sa) = single.render_frame(frame);
                let (b, sb) = wavefront.render_frame(frame);
                assert_eq!(sa.rays, sb.rays, "{what}: rays traced, frame {frame}");
                assert_eq!(bits(&a), bits(&b), "{what}: frame {frame}");
                // Not vacuous: at 1 spp the implicit estimator finds the small lamp of a few paths.
                let lit = a.iter().filter(|p| p.max_element() > 0.0).count();
                assert!(lit > a.len() / 100, "{what}: a dark image, {lit} of {} pixels lit", a.len());
                let (ga, ha, _) = single.render_frame_guided(frame);
                let (gb, hb, _) = wavefront.render_frame_guided(frame);
                assert_eq!(bits(&ga), bits(&a), "{what}: guided single-ray colour, frame {frame}");
                assert_eq!(bits(&gb), bits(&a), "{what}: guided wavefront colour, frame {frame}");
                assert_eq!(ha, hb, "{what}: first hits, frame {frame}");
                assert!(ha.iter().any(|h| h.normal != Vec3::ZERO), "{what}: no first hit recorded");
            }
        }
    }
}

/// The batch queries the wavefront uses give each ray what the one-ray queries give it, on
/// scenes cut into parts: the built-in scene cut into three parts, one of them moved by a
/// transform (searched as a batch in its object space after the parts in place), the same
/// with all three moved (under a top-level tree, searched one ray at a time), a mesh placed
/// as a copy under a floor (`scenes/instances/bunnies_1.json`), and a quad cut out by an alpha
/// mask (`tests/references/alpha_mask.json`).
/// Camera rays, rays in every direction from inside the scene, and finite shadow-like
/// intervals; the renders of both tracings agree too.
#[test]
fn batch_queries_equal_single_ray_queries_on_parts_and_copies() {
    use glam::Affine3A;
    use phr_bvh::Ray;
    use phr_render::render::Tracing;
    let split_in_three = || {
        let mut g = Geometry::new(&builtin::cornell_knot());
        let n = g.prim_count() as u32;
        g.split((0..3).map(|k| (0..n).filter(|p| p % 3 == k).collect()).collect(), &Builder::default());
        g
    };
    let moved = Affine3A::from_rotation_y(0.2) * Affine3A::from_translation(Vec3::new(0.05, 0.0, -0.1));
    let mut split = split_in_three();
    split.place(&[(2, moved)]);
    let mut all_moved = split_in_three();
    all_moved.place(&[(0, Affine3A::from_translation(Vec3::new(0.0, 0.02, 0.0))), (1, moved.inverse()), (2, moved)]);
    let bunnies = concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/instances/bunnies_1.json");
    let bunnies = phr_render::scene::load_scene(std::path::Path::new(bunnies)).expect("bunnies_1.json");
    let mut copies = Geometry::new(&bunnies);
    copies.build(&Builder::default());
    let cornell = builtin::cornell_knot();
    let masked = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/references/alpha_mask.json");
    let masked = phr_render::scene::load_scene(std::path::Path::new(masked)).expect("alpha_mask.json");
    let mut cutout = Geometry::new(&masked);
    cutout.build(&Builder::default());
    // A point to aim rays at, and a spread around it: the middle of the built-in box, and
    // the one bunny (far to the left of its file's views).
    let aims = [
        (cornell_view_target(), 150.0),
        (cornell_view_target(), 150.0),
        (Vec3::new(-42.7, 1.0, 0.1), 1.0),
        (Vec3::new(0.0, 0.9, 0.15), 0.7),
    ];
    let cases = [
        ("split builtin", &split, &cornell),
        ("split builtin, all moved", &all_moved, &cornell),
        ("bunny copy", &copies, &bunnies),
        ("alpha mask", &cutout, &masked),
    ];
    for ((name, geometry, scene), (aim, spread)) in cases.into_iter().zip(aims) {
        let view = scene.view(None).expect("default view");
        let settings = RenderSettings { width: 24, height: 24, spp: 1, max_depth: MAX_DEPTH };
        let renderer = Renderer::new(scene, geometry, &view, &settings, None);
        let mut rays: Vec<Ray> =
            (0..24 * 24).map(|i| renderer.camera.ray((i % 24) as f32 + 0.5, (i / 24) as f32 + 0.5)).collect();
        let origin = view.position;
        let mut s = 7u32;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s as f32 / u32::MAX as f32 * 2.0 - 1.0
        };
        for _ in 0..600 {
            let dir = Vec3::new(next(), next(), next());
            rays.push(Ray::new(origin + dir * 0.5, dir));
            rays.push(Ray::with_interval(origin, Vec3::new(next(), next(), next()) * 4.0, 0.0, 1.0 - 1e-4));
            let target = aim + Vec3::new(next(), next(), next()) * spread;
            let from = target + Vec3::new(next(), 1.0, next()) * 6.0 * spread;
            rays.push(Ray::new(from, target - from));
        }
        let mut hits = vec![None; rays.len()];
        geometry.intersect_batch(&rays, &mut hits);
        let mut occluded = vec![false; rays.len()];
        geometry.occluded_batch(&rays, &mut occluded);
        for (i, ray) in rays.iter().enumerate() {
            assert_eq!(hits[i], geometry.intersect(ray), "{name}: closest hit, ray {i} {ray:?}");
            assert_eq!(occluded[i], geometry.occluded(ray), "{name}: occlusion, ray {i} {ray:?}");
        }
        let found = hits.iter().filter(|h| h.is_some()).count();
        assert!(found > rays.len() / 5, "{name}: only {found} of {} rays hit", rays.len());
        let parts: std::collections::BTreeSet<u32> = hits.iter().flatten().map(|h| h.part).collect();
        assert!(parts.len() > 1 || name == "alpha mask", "{name}: every hit in one part: {parts:?}");
        let single = renderer.with_tracing(Tracing::Single);
        let (a, _) = single.render_frame(1);
        let (b, _) = Renderer::new(scene, geometry, &view, &settings, None).render_frame(1);
        assert_eq!(bits(&a), bits(&b), "{name}: wavefront and single-ray renders");
    }
}

/// Where the built-in scene's default view looks.
fn cornell_view_target() -> Vec3 {
    builtin::cornell_knot().view(None).expect("default view").look_at
}

/// A renderer made with paths of no segment (the library does not forbid it; the command
/// line refuses it) traces no ray and renders black, in both tracings.
#[test]
fn paths_of_no_segment_trace_nothing() {
    use phr_render::render::Tracing;
    let scene = builtin::cornell_knot();
    let mut geometry = Geometry::new(&scene);
    geometry.build(&Builder::default());
    let view = scene.view(None).expect("default view");
    let settings = RenderSettings { width: 16, height: 16, spp: 1, max_depth: 0 };
    for tracing in [Tracing::Single, Tracing::Wavefront] {
        let (pixels, stats) =
            Renderer::new(&scene, &geometry, &view, &settings, None).with_tracing(tracing).render_frame(0);
        assert_eq!(stats.rays, 0, "{tracing}");
        assert!(pixels.iter().all(|p| *p == Vec3::ZERO), "{tracing}");
    }
}

/// Renders `geometry` as `phr render` does, with explicit light sampling if `nee`: 2 frames of
/// 32², film mean.
fn render_geometry(scene: &Scene, geometry: &Geometry, nee: bool) -> Vec<Vec3> {
    let lights = nee.then(|| LightSet::new(geometry, &scene.materials, &scene.background));
    let view = scene.view(None).expect("default view");
    let settings = RenderSettings { width: 32, height: 32, spp: 2, max_depth: MAX_DEPTH };
    let renderer = Renderer::new(scene, geometry, &view, &settings, lights.as_ref()).with_seed(3);
    let mut film = Film::new(32, 32);
    for frame in 0..2 {
        film.add_frame(&renderer.render_frame(frame).0);
    }
    film.mean()
}

/// Releasing the scene-order triangles (`phr render` does, so that the packed blocks are the
/// only copy) changes nothing: the same triangles, bit for bit, through
/// `Geometry::triangle_edges`, the same hits on the counting traversal (which reads the
/// triangles by primitive index), the same lights and the same images, implicit and with
/// light sampling; on one tree (with the SBVH too, which puts a triangle in several leaves)
/// and on parts, one of them moved, which can still be placed after the release.
#[test]
fn released_triangles_render_the_same_image() {
    use glam::Affine3A;
    use phr_bvh::sbvh::SbvhOptions;
    use phr_bvh::{Ray, TraversalStats};
    let scene = builtin::cornell_knot();
    let moved = Affine3A::from_rotation_y(0.2) * Affine3A::from_translation(Vec3::new(0.05, 0.0, -0.1));
    let make = |case: &str| {
        let mut g = Geometry::new(&scene);
        match case {
            "sbvh" => g.build(&Builder::Sbvh(SbvhOptions::default())),
            "parts" => {
                let n = g.prim_count() as u32;
                let groups: Vec<Vec<u32>> = (0..3).map(|k| (0..n).filter(|p| p % 3 == k).collect()).collect();
                g.split(groups, &Builder::default());
                g.place(&[(2, moved)]);
            }
            _ => g.build(&Builder::default()),
        }
        g
    };
    for case in ["one tree", "sbvh", "parts"] {
        let kept = make(case);
        let mut released = make(case);
        assert!(released.release_triangles(), "{case}: every triangle is in a tree");
        assert!(released.triangles.is_empty(), "{case}");
        let n = kept.triangle_count();
        assert_eq!(released.triangle_count(), n, "{case}");
        let saved = kept.memory().triangles - released.memory().triangles;
        assert_eq!(saved, n * 32, "{case}: 36 bytes of vertices less 4 of slot, per triangle");
        for p in 0..n {
            let [a, b, c] = kept.world_triangle(p);
            let [v0, e1, e2] = kept.triangle_edges(p);
            assert_eq!(released.triangle_edges(p), [v0, e1, e2], "{case}: triangle {p}");
            assert_eq!(released.world_triangle_edges(p), kept.world_triangle_edges(p), "{case}: triangle {p}");
            if case != "parts" {
                assert_eq!([v0, e1, e2], [a, b - a, c - a], "{case}: triangle {p}");
            }
        }
        let view = scene.view(None).expect("default view");
        let settings = RenderSettings { width: 24, height: 24, spp: 1, max_depth: MAX_DEPTH };
        let camera = Renderer::new(&scene, &kept, &view, &settings, None).camera;
        for i in 0..24 * 24 {
            let ray: Ray = camera.ray((i % 24) as f32 + 0.5, (i / 24) as f32 + 0.5);
            let (mut s1, mut s2) = (TraversalStats::default(), TraversalStats::default());
            assert_eq!(released.intersect_counted(&ray, &mut s1), kept.intersect_counted(&ray, &mut s2), "{case}");
        }
        for nee in [false, true] {
            let a = render_geometry(&scene, &kept, nee);
            assert!(a.iter().any(|p| p.max_element() > 0.0), "{case}: a black image");
            assert_eq!(bits(&render_geometry(&scene, &released, nee)), bits(&a), "{case}, light sampling {nee}");
        }
        if case == "parts" {
            let (mut kept, mut released) = (kept, released);
            kept.place(&[(2, Affine3A::IDENTITY)]);
            released.place(&[(2, Affine3A::IDENTITY)]);
            assert_eq!(bits(&render_geometry(&scene, &released, true)), bits(&render_geometry(&scene, &kept, true)));
        }
    }
}

/// What would build or pack triangles refuses a released geometry, loudly.
#[test]
#[should_panic(expected = "the triangles were released")]
fn a_released_geometry_is_not_rebuilt() {
    let mut geometry = Geometry::new(&builtin::cornell_knot());
    geometry.build(&Builder::default());
    assert!(geometry.release_triangles());
    geometry.build(&Builder::default());
}

/// An alpha mask removes hits and nothing else: against the same quad without its mask, every
/// ray that hits the masked quad hits it at the same place, every ray whose hits differ hit
/// the quad without the mask, and some rays pass through the holes to the wall behind.
#[test]
fn alpha_masks_only_remove_hits() {
    use phr_bvh::Ray;
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/references/alpha_mask.json");
    let masked = phr_render::scene::load_scene(std::path::Path::new(path)).expect("alpha_mask.json");
    let leaf = masked.material_index("leaf").expect("the masked material");
    assert!(masked.material_mask[leaf as usize].is_some());
    let mut solid = masked.clone();
    solid.material_mask.iter_mut().for_each(|m| *m = None);
    let (mut with, mut without) = (Geometry::new(&masked), Geometry::new(&solid));
    with.build(&Builder::default());
    without.build(&Builder::default());
    let view = masked.view(None).expect("default view");
    let settings = RenderSettings { width: 64, height: 64, spp: 1, max_depth: MAX_DEPTH };
    let camera = Renderer::new(&masked, &with, &view, &settings, None).camera;
    let (mut through, mut on_leaf) = (0, 0);
    for i in 0..64 * 64 {
        let ray: Ray = camera.ray((i % 64) as f32 + 0.5, (i / 64) as f32 + 0.5);
        let (a, b) = (with.intersect(&ray), without.intersect(&ray));
        let material =
            |g: &Geometry, h: &Option<phr_render::geometry::Hit>| h.map(|h| g.surface_point(&ray, &h).material);
        if material(&with, &a) == Some(leaf) {
            on_leaf += 1;
            assert_eq!(a, b, "ray {i}: a covered hit moved");
        } else if a != b {
            assert_eq!(material(&without, &b), Some(leaf), "ray {i}: a hit changed that was not on the leaf");
            through += 1;
        }
    }
    assert!(on_leaf > 300 && through > 300, "{on_leaf} rays on the leaf, {through} through its holes");
}

/// A renderer handed another renderer's jitter table (as the viewer's pipeline does from
/// frame to frame) renders what a fresh one does, whatever the table's seed, and so does a
/// renderer whose seed is changed after its table was made.
#[test]
fn a_handed_over_jitter_table_changes_nothing() {
    let scene = builtin::cornell_knot();
    let mut geometry = Geometry::new(&scene);
    geometry.build(&Builder::default());
    let view = scene.view(None).expect("default view");
    let settings = RenderSettings { width: WIDTH, height: HEIGHT, spp: 1, max_depth: MAX_DEPTH };
    let fresh = |seed: u64| Renderer::new(&scene, &geometry, &view, &settings, None).with_seed(seed);
    let expected = bits(&fresh(2).render_frame(3).0);
    // A table for seed 1 handed to a seed-2 renderer is not used.
    let other = fresh(1).jitter_table();
    assert_eq!(bits(&fresh(2).with_jitter(Some(other.clone())).render_frame(3).0), expected);
    // Nor is it when the seed changes afterwards, by `with_seed` or by the public field.
    let reseeded = Renderer::new(&scene, &geometry, &view, &settings, None).with_jitter(Some(other)).with_seed(2);
    assert_eq!(bits(&reseeded.render_frame(3).0), expected);
    let mut changed = fresh(1);
    let _ = changed.render_frame(0);
    changed.seed = 2;
    assert_eq!(bits(&changed.render_frame(3).0), expected);
    // A fitting table is used, and gives the same image.
    let table = fresh(2).jitter_table();
    assert_eq!(bits(&fresh(2).with_jitter(Some(table)).render_frame(3).0), expected);
    assert_ne!(bits(&fresh(1).render_frame(3).0), expected, "the seed changes the image");
}
