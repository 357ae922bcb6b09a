//! # phr-gpu: the path tracer on the GPU
//!
//! The thesis asked for its CPU tracer to be compared with "an equivalent CUDA ray tracer".
//! This is that tracer, portable: WGSL compute kernels run through wgpu on Vulkan, Metal or
//! DX12, and on Mesa's software Vulkan driver (lavapipe) where there is no GPU, which is how
//! the tests run everywhere.
//!
//! It traces what the CPU traces: [`scene::GpuScene`] uploads the triangles, spheres and
//! materials of a [`phr_render::geometry::Geometry`] and the 8-wide BVH its CPU queries trace
//! (any of `phr-bvh`'s builders, collapsed or built straight into that layout), with the
//! primitives in leaf order, and the emitters of a light set.
//! [`trace::GpuTracer`] runs the estimators of `phr_render::integrator` (the thesis's implicit
//! lights, or light sampling with MIS and Russian roulette) one sample per pixel per frame,
//! accumulating on the GPU, with the CPU's random numbers per pixel drawn in the CPU's order,
//! so the two converge to the same image; [`queries::HitQueries`] answers closest-hit queries
//! for a batch of rays, which the tests hold against the CPU's. [`frames::GpuFrames`] traces
//! the viewer's frames (`phr view --device gpu`), keeping the film on the GPU and writing the
//! image to show into a texture ([`display`]) for a window that draws with the same device.
//!
//! Colour textures, alpha masks and environment maps are looked up and sampled as on the CPU.
//! The parts of a two-level scene and the copies of meshes placed many times are traced
//! through their instances under a top-level tree, as on the CPU. Not yet on the GPU: the
//! denoiser (the front ends run the CPU's).

pub mod device;
pub mod display;
pub mod frames;
mod moving;
pub mod queries;
pub mod scene;
pub mod trace;

pub use device::{Gpu, GpuError};
pub use display::{Shown, ShownImage, Watching};
pub use frames::GpuFrames;
pub use queries::{GpuHit, HitQueries};
pub use scene::GpuScene;
pub use trace::GpuTracer;
