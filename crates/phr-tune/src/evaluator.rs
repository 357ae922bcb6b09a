//! One evaluation of PHR at (α, δ): build from a shared auxiliary LBVH, and measure the
//! build cost `b = Σ |cut|`, the SAH cost `c` (traversal 2, intersection 1, as the thesis) and
//! the build time. Builds are deterministic, so `b` and `c` are cached per (α, δ).

use phr_bvh::phr::{build_phr, AuxTree, PhrOptions};
use phr_bvh::{sah_cost, Aabb, Bvh, SahConstants};
use std::collections::HashMap;
use std::sync::Mutex;
use std::time::Instant;

/// What one PHR build at (α, δ) gave.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Evaluation {
    pub alpha: f64,
    pub delta: f64,
    /// `Σ |cut|`.
    pub build_cost: f64,
    /// SAH cost with traversal 2, intersection 1, normalised by the root area.
    pub sah_cost: f64,
    /// Measured build time (PHR only, without the auxiliary LBVH).
    pub build_ms: f64,
}

/// A callback told about every new build.
pub type BuildCallback = Box<dyn Fn(&Evaluation) + Send + Sync>;

/// Evaluates PHR builds from one auxiliary LBVH.
pub struct PhrEvaluator {
    /// Called after every new build (progress display).
    on_build: Option<BuildCallback>,
    aux: AuxTree,
    base: PhrOptions,
    cache: Mutex<HashMap<(u64, u64), Evaluation>>,
    /// Primitives in the scene.
    pub prims: usize,
}

impl PhrEvaluator {
    /// Builds the auxiliary LBVH over `boxes`; `base` gives everything but α and δ.
    pub fn new(boxes: &[Aabb], base: PhrOptions) -> Self {
        Self { on_build: None, aux: AuxTree::build(boxes), base, cache: Mutex::new(HashMap::new()), prims: boxes.len() }
    }

    /// Calls `f` after every new (uncached) build.
    pub fn with_progress(mut self, f: impl Fn(&Evaluation) + Send + Sync + 'static) -> Self {
        self.on_build = Some(Box::new(f));
        self
    }

    /// The PHR options at (α, δ).
    pub fn options(&self, alpha: f64, delta: f64) -> PhrOptions {
        PhrOptions { alpha: alpha as f32, delta: delta as f32, ..self.base }
    }

    /// Builds the tree at (α, δ) (for rendering with it).
    pub fn build(&self, alpha: f64, delta: f64) -> Bvh {
        build_phr(&self.aux, &self.options(alpha, delta)).0
    }

    /// Builds (α, δ) afresh and times it, bypassing the cache (whose timings may come from
    /// builds run in parallel, as in grid search).
    pub fn measure(&self, alpha: f64, delta: f64) -> Evaluation {
        let start = Instant::now();
        let (bvh, stats) = build_phr(&self.aux, &self.options(alpha, delta));
        let build_ms = start.elapsed().as_secs_f64() * 1e3;
        Evaluation {
            alpha,
            delta,
            build_cost: stats.build_cost as f64,
            sah_cost: sah_cost(&bvh, SahConstants::THESIS),
            build_ms,
        }
    }

    /// Evaluates (α, δ), from the cache when it was evaluated before.
    pub fn evaluate(&self, alpha: f64, delta: f64) -> Evaluation {
        let key = (alpha.to_bits(), delta.to_bits());
        if let Some(e) = self.cache.lock().expect("cache lock").get(&key) {
            return *e;
        }
        let start = Instant::now();
        let (bvh, stats) = build_phr(&self.aux, &self.options(alpha, delta));
        let build_ms = start.elapsed().as_secs_f64() * 1e3;
        let e = Evaluation {
            alpha,
            delta,
            build_cost: stats.build_cost as f64,
            sah_cost: sah_cost(&bvh, SahConstants::THESIS),
            build_ms,
        };
        self.cache.lock().expect("cache lock").insert(key, e);
        if let Some(f) = &self.on_build {
            f(&e);
        }
        e
    }

    /// Distinct builds done so far.
    pub fn builds(&self) -> usize {
        self.cache.lock().expect("cache lock").len()
    }
}
