//! The GPU as a [`FrameTracer`]: traces the colour frames of a
//! [`phr_render::pipeline::FramePipeline`] (the viewer and its headless mode) while the CPU
//! poses, builds the trees, accumulates and denoises. The scene is uploaded once, and what
//! changed when it moves ([`crate::moving`]: the instances and the emitters, and the trees
//! and primitives of the parts that changed; timed apart, waited for); each frame's samples
//! are read back for the pipeline's film.

use crate::device::{Gpu, GpuError};
use crate::moving::Uploaded;
use crate::scene::{GpuScene, Packed};
use crate::trace::GpuTracer;
use phr_render::camera::{Camera, CameraDesc};
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
}

impl GpuFrames {
    pub fn new(gpu: Gpu) -> Self {
        Self { gpu, scene: None, uploaded: None, tracer: None }
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

    fn trace_frame(&mut self, job: &FrameJob) -> Result<TracedFrame, GpuError> {
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
            }
        }
        let (tracer, _, _) = self.tracer.as_mut().expect("made above");
        tracer.clear();
        tracer.render(scene, job.frame..job.frame + 1);
        Ok(TracedFrame { pixels: tracer.mean()?, rays: tracer.rays()?, upload_ms, upload_bytes })
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
}
