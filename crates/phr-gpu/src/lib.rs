//! # phr-gpu: the path tracer on the GPU
//!
//! The thesis asked for its CPU tracer to be compared with "an equivalent CUDA ray tracer".
//! This is that tracer, portable: WGSL compute kernels run through wgpu on Vulkan, Metal or
//! DX12, and on Mesa's software Vulkan driver (lavapipe) where there is no GPU, which is how
//! the tests run everywhere.
//!
//! It traces what the CPU traces: [`scene::GpuScene`] uploads the triangles, spheres and
//! materials of a [`phr_render::geometry::Geometry`] and the binary BVH any of `phr-bvh`'s
//! builders made for it, with the primitives in leaf order. [`trace::GpuTracer`] runs the
//! thesis's estimator (`phr_render::integrator`, implicit lights) one sample per pixel per
//! frame, accumulating on the GPU, with the CPU's random numbers per pixel, so the two converge
//! to the same image; [`queries::HitQueries`] answers closest-hit queries for a batch of
//! rays, which the tests hold against the CPU's.
//!
//! Not yet on the GPU (each refused with a clear error, never drawn wrong): textures, alpha
//! masks, environment maps, light sampling, meshes placed by instances, trees other than
//! binary ones.

pub mod device;
pub mod queries;
pub mod scene;
pub mod trace;

pub use device::{Gpu, GpuError};
pub use queries::{GpuHit, HitQueries};
pub use scene::GpuScene;
pub use trace::GpuTracer;
