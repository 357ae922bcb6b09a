//! The threads a call runs on. `threads=None`: rayon's global pool (all cores). `threads=1`:
//! tracing on the calling thread, so that several Python threads trace at once, each on its
//! own core (builds, which use rayon inside, run on a one-thread pool made for the call).
//! Any other number: a pool of that many threads, kept by the object.

use pyo3::exceptions::PyValueError;
use pyo3::PyResult;
use rayon::prelude::*;
use std::sync::Arc;

#[derive(Clone)]
pub enum Pool {
    Global,
    Caller,
    Own(Arc<rayon::ThreadPool>),
}

impl Pool {
    pub fn new(threads: Option<usize>) -> PyResult<Self> {
        match threads {
            None => Ok(Pool::Global),
            Some(0) => Err(PyValueError::new_err("threads must be at least 1 (None: all cores)")),
            Some(1) => Ok(Pool::Caller),
            Some(n) => Ok(Pool::Own(Arc::new(pool(n)?))),
        }
    }

    /// Runs `f` (which may use rayon inside, as the builders do) on these threads; for
    /// [`Pool::Caller`], on one thread of a pool made for the call.
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> PyResult<R> {
        match self {
            Pool::Global => Ok(f()),
            Pool::Caller => Ok(pool(1)?.install(f)),
            Pool::Own(pool) => Ok(pool.install(f)),
        }
    }

    /// Calls `f` on every item: in parallel on the pool, or one after the other on the
    /// calling thread.
    pub fn for_each<T: Send>(&self, items: Vec<T>, f: impl Fn(T) + Sync + Send) {
        match self {
            Pool::Global => items.into_par_iter().for_each(f),
            Pool::Caller => items.into_iter().for_each(f),
            Pool::Own(pool) => pool.install(|| items.into_par_iter().for_each(f)),
        }
    }
}

fn pool(n: usize) -> PyResult<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .map_err(|e| PyValueError::new_err(format!("cannot start {n} threads: {e}")))
}
