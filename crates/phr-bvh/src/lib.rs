//! # phr-bvh: bounding volume hierarchies for ray tracing
//!
//! Geometry in, tree out: give the builders one bounding box per primitive, get a [`Bvh`]
//! (flat node array, see [`node`]); trace rays through it with [`traverse`] and a closure
//! that intersects your primitives; measure it with [`metrics`]; check it with [`validate()`].
//! Nothing here knows about files, materials or images.
//!
//! Builders, each in a module named after its algorithm:
//! - [`lbvh`]: the linear BVH (Morton codes + radix sort + radix tree), the fast builder.
//! - [`phr`]: Progressive Hierarchical Refinement, the builder the thesis is about, over its
//!   auxiliary tree ([`phr::AuxTree`]: the same radix tree with one primitive per leaf, laid
//!   out for opening nodes and for refitting every frame).
//! - [`sweep_sah`]: the full-sweep SAH builder, the quality reference PHR approximates.
//! - [`binned_sah`]: the binned SAH builder, what Embree, pbrt and tinybvh use by default.
//! - [`sbvh`]: binned SAH with spatial splits (Embree's high-quality builder): a primitive
//!   may be cut into parts in several leaves.
//!
//! [`builder::Builder`] names them all for front ends; all top-down builders share one
//! [`sah::LeafPolicy`], so their SAH costs ([`metrics::sah_cost`]) compare.
//!
//! Primitive tests for the common cases: [`triangle`] (Möller–Trumbore), [`sphere`].
//!
//! For tracing speed, [`wide`] collapses any tree into a 4- or 8-wide BVH traversed with SIMD
//! box tests, with triangles packed in leaf order ([`wide::PackedTriangles`]). For scenes whose
//! objects move rigidly, [`instance`] places bottom-level trees with affine transforms under a
//! small top-level tree rebuilt per frame.

pub mod aabb;
pub mod binned_sah;
pub mod builder;
pub mod dynamic;
pub mod instance;
pub mod lbvh;
pub mod metrics;
pub mod morton;
pub mod node;
mod parallel;
pub mod phr;
pub mod radix_sort;
pub mod ray;
pub mod refit;
pub mod sah;
pub mod sbvh;
pub mod sphere;
pub mod sweep_sah;
mod topdown;
pub mod traverse;
pub mod triangle;
pub mod validate;
pub mod wide;

pub use aabb::Aabb;
pub use builder::Builder;
pub use lbvh::{build_lbvh, LbvhOptions};
pub use metrics::{sah_cost, tree_stats, wide_sah_cost, SahConstants, TreeStats};
pub use node::{Bvh, Node};
pub use ray::Ray;
pub use refit::refit;
pub use traverse::{any_hit, closest_hit, closest_hit_counted, TraversalStats};
pub use validate::validate;
pub use wide::{PackedTriangles, RefitAreas, SimdLevel, WideBvh};
