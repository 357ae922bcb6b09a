//! `phr view --device gpu` (and `phr animate --device gpu`): the GPU (`crates/phr-gpu`, in a `phr` built with the cargo
//! feature `gpu`) traces the viewer's colour frames, with any pipeline: one tree over the
//! scene, or the two-level layout's parts under their instances. The CPU still poses the
//! scene, refits and rebuilds the trees, accumulates and denoises (the guide's first hits come
//! from the same camera rays, traced on the CPU); the normal, albedo and heatmap modes stay on
//! the CPU. Each frame's samples are read back from the GPU (a 256² frame is 1 MiB).

use anyhow::Result;
use phr_render::pipeline::FramePipeline;

#[cfg(not(feature = "gpu"))]
pub fn attach_gpu(_: FramePipeline, command: &str) -> Result<FramePipeline> {
    Err(crate::render::without_gpu(command))
}

#[cfg(feature = "gpu")]
pub fn attach_gpu(pipeline: FramePipeline, _command: &str) -> Result<FramePipeline> {
    let gpu = phr_gpu::Gpu::new()?;
    Ok(pipeline.with_tracer(Box::new(phr_gpu::GpuFrames::new(gpu))))
}
