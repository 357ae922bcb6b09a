//! The viewer window (eframe/egui, on OpenGL, or on the GPU's own device when it traces the
//! frames): the path-traced image in the middle, controls and live statistics on the left.
//!
//! Rendering runs on its own thread ([`worker`]) so the window stays responsive however long
//! a frame takes: the window publishes what the user set (camera, settings, requests), the
//! worker steps the [`FramePipeline`] with it and publishes the newest image and its
//! statistics, and asks for a repaint.
//!
//! Input: left drag orbits, right drag looks around, the wheel dollies, WASD flies (Q/E down
//! and up, Shift ×4), R resets the camera, 1–9 jump to the scene's named views, Space plays or
//! pauses the animation, P saves the render (PNG and EXR), F12 saves a screenshot of the
//! window (PNG).

use super::camera_control::CameraControl;
use super::device::{OnGpu, ShownTexture};
use super::ViewArgs;
use anyhow::anyhow;
use eframe::egui;
use glam::Vec3;
use phr_bvh::phr::PhrOptions;
use phr_bvh::Builder;
use phr_render::auto_builder::AutoBuilder;
use phr_render::camera::CameraDesc;
use phr_render::denoise::{oidn, Filter};
use phr_render::output::write_image;
use phr_render::pipeline::{FramePipeline, FrameReport, PipelineKind, PipelineSettings, ViewMode};
use std::collections::VecDeque;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Frames kept in the frame-time plot.
const HISTORY: usize = 240;
/// A still view stops rendering after this many samples per pixel.
const MAX_SAMPLES: u32 = 4096;

/// The builders the panel offers.
#[derive(Clone, Copy, Debug, PartialEq)]
enum BuilderChoice {
    /// Online tuning: the builder whose moving frames are fastest ([`AutoBuilder`]).
    Auto,
    Lbvh,
    PhrFast,
    PhrHq,
    /// PHR with the α and δ of the sliders.
    PhrCustom,
    /// PHR with α and δ chosen by Bayesian optimisation (phr-tune) for this scene and size.
    PhrTuned,
    SweepSah,
    BinnedSah,
    Sbvh,
}

impl BuilderChoice {
    const ALL: [BuilderChoice; 9] = [
        BuilderChoice::Auto,
        BuilderChoice::Lbvh,
        BuilderChoice::PhrFast,
        BuilderChoice::PhrHq,
        BuilderChoice::PhrCustom,
        BuilderChoice::PhrTuned,
        BuilderChoice::SweepSah,
        BuilderChoice::BinnedSah,
        BuilderChoice::Sbvh,
    ];

    fn label(self) -> &'static str {
        match self {
            BuilderChoice::Auto => "auto (fastest moving frame)",
            BuilderChoice::Lbvh => "LBVH",
            BuilderChoice::PhrFast => "PHR-Fast (α 0.5, δ 6)",
            BuilderChoice::PhrHq => "PHR-HQ (α 0.55, δ 9)",
            BuilderChoice::PhrCustom => "PHR (α, δ below)",
            BuilderChoice::PhrTuned => "PHR tuned (BO)",
            BuilderChoice::SweepSah => "Sweep SAH",
            BuilderChoice::BinnedSah => "Binned SAH",
            BuilderChoice::Sbvh => "SBVH (spatial splits)",
        }
    }

    fn is_phr(self) -> bool {
        matches!(
            self,
            BuilderChoice::PhrFast | BuilderChoice::PhrHq | BuilderChoice::PhrCustom | BuilderChoice::PhrTuned
        )
    }
}

/// What the window asks of the worker.
#[derive(Clone)]
struct Controls {
    camera: CameraDesc,
    settings: PipelineSettings,
    playing: bool,
    speed: f32,
    /// Reset the animation clock.
    rewind: bool,
    /// Save the accumulated render (PNG and EXR).
    save_render: bool,
    /// Run the tuner, then use its α, δ.
    tune: bool,
    /// Online tuning of the builder.
    auto: bool,
    quit: bool,
}

/// What the worker shows the window.
#[derive(Default)]
struct Published {
    version: u64,
    width: u32,
    height: u32,
    /// The image, unless the GPU keeps it (`on_device`: the window draws the GPU's texture).
    rgba: Vec<u8>,
    on_device: bool,
    report: FrameReport,
    /// (frame ms, render ms, refit + build ms) of the last frames.
    history: VecDeque<[f32; 3]>,
    message: String,
    /// α, δ found by the tuner.
    tuned: Option<(f32, f32)>,
    tuning: bool,
    /// What online tuning does, when it is on.
    auto: Option<String>,
}

struct Shared {
    controls: Mutex<Controls>,
    published: Mutex<Published>,
}

/// Why the viewer stopped with an error.
pub enum WindowError {
    /// No window could be opened (no usable display, OpenGL, or, with `--device gpu`, a
    /// GPU that cannot draw to it): the caller may go headless.
    Start(String),
    Other(anyhow::Error),
}

pub fn run(args: &ViewArgs, mut pipeline: FramePipeline, on_gpu: Option<OnGpu>) -> Result<(), WindowError> {
    std::fs::create_dir_all(&args.out)
        .map_err(|e| WindowError::Other(anyhow!("creating {}: {e}", args.out.display())))?;
    let scene = pipeline.scene();
    let views: Vec<(String, CameraDesc)> = scene.views.clone();
    let size = scene.bounds().extent().length();
    let triangles = pipeline.geometry().triangle_count();
    let animated = pipeline.is_animated();
    let settings = pipeline.settings().clone();
    let camera = CameraControl::new(pipeline.camera(), size);
    let controls = Controls {
        camera: camera.desc(),
        settings: settings.clone(),
        playing: pipeline.playing,
        speed: 1.0,
        rewind: false,
        save_render: false,
        tune: false,
        auto: pipeline.auto().is_some(),
        quit: false,
    };
    let shared = Arc::new(Shared { controls: Mutex::new(controls.clone()), published: Mutex::default() });
    let (choice, alpha, delta, branching) = match settings.builder {
        _ if pipeline.auto().is_some() => (BuilderChoice::Auto, 0.5, 6.0, 2),
        Builder::Lbvh(_) => (BuilderChoice::Lbvh, 0.5, 6.0, 2),
        Builder::SweepSah(_) => (BuilderChoice::SweepSah, 0.5, 6.0, 2),
        Builder::BinnedSah(_) => (BuilderChoice::BinnedSah, 0.5, 6.0, 2),
        Builder::Sbvh(_) => (BuilderChoice::Sbvh, 0.5, 6.0, 2),
        Builder::Phr(o) if (o.alpha, o.delta) == (PhrOptions::FAST.alpha, PhrOptions::FAST.delta) => {
            (BuilderChoice::PhrFast, o.alpha, o.delta, o.branching)
        }
        Builder::Phr(o) if (o.alpha, o.delta) == (PhrOptions::HQ.alpha, PhrOptions::HQ.delta) => {
            (BuilderChoice::PhrHq, o.alpha, o.delta, o.branching)
        }
        Builder::Phr(o) => (BuilderChoice::PhrCustom, o.alpha, o.delta, o.branching),
    };
    let title = format!("phr — {}", args.scene);
    // Drawing with the GPU's device, the window shows the film the GPU keeps.
    pipeline.keep_film_on_device(on_gpu.is_some());
    let app = ViewerApp {
        shared: shared.clone(),
        worker: None,
        pipeline: Some(pipeline),
        camera,
        home: controls.camera.clone(),
        views,
        controls,
        texture: None,
        shown: on_gpu.as_ref().map(OnGpu::shown_texture),
        on_device: false,
        shown_version: 0,
        choice,
        alpha,
        delta,
        branching,
        base_size: (args.width, args.height),
        scale: 1.0,
        triangles,
        animated,
        out: args.out.clone(),
        screenshots: Arc::new(AtomicU32::new(0)),
        scene_name: args.scene.clone(),
    };
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default().with_title(title).with_inner_size([
            300.0 + (2 * args.width).clamp(512, 1280) as f32,
            (2 * args.height).clamp(860, 1000) as f32,
        ]),
        renderer: eframe::Renderer::Glow,
        ..Default::default()
    };
    let options = match &on_gpu {
        Some(gpu) => gpu.native_options(options),
        None => options,
    };
    let result = eframe::run_native("phr", options, Box::new(|_cc| Ok(Box::new(app))));
    shared.controls.lock().expect("controls").quit = true;
    result.map_err(|e| WindowError::Start(e.to_string()))
}

struct ViewerApp {
    shared: Arc<Shared>,
    worker: Option<std::thread::JoinHandle<()>>,
    /// Handed to the worker on the first frame (when the egui context exists).
    pipeline: Option<FramePipeline>,
    camera: CameraControl,
    home: CameraDesc,
    views: Vec<(String, CameraDesc)>,
    controls: Controls,
    texture: Option<egui::TextureHandle>,
    /// The GPU's image (`--device gpu`), and whether the last frame is there.
    shown: Option<ShownTexture>,
    on_device: bool,
    shown_version: u64,
    choice: BuilderChoice,
    alpha: f32,
    delta: f32,
    branching: u32,
    base_size: (u32, u32),
    scale: f32,
    triangles: usize,
    animated: bool,
    out: PathBuf,
    screenshots: Arc<AtomicU32>,
    scene_name: String,
}

impl Drop for ViewerApp {
    fn drop(&mut self) {
        self.shared.controls.lock().expect("controls").quit = true;
        if let Some(worker) = self.worker.take() {
            let _ = worker.join();
        }
    }
}

impl eframe::App for ViewerApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let ctx = ui.ctx().clone();
        if let Some(pipeline) = self.pipeline.take() {
            let shared = self.shared.clone();
            let repaint = ctx.clone();
            let out = self.out.clone();
            self.worker = Some(std::thread::spawn(move || worker(pipeline, shared, repaint, out)));
        }
        self.update_texture(&ctx);
        self.keyboard(&ctx);
        egui::Panel::left("controls").resizable(false).exact_size(280.0).show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| self.side_panel(ui));
        });
        egui::CentralPanel::default().frame(egui::Frame::NONE.fill(egui::Color32::BLACK)).show(ui, |ui| {
            self.image(ui, frame);
        });
        self.controls.camera = self.camera.desc();
        self.controls.settings.builder = self.builder();
        self.controls.auto = self.choice == BuilderChoice::Auto;
        let (w, h) = self.base_size;
        self.controls.settings.width = ((w as f32 * self.scale).round() as u32).max(8);
        self.controls.settings.height = ((h as f32 * self.scale).round() as u32).max(8);
        let mut shared = self.shared.controls.lock().expect("controls");
        // One-shot requests stay set until the worker takes them.
        let (rewind, save, tune) = (shared.rewind, shared.save_render, shared.tune);
        *shared = self.controls.clone();
        shared.rewind |= rewind;
        shared.save_render |= save;
        shared.tune |= tune;
        self.controls.rewind = false;
        self.controls.save_render = false;
        self.controls.tune = false;
    }
}

impl ViewerApp {
    fn builder(&self) -> Builder {
        let phr =
            |alpha, delta| Builder::Phr(PhrOptions { branching: self.branching, ..PhrOptions::with(alpha, delta) });
        match self.choice {
            // The pipeline's tuner picks it.
            BuilderChoice::Auto => Builder::PHR_FAST,
            BuilderChoice::Lbvh => Builder::Lbvh(Default::default()),
            BuilderChoice::PhrFast => phr(PhrOptions::FAST.alpha, PhrOptions::FAST.delta),
            BuilderChoice::PhrHq => phr(PhrOptions::HQ.alpha, PhrOptions::HQ.delta),
            BuilderChoice::PhrCustom => phr(self.alpha, self.delta),
            BuilderChoice::PhrTuned => {
                let tuned = self.shared.published.lock().expect("published").tuned;
                let (a, d) = tuned.unwrap_or((PhrOptions::FAST.alpha, PhrOptions::FAST.delta));
                phr(a, d)
            }
            BuilderChoice::SweepSah => Builder::SweepSah(Default::default()),
            BuilderChoice::BinnedSah => Builder::BinnedSah(Default::default()),
            BuilderChoice::Sbvh => Builder::Sbvh(Default::default()),
        }
    }

    fn update_texture(&mut self, ctx: &egui::Context) {
        let published = self.shared.published.lock().expect("published");
        if published.version == self.shown_version {
            return;
        }
        self.on_device = published.on_device;
        if published.rgba.is_empty() {
            return;
        }
        let size = [published.width as usize, published.height as usize];
        let image = egui::ColorImage::from_rgba_unmultiplied(size, &published.rgba);
        self.shown_version = published.version;
        drop(published);
        match &mut self.texture {
            Some(t) => t.set(image, egui::TextureOptions::NEAREST),
            None => self.texture = Some(ctx.load_texture("render", image, egui::TextureOptions::NEAREST)),
        }
    }

    fn keyboard(&mut self, ctx: &egui::Context) {
        if ctx.egui_wants_keyboard_input() {
            return;
        }
        let (dt, fast, mut fly, keys) = ctx.input(|i| {
            let axis = |neg, pos| (i.key_down(pos) as i32 - i.key_down(neg) as i32) as f32;
            let fly = Vec3::new(
                axis(egui::Key::A, egui::Key::D),
                axis(egui::Key::Q, egui::Key::E),
                axis(egui::Key::S, egui::Key::W),
            );
            let pressed: Vec<egui::Key> = i
                .events
                .iter()
                .filter_map(|e| match e {
                    egui::Event::Key { key, pressed: true, repeat: false, .. } => Some(*key),
                    _ => None,
                })
                .collect();
            (i.stable_dt.min(0.1), i.modifiers.shift, fly, pressed)
        });
        if fly != Vec3::ZERO {
            fly = fly.normalize();
            self.camera.fly(fly, dt, fast);
            ctx.request_repaint();
        }
        let numbers = [
            egui::Key::Num1,
            egui::Key::Num2,
            egui::Key::Num3,
            egui::Key::Num4,
            egui::Key::Num5,
            egui::Key::Num6,
            egui::Key::Num7,
            egui::Key::Num8,
            egui::Key::Num9,
        ];
        for key in keys {
            if let Some(n) = numbers.iter().position(|&k| k == key) {
                self.go_to_view(n);
            }
            match key {
                egui::Key::R => self.camera = CameraControl::new(&self.home, self.camera.speed * 4.0),
                egui::Key::Space => self.controls.playing = !self.controls.playing,
                egui::Key::P => self.controls.save_render = true,
                egui::Key::F12 => self.window_screenshot(ctx),
                _ => {}
            }
        }
    }

    fn go_to_view(&mut self, n: usize) {
        if let Some((_, desc)) = self.views.get(n) {
            self.camera = CameraControl::new(desc, self.camera.speed * 4.0);
        }
    }

    /// Saves what the window shows (its framebuffer, OpenGL's or the GPU's) as `window-N.png`.
    fn window_screenshot(&self, ctx: &egui::Context) {
        let n = self.screenshots.fetch_add(1, Ordering::Relaxed);
        let path = self.out.join(format!("window-{n:03}.png"));
        let shared = self.shared.clone();
        ctx.request_screenshot(move |image| {
            let [w, h] = image.size;
            let bytes: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_array()).collect();
            let message = match image::RgbaImage::from_raw(w as u32, h as u32, bytes) {
                Some(img) => {
                    let tmp = path.with_extension("png.tmp");
                    match img
                        .save_with_format(&tmp, image::ImageFormat::Png)
                        .and_then(|_| std::fs::rename(&tmp, &path).map_err(image::ImageError::IoError))
                    {
                        Ok(()) => format!("saved {}", path.display()),
                        Err(e) => format!("cannot save {}: {e}", path.display()),
                    }
                }
                None => "screenshot has the wrong size".to_string(),
            };
            shared.published.lock().expect("published").message = message;
        });
        ctx.request_repaint();
    }

    fn image(&mut self, ui: &mut egui::Ui, frame: &eframe::Frame) {
        let on_gpu = match (&mut self.shown, self.on_device) {
            (Some(shown), true) => shown.texture(frame),
            _ => None,
        };
        let Some((id, [w, h])) = on_gpu.or_else(|| self.texture.as_ref().map(|t| (t.id(), t.size()))) else {
            ui.centered_and_justified(|ui| ui.label("building the BVH…"));
            return;
        };
        let (w, h) = (w as f32, h as f32);
        let available = ui.available_size();
        let fit = (available.x / w).min(available.y / h).max(0.01);
        let size = egui::vec2(w * fit, h * fit);
        let response = ui
            .centered_and_justified(|ui| ui.add(egui::Image::new((id, size)).sense(egui::Sense::click_and_drag())))
            .inner;
        let delta = response.drag_delta();
        if response.dragged_by(egui::PointerButton::Primary) && delta != egui::Vec2::ZERO {
            self.camera.orbit(delta.x, delta.y);
        }
        if response.dragged_by(egui::PointerButton::Secondary) && delta != egui::Vec2::ZERO {
            self.camera.look(delta.x, delta.y);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.camera.dolly(scroll / 50.0);
            }
        }
    }

    fn side_panel(&mut self, ui: &mut egui::Ui) {
        let published = self.shared.published.lock().expect("published");
        let report = published.report;
        let history: Vec<[f32; 3]> = published.history.iter().copied().collect();
        let message = published.message.clone();
        let (tuned, tuning) = (published.tuned, published.tuning);
        let auto = published.auto.clone();
        drop(published);

        self.bvh_controls(ui, tuned, tuning);
        if let (BuilderChoice::Auto, Some(auto)) = (self.choice, auto) {
            ui.label(egui::RichText::new(auto).small());
        }
        self.image_controls(ui);
        self.animation_controls(ui, report.time);
        self.statistics(ui, &report, &history, message);
        ui.separator();
        ui.label(
            egui::RichText::new(
                "drag: orbit · right drag: look · wheel: dolly\nWASD QE: fly (Shift faster) · R: reset\n1–9: views · Space: play · P: save · F12: window",
            )
            .small(),
        );
    }

    /// The builder, PHR's parameters and the tuning button.
    fn bvh_controls(&mut self, ui: &mut egui::Ui, tuned: Option<(f32, f32)>, tuning: bool) {
        ui.heading("phr");
        ui.label(egui::RichText::new(&self.scene_name).small());
        ui.separator();
        ui.strong("BVH");
        egui::ComboBox::from_id_salt("builder").selected_text(self.choice.label()).width(250.0).show_ui(ui, |ui| {
            for c in BuilderChoice::ALL {
                ui.selectable_value(&mut self.choice, c, c.label());
            }
        });
        if self.choice == BuilderChoice::PhrCustom {
            ui.add(egui::Slider::new(&mut self.alpha, 0.0..=1.0).step_by(0.01).text("α"));
            ui.add(egui::Slider::new(&mut self.delta, 0.0..=16.0).step_by(0.1).text("δ"));
        }
        if self.choice == BuilderChoice::PhrTuned {
            ui.horizontal(|ui| {
                if tuning {
                    ui.spinner();
                    ui.label("tuning…");
                } else {
                    if ui.button("Tune now").clicked() || tuned.is_none() {
                        self.controls.tune = true;
                    }
                    if let Some((a, d)) = tuned {
                        ui.label(format!("α {a:.2}, δ {d:.1}"));
                    }
                }
            });
        }
        ui.add_enabled(self.choice.is_phr(), egui::Slider::new(&mut self.branching, 2..=16).text("branching"));
        ui.horizontal(|ui| {
            ui.label("moving objects:");
            for kind in PipelineKind::ALL {
                ui.radio_value(&mut self.controls.settings.pipeline, kind, kind.name()).on_hover_text(match kind {
                    PipelineKind::Thesis => "one tree over the whole scene, refitted and rebuilt every moving frame",
                    PipelineKind::TwoLevel => "rigid objects move by their transforms; only deforming ones are rebuilt",
                    PipelineKind::Async => {
                        "two-level, deforming objects rebuilt on a worker thread and refitted meanwhile"
                    }
                });
            }
        });
    }

    /// Resolution, depth, light sampling, view mode, saving.
    fn image_controls(&mut self, ui: &mut egui::Ui) {
        ui.separator();
        ui.strong("Image");
        ui.add(egui::Slider::new(&mut self.scale, 0.25..=2.0).text("resolution scale"));
        ui.add(egui::Slider::new(&mut self.controls.settings.max_depth, 1..=16).text("max depth"));
        ui.checkbox(&mut self.controls.settings.explicit_lights, "light sampling (MIS)");
        ui.horizontal_wrapped(|ui| {
            ui.label("denoise");
            let denoise = &mut self.controls.settings.denoise;
            ui.radio_value(denoise, None, "off");
            ui.radio_value(denoise, Some(Filter::Atrous), "à-trous");
            if oidn::AVAILABLE {
                ui.radio_value(denoise, Some(Filter::Oidn), "OIDN (still view)");
            }
        });
        ui.horizontal_wrapped(|ui| {
            for mode in ViewMode::ALL {
                ui.radio_value(&mut self.controls.settings.mode, mode, mode.name());
            }
        });
        ui.horizontal(|ui| {
            if ui.button("Save render (P)").clicked() {
                self.controls.save_render = true;
            }
            if ui.button("Window (F12)").clicked() {
                self.window_screenshot(ui.ctx());
            }
        });
    }

    /// Play, pause, rewind and speed, for animated scenes.
    fn animation_controls(&mut self, ui: &mut egui::Ui, time: f32) {
        ui.separator();
        ui.strong("Animation");
        if self.animated {
            ui.horizontal(|ui| {
                let label = if self.controls.playing { "Pause (Space)" } else { "Play (Space)" };
                if ui.button(label).clicked() {
                    self.controls.playing = !self.controls.playing;
                }
                if ui.button("Rewind").clicked() {
                    self.controls.rewind = true;
                }
            });
            ui.add(egui::Slider::new(&mut self.controls.speed, 0.0..=4.0).text("speed"));
            ui.label(format!("t = {:.2} s", time));
        } else {
            ui.label("static scene");
        }
    }

    /// The last frame's timings, the frame-time plot and the last message.
    fn statistics(&self, ui: &mut egui::Ui, report: &FrameReport, history: &[[f32; 3]], message: String) {
        ui.separator();
        ui.strong("Statistics");
        egui::Grid::new("stats").num_columns(2).striped(true).show(ui, |ui| {
            let mut row = |name: &str, value: String| {
                ui.label(name);
                ui.label(value);
                ui.end_row();
            };
            row("triangles", format!("{}", self.triangles));
            row(
                "builder",
                match report.static_builder {
                    Some(b) => format!("{} (what never moves: {b})", report.builder),
                    None => report.builder.to_string(),
                },
            );
            row("pose", format!("{:.2} ms", report.pose_ms));
            row("refit", format!("{:.2} ms", report.refit_ms));
            row("PHR / build", format!("{:.2} ms", report.build_ms));
            row("wide tree + packing", format!("{:.2} ms", report.wide_ms));
            row("render", format!("{:.2} ms on the {}", report.render_ms, report.device));
            if report.device != "cpu" {
                let kib = report.upload_bytes as f64 / 1024.0;
                row("of which upload", format!("{:.2} ms ({kib:.1} KiB)", report.upload_ms));
            }
            row("frame", format!("{:.2} ms", report.frame_ms));
            row("fps", format!("{:.1}", 1e3 / report.frame_ms.max(1e-3)));
            row("Mrays/s", format!("{:.2}", report.mrays_per_s()));
            row("SAH cost", format!("{:.2}", report.sah_cost));
            row("Σ|cut|", format!("{}", report.build_cost));
            // Frames since the traced tree's boxes: grows while the async pipeline refits.
            row("tree age", format!("{} frames", report.tree_age));
            row("samples", format!("{}", report.samples));
        });
        frame_time_plot(ui, history);
        if !message.is_empty() {
            ui.separator();
            ui.label(egui::RichText::new(message).small());
        }
    }
}

/// Frame, render and build time of the last frames, in ms.
fn frame_time_plot(ui: &mut egui::Ui, history: &[[f32; 3]]) {
    let (rect, _) = ui.allocate_exact_size(egui::vec2(ui.available_width(), 90.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, egui::Color32::from_gray(20));
    let max = history.iter().map(|h| h[0]).fold(1.0f32, f32::max) * 1.1;
    let colours = [egui::Color32::WHITE, egui::Color32::LIGHT_BLUE, egui::Color32::ORANGE];
    for (series, colour) in colours.iter().enumerate() {
        let points: Vec<egui::Pos2> = history
            .iter()
            .enumerate()
            .map(|(i, h)| {
                let x = rect.left() + rect.width() * i as f32 / (HISTORY - 1) as f32;
                let y = rect.bottom() - rect.height() * h[series] / max;
                egui::pos2(x, y)
            })
            .collect();
        if points.len() > 1 {
            painter.add(egui::Shape::line(points, egui::Stroke::new(1.0, *colour)));
        }
    }
    painter.text(
        rect.left_top() + egui::vec2(4.0, 2.0),
        egui::Align2::LEFT_TOP,
        format!("{max:.0} ms   frame · render · refit+build"),
        egui::FontId::proportional(10.0),
        egui::Color32::GRAY,
    );
}

/// The render thread: applies the window's controls to the pipeline, steps it, publishes.
fn worker(mut pipeline: FramePipeline, shared: Arc<Shared>, ctx: egui::Context, out: PathBuf) {
    let mut last = Instant::now();
    let mut saved = 0u32;
    loop {
        let controls = {
            let mut c = shared.controls.lock().expect("controls");
            let snapshot = c.clone();
            if c.tune {
                // Marked while the request is taken, so the window cannot ask twice.
                shared.published.lock().expect("published").tuning = true;
            }
            c.rewind = false;
            c.save_render = false;
            c.tune = false;
            snapshot
        };
        if controls.quit {
            return;
        }
        if controls.tune {
            tune(&pipeline, &shared, &ctx);
            continue;
        }
        pipeline.set_camera(controls.camera);
        if controls.auto != pipeline.auto().is_some() {
            pipeline.set_auto(controls.auto.then(AutoBuilder::default));
        }
        pipeline.set_settings(controls.settings);
        pipeline.playing = controls.playing;
        pipeline.speed = controls.speed;
        if controls.rewind {
            pipeline.time = 0.0;
        }
        if controls.save_render {
            let message = save_render(&mut pipeline, &out, &mut saved);
            shared.published.lock().expect("published").message = message;
            ctx.request_repaint();
        }
        let moving = pipeline.playing && pipeline.speed != 0.0 && pipeline.is_animated();
        if !moving && pipeline.samples() >= MAX_SAMPLES {
            std::thread::sleep(Duration::from_millis(20));
            last = Instant::now();
            continue;
        }
        let dt = last.elapsed().as_secs_f32().min(0.1);
        last = Instant::now();
        let report = pipeline.step(dt);
        // The GPU shows the film it keeps: nothing to read back.
        let on_device = pipeline.film_on_device();
        let rgba = if on_device { Vec::new() } else { pipeline.image_rgba8() };
        let mut p = shared.published.lock().expect("published");
        p.version += 1;
        p.width = pipeline.settings().width;
        p.height = pipeline.settings().height;
        p.rgba = rgba;
        p.on_device = on_device;
        p.report = report;
        p.auto = pipeline.auto().map(AutoBuilder::describe);
        if p.history.len() == HISTORY {
            p.history.pop_front();
        }
        p.history.push_back([
            report.frame_ms as f32,
            report.render_ms as f32,
            (report.refit_ms + report.build_ms + report.wide_ms) as f32,
        ]);
        drop(p);
        ctx.request_repaint();
    }
}

fn save_render(pipeline: &mut FramePipeline, out: &std::path::Path, saved: &mut u32) -> String {
    let (w, h) = (pipeline.settings().width, pipeline.settings().height);
    let Some(image) = pipeline.image_to_save() else {
        return "nothing to save yet".to_string();
    };
    let stem = out.join(format!("render-{:03}", *saved));
    *saved += 1;
    for ext in ["png", "exr"] {
        let path = stem.with_extension(ext);
        if let Err(e) = write_image(&path, w, h, &image) {
            return format!("cannot save {}: {e}", path.display());
        }
    }
    format!("saved {}.png and .exr ({} spp)", stem.display(), pipeline.samples())
}

/// Bayesian optimisation of α and δ (20 PHR builds) over the thesis's box, for the current
/// geometry and image size, with the thesis's objective: the search `phr bench`'s PHR-BO runs.
fn tune(pipeline: &FramePipeline, shared: &Shared, ctx: &egui::Context) {
    use phr_tune::bayes::BoOptions;
    use phr_tune::objective::{OMEGA_P, OMEGA_R};
    use phr_tune::tune::{tune, Method, ObjectiveKind, TuneOptions};
    ctx.request_repaint();
    let settings = pipeline.settings();
    let base = match settings.builder {
        Builder::Phr(o) => o,
        _ => PhrOptions::FAST,
    };
    let evaluator = phr_tune::PhrEvaluator::new(&pipeline.geometry().primitive_boxes(), base);
    let options = TuneOptions {
        method: Method::Bayes(BoOptions::default()),
        objective: ObjectiveKind::Thesis {
            width: settings.width,
            height: settings.height,
            omega_p: OMEGA_P,
            omega_r: OMEGA_R,
        },
        search: phr_tune::SearchBox::THESIS,
        cache: None,
    };
    let result = tune(&evaluator, &options);
    let (a, d) = (result.best.alpha as f32, result.best.delta as f32);
    let mut p = shared.published.lock().expect("published");
    p.tuned = Some((a, d));
    p.tuning = false;
    p.message = format!(
        "tuned: α {a:.2}, δ {d:.1} after {} builds in {:.1} s",
        result.evaluations.len(),
        result.elapsed.as_secs_f64()
    );
    drop(p);
    ctx.request_repaint();
}
