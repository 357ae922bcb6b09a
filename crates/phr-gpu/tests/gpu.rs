//! The GPU tracer held against the CPU's and against Mitsuba 3.
//!
//! The tests that run kernels need a GPU adapter: a real GPU, or Mesa's software Vulkan driver
//! lavapipe (`apt-get install mesa-vulkan-drivers libvulkan1`). The plain test command skips
//! them (`#[ignore]`); `.ci/run` installs lavapipe and runs them with `--ignored`, where a
//! missing adapter fails them, saying what to install.

use glam::Vec3;
use phr_bvh::{Builder, Ray};
use phr_gpu::scene::{Packed, EMPTY_SLOT};
use phr_gpu::{Gpu, GpuError, GpuFrames, GpuScene, GpuTracer, HitQueries};
use phr_render::camera::Camera;
use phr_render::film::Film;
use phr_render::frame_tracer::{FrameJob, FrameTracer};
use phr_render::geometry::Geometry;
use phr_render::lights::LightSet;
use phr_render::output::{rgba8, write_image};
use phr_render::pipeline::{FramePipeline, PipelineKind, PipelineSettings, ViewMode};
use phr_render::render::Renderer;
use phr_render::sampler::Pcg32;
use phr_render::scene::json::parse_scene;
use phr_render::scene::{load_scene, Scene};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

#[path = "../../phr-render/tests/support/compare_images.rs"]
mod compare_images;
use compare_images::{compare, shared, Noise};

fn gpu() -> &'static Gpu {
    static GPU: OnceLock<Gpu> = OnceLock::new();
    GPU.get_or_init(|| {
        let gpu = Gpu::new().unwrap_or_else(|e| panic!("{e}"));
        println!("GPU: {}", gpu.describe());
        gpu
    })
}

/// A reference scene: one of `shared/reference`, or of phr-render's own (`OWN`).
fn reference_scene(name: &str) -> Scene {
    let path = reference_paths(name).0;
    load_scene(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A reference's scene file and image.
fn reference_paths(name: &str) -> (PathBuf, PathBuf) {
    if OWN.contains(&name) {
        let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../phr-render/tests/references"));
        return (dir.join(format!("{name}.json")), dir.join(format!("{name}_ref.exr")));
    }
    let dir = shared().join("reference");
    (dir.join(format!("scenes/{name}.json")), dir.join(format!("images/{name}.exr")))
}

/// phr-render's references (`crates/phr-render/tests/references`) the GPU draws: a triangle
/// light, an emissive sphere, the sky and glass; OBJ texture coordinates and MTL `map_Kd`; an
/// MTL `map_d` alpha mask cutting holes in a quad; an HDR environment map with a small sun.
const OWN: [&str; 4] = ["lights_mixed", "textured", "alpha_mask", "environment"];

/// The light set of the path tracer with light sampling, or none for the thesis's estimator.
fn light_set(geometry: &Geometry, scene: &Scene, sampled: bool) -> Option<LightSet> {
    sampled.then(|| LightSet::new(geometry, &scene.materials, &scene.background))
}

/// A scene of the repository's `scenes/suite`.
fn suite_scene(name: &str) -> Scene {
    let path = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../../scenes/suite")).join(format!("{name}.json"));
    load_scene(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn built(scene: &Scene, builder: &Builder) -> Geometry {
    let mut geometry = Geometry::new(scene);
    geometry.build(builder);
    geometry
}

/// The nodes are the CPU's wide tree's (empty slots marked), and each leaf's primitives one
/// run of records, the tree's own, with the CPU's edges.
#[test]
fn packing_puts_each_leaf_in_a_row() {
    let scene = reference_scene("cornell_glass_mirror");
    let geometry = built(&scene, &Builder::default());
    let lights = LightSet::new(&geometry, &scene.materials, &scene.background);
    let packed = Packed::new(&scene, &geometry, Some(&lights)).unwrap();
    let tree = geometry.wide_bvh();
    assert_eq!(packed.nodes.len(), tree.nodes.len());
    assert_eq!(packed.prims.len(), tree.prim_indices.len());
    let n_tris = geometry.triangle_count();
    let mut spheres = 0;
    for (node, gpu_node) in tree.nodes.iter().zip(&packed.nodes) {
        for i in 0..8 {
            if !node.is_used(i) {
                assert_eq!(gpu_node.count[i], EMPTY_SLOT, "an empty slot");
                continue;
            }
            assert_eq!((gpu_node.child[i], gpu_node.count[i]), (node.child[i], node.count[i]));
            for row in 0..6 {
                assert_eq!(gpu_node.bounds[row][i].to_bits(), node.bounds[row][i].to_bits());
            }
            let first = node.child[i] as usize;
            for k in 0..node.count[i] as usize {
                let p = tree.prim_indices[first + k];
                let record = packed.prims[first + k];
                assert_eq!(record.b[3].to_bits(), p, "the record's number");
                let emitter = lights.emitters().position(|(q, _, _)| q == p).map_or(0, |k| k as u32 + 1);
                assert_eq!(record.c[3].to_bits(), emitter, "prim {p}'s emitter");
                if (p as usize) < n_tris {
                    let [v0, e1, e2] = geometry.triangle_edges(p as usize);
                    assert_eq!([record.a[0], record.a[1], record.a[2]], v0.to_array());
                    assert_eq!([record.b[0], record.b[1], record.b[2]], e1.to_array());
                    assert_eq!([record.c[0], record.c[1], record.c[2]], e2.to_array());
                    assert_eq!(record.a[3].to_bits(), geometry.triangle_material[p as usize]);
                } else {
                    spheres += 1;
                    let s = &geometry.spheres[p as usize - n_tris];
                    assert_eq!(record.b[0], s.sphere.radius);
                    assert_eq!(record.a[3].to_bits(), s.material | 1 << 31);
                }
            }
        }
    }
    assert_eq!(spheres, 2);
    assert_eq!(packed.materials.len(), scene.materials.len());
    // The ceiling light's two triangles, with their areas and selection probabilities.
    assert_eq!(packed.lights.len(), 2);
    for (light, (p, area, selection)) in packed.lights.iter().zip(lights.emitters()) {
        let [v0, e1, _] = geometry.triangle_edges(p as usize);
        assert_eq!(
            [light.a[0], light.a[1], light.a[2], light.b[0], light.b[1], light.b[2]],
            [v0.x, v0.y, v0.z, e1.x, e1.y, e1.z]
        );
        assert_eq!((light.b[3], light.c[3]), (area, selection));
    }
    assert_eq!(packed.light_cdf, lights.cdf());
    assert_eq!(packed.sky_probability, Some(0.0), "a black background is no light");
    assert!(Packed::new(&scene, &geometry, None).unwrap().lights.is_empty());
}

/// What the kernels cannot draw yet is refused, never drawn wrong.
#[test]
fn what_the_gpu_cannot_draw_is_refused() {
    let scene = reference_scene("cornell_obj");
    let mut released = built(&scene, &Builder::default());
    released.release_triangles();
    match Packed::new(&scene, &released, None) {
        Err(GpuError::Unsupported(what)) => assert!(what.contains("released"), "{what}"),
        other => panic!("released triangles were not refused: {:?}", other.map(|p| p.nodes.len())),
    }
}

/// Rays of every kind through `scene`: the camera's through a grid of pixels, and rays from
/// random points in the scene's box in random directions, some with a finite `tmax`.
fn probe_rays(scene: &Scene, n: usize) -> Vec<Ray> {
    let view = scene.view(None).unwrap();
    let camera = Camera::new(&view, 64, 64);
    let mut rays: Vec<Ray> = (0..64 * 64).map(|i| camera.ray((i % 64) as f32 + 0.5, (i / 64) as f32 + 0.5)).collect();
    let bounds = scene.bounds();
    let mut rng = Pcg32::new(7, 3);
    while rays.len() < n {
        let at = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
        let origin = bounds.min + at * (bounds.max - bounds.min);
        let dir = rng.unit_vector();
        let tmax =
            if rng.next_f32() < 0.25 { rng.next_f32() * (bounds.max - bounds.min).length() } else { f32::INFINITY };
        rays.push(Ray::with_interval(origin, dir, 0.0, tmax));
    }
    rays
}

/// The GPU's traversal finds the CPU's closest hits: the same primitive at the same distance,
/// but where two primitives are hit at the same distance within float rounding (a ray through
/// an edge), and the same misses.
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn closest_hits_equal_the_cpu() {
    let gpu = gpu();
    let scenes = ["cornell_obj", "cornell_glass_mirror", "spheres_sky", "bunny_sky"];
    let mut cases: Vec<(&str, Builder)> =
        scenes.iter().flat_map(|&s| [(s, Builder::default()), (s, Builder::PHR_FAST)]).collect();
    // A 4-ary PHR tree, collapsed into the wide tree like any other.
    cases.push(("bunny_sky", Builder::PHR_FAST.with_branching(4).unwrap()));
    // 262k triangles, and the SBVH, whose leaves share triangles.
    cases.push(("sponza", "sbvh".parse().unwrap()));
    // Holes cut by an alpha mask.
    cases.push(("alpha_mask", Builder::default()));
    for (name, builder) in cases {
        let scene = if name == "sponza" { suite_scene(name) } else { reference_scene(name) };
        let geometry = built(&scene, &builder);
        let uploaded = GpuScene::upload(gpu, &scene, &geometry, None).unwrap();
        let rays = probe_rays(&scene, 50_000);
        let hits = HitQueries::new(gpu, &uploaded).closest_hits(gpu, &uploaded, &rays).unwrap();
        assert_hits_equal(&format!("{name} ({builder})"), &hits, &geometry, &rays);
    }
}

/// `scene`'s primitives cut into three parts by number, two of them moved by transforms: a
/// rotation with a non-uniform scale, and a mirror.
fn in_three_parts(scene: &Scene) -> Geometry {
    use glam::{Affine3A, Quat};
    let mut geometry = Geometry::new(scene);
    let n = geometry.prim_count() as u32;
    geometry
        .split(vec![(0..n / 3).collect(), (n / 3..2 * n / 3).collect(), (2 * n / 3..n).collect()], &Builder::default());
    let turned = Affine3A::from_scale_rotation_translation(
        Vec3::new(1.1, 0.8, 1.0),
        Quat::from_rotation_y(0.6),
        Vec3::new(0.05, 0.02, -0.04),
    );
    let mirrored =
        Affine3A::from_translation(Vec3::new(0.02, 0.0, 0.0)) * Affine3A::from_scale(Vec3::new(-1.0, 1.0, 1.0));
    geometry.place(&[(1, turned), (2, mirrored)]);
    assert_eq!(geometry.part_count(), 3);
    geometry
}

/// Through the parts' instances ([`in_three_parts`]), the GPU's closest hits are the CPU's, on
/// triangles and spheres alike.
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn closest_hits_through_instances_equal_the_cpu() {
    let gpu = gpu();
    for name in ["cornell_glass_mirror", "bunny_sky"] {
        let scene = reference_scene(name);
        let geometry = in_three_parts(&scene);
        let uploaded = GpuScene::upload(gpu, &scene, &geometry, None).unwrap();
        let rays = probe_rays(&scene, 50_000);
        let hits = HitQueries::new(gpu, &uploaded).closest_hits(gpu, &uploaded, &rays).unwrap();
        assert_hits_equal(&format!("{name} in three parts, two moved"), &hits, &geometry, &rays);
    }
    // The whole scene one part, moved (a scene of a single moving object).
    let scene = reference_scene("bunny_sky");
    let mut geometry = Geometry::new(&scene);
    geometry.split(vec![(0..geometry.prim_count() as u32).collect()], &Builder::default());
    geometry.place(&[(0, glam::Affine3A::from_rotation_z(0.3) * glam::Affine3A::from_scale(Vec3::new(1.0, 1.3, 0.9)))]);
    assert_eq!(geometry.part_count(), 1);
    let uploaded = GpuScene::upload(gpu, &scene, &geometry, None).unwrap();
    let rays = probe_rays(&scene, 20_000);
    let hits = HitQueries::new(gpu, &uploaded).closest_hits(gpu, &uploaded, &rays).unwrap();
    assert_hits_equal("bunny_sky as one moved part", &hits, &geometry, &rays);
}

/// A scene of meshes placed many times (`instances`): five bunnies (turned, scaled unevenly,
/// mirrored), three copies of a tetrahedron, two of a textured corner (phr-render's `textured`
/// reference, its texture read through the copies' texture coordinates), a floor and a
/// ball; with `animate`, the tetrahedra turn.
fn copies_scene(animate: bool) -> Scene {
    let bunny = compare_images::shared().join("scenes/bunny/bun_zipper.ply");
    let textured = reference_paths("textured").0.with_file_name("textured.obj");
    let turning = if animate { r#", "animate": { "type": "rotate", "degrees_per_second": 90 }"# } else { "" };
    let text = format!(
        r#"{{
  "background": {{ "type": "gradient", "bottom": [1, 1, 1], "top": [0.5, 0.7, 1.0] }},
  "camera": {{ "position": [0, 0.6, 1.6], "look_at": [0, 0.1, 0], "vfov": 50 }},
  "materials": {{
    "clay": {{ "type": "lambertian", "albedo": [0.8, 0.45, 0.3] }},
    "steel": {{ "type": "metal", "albedo": [0.8, 0.8, 0.9], "fuzz": 0.05 }},
    "floor": {{ "type": "lambertian", "albedo": 0.6 }}
  }},
  "objects": [
    {{ "type": "quad", "Q": [-2, -0.03, 1], "u": [4, 0, 0], "v": [0, 0, -3], "material": "floor" }},
    {{ "type": "sphere", "center": [0.45, 0.12, -0.4], "radius": 0.15, "material": "steel" }},
    {{ "type": "mesh", "file": "{}", "material": "clay", "instances": [
      {{ "scale": 2, "translate": [0, -0.1, 0] }},
      {{ "scale": [2.5, 1.5, 2], "rotate": [0, 1, 0, 60], "translate": [-0.5, -0.08, -0.3] }},
      {{ "scale": [-2, 2, 2], "translate": [0.5, -0.1, 0] }},
      {{ "scale": 3, "rotate": [[1, 0, 0, 20], [0, 1, 0, -40]], "translate": [0.1, -0.05, -0.8] }},
      {{ "scale": 1.2, "translate": [-0.3, -0.05, 0.35] }}
    ] }},
    {{ "type": "triangles", "material": "steel",
       "vertices": [[0, 0, 0], [0.2, 0, 0], [0.1, 0.25, 0.05], [0.1, 0, 0.18]],
       "faces": [[0, 1, 2], [1, 3, 2], [3, 0, 2], [0, 3, 1]],
       "instances": [{{ "translate": [-0.7, -0.03, 0.1] }}, {{ "rotate": [0, 0, 1, 30], "translate": [0.7, 0, 0.2] }},
                     {{ "scale": [1, -1.5, 1], "translate": [0, 0.45, -0.2] }}]{} }},
    {{ "type": "obj_mtl", "file": "{}", "instances": [
      {{ "scale": 0.3, "rotate": [0, 1, 0, 30], "translate": [-0.75, -0.01, -0.6] }},
      {{ "scale": [-0.25, 0.3, 0.3], "rotate": [0, 1, 0, -20], "translate": [0.8, -0.01, -0.5] }}
    ] }}
  ]
}}"#,
        bunny.display(),
        turning,
        textured.display()
    );
    let scene = parse_scene(&text, Path::new("copies.json")).unwrap();
    assert_eq!(scene.instanced.len(), 3, "three meshes placed many times");
    assert!(scene.material_texture.iter().any(Option::is_some), "a textured copy");
    scene
}

/// Through the copies of meshes placed many times (three meshes, ten copies under the
/// top-level tree, mirrored ones among them), with the scene in one tree and cut into parts,
/// the GPU's closest hits are the CPU's.
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn closest_hits_through_copies_equal_the_cpu() {
    let gpu = gpu();
    let scene = copies_scene(false);
    let mut geometry = built(&scene, &Builder::default());
    assert_eq!(geometry.copy_count(), 10);
    let rays = probe_rays(&scene, 50_000);
    for layout in ["one tree", "two parts, one moved"] {
        if layout != "one tree" {
            let n = geometry.prim_count() as u32;
            geometry.split(vec![vec![0, 1], (2..n).collect()], &Builder::default());
            geometry.place(&[(1, glam::Affine3A::from_translation(Vec3::new(0.0, 0.05, 0.1)))]);
        }
        let uploaded = GpuScene::upload(gpu, &scene, &geometry, None).unwrap();
        let hits = HitQueries::new(gpu, &uploaded).closest_hits(gpu, &uploaded, &rays).unwrap();
        assert_hits_equal(&format!("copies, {layout}"), &hits, &geometry, &rays);
    }
}

/// Frames through copies of meshes placed many times ([`copies_scene`]) are the CPU's, pixel
/// by pixel.
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn frames_through_copies_equal_the_cpu() {
    let gpu = gpu();
    let scene = copies_scene(false);
    let geometry = built(&scene, &Builder::default());
    let uploaded = GpuScene::upload(gpu, &scene, &geometry, None).unwrap();
    let view = scene.view(None).unwrap();
    let settings = phr_render::scene::RenderSettings { width: 96, height: 80, max_depth: 6, ..scene.settings };
    let camera = Camera::new(&view, settings.width, settings.height);
    let cpu = Renderer::new(&scene, &geometry, &view, &settings, None).with_seed(99);
    let mut tracer = GpuTracer::new(gpu, &uploaded, &camera, 96, 80, settings.max_depth, 99).unwrap();
    tracer.render(&uploaded, 3..4);
    assert_alike(&cpu.render_frame(3).0, &tracer.film().unwrap().mean(), 100, "copies");
}

/// The number the GPU gives `hit`'s primitive: a copy's triangle is numbered after the
/// scene's primitives, mesh after mesh (`Packed`'s layout), the others keep theirs.
fn gpu_number(geometry: &Geometry, hit: &phr_render::geometry::Hit) -> u32 {
    use phr_render::geometry::COPY;
    if hit.part & COPY == 0 {
        return hit.prim;
    }
    let (mesh, _, _) = geometry.copy_placement((hit.part & !COPY) as usize).unwrap();
    let before: usize = (0..mesh).map(|m| geometry.copied_mesh(m).triangles.len()).sum();
    (geometry.prim_count() + before) as u32 + hit.prim
}

/// The GPU's closest hits `hits` of `rays` are the CPU's ([`closest_hits_equal_the_cpu`]).
fn assert_hits_equal(name: &str, hits: &[Option<phr_gpu::GpuHit>], geometry: &Geometry, rays: &[Ray]) {
    let (mut same, mut ties, mut found) = (0, 0, 0);
    for (ray, gpu_hit) in rays.iter().zip(hits) {
        let cpu_hit = geometry.intersect(ray);
        found += usize::from(cpu_hit.is_some());
        match (cpu_hit, gpu_hit) {
            (None, None) => same += 1,
            (Some(c), Some(g)) if gpu_number(geometry, &c) == g.prim => {
                assert!(
                    (c.t - g.t).abs() <= 1e-5 * c.t,
                    "{name}: prim {} at t {} (CPU) and {} (GPU)",
                    c.prim,
                    c.t,
                    g.t
                );
                same += 1;
            }
            (Some(c), Some(g)) if (c.t - g.t).abs() <= 1e-5 * c.t => ties += 1,
            (c, g) => panic!("{name}: ray {ray:?}: CPU {c:?}, GPU {g:?}"),
        }
    }
    println!("{name}: {same} rays alike, {ties} ties at one distance, {found} hits of {}", rays.len());
    assert!(found > rays.len() / 4, "{name}: the rays should hit something");
    assert!(ties * 1000 <= rays.len(), "{name}: {ties} ties of {}", rays.len());
}

/// A scene whose nodes and primitives exceed one storage binding is cut across several (as
/// dragons8 is on lavapipe, whose bindings hold 128 MiB). With the adapter's limit lowered so
/// that the bunny's primitives take four bindings and its nodes at least two, the hits are
/// still the CPU's: through a scene uploaded so, and through Sponza uploaded whole and then
/// updated to it (the kernel, compiled for one binding each, must be compiled again). One
/// binding fewer than the primitives need is refused with a clear error.
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn trees_cut_across_bindings_give_the_cpus_hits() {
    let scene = reference_scene("bunny_sky");
    let geometry = built(&scene, &Builder::default());
    let packed = Packed::new(&scene, &geometry, None).unwrap();
    let node_bytes = std::mem::size_of_val(&packed.nodes[..]) as u64;
    let prim_bytes = std::mem::size_of_val(&packed.prims[..]) as u64;
    let mut small = gpu().clone();
    // The primitives over four bindings (the most there are), the nodes over two or more.
    small.max_binding = prim_bytes.div_ceil(4).next_multiple_of(96);
    let node_bindings = node_bytes.div_ceil(small.max_binding);
    assert!((2..=4).contains(&node_bindings), "{prim_bytes} bytes of primitives, {node_bytes} of nodes");
    // 20,000 rays: the query's own buffer must fit the lowered limit too.
    let rays = probe_rays(&scene, 20_000);
    let name = format!("bunny_sky, primitives over 4 bindings, nodes over {node_bindings}");
    let uploaded = GpuScene::upload_packed(&small, &packed, scene.background.clone()).unwrap();
    let hits = HitQueries::new(&small, &uploaded).closest_hits(&small, &uploaded, &rays).unwrap();
    assert_hits_equal(&name, &hits, &geometry, &rays);
    // Sponza uploaded whole, then the bunny written over it: the bindings' first parts in
    // place, over Sponza's, whose nodes and primitives stay beyond them.
    let sponza = suite_scene("sponza");
    let sponza = Packed::new(&sponza, &built(&sponza, &Builder::default()), None).unwrap();
    // Sponza's arrays fill at least a lowered binding each, so the bunny's first parts are
    // written into them in place.
    let bytes = |items: usize, size: usize| (items * size) as u64;
    assert!(
        bytes(sponza.nodes.len(), std::mem::size_of::<phr_gpu::scene::GpuNode>()) >= small.max_binding
            && bytes(sponza.prims.len(), std::mem::size_of::<phr_gpu::scene::GpuPrim>()) >= small.max_binding
    );
    let mut whole = GpuScene::upload_packed(gpu(), &sponza, scene.background.clone()).unwrap();
    let queries = HitQueries::new(gpu(), &whole);
    whole.update(&small, &packed).unwrap();
    let hits = queries.closest_hits(&small, &whole, &rays).unwrap();
    assert_hits_equal(&format!("{name}, after an update"), &hits, &geometry, &rays);
    small.max_binding = prim_bytes.div_ceil(5).next_multiple_of(96);
    match GpuScene::upload_packed(&small, &packed, scene.background.clone()) {
        Err(GpuError::TooLarge(why)) => assert!(why.contains("primitives"), "{why}"),
        other => panic!("five bindings' worth of primitives: {:?}", other.err()),
    }
}

/// Frame `k` on the GPU gives (almost) every pixel the sample the CPU's frame `k` gives it,
/// with either estimator: the same camera ray, random numbers drawn in the same order, the
/// same materials and lights, so the paths coincide until rounding sends one elsewhere (a
/// bounce off an edge).
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn frames_equal_the_cpu_pixel_by_pixel() {
    let gpu = gpu();
    for name in ["cornell_glass_mirror", "spheres_sky", "lights_mixed", "textured", "alpha_mask", "environment"] {
        let scene = reference_scene(name);
        let geometry = built(&scene, &Builder::default());
        for sampled in [false, true] {
            let lights = light_set(&geometry, &scene, sampled);
            let uploaded = GpuScene::upload(gpu, &scene, &geometry, lights.as_ref()).unwrap();
            let view = scene.view(None).unwrap();
            let settings = phr_render::scene::RenderSettings { width: 96, height: 80, ..scene.settings };
            let camera = Camera::new(&view, settings.width, settings.height);
            let cpu = Renderer::new(&scene, &geometry, &view, &settings, lights.as_ref()).with_seed(99);
            for frame in [0, 7] {
                let (w, h) = (settings.width, settings.height);
                let mut tracer = GpuTracer::new(gpu, &uploaded, &camera, w, h, settings.max_depth, 99).unwrap();
                tracer.render(&uploaded, frame..frame + 1);
                let gpu_pixels = tracer.film().unwrap().mean();
                let cpu_pixels = cpu.render_frame(frame).0;
                assert_alike(
                    &cpu_pixels,
                    &gpu_pixels,
                    100,
                    &format!("{name}, light sampling {sampled}, frame {frame}"),
                );
            }
        }
    }
}

/// Frames through the parts' instances ([`in_three_parts`]; the lights of `lights_mixed` among
/// the moved primitives) are the CPU's, pixel by pixel, with either estimator: surfaces and
/// normals placed in the world as on the CPU, mirrored triangles turned around, emitters
/// sampled where they are.
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn frames_through_instances_equal_the_cpu() {
    let gpu = gpu();
    for name in ["cornell_glass_mirror", "lights_mixed"] {
        let scene = reference_scene(name);
        let geometry = in_three_parts(&scene);
        for sampled in [false, true] {
            let lights = light_set(&geometry, &scene, sampled);
            let uploaded = GpuScene::upload(gpu, &scene, &geometry, lights.as_ref()).unwrap();
            let view = scene.view(None).unwrap();
            let settings = phr_render::scene::RenderSettings { width: 96, height: 80, ..scene.settings };
            let camera = Camera::new(&view, settings.width, settings.height);
            let cpu = Renderer::new(&scene, &geometry, &view, &settings, lights.as_ref()).with_seed(99);
            let (w, h) = (settings.width, settings.height);
            let mut tracer = GpuTracer::new(gpu, &uploaded, &camera, w, h, settings.max_depth, 99).unwrap();
            tracer.render(&uploaded, 3..4);
            let what = format!("{name} in three parts, light sampling {sampled}");
            assert_alike(&cpu.render_frame(3).0, &tracer.film().unwrap().mean(), 100, &what);
        }
    }
}

/// The GPU's images of the four references of `shared/reference` and of phr-render's own
/// (`OWN`), 256 samples per pixel, with both estimators, through the team's comparison tool: the thesis's estimator
/// judged by the reference's noise per sample, light sampling by its own variance.
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn images_match_the_mitsuba_references() {
    let gpu = gpu();
    const SPP: u32 = 256;
    let shared = ["cornell_obj", "cornell_glass_mirror", "spheres_sky", "bunny_sky"];
    for name in shared.into_iter().chain(OWN) {
        let scene = reference_scene(name);
        let geometry = built(&scene, &Builder::default());
        for sampled in [false, true] {
            let lights = light_set(&geometry, &scene, sampled);
            let uploaded = GpuScene::upload(gpu, &scene, &geometry, lights.as_ref()).unwrap();
            let (w, h) = (scene.settings.width, scene.settings.height);
            let camera = Camera::new(&scene.view(None).unwrap(), w, h);
            let mut tracer = GpuTracer::new(gpu, &uploaded, &camera, w, h, scene.settings.max_depth, 12345).unwrap();
            tracer.render(&uploaded, 0..SPP);
            let film = tracer.film().unwrap();
            assert_eq!(film.samples, SPP);
            let out = std::env::temp_dir().join(format!("phr-gpu-{name}-{sampled}-{}.pfm", std::process::id()));
            let variance = out.with_extension("var.pfm");
            write_image(&out, w, h, &film.mean()).unwrap();
            let noise = if sampled {
                write_image(&variance, w, h, &film.variance_of_mean()).unwrap();
                Noise::Variance(&variance)
            } else {
                Noise::Spp(SPP)
            };
            let (passed, text) = compare(&out, &reference_paths(name).1, noise);
            let _ = std::fs::remove_file(&out);
            let _ = std::fs::remove_file(&variance);
            println!("{name}, {SPP} spp on the GPU, light sampling {sampled}:\n{text}");
            assert!(passed, "{name} on the GPU (light sampling {sampled}) does not match the reference:\n{text}");
        }
    }
}

/// A scene uploaded over another ([`GpuScene::update`]): the hits are the new scene's, both
/// where its contents need larger buffers (the bunny over the Cornell box) and where they fit
/// the ones there are (the bunny moved, rebuilt by PHR, then by the SBVH).
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn an_updated_scene_is_the_moved_one() {
    let gpu = gpu();
    let small = reference_scene("cornell_obj");
    let mut uploaded = GpuScene::upload(gpu, &small, &built(&small, &Builder::default()), None).unwrap();
    let queries = HitQueries::new(gpu, &uploaded);
    let scene = reference_scene("bunny_sky");
    let mut geometry = built(&scene, &Builder::PHR_FAST);
    let rays = probe_rays(&scene, 20_000);
    let shift = Vec3::new(0.01, 0.02, -0.01);
    let builders = [Builder::PHR_FAST, Builder::PHR_FAST, "sbvh".parse().unwrap()];
    for (step, builder) in builders.into_iter().enumerate() {
        if step > 0 {
            for t in &mut geometry.triangles {
                *t = t.map(|v| v + shift);
            }
        }
        geometry.update_boxes();
        let bvh = geometry.build_report(&builder).bvh;
        geometry.set_bvh(bvh);
        let packed = Packed::moved(&scene, &geometry, geometry.wide_bvh(), None).unwrap();
        uploaded.update(gpu, &packed).unwrap();
        let hits = queries.closest_hits(gpu, &uploaded, &rays).unwrap();
        let mismatches = rays
            .iter()
            .zip(&hits)
            .filter(|(ray, g)| match (geometry.intersect(ray), g) {
                (None, None) => false,
                // Another primitive at the same distance is a tie, not a mismatch.
                (Some(c), Some(g)) => (c.t - g.t).abs() > 1e-5 * c.t,
                _ => true,
            })
            .count();
        assert_eq!(mismatches, 0, "update {step} ({builder}): {mismatches} rays disagree");
    }
}

/// At least 98 % of the pixels lit on either side (more than `min_lit` of them) have samples
/// that agree to 1e-3 (relative). Black samples (paths that never reached a light) agree
/// whatever the random numbers, so they are left out.
fn assert_alike(cpu: &[Vec3], gpu: &[Vec3], min_lit: usize, what: &str) {
    let lit: Vec<(Vec3, Vec3)> = cpu
        .iter()
        .zip(gpu)
        .filter(|(c, g)| c.max_element() > 0.0 || g.max_element() > 0.0)
        .map(|(c, g)| (*c, *g))
        .collect();
    let close = |c: Vec3, g: Vec3| (c - g).abs().max_element() <= 1e-3 * (1.0 + c.abs().max_element());
    let alike = lit.iter().filter(|(c, g)| close(*c, *g)).count();
    let share = alike as f64 / lit.len().max(1) as f64;
    println!("{what}: {:.2} % of {} lit pixels alike", 100.0 * share, lit.len());
    assert!(lit.len() > min_lit, "{what}: too few lit pixels ({})", lit.len());
    assert!(share >= 0.98, "{what}: only {:.2} % of the lit pixels alike", 100.0 * share);
}

/// The viewer's pipeline with the GPU tracing its frames ([`GpuFrames`]) shows the CPU's
/// frames: while the scene moves (what moved uploaded), while it is still (accumulating),
/// after the camera moved and after light sampling was switched. Three scenes: a deforming
/// floor and lamp (`moving_light.json`), parts that move rigidly around a deforming one
/// ([`moving_parts`]), and turning copies of a mesh placed many times ([`copies_scene`]).
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn the_viewers_frames_on_the_gpu_are_the_cpus() {
    let text = |text: String| move || parse_scene(&text, Path::new("moving.json")).unwrap();
    let moving_light = text(include_str!("../../phr-render/tests/support/moving_light.json").into());
    let moving_parts = text(moving_parts());
    for pipeline in PipelineKind::ALL {
        viewer_frames_alike(&moving_light, pipeline, false);
        viewer_frames_alike(&moving_parts, pipeline, true);
        viewer_frames_alike(&|| copies_scene(true), pipeline, true);
    }
}

/// A scene of a static floor of 2,048 triangles; a box, a sphere and a lamp that move rigidly
/// (three parts under instances, more than the CPU searches without a top-level tree); and a
/// small waving sheet (a deforming part).
fn moving_parts() -> String {
    let n = 32;
    let floor_vertices: Vec<String> = (0..=n)
        .flat_map(|i| {
            (0..=n).map(move |j| {
                format!("[{}, 0, {}]", -3.0 + 6.0 * i as f32 / n as f32, -3.0 + 6.0 * j as f32 / n as f32)
            })
        })
        .collect();
    let floor_faces: Vec<String> = (0..n)
        .flat_map(|i| {
            (0..n).flat_map(move |j| {
                let v = |a: usize, b: usize| a * (n + 1) + b;
                [
                    format!("[{}, {}, {}]", v(i, j), v(i, j + 1), v(i + 1, j)),
                    format!("[{}, {}, {}]", v(i + 1, j), v(i, j + 1), v(i + 1, j + 1)),
                ]
            })
        })
        .collect();
    format!(
        r#"{{
  "background": [0.05, 0.05, 0.05],
  "camera": {{ "position": [0, 2, 5], "look_at": [0, 0.5, 0], "vfov": 50 }},
  "materials": {{
    "white": {{ "type": "lambertian", "albedo": 0.7 }},
    "steel": {{ "type": "metal", "albedo": [0.8, 0.7, 0.6], "fuzz": 0.1 }},
    "lamp": {{ "type": "emissive", "emit": [8, 8, 8], "two_sided": true }}
  }},
  "objects": [
    {{ "type": "triangles", "material": "white", "vertices": [{}], "faces": [{}] }},
    {{ "type": "sphere", "center": [-1.2, 0.5, 0], "radius": 0.5, "material": "steel",
       "animate": {{ "type": "oscillate", "amplitude": [0, 0.4, 0.3], "period": 1.3 }} }},
    {{ "type": "triangles", "material": "white",
       "vertices": [[0.6, 0, -0.4], [1.4, 0, -0.4], [1.0, 0.9, 0.0], [1.0, 0, 0.4]],
       "faces": [[0, 1, 2], [1, 3, 2], [3, 0, 2], [0, 3, 1]],
       "animate": {{ "type": "rotate", "axis": [0.3, 1, 0], "degrees_per_second": 120 }} }},
    {{ "type": "quad", "Q": [-0.5, 2.5, -0.5], "u": [1, 0, 0], "v": [0, 0, 1], "material": "lamp",
       "animate": {{ "type": "oscillate", "amplitude": [1.2, 0, 0.5], "period": 2 }} }},
    {{ "type": "triangles", "material": "steel",
       "vertices": [[-0.5, 0.2, -1.5], [0, 0.2, -1.5], [0.5, 0.2, -1.5], [-0.5, 0.7, -1.5], [0, 0.7, -1.5], [0.5, 0.7, -1.5]],
       "faces": [[0, 1, 3], [1, 4, 3], [1, 2, 4], [2, 5, 4]],
       "animate": {{ "type": "wave", "amplitude": 0.1, "wavelength": 0.8, "period": 1.0, "direction": [1, 1, 0] }} }}
  ]
}}"#,
        floor_vertices.join(", "),
        floor_faces.join(", ")
    )
}

/// [`the_viewers_frames_on_the_gpu_are_the_cpus`] with one scene and one pipeline. With
/// `small_changes` (most of the scene static or rigid) and the scene cut into parts, a moving
/// frame writes only what changed: less than a third of what a whole upload writes, once the
/// deforming part's tree has room to change in place.
fn viewer_frames_alike(make_scene: &dyn Fn() -> Scene, pipeline: PipelineKind, small_changes: bool) {
    let make = || {
        let scene = make_scene();
        let camera = scene.view(None).unwrap();
        let settings = PipelineSettings {
            builder: Builder::PHR_FAST,
            pipeline,
            width: 64,
            height: 48,
            max_depth: 4,
            mode: ViewMode::Colour,
            explicit_lights: false,
            denoise: None,
        };
        FramePipeline::new(scene, settings, camera)
    };
    let mut on_gpu = make().with_tracer(Box::new(GpuFrames::new(gpu().clone())));
    // The film kept on the GPU, as for a window drawing with the device, read back here.
    let mut kept = make().with_tracer(Box::new(GpuFrames::new(gpu().clone())));
    kept.keep_film_on_device(true);
    let mut on_cpu = make();
    let mut whole = 0;
    for frame in 0..14 {
        for p in [&mut on_gpu, &mut kept, &mut on_cpu] {
            p.playing = !(4..8).contains(&frame);
            if frame == 6 {
                let mut camera = p.camera().clone();
                camera.position += Vec3::new(0.4, 0.1, 0.0);
                p.set_camera(camera);
            }
            if frame == 8 {
                let mut settings = p.settings().clone();
                settings.explicit_lights = true;
                p.set_settings(settings);
            }
        }
        let (g, k, c) = (on_gpu.step(0.1), kept.step(0.1), on_cpu.step(0.1));
        let what = format!("{pipeline:?} viewer frame {frame}");
        assert_eq!((g.device, k.device), ("gpu", "gpu"), "{what}");
        assert_eq!((g.moved, g.samples, k.samples), (c.moved, c.samples, c.samples), "{what}");
        assert_eq!((g.rays, k.rays), (c.rays, c.rays), "{what}");
        assert!(kept.film_on_device(), "{what}");
        let cpu_image = on_cpu.raw_image();
        assert_alike(&cpu_image, &on_gpu.raw_image(), 300, &what);
        assert_alike(&cpu_image, &kept.raw_image(), 300, &format!("{what}, film kept on the GPU"));
        if matches!(frame, 0 | 8) {
            // Uploaded whole: the first frame, and light sampling switched on.
            whole = g.upload_bytes;
        } else if small_changes && g.moved && pipeline != PipelineKind::Thesis && !matches!(frame, 1 | 9) {
            assert!(g.upload_bytes * 3 < whole, "{what}: {} bytes of {whole} uploaded", g.upload_bytes);
        }
    }
}

/// The film the GPU keeps for a window is the one read back frame by frame, and the image it
/// writes for the window to show is that film's mean encoded as the CPU's viewer encodes it
/// (to one level in 255), at a width whose rows the texture pads.
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn the_kept_film_and_its_shown_image_are_the_read_back_ones() {
    let scene = reference_scene("spheres_sky");
    let geometry = built(&scene, &Builder::default());
    let camera = scene.view(None).unwrap();
    let (width, height) = (72, 40);
    let job = |frame| FrameJob {
        scene: &scene,
        geometry: &geometry,
        lights: None,
        camera: &camera,
        width,
        height,
        max_depth: 6,
        seed: 5,
        frame,
        version: 0,
    };
    let (mut kept, mut read_back) = (GpuFrames::new(gpu().clone()), GpuFrames::new(gpu().clone()));
    // Nobody watches: the film is kept, no image is written.
    read_back.accumulate(&job(0), true).unwrap();
    assert!(read_back.shown_pixels().is_err(), "an image written that nobody watches");
    let shown = kept.shown().watch();
    assert!(shown.get().is_none(), "nothing shown before a frame is kept");
    let mut film = Film::new(width, height);
    for frame in 0..6 {
        let k = kept.accumulate(&job(frame), frame == 0).unwrap();
        let r = read_back.trace(&job(frame)).unwrap();
        assert!(k.pixels.is_empty(), "frame {frame}: nothing read back");
        assert_eq!(k.rays, r.rays, "frame {frame}");
        film.add_frame(&r.pixels);
    }
    let kept_film = kept.film().unwrap();
    assert_alike(&film.mean(), &kept_film.mean(), 2000, "the kept film");
    let image = shown.get().expect("shown");
    assert_eq!((image.width, image.height, image.texture_number), (width, height, 1));
    let expected = rgba8(&kept_film.mean());
    let on_screen = kept.shown_pixels().unwrap();
    assert_eq!(on_screen.len(), expected.len());
    let worst = on_screen.iter().zip(&expected).map(|(a, b)| a.abs_diff(*b)).max().unwrap();
    let exact = on_screen.iter().zip(&expected).filter(|(a, b)| a == b).count();
    println!("shown image: {exact} of {} bytes exact, worst {worst}", expected.len());
    assert!(worst <= 1, "the shown image is off by {worst} levels");
    assert!(exact * 10 > expected.len() * 9, "{exact} of {} bytes exact", expected.len());
    // A restart empties the kept film; the same texture shows it.
    let k = kept.accumulate(&job(6), true).unwrap();
    let r = read_back.trace(&job(6)).unwrap();
    assert_eq!(k.rays, r.rays, "after a restart");
    let restarted = kept.film().unwrap().mean();
    assert_alike(&r.pixels, &restarted, 2000, "the kept film after a restart");
    assert_eq!(shown.get().expect("shown").texture_number, 1);
    assert_shown(&kept, &restarted, "after a restart");
    // Another size: a new tracer, a new film and a new texture, shown once written.
    let resized = FrameJob { width: 40, height: 24, ..job(7) };
    let k = kept.accumulate(&resized, false).unwrap();
    let r = read_back.trace(&resized).unwrap();
    assert_eq!(k.rays, r.rays, "another size");
    let film = kept.film().unwrap().mean();
    assert_alike(&r.pixels, &film, 800, "the kept film of another size");
    let image = shown.get().expect("shown");
    assert_eq!((image.width, image.height, image.texture_number), (40, 24, 2));
    assert_shown(&kept, &film, "another size");
    // A frame traced alone in between (its sums cleared): the next kept frame starts the
    // film again, even unasked.
    kept.trace(&FrameJob { frame: 8, ..resized }).unwrap();
    let k = kept.accumulate(&FrameJob { frame: 9, ..resized }, false).unwrap();
    let r = read_back.trace(&FrameJob { frame: 9, ..resized }).unwrap();
    assert_eq!(k.rays, r.rays, "after a frame traced alone");
    let film = kept.film().unwrap().mean();
    assert_alike(&r.pixels, &film, 800, "the kept film after a frame traced alone");
    assert_shown(&kept, &film, "after a frame traced alone");
}

/// What `frames` shows is `film` encoded as the CPU's viewer encodes it, to one level in 255.
fn assert_shown(frames: &GpuFrames, film: &[Vec3], what: &str) {
    let (expected, on_screen) = (rgba8(film), frames.shown_pixels().unwrap());
    assert_eq!(on_screen.len(), expected.len(), "{what}");
    let worst = on_screen.iter().zip(&expected).map(|(a, b)| a.abs_diff(*b)).max().unwrap();
    assert!(worst <= 1, "{what}: the shown image is off by {worst} levels");
}

/// An error the device reports on its own (here a buffer wgpu's validation refuses) comes back
/// from the next wait as an error, not as wgpu's default panic.
#[test]
#[ignore = "needs a GPU adapter (lavapipe: apt-get install mesa-vulkan-drivers libvulkan1); .ci/run runs it"]
fn a_device_error_is_an_error_not_a_panic() {
    // A device of its own: the error stays with it.
    let gpu = Gpu::new().unwrap_or_else(|e| panic!("{e}"));
    gpu.wait().expect("a fresh device has nothing to report");
    let _invalid = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("mapped both ways"),
        size: 64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::MAP_WRITE,
        mapped_at_creation: false,
    });
    let error = gpu.wait().expect_err("the invalid buffer is reported");
    assert!(matches!(error, GpuError::Failed(_)), "{error}");
    println!("{error}");
}
