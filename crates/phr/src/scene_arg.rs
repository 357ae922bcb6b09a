//! The SCENE argument shared by the subcommands: a scene file, a mesh file, `builtin`, or the
//! name of a scene of `scenes/suite` (`sponza`, `dragon`, ...), opened by
//! [`phr_bench::suite::open_scene`], which the Python module shares.

pub use phr_bench::suite::{open_scene, BUILTIN};
