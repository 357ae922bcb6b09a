//! `phr view --device gpu`: the GPU (`crates/phr-gpu`, in a `phr` built with the cargo
//! feature `gpu`) traces the viewer's colour frames. The CPU still poses the scene, refits
//! and rebuilds its tree with the thesis's pipeline, accumulates and denoises (the guide's
//! first hits come from the same camera rays, traced on the CPU); the normal, albedo and
//! heatmap modes, and the two-level pipelines a user may switch to in the window, stay on the
//! CPU. Each frame's samples are read back from the GPU (a 256² frame is 1 MiB).

use anyhow::Result;
use phr_render::pipeline::FramePipeline;

#[cfg(not(feature = "gpu"))]
pub fn attach_gpu(_: FramePipeline) -> Result<FramePipeline> {
    Err(crate::render::without_gpu("view"))
}

#[cfg(feature = "gpu")]
pub fn attach_gpu(pipeline: FramePipeline) -> Result<FramePipeline> {
    let gpu = phr_gpu::Gpu::new()?;
    Ok(pipeline.with_tracer(Box::new(phr_gpu::GpuFrames::new(gpu))))
}
