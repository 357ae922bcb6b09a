//! The GPU as a [`FrameTracer`]: traces the colour frames of a
//! [`phr_render::pipeline::FramePipeline`] (the viewer and its headless mode) while the CPU
//! poses, builds the trees, accumulates and denoises. The scene is uploaded once, and what
//! changed when it moves ([`crate::moving`]: the instances and the emitters, and the trees
//! and primitives of the parts that changed; timed apart, waited for). Each frame's samples
//! are read back for the pipeline's film, or, for a window drawing with the same device, the
//! GPU keeps the film ([`FrameTracer::accumulate`]) and writes the image to show into a
//! texture ([`Shown`], written only while a window watches it): then only the ray count comes
//! back, and the film when it is asked for. (The kept film sums in single precision, as the
//! GPU's renders do between their drains: rounding to nearest, of the order of 1e-5 of the
//! mean after 100,000 frames.)

use crate::device::{Gpu, GpuError};
use crate::display::{Display, Shown};
use crate::moving::Uploaded;
use crate::scene::{GpuScene, Packed};
use crate::trace::GpuTracer;
use phr_render::camera::{Camera, CameraDesc};
use phr_render::film::Film;
use phr_render::frame_tracer::{FrameJob, FrameTracer, TracedFrame};
use std::time::Instant;

/// What a [`GpuTracer`] is made for: size, path depth, seed, and whether it samples lights.
#[derive(Clone, Copy, PartialEq, Eq)]
struct TracerKey {
    width: u32,
    height: u32,
    max_depth: u32,
    seed: u64,
    lights: bool,
}

/// The GPU tracing a pipeline's frames.
pub struct GpuFrames {
    gpu: Gpu,
    scene: Option<GpuScene>,
    /// The [`FrameJob::version`] uploaded, whether with lights, and what is on the GPU.
    uploaded: Option<(u64, bool, Uploaded)>,
    tracer: Option<(GpuTracer, TracerKey, CameraDesc)>,
    /// The kept film's display (made for the tracer's sums), what it shows, and how many
    /// textures it has had.
    display: Option<Display>,
    shown: Shown,
    textures: u64,
    /// The kept film's ray count after the last frame.
    rays_before: u64,
    /// Whether the tracer's sums are the kept film (no tracer made and no frame traced alone
    /// since its last restart): else the next kept frame restarts it.
    kept: bool,
}

impl GpuFrames {
    pub fn new(gpu: Gpu) -> Self {
        Self {
            gpu,
            scene: None,
            uploaded: None,
            tracer: None,
            display: None,
            shown: Shown::default(),
            textures: 0,
            rays_before: 0,
            kept: false,
        }
    }

    /// The image of the kept film, for a window drawing with this device.
    pub fn shown(&self) -> Shown {
        self.shown.clone()
    }

    /// The scene of `job` on the GPU: uploaded whole the first time and when light sampling
    /// is switched, what changed when the version changed (then waited for). Returns whether
    /// it uploaded anything.
    fn upload(&mut self, job: &FrameJob) -> Result<bool, GpuError> {
        let lights = job.lights.is_some();
        match (&mut self.scene, &mut self.uploaded) {
            (Some(_), Some((version, with_lights, _))) if *version == job.version && *with_lights == lights => {
                return Ok(false)
            }
            (Some(scene), Some((version, with_lights, uploaded))) if *with_lights == lights => {
                uploaded.update(&self.gpu, scene, job)?;
                *version = job.version;
            }
            _ => {
                let packed = Packed::new(job.scene, job.geometry, job.lights)?;
                self.scene = Some(GpuScene::upload_packed(&self.gpu, &packed, job.scene.background.clone())?);
                let changing = vec![false; job.geometry.part_count()];
                self.uploaded = Some((job.version, lights, Uploaded::new(job, &packed, changing)));
                // A tracer is bound to the scene it was made for.
                self.tracer = None;
            }
        }
        self.gpu.wait()?;
        Ok(true)
    }

    /// The scene of `job` uploaded and a tracer made for it, seeing its view: how long the
    /// upload took and how many bytes it wrote.
    fn prepare(&mut self, job: &FrameJob) -> Result<(f64, u64), GpuError> {
        let start = Instant::now();
        let uploaded = self.upload(job)?;
        let upload_ms = if uploaded { start.elapsed().as_secs_f64() * 1e3 } else { 0.0 };
        let scene = self.scene.as_ref().expect("uploaded");
        let upload_bytes = if uploaded { scene.bytes } else { 0 };
        let key = TracerKey {
            width: job.width,
            height: job.height,
            max_depth: job.max_depth,
            seed: job.seed,
            lights: job.lights.is_some(),
        };
        let camera = Camera::new(job.camera, job.width, job.height);
        match &mut self.tracer {
            Some((tracer, made_for, view)) if *made_for == key => {
                if view != job.camera {
                    tracer.set_camera(&camera);
                    *view = job.camera.clone();
                }
            }
            _ => {
                let tracer = GpuTracer::new(&self.gpu, scene, &camera, job.width, job.height, job.max_depth, job.seed)?;
                self.tracer = Some((tracer, key, job.camera.clone()));
                // The display reads the tracer's sums; they hold no kept film.
                self.display = None;
                self.kept = false;
            }
        }
        Ok((upload_ms, upload_bytes))
    }

    fn trace_frame(&mut self, job: &FrameJob) -> Result<TracedFrame, GpuError> {
        let (upload_ms, upload_bytes) = self.prepare(job)?;
        let scene = self.scene.as_ref().expect("uploaded");
        let (tracer, _, _) = self.tracer.as_mut().expect("made");
        tracer.clear();
        self.kept = false;
        tracer.render(scene, job.frame..job.frame + 1);
        Ok(TracedFrame { pixels: tracer.mean()?, rays: tracer.rays()?, upload_ms, upload_bytes })
    }

    /// Adds the frame to the kept film (emptied first if `restart`) and shows it.
    fn accumulate_frame(&mut self, job: &FrameJob, restart: bool) -> Result<TracedFrame, GpuError> {
        let (upload_ms, upload_bytes) = self.prepare(job)?;
        let scene = self.scene.as_ref().expect("uploaded");
        let (tracer, _, _) = self.tracer.as_mut().expect("made");
        if restart || !self.kept {
            tracer.clear();
            (self.rays_before, self.kept) = (0, true);
        }
        tracer.render(scene, job.frame..job.frame + 1);
        if self.shown.watched() {
            let made = match self.display.take() {
                Some(d) if (d.width, d.height) == (tracer.width, tracer.height) => d,
                _ => {
                    self.textures += 1;
                    Display::new(&self.gpu, tracer.sums(), tracer.width, tracer.height, self.textures)
                }
            };
            made.write(&self.gpu, tracer.samples());
            // Shown once written: a new texture is never drawn empty.
            self.shown.set(made.image());
            self.display = Some(made);
        }
        // Waits for the frame (so frames are not queued ahead of the window).
        let rays = tracer.rays()?;
        let frame_rays = rays.saturating_sub(self.rays_before);
        self.rays_before = rays;
        Ok(TracedFrame { pixels: Vec::new(), rays: frame_rays, upload_ms, upload_bytes })
    }

    /// The kept film's displayed image, read back (8-bit RGBA): what a window shows.
    pub fn shown_pixels(&self) -> Result<Vec<u8>, GpuError> {
        match &self.display {
            Some(display) => display.read(&self.gpu),
            None => Err(GpuError::Failed("no frame has been kept on the GPU".into())),
        }
    }
}

impl FrameTracer for GpuFrames {
    fn name(&self) -> &'static str {
        "gpu"
    }

    fn describe(&self) -> String {
        self.gpu.describe()
    }

    fn trace(&mut self, job: &FrameJob) -> Result<TracedFrame, String> {
        self.trace_frame(job).map_err(|e| e.to_string())
    }

    fn keeps_film(&self) -> bool {
        true
    }

    fn accumulate(&mut self, job: &FrameJob, restart: bool) -> Result<TracedFrame, String> {
        self.accumulate_frame(job, restart).map_err(|e| e.to_string())
    }

    fn film(&mut self) -> Result<Film, String> {
        match &self.tracer {
            Some((tracer, _, _)) => tracer.film().map_err(|e| e.to_string()),
            None => Err("nothing traced on the GPU yet".into()),
        }
    }
}
