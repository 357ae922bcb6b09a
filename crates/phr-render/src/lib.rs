//! # phr-render: a path tracer on top of phr-bvh
//!
//! The data path, one module per step: scene file ([`scene::json`]) or mesh file ([`load`])
//! → [`scene::Scene`] → triangles and spheres with a BVH ([`geometry`]) → camera rays
//! ([`camera`]) → hits → shading ([`material`], [`integrator`]) → [`film`] → [`denoise`] →
//! image files ([`output`]). [`render`] runs the progressive, multi-threaded loop; [`motion`] describes
//! what moves (plain data the loaders fill in), [`animation`] poses
//! dynamic scenes and [`pipeline`] runs the per-frame loop of the interactive viewer.

pub mod animation;
pub mod auto_builder;
pub mod camera;
pub mod denoise;
pub mod environment;
pub mod error;
pub mod film;
pub mod frame_tracer;
pub mod geometry;
pub mod integrator;
pub mod lights;
pub mod load;
pub mod material;
pub mod motion;
pub mod output;
pub mod pipeline;
pub mod rebuild;
pub mod render;
pub mod sampler;
pub mod scene;
pub mod static_rebuild;
pub mod texture;

pub use error::LoadError;
pub use scene::Scene;
