//! The `phr` Python module (built by maturin as `phr._phr`, re-exported by
//! `python/phr/__init__.py`): thin wrappers over the workspace's crates.
//!
//! - [`bvh`]: `phr.Bvh`, build any of our BVHs over numpy triangles, trace rays, refit;
//! - [`scene`]: `phr.Scene`, the path tracer on a scene file (`phr.render` is its one-call
//!   form, in `__init__.py`);
//! - [`tune`]: `phr.tune`, choosing PHR's α and δ (thesis chapter 6).
//!
//! Every long call releases the GIL, so Python threads trace or render at the same time.

mod arrays;
mod bvh;
mod pool;
mod scene;
mod tune;

use pyo3::prelude::*;

#[pymodule]
fn _phr(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("BUILDERS", phr_bvh::Builder::NAMES)?;
    m.add_class::<bvh::Bvh>()?;
    m.add_class::<scene::Scene>()?;
    m.add_function(wrap_pyfunction!(tune::tune, m)?)?;
    Ok(())
}
