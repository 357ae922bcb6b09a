//! `phr view --device gpu` (and `phr animate --device gpu`): the GPU (`crates/phr-gpu`, in a
//! `phr` built with the cargo feature `gpu`) traces the viewer's colour frames, with any
//! pipeline: one tree over the scene, or the two-level layout's parts under their instances.
//! The CPU still poses the scene, refits and rebuilds the trees and denoises (the guide's
//! first hits come from the same camera rays, traced on the CPU); the normal, albedo and
//! heatmap modes stay on the CPU.
//!
//! The window draws with the GPU's own device (eframe's wgpu renderer on it): while the image
//! shown is the accumulated film itself (no denoiser), the GPU keeps the film and writes the
//! image into a texture the window draws, and no frame comes back to the CPU (the headless
//! mode keeps the film there too, and reads it back for its PNGs). With a denoiser each
//! frame's samples are read back (a 256² frame is 1 MiB) into the CPU's film.

use anyhow::Result;
use phr_render::pipeline::FramePipeline;

/// The device the frames are traced on, for a window drawing with it.
#[cfg(feature = "gpu")]
pub struct OnGpu {
    gpu: phr_gpu::Gpu,
    shown: phr_gpu::Shown,
}

/// Without the feature `gpu` there is none.
#[cfg(not(feature = "gpu"))]
pub enum OnGpu {}

#[cfg(not(feature = "gpu"))]
pub fn attach_gpu(_: FramePipeline, command: &str) -> Result<(FramePipeline, OnGpu)> {
    Err(crate::render::without_gpu(command))
}

#[cfg(feature = "gpu")]
pub fn attach_gpu(pipeline: FramePipeline, _command: &str) -> Result<(FramePipeline, OnGpu)> {
    let gpu = phr_gpu::Gpu::new()?;
    let frames = phr_gpu::GpuFrames::new(gpu.clone());
    let shown = frames.shown();
    Ok((pipeline.with_tracer(Box::new(frames)), OnGpu { gpu, shown }))
}

#[cfg(not(feature = "gpu"))]
impl OnGpu {
    pub fn native_options(&self, _: eframe::NativeOptions) -> eframe::NativeOptions {
        match *self {}
    }

    pub fn shown_texture(&self) -> ShownTexture {
        match *self {}
    }
}

#[cfg(feature = "gpu")]
impl OnGpu {
    /// `options` with eframe's wgpu renderer on this device.
    pub fn native_options(&self, options: eframe::NativeOptions) -> eframe::NativeOptions {
        use eframe::egui_wgpu::{WgpuConfiguration, WgpuSetup, WgpuSetupExisting};
        let gpu = &self.gpu;
        let existing = WgpuSetupExisting {
            instance: gpu.instance.clone(),
            adapter: gpu.adapter.clone(),
            device: gpu.device.clone(),
            queue: gpu.queue.clone(),
        };
        eframe::NativeOptions {
            renderer: eframe::Renderer::Wgpu,
            wgpu_options: WgpuConfiguration { wgpu_setup: WgpuSetup::Existing(existing), ..Default::default() },
            ..options
        }
    }

    /// The image the GPU keeps, for the window to draw.
    pub fn shown_texture(&self) -> ShownTexture {
        ShownTexture { shown: self.shown.watch(), registered: None }
    }
}

/// The GPU's image as a texture of the window's renderer.
pub struct ShownTexture {
    #[cfg(feature = "gpu")]
    shown: phr_gpu::Watching,
    /// The egui texture and the [`phr_gpu::ShownImage::texture_number`] it shows.
    #[cfg(feature = "gpu")]
    registered: Option<(eframe::egui::TextureId, u64)>,
    #[cfg(not(feature = "gpu"))]
    _none: OnGpu,
}

impl ShownTexture {
    /// The texture and its size in pixels, registered with the window's wgpu renderer (again
    /// when the GPU made another texture); `None` before the GPU wrote one, or on another
    /// renderer.
    #[cfg(feature = "gpu")]
    pub fn texture(&mut self, frame: &eframe::Frame) -> Option<(eframe::egui::TextureId, [usize; 2])> {
        let image = self.shown.get()?;
        let state = frame.wgpu_render_state()?;
        let filter = eframe::wgpu::FilterMode::Nearest;
        let id = match self.registered {
            Some((id, number)) if number == image.texture_number => id,
            Some((id, _)) => {
                state.renderer.write().update_egui_texture_from_wgpu_texture(&state.device, &image.view, filter, id);
                id
            }
            None => {
                eprintln!("phr view: the window shows the GPU's image, with nothing read back");
                state.renderer.write().register_native_texture(&state.device, &image.view, filter)
            }
        };
        self.registered = Some((id, image.texture_number));
        Some((id, [image.width as usize, image.height as usize]))
    }

    #[cfg(not(feature = "gpu"))]
    pub fn texture(&mut self, _: &eframe::Frame) -> Option<(eframe::egui::TextureId, [usize; 2])> {
        match self._none {}
    }
}
