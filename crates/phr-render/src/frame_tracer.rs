//! Frames traced elsewhere: the hook through which another device (the GPU tracer of
//! `phr-gpu`) traces the samples of a [`crate::pipeline::FramePipeline`]'s frames while the
//! pipeline keeps everything else on the CPU (posing, trees, the film, denoising), so the
//! viewer, its headless mode and their reports work the same on every device.
//!
//! A device may also keep the film itself ([`FrameTracer::accumulate`]): then a window that
//! shows the device's image where it is (`phr view --device gpu`) needs no frame read back,
//! and the film comes back only when something on the CPU asks for it (a saved render).

use crate::camera::CameraDesc;
use crate::film::Film;
use crate::geometry::Geometry;
use crate::lights::LightSet;
use crate::scene::Scene;
use glam::Vec3;

/// One frame to trace: one sample per pixel of frame number `frame`, the sample
/// [`crate::render::Renderer::render_frame`] gives each pixel for the same seed and frame.
pub struct FrameJob<'a> {
    /// Materials, textures and background.
    pub scene: &'a Scene,
    /// The primitives as posed, and their trees: one over the scene, or one per part under its
    /// instance.
    pub geometry: &'a Geometry,
    /// The light set to sample (made for `geometry`); `None`: the implicit estimator.
    pub lights: Option<&'a LightSet>,
    pub camera: &'a CameraDesc,
    pub width: u32,
    pub height: u32,
    /// Maximum ray segments per path.
    pub max_depth: u32,
    pub seed: u64,
    pub frame: u32,
    /// Changes whenever `geometry`, its tree or `lights` changed since an earlier job: what
    /// a device that keeps the scene uploads again.
    pub version: u64,
}

/// What a [`FrameTracer`] traced.
pub struct TracedFrame {
    /// One sample per pixel, row-major from the top left.
    pub pixels: Vec<Vec3>,
    pub rays: u64,
    /// Of the time the frame took, milliseconds spent moving the scene to the device: laying
    /// out what moved and writing it (included in the render time the pipeline measures, and
    /// reported apart).
    pub upload_ms: f64,
    /// Bytes written to the device for it (what changed since the last frame).
    pub upload_bytes: u64,
}

/// A device that traces frames.
pub trait FrameTracer: Send {
    /// A short name for reports and CSV files (`gpu`).
    fn name(&self) -> &'static str;
    /// The device, for people (its adapter and driver).
    fn describe(&self) -> String;
    /// The frame's samples, or why the device cannot trace it.
    fn trace(&mut self, job: &FrameJob) -> Result<TracedFrame, String>;
    /// Whether the device can keep the film ([`FrameTracer::accumulate`]).
    fn keeps_film(&self) -> bool {
        false
    }
    /// Adds the frame's samples to the film the device keeps (emptied first when `restart`)
    /// and reads nothing back but the ray count: `pixels` is empty.
    fn accumulate(&mut self, job: &FrameJob, restart: bool) -> Result<TracedFrame, String> {
        let _ = (job, restart);
        Err(format!("{} keeps no film", self.name()))
    }
    /// The film the device keeps, read back.
    fn film(&mut self) -> Result<Film, String> {
        Err(format!("{} keeps no film", self.name()))
    }
}
