//! The per-frame pipeline of dynamic scenes (pose → refit → rebuild → collapse → render →
//! accumulate), checked against things computed afresh from the posed scene: after every
//! animated frame the primitive boxes are those of the moved triangles, the tree is valid over
//! them and its closest hits equal brute force, the film holds exactly that frame's render
//! (nothing of the previous pose), and light sampling samples the lights where they are now.
//! A paused pipeline keeps its tree and accumulates.

use glam::Vec3;
use phr_bvh::triangle::{intersect_triangle, triangle_bounds};
use phr_bvh::{validate, Builder, Ray};
use phr_render::auto_builder::{AutoBuilder, AutoState, MARGIN, RECENT_FRAMES, TRIAL_FRAMES};
use phr_render::film::Film;
use phr_render::frame_tracer::{FrameJob, FrameTracer, TracedFrame};
use phr_render::lights::LightSet;
use phr_render::pipeline::{
    FramePipeline, FrameReport, PipelineKind, PipelineSettings, ViewMode, ACCUMULATED_DENOISE_FROM,
};
use phr_render::render::Renderer;
use phr_render::scene::json::parse_scene;
use phr_render::scene::RenderSettings;
use std::path::Path;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Arc;

/// A floor, a sphere, and a quad light that moves sideways over them; the floor waves, and so
/// does the light, so that its two triangles' areas (and light sampling's choice between
/// them) change with time.
const SCENE: &str = include_str!("support/moving_light.json");

const SIZE: u32 = 32;

fn pipeline(builder: Builder, explicit_lights: bool) -> FramePipeline {
    pipeline_of(PipelineKind::Thesis, builder, explicit_lights)
}

/// An image's bits, for exact comparisons.
fn bits(v: &[Vec3]) -> Vec<[u32; 3]> {
    v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
}

fn pipeline_of(kind: PipelineKind, builder: Builder, explicit_lights: bool) -> FramePipeline {
    let scene = parse_scene(SCENE, Path::new("moving_light.json")).unwrap();
    let camera = scene.view(None).unwrap();
    let settings = PipelineSettings {
        builder,
        pipeline: kind,
        width: SIZE,
        height: SIZE,
        max_depth: 4,
        mode: ViewMode::Colour,
        explicit_lights,
        denoise: None,
    };
    FramePipeline::new(scene, settings, camera)
}

fn rng_rays(bounds: phr_bvh::Aabb, n: usize, seed: u64) -> Vec<Ray> {
    let mut s = seed | 1;
    let mut f = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    let (c, e) = (bounds.center(), bounds.extent());
    (0..n)
        .map(|_| {
            let o = c + e * Vec3::new(f() - 0.5, f() - 0.5, f() - 0.5) * 2.0;
            let target = bounds.min + e * Vec3::new(f(), f(), f());
            Ray::new(o, (target - o).normalize_or(Vec3::Y))
        })
        .collect()
}

/// Closest hit over every triangle and sphere, lowest index on ties.
fn brute_force(p: &FramePipeline, ray: &Ray) -> Option<(f32, u32)> {
    let g = p.geometry();
    let tris = g.triangles.iter().map(|t| intersect_triangle(ray, t[0], t[1], t[2]).map(|h| h.t));
    let spheres = g.spheres.iter().map(|s| s.sphere.intersect(ray));
    let mut best: Option<(f32, u32)> = None;
    for (i, t) in tris.chain(spheres).enumerate() {
        if let Some(t) = t {
            if best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, i as u32));
            }
        }
    }
    best
}

/// The pipeline's geometry is the posed scene's: fresh boxes, a valid tree (PHR's straight into
/// the wide layout, the others' binary ones), exact hits.
fn check_geometry(p: &FramePipeline, builder: Builder, frame: usize) {
    let g = p.geometry();
    let what = format!("{builder}, frame {frame}");
    for (i, t) in g.triangles.iter().enumerate() {
        assert_eq!(g.boxes[i], triangle_bounds(t[0], t[1], t[2]), "{what}: stale box of triangle {i}");
    }
    match builder {
        Builder::Phr(_) => {
            assert!(g.bvh().nodes.is_empty(), "{what}: PHR builds no binary tree");
            g.wide_bvh().validate(&g.boxes)
        }
        _ => validate(g.bvh(), &g.boxes, builder.max_leaf_size()),
    }
    .unwrap_or_else(|e| panic!("{what}: {e}"));
    let bounds = g.boxes.iter().fold(phr_bvh::Aabb::EMPTY, |b, x| b.union(*x));
    for (i, ray) in rng_rays(bounds, 300, frame as u64 + 1).iter().enumerate() {
        let got = g.intersect(ray).map(|h| (h.t, h.prim));
        assert_eq!(got, brute_force(p, ray), "{what}: ray {i}");
    }
}

/// What a renderer made from scratch over the pipeline's current geometry renders for `frame`.
fn fresh_render(p: &FramePipeline, frame: u32, lights: bool) -> Vec<Vec3> {
    let (scene, g) = (p.scene(), p.geometry());
    let light_set = lights.then(|| LightSet::new(g, &scene.materials, &scene.background));
    let size = RenderSettings { width: SIZE, height: SIZE, spp: 1, max_depth: p.settings().max_depth };
    Renderer::new(scene, g, p.camera(), &size, light_set.as_ref()).render_frame(frame).0
}

#[test]
fn every_animated_frame_traces_the_posed_scene() {
    for builder in [Builder::PHR_FAST, Builder::PHR_HQ.with_branching(4).unwrap(), "binned-sah".parse().unwrap()] {
        let mut p = pipeline(builder, false);
        let first = p.geometry().triangles.clone();
        for frame in 0..6 {
            let report = p.step(0.125);
            assert!(report.moved, "{builder}, frame {frame} did not move");
            check_geometry(&p, builder, frame);
        }
        assert_ne!(p.geometry().triangles, first, "{builder}: nothing moved");
    }
}

/// Poses depend on the time only: 4 frames of 0.125 s pose the scene as one of 0.5 s.
#[test]
fn the_pose_depends_on_the_time_not_the_history() {
    let mut stepped = pipeline(Builder::PHR_FAST, false);
    for _ in 0..4 {
        stepped.step(0.125);
    }
    let mut jumped = pipeline(Builder::PHR_FAST, false);
    jumped.step(0.5);
    assert_eq!(stepped.time, 0.5);
    assert_eq!(stepped.geometry().triangles, jumped.geometry().triangles);
    assert_eq!(stepped.geometry().spheres.len(), jumped.geometry().spheres.len());
}

/// After a moving frame the film holds that frame alone, as a fresh renderer draws it, light
/// sampling included: a stale film would ghost, stale lights would light from the old place.
#[test]
fn a_moving_frame_shows_only_the_new_pose_with_lights_where_they_are() {
    for (kind, lights) in PipelineKind::ALL.into_iter().flat_map(|k| [(k, false), (k, true)]) {
        let mut p = pipeline_of(kind, Builder::PHR_FAST, lights);
        for frame in 0..3 {
            let report = p.step(0.25);
            assert_eq!(report.samples, 1, "{kind:?}, lights {lights}, frame {frame}: the film was not restarted");
            let expected = fresh_render(&p, report.frame as u32, lights);
            assert!(bits(&p.image()) == bits(&expected), "{kind:?}, lights {lights}, frame {frame}: image differs");
            assert!(expected.iter().any(|c| c.max_element() > 0.1), "lights {lights}: a dark image proves nothing");
        }
    }
}

/// With online tuning on, each candidate builds its trial of moving frames in turn, every
/// tree is valid and traces the posed scene, each frame shows what a fresh renderer draws, and
/// the tuner then keeps the candidate whose frames were fastest; a builder the settings ask
/// for meanwhile does not override it, and paused frames are not counted.
#[test]
fn the_auto_builder_tries_each_candidate_then_keeps_the_fastest() {
    let tuner = AutoBuilder::default();
    let candidates = tuner.candidates.clone();
    let mut p = pipeline(Builder::PHR_FAST, true);
    p.set_auto(Some(tuner));
    let mut used = Vec::new();
    for frame in 0..candidates.len() * TRIAL_FRAMES {
        let report = p.step(0.05);
        assert!(report.moved);
        used.push(report.builder);
        check_geometry(&p, report.builder, frame);
        let expected = fresh_render(&p, report.frame as u32, true);
        assert!(bits(&p.image()) == bits(&expected), "frame {frame} ({}): image differs", report.builder);
        // The panel's builder does not fight the tuner.
        let mut settings = p.settings().clone();
        settings.builder = Builder::PHR_HQ;
        p.set_settings(settings);
    }
    for (k, c) in candidates.iter().enumerate() {
        assert!(used[k * TRIAL_FRAMES..(k + 1) * TRIAL_FRAMES].iter().all(|b| b == c), "trial {k}: {used:?}");
    }
    let auto = p.auto().expect("on");
    let AutoState::Chosen { index, median_ms } = auto.state else { panic!("still exploring: {}", auto.describe()) };
    let fastest = auto.medians.iter().map(|m| m.expect("measured")).fold(f64::INFINITY, f64::min);
    // The fastest, or the first (the default) when it is within the noise margin of it.
    assert!(median_ms == fastest || (index == 0 && median_ms <= fastest * (1.0 + MARGIN)), "{}", auto.describe());
    assert_eq!(p.step(0.05).builder, candidates[index]);
    // Paused frames leave the tuner alone.
    p.playing = false;
    let before = format!("{:?}", p.auto().unwrap().state);
    for _ in 0..3 * RECENT_FRAMES {
        p.step(0.05);
    }
    assert_eq!(format!("{:?}", p.auto().unwrap().state), before);
}

#[test]
fn a_paused_pipeline_keeps_its_tree_and_accumulates() {
    for kind in PipelineKind::ALL {
        paused_pipeline_keeps_its_tree_and_accumulates(kind);
    }
}

fn paused_pipeline_keeps_its_tree_and_accumulates(kind: PipelineKind) {
    let mut p = pipeline_of(kind, Builder::PHR_FAST, true);
    p.step(0.25);
    let (nodes, triangles) = (p.geometry().bvh().nodes.len(), p.geometry().triangles.clone());
    p.playing = false;
    for n in 2..=5 {
        let report = p.step(0.25);
        assert!(!report.moved && report.build_ms == 0.0 && report.refit_ms == 0.0, "paused frame rebuilt");
        assert_eq!(report.samples, n);
        assert_eq!(report.time, 0.25);
    }
    assert_eq!(p.geometry().bvh().nodes.len(), nodes);
    assert_eq!(p.geometry().triangles, triangles);
}

/// With denoising on, every frame is shown denoised: the first ones (and every frame after
/// the camera moves) through the temporal filter, smoother than the raw mean of the same
/// samples, which a pipeline without denoising shows; from [`ACCUMULATED_DENOISE_FROM`]
/// samples on, the accumulated image, at powers of two.
#[test]
fn denoising_shows_a_smoother_image_from_the_first_frame_on() {
    let mut plain = pipeline(Builder::default(), true);
    let mut denoised = pipeline(Builder::default(), true);
    // Paused: a playing animation restarts the film every frame.
    plain.playing = false;
    denoised.playing = false;
    let mut settings = denoised.settings().clone();
    settings.denoise = Some(phr_render::denoise::Filter::Atrous);
    denoised.set_settings(settings);
    let roughness = |image: &[Vec3]| image.windows(2).map(|p| (p[0] - p[1]).abs().element_sum()).sum::<f32>();
    let mut camera = denoised.camera().clone();
    for moved in [false, true] {
        if moved {
            camera.position += Vec3::new(0.1, 0.0, 0.0);
            denoised.set_camera(camera.clone());
            plain.set_camera(camera.clone());
        }
        let report = plain.step(0.0);
        let report_denoised = denoised.step(0.0);
        assert_eq!((report.samples, report_denoised.samples), (1, 1));
        assert_eq!(report.denoise_ms, 0.0);
        assert!(report_denoised.denoise_ms > 0.0);
        let (raw, smooth) = (plain.image(), denoised.image());
        assert!(roughness(&smooth) < 0.8 * roughness(&raw), "{} vs raw {}", roughness(&smooth), roughness(&raw));
    }
    for n in 2..=2 * ACCUMULATED_DENOISE_FROM {
        let report = denoised.step(0.0);
        assert_eq!(report.samples, n);
        let accumulated = n >= ACCUMULATED_DENOISE_FROM;
        let denoises = !accumulated || n.is_power_of_two();
        assert_eq!(report.denoise_ms > 0.0, denoises, "{n} samples: denoise_ms {}", report.denoise_ms);
    }
}

/// A camera that moves every frame (so every frame has one sample per pixel) towards the view
/// of the Cornell box's Mitsuba reference: the last frame, denoised by the temporal filter,
/// is far closer to the reference than that frame's raw samples.
#[test]
fn a_moving_view_is_denoised_towards_the_reference() {
    let dir = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../../shared/reference"));
    let scene = phr_render::scene::load_scene(&dir.join("scenes/cornell_obj.json")).unwrap();
    let reference = image::open(dir.join("images/cornell_obj.exr")).unwrap().into_rgb32f();
    let target = scene.view(None).unwrap();
    let (w, h) = reference.dimensions();
    let settings = PipelineSettings {
        builder: Builder::default(),
        pipeline: PipelineKind::Thesis,
        width: w,
        height: h,
        max_depth: scene.settings.max_depth,
        mode: ViewMode::Colour,
        explicit_lights: true,
        denoise: Some(phr_render::denoise::Filter::Atrous),
    };
    // The same last frame with no history: the spatial filter alone.
    let mut fresh = FramePipeline::new(scene.clone(), settings.clone(), target.clone());
    let mut p = FramePipeline::new(scene, settings, target.clone());
    // Over the surfaces: the lamp (and its edges, above 1) is left as sampled, and its
    // coverage noise at 1 spp would hide everything else. The reference's own noise (its
    // variance of the mean, about 0.01² here) is taken out of the squared error.
    let reference_var = image::open(dir.join("images/cornell_obj_var.exr")).unwrap().into_rgb32f();
    let rmse = |image: &[Vec3]| {
        let surface = image
            .iter()
            .zip(reference.pixels().zip(reference_var.pixels()))
            .filter(|(_, (r, _))| r.0.iter().all(|c| *c <= 1.0));
        let (sum, n) = surface.fold((0.0, 0), |(sum, n), (a, (r, v))| {
            (sum + (*a - Vec3::from(r.0)).length_squared() - Vec3::from(v.0).element_sum(), n + 3)
        });
        (sum / n as f32).max(0.0).sqrt()
    };
    const FRAMES: usize = 16;
    for k in (0..FRAMES).rev() {
        let mut camera = target.clone();
        camera.position += Vec3::new(0.02, 0.01, 0.0) * k as f32;
        p.set_camera(camera);
        assert_eq!(p.step(0.0).samples, 1);
    }
    fresh.step(0.0);
    let (denoised, raw, spatial) = (rmse(&p.image()), rmse(&p.raw_image()), rmse(&fresh.image()));
    println!("moving view, last frame: RMSE {denoised} denoised, {raw} raw, {spatial} without history");
    assert!(denoised < 0.2 * raw, "RMSE {denoised} denoised against {raw} raw");
    assert!(denoised < 0.8 * spatial, "RMSE {denoised} denoised against {spatial} without history");
}

/// A [`FrameTracer`] that traces on the CPU from the job alone (a renderer made afresh from
/// what the job gives), recording the versions it saw; `fail_at`: fails that frame. With
/// `keeps`, it keeps the film as the GPU does for a window that shows its image, counting the
/// frames it accumulated and the films read back from it.
#[derive(Default)]
struct JobTracer {
    versions: Arc<std::sync::Mutex<Vec<u64>>>,
    fail_at: Option<u32>,
    keeps: bool,
    /// Its film cannot be read back.
    fail_film: bool,
    film: Option<Film>,
    accumulated: Arc<AtomicU32>,
    reads: Arc<AtomicU32>,
}

impl FrameTracer for JobTracer {
    fn name(&self) -> &'static str {
        "job"
    }

    fn describe(&self) -> String {
        "the CPU, from the job".into()
    }

    fn trace(&mut self, job: &FrameJob) -> Result<TracedFrame, String> {
        if self.fail_at == Some(job.frame) {
            return Err("lost".into());
        }
        self.versions.lock().unwrap().push(job.version);
        let size = RenderSettings { width: job.width, height: job.height, spp: 1, max_depth: job.max_depth };
        let renderer = Renderer::new(job.scene, job.geometry, job.camera, &size, job.lights).with_seed(job.seed);
        let (pixels, stats) = renderer.render_frame(job.frame);
        Ok(TracedFrame { pixels, rays: stats.rays, upload_ms: 0.0, upload_bytes: 0 })
    }

    fn keeps_film(&self) -> bool {
        self.keeps
    }

    fn accumulate(&mut self, job: &FrameJob, restart: bool) -> Result<TracedFrame, String> {
        let traced = self.trace(job)?;
        if restart {
            self.film = Some(Film::new(job.width, job.height));
        }
        let film = self.film.as_mut().ok_or("a kept film must start with a restart")?;
        film.add_frame(&traced.pixels);
        self.accumulated.fetch_add(1, Ordering::Relaxed);
        Ok(TracedFrame { pixels: Vec::new(), ..traced })
    }

    fn film(&mut self) -> Result<Film, String> {
        self.reads.fetch_add(1, Ordering::Relaxed);
        if self.fail_film {
            return Err("lost".into());
        }
        self.film.clone().ok_or_else(|| "no film yet".to_string())
    }
}

/// Frame `frame` of two pipelines alike: the scene moves in frames 0–2, then stands still,
/// and the camera moves at frame 5.
fn step_both(a: &mut FramePipeline, b: &mut FramePipeline, frame: u32) -> (FrameReport, FrameReport) {
    for p in [&mut *a, &mut *b] {
        p.playing = frame < 3;
        if frame == 5 {
            let mut camera = p.camera().clone();
            camera.position += Vec3::new(0.3, 0.0, 0.0);
            p.set_camera(camera);
        }
    }
    (a.step(0.1), b.step(0.1))
}

/// A pipeline whose frames another device traces shows what the CPU shows, moving or still,
/// with either estimator and after a camera move: the job holds the posed geometry, its
/// lights, the view and the frame's number, and its version changes exactly when the scene
/// moved (or light sampling came on); denoised images agree too. Other modes stay on the CPU.
#[test]
fn a_frame_tracer_traces_the_frames_the_cpu_would() {
    for explicit_lights in [false, true] {
        let versions = Arc::new(std::sync::Mutex::new(Vec::new()));
        let tracer = JobTracer { versions: versions.clone(), ..Default::default() };
        let mut on_device = pipeline(Builder::PHR_FAST, explicit_lights).with_tracer(Box::new(tracer));
        let mut on_cpu = pipeline(Builder::PHR_FAST, explicit_lights);
        let mut moved = Vec::new();
        for frame in 0..8 {
            let (a, b) = step_both(&mut on_device, &mut on_cpu, frame);
            assert_eq!((a.device, b.device), ("job", "cpu"));
            assert_eq!(
                bits(&on_device.raw_image()),
                bits(&on_cpu.raw_image()),
                "frame {frame} (lights {explicit_lights})"
            );
            moved.push(a.moved);
        }
        let versions = versions.lock().unwrap().clone();
        for k in 1..versions.len() {
            assert_eq!(versions[k] != versions[k - 1], moved[k], "frame {k}: versions {versions:?}");
        }
        // Denoised, moving (the temporal filter, guided by first hits the CPU traces from the
        // device's camera rays) and still (the accumulated image's filter).
        for p in [&mut on_device, &mut on_cpu] {
            let mut settings = p.settings().clone();
            settings.denoise = Some(phr_render::denoise::Filter::Atrous);
            p.set_settings(settings);
        }
        for frame in 0..ACCUMULATED_DENOISE_FROM + 2 {
            for p in [&mut on_device, &mut on_cpu] {
                p.playing = frame < 3;
            }
            on_device.step(0.1);
            on_cpu.step(0.1);
            assert_eq!(
                bits(&on_device.image()),
                bits(&on_cpu.image()),
                "denoised frame {frame} (lights {explicit_lights})"
            );
        }
        let mut settings = on_device.settings().clone();
        settings.mode = ViewMode::Normals;
        on_device.set_settings(settings);
        assert_eq!(on_device.step(0.1).device, "cpu", "the normals are the CPU's");
    }
}

/// With a tracer that keeps the film, the colour frames are not read back, and the images,
/// read back when asked for (once per change), are the CPU's: still and moving, after a
/// camera move, and back on the CPU's film when the denoiser needs each frame's samples.
#[test]
fn a_tracer_keeping_the_film_shows_what_the_cpu_shows() {
    let (accumulated, reads) = (Arc::new(AtomicU32::new(0)), Arc::new(AtomicU32::new(0)));
    let tracer =
        JobTracer { keeps: true, accumulated: accumulated.clone(), reads: reads.clone(), ..Default::default() };
    let mut on_device = pipeline(Builder::PHR_FAST, true).with_tracer(Box::new(tracer));
    on_device.keep_film_on_device(true);
    let mut on_cpu = pipeline(Builder::PHR_FAST, true);
    for frame in 0..8 {
        let (a, b) = step_both(&mut on_device, &mut on_cpu, frame);
        assert_eq!((a.device, a.samples, a.rays), ("job", b.samples, b.rays), "frame {frame}");
        assert!(on_device.film_on_device(), "frame {frame}");
        if frame % 2 == 0 {
            assert_eq!(bits(&on_device.raw_image()), bits(&on_cpu.raw_image()), "frame {frame}");
            assert_eq!(on_device.image_rgba8(), on_cpu.image_rgba8(), "frame {frame}");
        }
    }
    assert_eq!(accumulated.load(Ordering::Relaxed), 8);
    assert_eq!(reads.load(Ordering::Relaxed), 4, "read once after each frame asked for");
    // The temporal filter takes each frame's samples: read back, into the CPU's film.
    for p in [&mut on_device, &mut on_cpu] {
        let mut settings = p.settings().clone();
        settings.denoise = Some(phr_render::denoise::Filter::Atrous);
        p.set_settings(settings);
    }
    for frame in 0..ACCUMULATED_DENOISE_FROM + 2 {
        on_device.step(0.1);
        on_cpu.step(0.1);
        assert!(!on_device.film_on_device());
        assert_eq!(bits(&on_device.image()), bits(&on_cpu.image()), "denoised frame {frame}");
    }
    assert_eq!(accumulated.load(Ordering::Relaxed), 8);
    // Without the denoiser the film goes back to the device; asked not to, it stays here.
    for keep in [true, false] {
        let mut settings = on_device.settings().clone();
        settings.denoise = None;
        on_device.set_settings(settings.clone());
        on_cpu.set_settings(settings);
        on_device.keep_film_on_device(keep);
        // The switch restarted the film.
        on_cpu.restart();
        for _ in 0..2 {
            on_device.step(0.1);
            on_cpu.step(0.1);
        }
        assert_eq!(on_device.film_on_device(), keep);
        assert_eq!(bits(&on_device.image()), bits(&on_cpu.image()), "keep {keep}");
    }
    assert_eq!(accumulated.load(Ordering::Relaxed), 10);
    // The normals are the CPU's; back in colour, the film goes to the device again.
    on_device.keep_film_on_device(true);
    for mode in [ViewMode::Normals, ViewMode::Colour] {
        for p in [&mut on_device, &mut on_cpu] {
            let mut settings = p.settings().clone();
            settings.mode = mode;
            p.set_settings(settings);
            p.step(0.1);
        }
        assert_eq!(on_device.film_on_device(), mode == ViewMode::Colour, "{mode:?}");
        assert_eq!(bits(&on_device.image()), bits(&on_cpu.image()), "{mode:?}");
    }
    assert_eq!(accumulated.load(Ordering::Relaxed), 11);
}

/// A tracer that fails is dropped, with a warning, and the CPU traces the frame instead.
#[test]
fn a_failing_frame_tracer_leaves_the_cpu_tracing() {
    let tracer = JobTracer { fail_at: Some(2), ..Default::default() };
    let mut on_device = pipeline(Builder::PHR_FAST, true).with_tracer(Box::new(tracer));
    let mut on_cpu = pipeline(Builder::PHR_FAST, true);
    for frame in 0..4 {
        let (a, _) = (on_device.step(0.1), on_cpu.step(0.1));
        assert_eq!(a.device, if frame < 2 { "job" } else { "cpu" });
        assert_eq!(bits(&on_device.raw_image()), bits(&on_cpu.raw_image()), "frame {frame}");
    }
    assert!(on_device.tracer().is_none());
}

/// A tracer that fails while keeping the film takes the film's samples with it: the film
/// starts again on the CPU, holding and counting the frames from the failure on.
#[test]
fn a_failing_tracer_that_kept_the_film_starts_it_again() {
    let tracer = JobTracer { keeps: true, fail_at: Some(2), ..Default::default() };
    let mut on_device = pipeline(Builder::PHR_FAST, true).with_tracer(Box::new(tracer));
    on_device.keep_film_on_device(true);
    let mut on_cpu = pipeline(Builder::PHR_FAST, true);
    (on_device.playing, on_cpu.playing) = (false, false);
    for frame in 0..4 {
        if frame == 2 {
            on_cpu.restart();
        }
        let (a, b) = (on_device.step(0.1), on_cpu.step(0.1));
        assert_eq!((a.device, a.samples), (if frame < 2 { "job" } else { "cpu" }, b.samples), "frame {frame}");
        assert_eq!(on_device.film_on_device(), frame < 2);
    }
    assert_eq!(on_device.samples(), 2);
    assert_eq!(bits(&on_device.raw_image()), bits(&on_cpu.raw_image()));
}

/// A kept film that cannot be read back is lost with its device: the image asked for is of
/// no samples (not a black one claiming them), and the CPU traces the film again.
#[test]
fn a_kept_film_that_cannot_be_read_starts_again_on_the_cpu() {
    let tracer = JobTracer { keeps: true, fail_film: true, ..Default::default() };
    let mut on_device = pipeline(Builder::PHR_FAST, true).with_tracer(Box::new(tracer));
    on_device.keep_film_on_device(true);
    on_device.playing = false;
    for _ in 0..2 {
        assert_eq!(on_device.step(0.1).device, "job");
    }
    on_device.image();
    assert!(on_device.tracer().is_none(), "the device is dropped");
    assert_eq!((on_device.samples(), on_device.film_on_device()), (0, false));
    assert!(on_device.image_to_save().is_none(), "an image of no samples to save");
    let mut on_cpu = pipeline(Builder::PHR_FAST, true);
    on_cpu.playing = false;
    for _ in 0..2 {
        on_cpu.step(0.1);
    }
    // Frame 2, the first the CPU traced again.
    on_cpu.restart();
    let (a, b) = (on_device.step(0.1), on_cpu.step(0.1));
    assert_eq!((a.device, a.samples), ("cpu", 1));
    assert_eq!(b.samples, 1);
    assert_eq!(bits(&on_device.raw_image()), bits(&on_cpu.raw_image()));
}
