//! The per-frame loop of the interactive viewer and of its headless mode: pose the animated
//! objects → update the trees → render one sample per pixel → accumulate. While nothing moves
//! (no animation playing, no camera or setting change), frames add samples to the film; any
//! change restarts it.
//!
//! How the trees follow the motion is the [`PipelineKind`]:
//! - [`PipelineKind::Thesis`], thesis section 5.3: one tree over the whole scene; every moving
//!   frame moves the vertices, refits the auxiliary LBVH over all primitives and rebuilds the
//!   render BVH with PHR, straight into the 8-wide layout the renderer traces (other
//!   builders' binary trees are collapsed into it).
//! - [`PipelineKind::TwoLevel`]: the static primitives, the deforming ones, and each rigidly
//!   moving object get trees of their own ([`Geometry::split`]), built once; a moving frame
//!   moves the rigid objects by their transforms and the top-level tree over them, and refits
//!   and rebuilds the deforming part alone. Rigid motion then costs next to nothing.
//!
//! - [`PipelineKind::Async`]: the two-level layout, with the deforming part's PHR rebuilds on
//!   a worker thread ([`crate::rebuild`]): moving frames refit the tree they trace and pack
//!   its triangles, and take a new tree when the worker has one.
//!
//! With a static builder ([`FramePipeline::set_static_builder`], [`crate::static_rebuild`]),
//! the trees of the parts that never move are built a second time, in the background, and
//! swapped in without restarting the accumulation.
//!
//! A [`FrameTracer`] set with [`FramePipeline::with_tracer`] (the GPU) traces the colour
//! frames; everything else stays on the CPU.
//!
//! [`FramePipeline::step`] does one frame and reports the time of each stage, which is what
//! the viewer's statistics panel and the headless CSV show.

use crate::animation::Animator;
use crate::auto_builder::{AutoBuilder, AutoState};
use crate::camera::Camera;
use crate::camera::CameraDesc;
use crate::denoise::{Filter, Guide, Temporal};
use crate::film::Film;
use crate::frame_tracer::{FrameJob, FrameTracer, TracedFrame};
use crate::geometry::Geometry;
use crate::integrator::FirstHit;
use crate::lights::LightSet;
use crate::output::{rgba8, turbo};
use crate::rebuild::AsyncRebuilder;
use crate::render::Renderer;
use crate::sampler::JitterTable;
use crate::scene::RenderSettings;
use crate::scene::Scene;
use crate::static_rebuild::{StaticJob, StaticRebuilder, StaticTree};
use glam::Vec3;
use phr_bvh::binned_sah::build_binned_sah_wide;
use phr_bvh::dynamic::DynamicBvh;
use phr_bvh::phr::PhrOptions;
use phr_bvh::{sah_cost, wide_sah_cost, Aabb, Builder, SahConstants, TraversalStats};
use std::sync::Arc;
use std::time::Instant;

/// [`PipelineKind::Async`] starts a rebuild when the refitted tree's SAH cost exceeds this
/// factor times the cost the last rebuilt tree had when it landed. A refit keeps the
/// traversal cost close to a rebuild's while the motion is small (the travelling wave of
/// `scenes/dynamic/dragon_wave.json` changes it by 0.1 %), and on two cores a rebuild's work
/// is taken from the frames (`docs/dynamic/history.md`).
pub const REBUILD_SAH_GROWTH: f64 = 1.10;

/// What the image shows.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ViewMode {
    /// The path-traced image.
    #[default]
    Colour,
    /// First-hit geometric normals, mapped from [-1, 1] to [0, 1].
    Normals,
    /// First-hit material colour (albedo; emitters by their normalised emission).
    Albedo,
    /// Traversal steps of the camera ray (thesis Figure 5.3), blue (few) to red (many).
    Heatmap,
}

impl ViewMode {
    pub const ALL: [ViewMode; 4] = [ViewMode::Colour, ViewMode::Normals, ViewMode::Albedo, ViewMode::Heatmap];

    pub fn name(self) -> &'static str {
        match self {
            ViewMode::Colour => "colour",
            ViewMode::Normals => "normals",
            ViewMode::Albedo => "albedo",
            ViewMode::Heatmap => "heatmap",
        }
    }
}

/// Traversal steps shown as red in the heatmap mode.
pub const HEATMAP_MAX_STEPS: f32 = 150.0;

/// How the trees follow a moving scene (see the module documentation).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PipelineKind {
    /// One tree over the whole scene, refitted and rebuilt with PHR when anything moves.
    Thesis,
    /// A tree per rigid object, placed by a transform under a top-level tree; the deforming
    /// objects' tree alone is rebuilt.
    TwoLevel,
    /// [`PipelineKind::TwoLevel`] with the deforming objects' tree rebuilt on a worker
    /// thread (PHR builders; other builders rebuild it in the frame), refitted meanwhile.
    #[default]
    Async,
}

impl PipelineKind {
    pub const ALL: [PipelineKind; 3] = [PipelineKind::Thesis, PipelineKind::TwoLevel, PipelineKind::Async];

    pub fn name(self) -> &'static str {
        match self {
            PipelineKind::Thesis => "thesis",
            PipelineKind::TwoLevel => "two-level",
            PipelineKind::Async => "async",
        }
    }
}

/// Settings whose change restarts accumulation (and, for the builder, rebuilds the tree).
#[derive(Clone, Debug, PartialEq)]
pub struct PipelineSettings {
    pub builder: Builder,
    pub pipeline: PipelineKind,
    pub width: u32,
    pub height: u32,
    /// Maximum ray segments per path (camera ray included).
    pub max_depth: u32,
    pub mode: ViewMode,
    /// Sample the lights at diffuse hits with MIS (see [`crate::lights`]) instead of relying
    /// on paths hitting them.
    pub explicit_lights: bool,
    /// Show the image denoised ([`crate::denoise`]), in colour mode: each frame through
    /// [`Temporal`] (SVGF) while the view moves and for its first still frames, then the
    /// accumulated image through this filter at [`ACCUMULATED_DENOISE_FROM`] samples and
    /// each power of two after (then every 64).
    pub denoise: Option<Filter>,
}

/// What one frame cost and produced.
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameReport {
    pub frame: u64,
    /// Animation time (seconds) the frame shows.
    pub time: f32,
    /// Objects moved this frame (so the tree was refitted and rebuilt).
    pub moved: bool,
    /// Moving vertices and recomputing primitive boxes (two-level: of the deforming objects,
    /// and the rigid objects' transforms).
    pub pose_ms: f64,
    /// Refitting the auxiliary LBVH (PHR builders; building it, the first time).
    pub refit_ms: f64,
    /// Building the render BVH (0 when the tree was kept; two-level: the deforming part's
    /// tree and the top-level tree).
    pub build_ms: f64,
    /// Collapsing it to the wide BVH the renderer traces and packing the triangles in its
    /// leaf order ([`Geometry::set_bvh`]); with PHR, which builds the wide tree directly, the
    /// packing alone ([`Geometry::set_part_wide`]).
    pub wide_ms: f64,
    /// Tracing the frame's samples (on another device: uploading what moved, tracing, reading
    /// the samples back).
    pub render_ms: f64,
    /// Of `render_ms`, moving the scene to the device that traced the frame (0 on the CPU).
    pub upload_ms: f64,
    /// Bytes written to that device for this frame: what changed (0 on the CPU).
    pub upload_bytes: u64,
    /// Denoising: this frame through the temporal filter (and tracing its guide), or the
    /// accumulated image (and its guide, after a restart) on the frames that do.
    pub denoise_ms: f64,
    /// Everything above.
    pub frame_ms: f64,
    pub rays: u64,
    /// SAH cost (unit constants) of the current render tree: thesis pipeline, the builder's
    /// tree over the whole scene (or the static builder's, once its tree landed:
    /// [`FramePipeline::set_static_builder`]; PHR's straight into the 8-wide layout:
    /// [`phr_bvh::wide_sah_cost`], lower than a binary tree's; the others' binary trees, the
    /// thesis's measure); two-level, the 8-wide tree traced for the deforming part, 0
    /// without one.
    pub sah_cost: f64,
    /// PHR's Σ|cut| of the last build (0 for other builders).
    pub build_cost: u64,
    /// Samples per pixel accumulated so far, this frame's included.
    pub samples: u32,
    /// Frames since the boxes the traced tree was built over: 0 when it was built this
    /// frame; with [`PipelineKind::Async`], the frames a rebuild took to land, and more while
    /// the landed tree is refitted.
    pub tree_age: u64,
    /// What traced the frame's samples: `cpu`, or the [`FrameTracer::name`] of the
    /// pipeline's tracer.
    pub device: &'static str,
    /// The builder of the frame's tree.
    pub builder: Builder,
    /// The builder whose trees the parts that never move had in this frame, when they are
    /// not the builder's ([`FramePipeline::set_static_builder`]).
    pub static_builder: Option<Builder>,
}

impl FrameReport {
    /// The columns of [`FrameReport::csv_row`]: what `phr view --headless` and `phr animate`
    /// write per frame.
    pub const CSV_HEADER: &'static str =
        "frame,time_s,moved,pose_ms,refit_ms,build_ms,wide_ms,render_ms,frame_ms,rays,mrays_per_s,sah_cost,build_cost,samples,tree_age,denoise_ms,upload_ms,upload_bytes,device,builder,static_builder";

    /// This frame as a CSV row of [`FrameReport::CSV_HEADER`]'s columns.
    pub fn csv_row(&self) -> String {
        format!(
            "{},{:.4},{},{:.3},{:.3},{:.3},{:.3},{:.3},{:.3},{},{:.3},{:.4},{},{},{},{:.3},{:.3},{},{},{},{}",
            self.frame,
            self.time,
            self.moved as u8,
            self.pose_ms,
            self.refit_ms,
            self.build_ms,
            self.wide_ms,
            self.render_ms,
            self.frame_ms,
            self.rays,
            self.mrays_per_s(),
            self.sah_cost,
            self.build_cost,
            self.samples,
            self.tree_age,
            self.denoise_ms,
            self.upload_ms,
            self.upload_bytes,
            self.device,
            self.builder,
            self.static_builder.map_or_else(|| "-".to_string(), |b| b.to_string())
        )
    }

    pub fn mrays_per_s(&self) -> f64 {
        if self.render_ms > 0.0 {
            self.rays as f64 / self.render_ms / 1e3
        } else {
            0.0
        }
    }
}

/// A scene being shown: geometry, tree, animation clock and the accumulating film.
pub struct FramePipeline {
    scene: Scene,
    geometry: Geometry,
    animator: Animator,
    /// PHR's auxiliary tree, kept across frames and refitted (PHR builders only): over the
    /// whole scene, or over the deforming part of the two-level layout.
    dynamic: Option<DynamicBvh>,
    /// The parts of the two-level layout, once split.
    parts: Option<Parts>,
    /// The deforming part's rebuild worker ([`PipelineKind::Async`] with PHR).
    rebuilder: Option<AsyncRebuilder>,
    /// The builder that rebuilds the trees of the parts that never move, in the background
    /// ([`FramePipeline::set_static_builder`]), and where that stands for the current trees.
    static_builder: Option<Builder>,
    static_trees: StaticTrees,
    /// [`FrameReport::tree_age`] of the traced tree.
    tree_age: u64,
    /// The SAH cost of the last tree the worker delivered, when it landed.
    landed_sah: f64,
    /// The scene's emitters, when explicit light sampling is on.
    lights: Option<LightSet>,
    /// Another device tracing the colour frames.
    tracer: Option<Box<dyn FrameTracer>>,
    /// Whether the tracer is to keep the film ([`FramePipeline::keep_film_on_device`]).
    keep_film: bool,
    /// The frames since the last restart are in the tracer's film, not in `film`, which holds
    /// them as last read back if `film_read` (nothing traced since).
    film_on_device: bool,
    film_read: bool,
    /// [`FrameJob::version`]: counts the changes of the geometry, its tree and the lights.
    version: u64,
    /// Online tuning: the builder chosen by measuring moving frames ([`FramePipeline::set_auto`]).
    auto: Option<AutoBuilder>,
    settings: PipelineSettings,
    camera: CameraDesc,
    film: Film,
    /// The temporal filter's last guide, whose memory the next frame's reuses.
    spare_guide: Option<Guide>,
    /// The denoiser's guide for the current view (traced at the first denoising after a
    /// restart) and the last denoised image.
    guide: Option<Guide>,
    denoised: Option<Vec<Vec3>>,
    /// Why the still-view filter failed, once said.
    denoise_error: Option<String>,
    /// The frame-by-frame denoiser and its history (kept across camera moves: it follows
    /// the surfaces).
    temporal: Temporal,
    samples: u32,
    frame: u64,
    seed: u64,
    /// The pixels' jitter offsets under `seed`, handed from one frame's renderer to the next.
    jitter: Option<Arc<JitterTable>>,
    tree_dirty: bool,
    sah: f64,
    /// The deforming part's primitive boxes, kept for the next frame's memory.
    part_boxes: Vec<Aabb>,
    build_cost: u64,
    /// Animation time in seconds.
    pub time: f32,
    pub playing: bool,
    /// Animation speed factor (1 = real time).
    pub speed: f32,
    /// The rebuild policy's factor ([`REBUILD_SAH_GROWTH`]; 0: rebuild all the time).
    pub rebuild_sah_growth: f64,
}

/// Where the static builder's trees for the current trees stand
/// ([`FramePipeline::set_static_builder`]).
enum StaticTrees {
    /// To be built after the next frame.
    Due,
    /// Being built by the worker.
    Building(StaticRebuilder),
    /// Done for these trees: `rebuilt` if the parts have the static builder's trees, not if
    /// there was nothing to rebuild (or the worker failed).
    Done { rebuilt: bool },
}

/// Which part of the two-level layout holds what.
struct Parts {
    /// The part of the deforming objects' primitives, rebuilt when they move.
    deforming: Option<usize>,
    /// `(part, object)`: the part of each rigid object of [`Animator::objects`].
    rigid: Vec<(usize, usize)>,
}

impl FramePipeline {
    pub fn new(scene: Scene, settings: PipelineSettings, camera: CameraDesc) -> Self {
        let animator = Animator::new(&scene);
        Self::with_animator(scene, settings, camera, animator)
    }

    /// [`FramePipeline::new`] with `animator` (made for `scene`) posing it.
    pub fn with_animator(scene: Scene, settings: PipelineSettings, camera: CameraDesc, mut animator: Animator) -> Self {
        let geometry = posed_geometry(&scene, &mut animator, settings.pipeline, 0.0);
        let film = Film::new(settings.width, settings.height);
        Self {
            scene,
            geometry,
            animator,
            dynamic: None,
            parts: None,
            rebuilder: None,
            static_builder: None,
            static_trees: StaticTrees::Due,
            tree_age: 0,
            landed_sah: 0.0,
            lights: None,
            tracer: None,
            keep_film: false,
            film_on_device: false,
            film_read: false,
            version: 0,
            auto: None,
            settings,
            camera,
            film,
            guide: None,
            spare_guide: None,
            denoised: None,
            denoise_error: None,
            temporal: Temporal::default(),
            samples: 0,
            frame: 0,
            seed: 0,
            jitter: None,
            tree_dirty: true,
            sah: 0.0,
            part_boxes: Vec::new(),
            build_cost: 0,
            time: 0.0,
            playing: true,
            speed: 1.0,
            rebuild_sah_growth: REBUILD_SAH_GROWTH,
        }
    }

    /// The same pipeline with `tracer` tracing the colour frames (the other modes stay on the
    /// CPU). A tracer that fails is dropped, with a warning, and the CPU traces on.
    pub fn with_tracer(self, tracer: Box<dyn FrameTracer>) -> Self {
        Self { tracer: Some(tracer), ..self }
    }

    /// Has the tracer keep the film, where it can ([`FrameTracer::keeps_film`]): for a window
    /// that shows the device's image itself. Colour frames are then added to the device's film
    /// and not read back, and the film is read back when an image is asked for
    /// ([`FramePipeline::image`]). With a denoiser on, the frames are read back as without (it
    /// filters each frame's samples first, then the CPU's film). Restarts the film when it
    /// changes.
    pub fn keep_film_on_device(&mut self, keep: bool) {
        if keep != self.keep_film {
            self.keep_film = keep;
            self.restart();
        }
    }

    /// Whether the frames since the last restart are in the tracer's film (and the image to
    /// show is the device's, not [`FramePipeline::image_rgba8`]).
    pub fn film_on_device(&self) -> bool {
        self.film_on_device
    }

    /// The device of the pipeline's tracer, `None` without one (or after it failed).
    pub fn tracer(&self) -> Option<String> {
        self.tracer.as_ref().map(|t| format!("{} ({})", t.name(), t.describe()))
    }

    /// Turns online tuning of the builder on (`Some`: it picks the builder from then on, by
    /// measuring moving frames) or off (the builder stays the one last picked).
    pub fn set_auto(&mut self, auto: Option<AutoBuilder>) {
        if let Some(a) = &auto {
            self.switch_builder(a.current());
        }
        self.auto = auto;
    }

    /// The online tuner, when it is on.
    pub fn auto(&self) -> Option<&AutoBuilder> {
        self.auto.as_ref()
    }

    /// Builds the trees with `builder` from the next frame on.
    fn switch_builder(&mut self, builder: Builder) {
        if builder != self.settings.builder {
            self.settings.builder = builder;
            self.build_trees_anew();
        }
    }

    /// Has the next frame build every tree afresh with the builder: drops PHR's auxiliary
    /// tree, the two-level layout, the deforming part's rebuild worker and the static rebuild
    /// (its trees were made for the current layout).
    fn build_trees_anew(&mut self) {
        self.tree_dirty = true;
        self.dynamic = None;
        self.parts = None;
        self.rebuilder = None;
        self.forget_static_rebuild();
    }

    /// Has `builder` rebuild, in the background, the trees of the parts whose primitives
    /// never move ([`crate::static_rebuild`]): once the first frame with the current trees is out,
    /// and again whenever they are built anew (another builder, another layout). `None`
    /// keeps the builder's trees. In the thesis pipeline, whose one tree is rebuilt when
    /// anything moves, only a scene without animation is; with another device tracing, or
    /// in the heatmap view mode (which shows the steps through the builder's trees), nothing
    /// is. The image does not change, so the accumulation goes on.
    pub fn set_static_builder(&mut self, builder: Option<Builder>) {
        if builder != self.static_builder {
            self.static_builder = builder;
            match self.static_rebuilt() {
                // The last static builder's trees are in place: back to the builder's.
                true => self.build_trees_anew(),
                false => self.forget_static_rebuild(),
            }
        }
    }

    /// Whether the trees of the parts that never move are now the static builder's (false
    /// while it builds them, and without one).
    pub fn static_rebuilt(&self) -> bool {
        matches!(self.static_trees, StaticTrees::Done { rebuilt: true })
    }

    /// Waits for the static rebuild under way, if any, and swaps its trees in (between frames,
    /// like [`FramePipeline::step`]; not from one of rayon's worker threads). For tests and
    /// benchmarks that need to know which trees a frame traces.
    pub fn finish_static_rebuild(&mut self) {
        if let StaticTrees::Building(worker) = &mut self.static_trees {
            let trees = worker.wait();
            self.land_static_trees(trees, &mut FrameReport::default());
        }
    }

    /// Drops the static rebuild under way (its trees would replace newer ones) and marks
    /// the current trees as not rebuilt.
    fn forget_static_rebuild(&mut self) {
        self.static_trees = StaticTrees::Due;
    }

    /// Starts the static rebuild of the current trees if it is due: after a frame, with the
    /// trees built, when none is under way or done. The parts' boxes and triangles are
    /// copied for the worker here, timed as `report.build_ms`.
    fn start_static_rebuild(&mut self, report: &mut FrameReport) {
        let Some(builder) = self.static_builder else { return };
        let due = matches!(self.static_trees, StaticTrees::Due) && !self.tree_dirty;
        if !due || self.tracer.is_some() || self.settings.mode == ViewMode::Heatmap {
            return;
        }
        // Not while the online tuner measures its candidates: a build beside their frames
        // would slow them down.
        if matches!(self.auto.as_ref().map(|a| &a.state), Some(AutoState::Exploring { .. })) {
            return;
        }
        // Unless a worker starts below, there is nothing to rebuild.
        self.static_trees = StaticTrees::Done { rebuilt: false };
        if builder == self.settings.builder {
            return;
        }
        let deforming = match (&self.parts, self.settings.pipeline) {
            (None, PipelineKind::Thesis) if self.animator.is_animated() => return,
            (None, _) => None,
            (Some(parts), _) => parts.deforming,
        };
        let copy_start = Instant::now();
        let jobs: Vec<StaticJob> = (0..self.geometry.part_count())
            .filter(|&k| Some(k) != deforming)
            .map(|k| StaticJob {
                part: k,
                boxes: self.geometry.part_boxes(k),
                triangles: self.geometry.part_triangles(k).into_owned(),
            })
            .collect();
        report.build_ms += ms_since(copy_start);
        if !jobs.is_empty() {
            self.static_trees = StaticTrees::Building(StaticRebuilder::start(builder, jobs));
        }
    }

    /// Gives the parts the static builder's trees (their numbering and packing timed as
    /// `report.wide_ms`). A part's box is that of the same primitives in any tree, so the top
    /// level needs no rebuild. No trees: the worker failed, and the builder's trees stay.
    fn land_static_trees(&mut self, trees: Vec<StaticTree>, report: &mut FrameReport) {
        self.static_trees = StaticTrees::Done { rebuilt: !trees.is_empty() };
        for tree in trees {
            debug_assert!(tree.part < self.geometry.part_count(), "a static tree of another layout");
            let (_, packing) = self.geometry.set_part_wide(tree.part, |wide| *wide = tree.wide);
            report.wide_ms += packing.as_secs_f64() * 1e3;
            if self.parts.is_none() {
                // The thesis pipeline's one tree: its cost is the one reported.
                self.sah = tree.sah;
            }
        }
        self.version += 1;
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    pub fn geometry(&self) -> &Geometry {
        &self.geometry
    }

    pub fn settings(&self) -> &PipelineSettings {
        &self.settings
    }

    pub fn camera(&self) -> &CameraDesc {
        &self.camera
    }

    pub fn is_animated(&self) -> bool {
        self.animator.is_animated()
    }

    /// Samples per pixel in the film.
    pub fn samples(&self) -> u32 {
        self.samples
    }

    /// Moves the camera; a different camera restarts accumulation.
    pub fn set_camera(&mut self, camera: CameraDesc) {
        if camera != self.camera {
            self.camera = camera;
            self.restart();
        }
    }

    /// Changes settings; a different builder rebuilds the tree, a different size makes a new
    /// film, and any change restarts accumulation.
    pub fn set_settings(&mut self, settings: PipelineSettings) {
        // With online tuning on, the tuner picks the builder.
        let settings = match self.auto {
            Some(_) => PipelineSettings { builder: self.settings.builder, ..settings },
            None => settings,
        };
        if settings == self.settings {
            return;
        }
        if settings.pipeline != self.settings.pipeline {
            self.geometry = posed_geometry(&self.scene, &mut self.animator, settings.pipeline, self.time);
            self.lights = None;
        }
        // The heatmap counts the steps through the builder's trees.
        let heatmap_over_static_trees = settings.mode == ViewMode::Heatmap && self.static_rebuilt();
        if settings.builder != self.settings.builder
            || settings.pipeline != self.settings.pipeline
            || heatmap_over_static_trees
        {
            self.build_trees_anew();
        }
        if (settings.width, settings.height) != (self.settings.width, self.settings.height) {
            self.film = Film::new(settings.width.max(1), settings.height.max(1));
        }
        self.settings = settings;
        self.temporal.reset();
        self.restart();
    }

    /// Throws the accumulated samples away.
    pub fn restart(&mut self) {
        self.film.clear();
        self.film_on_device = false;
        self.film_read = false;
        self.samples = 0;
        self.guide = None;
        self.denoised = None;
    }

    /// Renders one frame: advances the animation by `dt` seconds (times the speed) if it is
    /// playing, rebuilds the tree if anything moved or the builder changed, traces one sample
    /// per pixel and adds it to the film.
    ///
    /// A frame the CPU traces runs on one of rayon's worker threads, serial parts included,
    /// so that it keeps as many threads busy as the pool has. Run from the caller's thread,
    /// its serial parts (posing, placing, the filter's set-up) made one thread more than
    /// cores between the parallel loops, and the scheduler at times left both workers of a
    /// 2-core pool on one core for the next loop: on the carousel, one moving frame in four
    /// to seven rendered in 19 ms instead of 12. A frame another device traces stays on the
    /// caller's thread, which waits for the device while the workers rebuild.
    pub fn step(&mut self, dt: f32) -> FrameReport {
        match self.tracer {
            Some(_) => self.run_frame(dt),
            None => rayon::scope(|_| self.run_frame(dt)),
        }
    }

    fn run_frame(&mut self, dt: f32) -> FrameReport {
        let start = Instant::now();
        let mut report = FrameReport { frame: self.frame, ..FrameReport::default() };
        if let StaticTrees::Building(worker) = &mut self.static_trees {
            // (A change of layout since it started dropped it: its trees are this layout's.)
            if let Some(trees) = worker.finished() {
                self.land_static_trees(trees, &mut report);
            }
        }
        let moved = self.playing && self.speed != 0.0 && self.animator.is_animated();
        if moved {
            self.time += dt * self.speed;
            match self.settings.pipeline {
                PipelineKind::Thesis => self.animator.pose(&mut self.geometry, self.time),
                PipelineKind::TwoLevel | PipelineKind::Async => {
                    self.animator.pose_deforming(&mut self.geometry, self.time)
                }
            }
            report.pose_ms = ms_since(start);
            self.restart();
        }
        if moved || self.tree_dirty {
            match self.settings.pipeline {
                PipelineKind::Thesis => self.rebuild(&mut report),
                PipelineKind::TwoLevel | PipelineKind::Async => self.update_parts(&mut report),
            }
            if let Some(lights) = &mut self.lights {
                lights.refresh(&self.geometry, &self.scene.materials);
            }
            self.version += 1;
            self.restart();
        }
        if self.settings.explicit_lights && self.lights.is_none() {
            self.lights = Some(LightSet::new(&self.geometry, &self.scene.materials, &self.scene.background));
            self.version += 1;
        }
        // This frame's samples go through the temporal filter, guided by their own first hits.
        let temporal = self.settings.denoise.is_some()
            && self.settings.mode == ViewMode::Colour
            && self.samples + 1 < ACCUMULATED_DENOISE_FROM;
        let render_start = Instant::now();
        let (traced, first_hits, device) = self.render(temporal);
        report.render_ms = ms_since(render_start);
        report.upload_ms = traced.upload_ms;
        report.upload_bytes = traced.upload_bytes;
        report.device = device;
        let (pixels, rays) = (traced.pixels, traced.rays);
        if self.film_on_device && self.tracer.is_none() {
            // The device that kept the film failed: its samples went with it.
            self.restart();
        }
        if !self.film_on_device {
            self.film.add_frame(&pixels);
        }
        self.samples += 1;
        let s = self.samples;
        if let (Some(filter), ViewMode::Colour) = (self.settings.denoise, self.settings.mode) {
            let denoise_start = Instant::now();
            if let Some(first_hits) = first_hits {
                self.denoise_frame(&pixels, &first_hits);
                report.denoise_ms = ms_since(denoise_start);
            } else if s.is_power_of_two() || s.is_multiple_of(64) {
                self.denoise(filter);
                report.denoise_ms = ms_since(denoise_start);
            }
        }
        self.start_static_rebuild(&mut report);
        report.frame_ms = ms_since(start);
        report.builder = self.settings.builder;
        report.static_builder = self.static_builder.filter(|_| self.static_rebuilt());
        if let (true, Some(auto)) = (moved, &mut self.auto) {
            // The tuner sees the frames whose tree the builder made.
            if let Some(next) = auto.record(report.frame_ms) {
                self.switch_builder(next);
            }
        }
        self.frame += 1;
        report.moved = moved;
        report.time = self.time;
        report.rays = rays;
        report.sah_cost = self.sah;
        report.build_cost = self.build_cost;
        report.samples = self.samples;
        report.tree_age = self.tree_age;
        report
    }

    fn rebuild(&mut self, report: &mut FrameReport) {
        self.forget_static_rebuild();
        let boxes = &self.geometry.boxes;
        match self.settings.builder {
            Builder::Phr(options) => {
                let refit_start = Instant::now();
                let dynamic = match &mut self.dynamic {
                    Some(d) => d,
                    None => self.dynamic.insert(DynamicBvh::new(boxes, options)),
                };
                let created_ms = ms_since(refit_start);
                // Straight to the wide tree the renderer traces: no binary tree, no collapse.
                let boxes = std::mem::take(&mut self.geometry.boxes);
                let (timings, wide_time) = self.geometry.set_part_wide(0, |wide| dynamic.update_wide(&boxes, wide));
                self.geometry.boxes = boxes;
                report.refit_ms = created_ms + timings.refit.as_secs_f64() * 1e3;
                report.build_ms = timings.build.as_secs_f64() * 1e3;
                report.wide_ms = wide_time.as_secs_f64() * 1e3;
                self.build_cost = timings.build_cost;
                self.sah = wide_sah_cost(self.geometry.wide_bvh(), SahConstants::UNIT);
            }
            builder => {
                let build_start = Instant::now();
                let bvh = builder.build_with_triangles(boxes, &self.geometry.triangles);
                report.build_ms = ms_since(build_start);
                report.wide_ms = self.geometry.set_bvh(bvh).as_secs_f64() * 1e3;
                self.build_cost = 0;
                self.sah = sah_cost(self.geometry.bvh(), SahConstants::UNIT);
            }
        }
        // The meshes placed many times: built once, the first time.
        report.build_ms += self.geometry.build_copies(&self.settings.builder).as_secs_f64() * 1e3;
        self.tree_dirty = false;
    }

    /// The two-level layout's update: the first time, splits the scene into a static part, a
    /// deforming part and a part per rigid object, each built by the builder; then moves the
    /// rigid parts to the current time and rebuilds the deforming part from its moved boxes.
    fn update_parts(&mut self, report: &mut FrameReport) {
        if self.parts.is_none() {
            self.forget_static_rebuild();
            let build_start = Instant::now();
            let parts = self.split();
            report.build_ms = ms_since(build_start);
            self.parts = Some(parts);
        }
        let deforming = self.parts.as_ref().and_then(|p| p.deforming);
        if let Some(d) = deforming {
            // (Built once more on the first frame: the auxiliary tree starts here.)
            self.update_deforming(d, report);
        }
        let Some(parts) = &self.parts else { unreachable!("split above") };
        let place_start = Instant::now();
        let moves: Vec<_> = parts
            .rigid
            .iter()
            .filter_map(|&(part, object)| Some((part, self.animator.rigid_transform(object, self.time)?)))
            .collect();
        self.geometry.place(&moves);
        report.build_ms += ms_since(place_start);
        self.tree_dirty = false;
    }

    /// Recomputes the boxes of the deforming part `d` (its order) into
    /// [`FramePipeline::part_boxes`], timed as posing.
    fn update_part_boxes(&mut self, d: usize, report: &mut FrameReport) {
        let start = Instant::now();
        self.geometry.part_boxes_into(d, &mut self.part_boxes);
        report.pose_ms += ms_since(start);
    }

    /// Rebuilds the deforming part `d` from its moved primitives: with the builder in the
    /// frame, or, for [`PipelineKind::Async`] with PHR, by refitting the traced tree and
    /// taking the worker's tree when one has landed. (The refit needs no primitive boxes:
    /// they are computed only for a build.)
    fn update_deforming(&mut self, d: usize, report: &mut FrameReport) {
        let asynchronous =
            self.settings.pipeline == PipelineKind::Async && matches!(self.settings.builder, Builder::Phr(_));
        if !asynchronous || self.rebuilder.is_none() {
            self.update_part_boxes(d, report);
        }
        let build_start = Instant::now();
        let mut landed = false;
        let mut refitted_sah = None;
        let boxes = std::mem::take(&mut self.part_boxes);
        match self.settings.builder {
            Builder::Phr(options) if asynchronous => {
                let (new_tree, sah) = self.refit_or_land(d, &boxes, options, report);
                (landed, refitted_sah) = (new_tree, Some(sah));
            }
            Builder::Phr(options) => {
                self.tree_age = 0;
                // Straight to the wide tree the renderer traces: no binary tree, no collapse.
                let dynamic = self.dynamic.get_or_insert_with(|| DynamicBvh::new(&boxes, options));
                let created_ms = ms_since(build_start);
                let (timings, wide_time) = self.geometry.set_part_wide(d, |wide| dynamic.update_wide(&boxes, wide));
                report.refit_ms = created_ms + timings.refit.as_secs_f64() * 1e3;
                report.build_ms += timings.build.as_secs_f64() * 1e3;
                report.wide_ms = wide_time.as_secs_f64() * 1e3;
                self.build_cost = timings.build_cost;
            }
            Builder::BinnedSah(options) => {
                self.tree_age = 0;
                let (_, wide_time) =
                    self.geometry.set_part_wide(d, |wide| build_binned_sah_wide(&boxes, &options, wide));
                report.wide_ms = wide_time.as_secs_f64() * 1e3;
                report.build_ms += ms_since(build_start) - report.wide_ms;
            }
            builder => {
                self.tree_age = 0;
                let bvh = builder.build_with_triangles(&boxes, &self.geometry.part_triangles(d));
                report.build_ms += ms_since(build_start);
                report.wide_ms = self.geometry.set_part_bvh(d, bvh).as_secs_f64() * 1e3;
            }
        }
        self.part_boxes = boxes;
        // A refit costs its tree as it goes; a tree built here is costed now.
        self.sah = refitted_sah.unwrap_or_else(|| wide_sah_cost(self.geometry.part_wide(d), SahConstants::UNIT));
        self.apply_rebuild_policy(d, landed, report);
    }

    /// The asynchronous rebuild policy: a new tree once the refitted one's SAH cost has grown
    /// past `rebuild_sah_growth` times that of the last tree that landed, unless the worker
    /// is still busy with one.
    fn apply_rebuild_policy(&mut self, d: usize, landed: bool, report: &mut FrameReport) {
        let Some(rebuilder) = &self.rebuilder else { return };
        if landed {
            self.landed_sah = self.sah;
        }
        // Written as "not grown" so that a NaN cost starts no rebuild.
        let grown = self.sah > self.rebuild_sah_growth * self.landed_sah;
        if !grown || rebuilder.busy() {
            return;
        }
        self.update_part_boxes(d, report);
        if let Some(rebuilder) = &mut self.rebuilder {
            rebuilder.start(&self.part_boxes, self.frame);
        }
    }

    /// The asynchronous update of the deforming part `d`: takes the worker's tree if one has
    /// landed (the first time, builds one here and starts the worker), refits the traced tree
    /// to `boxes` and packs the triangles. Returns whether a new tree landed, and the refitted
    /// tree's SAH cost.
    fn refit_or_land(
        &mut self,
        d: usize,
        boxes: &[Aabb],
        options: PhrOptions,
        report: &mut FrameReport,
    ) -> (bool, f64) {
        let start = Instant::now();
        let mut landed = None;
        if self.rebuilder.is_none() {
            let (rebuilder, first) = AsyncRebuilder::new(boxes, options, self.frame);
            (self.rebuilder, landed) = (Some(rebuilder), Some(first));
        }
        let Some(rebuilder) = &mut self.rebuilder else { unreachable!("made above") };
        // (The build on this thread, the first time.)
        report.build_ms += ms_since(start);
        let mut landed = landed.or_else(|| rebuilder.finished());
        let (refit, areas) = self.geometry.refit_part(d, landed.as_mut().map(|l| &mut l.wide));
        // The refit of the traced tree and the packing of the moved triangles, which cost
        // the tree as they go.
        report.refit_ms = refit.as_secs_f64() * 1e3;
        let is_new = landed.is_some();
        self.tree_age = match landed {
            Some(l) => {
                self.build_cost = l.timings.build_cost;
                rebuilder.recycle(l.wide);
                self.frame - l.frame
            }
            None => self.tree_age + 1,
        };
        (is_new, areas.sah_cost(SahConstants::UNIT))
    }

    /// Cuts the scene into the two-level layout's parts and builds their trees.
    fn split(&mut self) -> Parts {
        let objects = self.animator.objects(self.geometry.triangle_count());
        let mut moving = vec![false; self.geometry.prim_count()];
        for object in &objects {
            for &p in &object.prims {
                moving[p as usize] = true;
            }
        }
        let mut deforming = Vec::new();
        let mut rigid = Vec::new();
        for (k, object) in objects.iter().enumerate() {
            if object.rigid {
                rigid.push(k);
            } else {
                deforming.extend_from_slice(&object.prims);
            }
        }
        deforming.sort_unstable();
        deforming.dedup();
        let still: Vec<u32> = (0..moving.len() as u32).filter(|&p| !moving[p as usize]).collect();
        let mut groups = Vec::new();
        let mut part = |prims: Vec<u32>| {
            (!prims.is_empty()).then(|| {
                groups.push(prims);
                groups.len() - 1
            })
        };
        part(still);
        let deforming = part(deforming);
        let rigid: Vec<(usize, usize)> =
            rigid.into_iter().filter_map(|k| Some((part(objects[k].prims.clone())?, k))).collect();
        if objects.is_empty() || groups.is_empty() {
            // Nothing moves (or there is nothing): one tree, no top level to pass through.
            self.geometry.build(&self.settings.builder);
        } else {
            let builder = self.settings.builder;
            self.geometry.split(groups, &builder);
        }
        self.sah = 0.0;
        self.build_cost = 0;
        Parts { deforming, rigid }
    }

    /// One sample per pixel in the current view mode; returns the frame, its first hits if
    /// `guided` (which the caller asks for in colour mode only) and the device that traced it.
    fn render(&mut self, guided: bool) -> (TracedFrame, Option<Vec<FirstHit>>, &'static str) {
        let s = &self.settings;
        let size = RenderSettings { width: s.width, height: s.height, spp: 1, max_depth: s.max_depth.max(1) };
        let lights = self.lights.as_ref().filter(|_| s.explicit_lights);
        let renderer = Renderer::new(&self.scene, &self.geometry, &self.camera, &size, lights)
            .with_seed(self.seed)
            .with_jitter(self.jitter.take());
        // Kept for the next frame's renderer (made now if the seed or the size changed).
        self.jitter = Some(renderer.jitter_table());
        // While accumulating, the frame number picks new random numbers for every sample;
        // while animating, it keeps the noise from freezing in place.
        let frame = self.frame as u32;
        let geometry = &self.geometry;
        if let Some(tracer) = self.tracer.as_mut().filter(|_| s.mode == ViewMode::Colour) {
            let job = FrameJob {
                scene: &self.scene,
                geometry,
                lights,
                camera: &self.camera,
                width: s.width,
                height: s.height,
                max_depth: size.max_depth,
                seed: self.seed,
                frame,
                version: self.version,
            };
            // The film starts on the device, or not at all (the temporal filter's frames, in
            // the first frames after a change, are read back into the CPU's film).
            let keep = self.keep_film && !guided && (self.samples == 0 || self.film_on_device) && tracer.keeps_film();
            let traced = if keep { tracer.accumulate(&job, self.samples == 0) } else { tracer.trace(&job) };
            match traced {
                Ok(traced) => {
                    (self.film_on_device, self.film_read) = (keep, false);
                    // The guide's first hits come from the same camera rays, traced here.
                    return (traced, guided.then(|| renderer.first_hits(frame)), tracer.name());
                }
                Err(why) => {
                    eprintln!("warning: {} failed ({why}); the CPU traces from frame {frame} on", tracer.name());
                    self.tracer = None;
                }
            }
        }
        if guided {
            let (pixels, first_hits, stats) = renderer.render_frame_guided(frame);
            return (
                TracedFrame { pixels, rays: stats.rays, upload_ms: 0.0, upload_bytes: 0 },
                Some(first_hits),
                "cpu",
            );
        }
        let (pixels, stats) = match s.mode {
            ViewMode::Colour => renderer.render_frame(frame),
            ViewMode::Normals => renderer.render_frame_with(frame, |ray, _| match geometry.intersect(&ray) {
                Some(hit) => {
                    let sp = geometry.surface_point(&ray, &hit);
                    let n = if sp.front { sp.normal } else { -sp.normal };
                    (0.5 * (n + Vec3::ONE), 1)
                }
                None => (Vec3::ZERO, 1),
            }),
            ViewMode::Albedo => renderer.render_frame_with(frame, |ray, _| match geometry.intersect(&ray) {
                Some(hit) => {
                    let sp = geometry.surface_point(&ray, &hit);
                    (renderer.tracer.albedo_at(&sp, &hit), 1)
                }
                None => (self.scene.background.radiance(ray.dir.normalize()), 1),
            }),
            ViewMode::Heatmap => renderer.render_frame_with(frame, |ray, _| {
                let mut counts = TraversalStats::default();
                geometry.intersect_counted(&ray, &mut counts);
                let [r, g, b] = turbo(counts.nodes as f32 / HEATMAP_MAX_STEPS);
                // turbo() gives display (sRGB) values; the film holds linear ones.
                let linear = |c: u8| (c as f32 / 255.0).powf(2.2);
                (Vec3::new(linear(r), linear(g), linear(b)), 1)
            }),
        };
        (TracedFrame { pixels, rays: stats.rays, upload_ms: 0.0, upload_bytes: 0 }, None, "cpu")
    }

    /// The first hits of the current view, `samples` jittered ones per pixel.
    fn trace_guide(&self, samples: u32) -> Guide {
        let s = &self.settings;
        let size = RenderSettings { width: s.width, height: s.height, spp: 1, max_depth: s.max_depth.max(1) };
        let renderer = Renderer::new(&self.scene, &self.geometry, &self.camera, &size, None).with_seed(self.seed);
        Guide::render(&renderer, samples)
    }

    /// Denoises this frame's samples `pixels` through the temporal filter, guided by the
    /// first hits of the rays they came from.
    fn denoise_frame(&mut self, pixels: &[Vec3], first_hits: &[FirstHit]) {
        let camera = Camera::new(&self.camera, self.settings.width, self.settings.height);
        let (width, height) = (self.settings.width, self.settings.height);
        let guide = Guide::from_first_hits_reusing(self.spare_guide.take(), &camera, width, height, first_hits);
        self.denoised = Some(self.temporal.denoise(pixels, &guide, &camera));
        self.spare_guide = Some(guide);
    }

    /// Denoises the film as it is now with `filter`, tracing the guide first if the film
    /// restarted. A filter that fails (OIDN without its library) leaves the raw mean, and
    /// says why once.
    fn denoise(&mut self, filter: Filter) {
        self.read_film();
        if self.guide.is_none() {
            self.guide = Some(self.trace_guide(VIEWER_GUIDE_SAMPLES));
        }
        let guide = self.guide.as_ref().expect("traced above");
        self.denoised = match filter.apply(&self.film, guide) {
            Ok(image) => Some(image),
            Err(why) => {
                if self.denoise_error.replace(why.clone()).is_none() {
                    eprintln!("warning: not denoised: {why}");
                }
                None
            }
        };
    }

    /// Brings the tracer's film into `film` if it keeps it and it changed since last read.
    /// A device whose film cannot be read is dropped, as one that fails to trace, and the
    /// film starts again (empty: 0 samples, not an image that claims them).
    fn read_film(&mut self) {
        if !self.film_on_device || self.film_read {
            return;
        }
        self.film_read = true;
        let Some(tracer) = self.tracer.as_mut() else { return };
        let why = match tracer.film() {
            Ok(film) if (film.width, film.height) == (self.film.width, self.film.height) => {
                self.film = film;
                return;
            }
            Ok(film) => {
                format!("its film is {} × {}, not {} × {}", film.width, film.height, self.film.width, self.film.height)
            }
            Err(why) => why,
        };
        eprintln!("warning: cannot read {}'s film ({why}); the CPU traces from here on", tracer.name());
        self.tracer = None;
        self.restart();
    }

    /// The accumulated image (linear radiance, row-major from the top left): the last
    /// denoised one when denoising is on and there is one since the film restarted. Reads
    /// the film back from the device that keeps it.
    pub fn image(&mut self) -> Vec<Vec3> {
        self.read_film();
        match &self.denoised {
            Some(image) if self.settings.denoise.is_some() => image.clone(),
            _ => self.film.mean(),
        }
    }

    /// [`FramePipeline::image`] for a file: `None` while the film holds no samples (nothing
    /// traced yet, or a device's kept film that could not be read back, which drops the
    /// device and starts the film again), rather than a black image.
    pub fn image_to_save(&mut self) -> Option<Vec<Vec3>> {
        let image = self.image();
        (self.samples > 0).then_some(image)
    }

    /// The film's mean, never denoised.
    pub fn raw_image(&mut self) -> Vec<Vec3> {
        self.read_film();
        self.film.mean()
    }

    /// [`FramePipeline::image`] as 8-bit sRGB RGBA, for display.
    pub fn image_rgba8(&mut self) -> Vec<u8> {
        rgba8(&self.image())
    }
}

/// The scene's geometry at time `t` as `pipeline` traces it: everything moved (the thesis's
/// one tree), or the deforming objects alone (the two-level layout places the others).
fn posed_geometry(scene: &Scene, animator: &mut Animator, pipeline: PipelineKind, t: f32) -> Geometry {
    let mut geometry = Geometry::new(scene);
    if animator.is_animated() {
        match pipeline {
            PipelineKind::Thesis => animator.pose(&mut geometry, t),
            PipelineKind::TwoLevel | PipelineKind::Async => {
                animator.pose_deforming(&mut geometry, t);
                geometry.update_boxes();
            }
        }
    }
    geometry
}

/// Jittered first hits per pixel for the viewer's guide of the accumulated image (the
/// albedo's anti-aliasing).
const VIEWER_GUIDE_SAMPLES: u32 = 4;

/// Below this many samples in the film, the viewer shows the temporal filter's image; from
/// it on, the accumulated image's (whose variance is then known well enough).
pub const ACCUMULATED_DENOISE_FROM: u32 = 16;

fn ms_since(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}
