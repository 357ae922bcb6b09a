//! Dynamic scenes, thesis section 5.3: per frame, refit the auxiliary LBVH to the moved
//! primitives (its topology is kept, so this is one parallel bottom-up pass), then rebuild the
//! render BVH with PHR from it. The LBVH's quality decays as things move, but PHR only uses it
//! as a hierarchy of candidate clusters, so the render tree stays good.
//!
//! A renderer that traces a wide tree only takes [`DynamicBvh::update_wide`]: PHR fills the
//! wide nodes directly ([`build_phr_wide`]), with no binary tree and no collapse per frame.

use crate::aabb::Aabb;
use crate::node::Bvh;
use crate::phr::{build_phr, build_phr_wide, AuxTree, PhrOptions};
use crate::wide::WideBvh;
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

    /// [`DynamicBvh::update`] straight to an `N`-wide tree, built into `wide`'s memory (the
    /// same tree as collapsing `update`'s; see [`build_phr_wide`]).
    pub fn update_wide<const N: usize>(&mut self, boxes: &[Aabb], wide: &mut WideBvh<N>) -> FrameTimings {
        assert_eq!(boxes.len(), self.aux.prim_count(), "a dynamic scene keeps its primitives");
        let start = Instant::now();
        self.aux.refit(boxes);
        let refit = start.elapsed();
        let stats = build_phr_wide(&self.aux, &self.options, wide);
        FrameTimings { refit, build: start.elapsed() - refit, build_cost: stats.build_cost }
    }

    pub fn set_options(&mut self, options: PhrOptions) {
        self.options = options;
    }

    pub fn aux(&self) -> &AuxTree {
        &self.aux
    }
}
