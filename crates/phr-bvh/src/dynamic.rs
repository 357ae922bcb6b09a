//! Dynamic scenes, thesis section 5.3: per frame, refit the auxiliary LBVH to the moved
//! primitives (its topology is kept, so this is one parallel bottom-up pass), then rebuild the
//! render BVH with PHR from it. The LBVH's quality decays as things move, but PHR only uses it
//! as a hierarchy of candidate clusters, so the render tree stays good.

use crate::aabb::Aabb;
use crate::node::Bvh;
use crate::phr::{build_phr, AuxTree, PhrOptions};
use std::time::{Duration, Instant};

/// The auxiliary tree of an animated primitive set, from which each frame's render tree is
/// built.
pub struct DynamicBvh {
    aux: AuxTree,
    options: PhrOptions,
}

/// What one frame's update cost.
#[derive(Clone, Copy, Debug, Default)]
pub struct FrameTimings {
    pub refit: Duration,
    pub build: Duration,
    /// PHR's `Σ |cut|`.
    pub build_cost: u64,
}

impl DynamicBvh {
    /// Builds the auxiliary LBVH over the primitives' first-frame boxes.
    pub fn new(boxes: &[Aabb], options: PhrOptions) -> Self {
        Self { aux: AuxTree::build(boxes), options }
    }

    /// Refits the auxiliary tree to `boxes` (same primitives, moved) and builds the render
    /// tree from it with PHR.
    pub fn update(&mut self, boxes: &[Aabb]) -> (Bvh, FrameTimings) {
        assert_eq!(boxes.len(), self.aux.prim_count(), "a dynamic scene keeps its primitives");
        let start = Instant::now();
        self.aux.refit(boxes);
        let refit_time = start.elapsed();
        let (render, stats) = build_phr(&self.aux, &self.options);
        let timings =
            FrameTimings { refit: refit_time, build: start.elapsed() - refit_time, build_cost: stats.build_cost };
        (render, timings)
    }

    pub fn set_options(&mut self, options: PhrOptions) {
        self.options = options;
    }

    pub fn aux(&self) -> &AuxTree {
        &self.aux
    }
}
