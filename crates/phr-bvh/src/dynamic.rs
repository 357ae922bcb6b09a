//! Dynamic scenes, thesis section 5.3: per frame, refit the auxiliary LBVH to the moved
//! primitives (its topology is kept, so this is one parallel bottom-up pass), then rebuild the
//! render BVH with PHR from it. The LBVH's quality decays as things move, but PHR only uses it
//! as a hierarchy of candidate clusters, so the render tree stays good.

use crate::aabb::Aabb;
use crate::builder::PHR_AUX;
use crate::lbvh::build_lbvh;
use crate::node::Bvh;
use crate::phr::{build_phr_with, Aux, PhrOptions};
use crate::refit::refit;
use std::time::{Duration, Instant};

/// The auxiliary tree and the render tree of an animated primitive set.
pub struct DynamicBvh {
    aux: Bvh,
    render: Bvh,
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
    /// Builds the auxiliary LBVH and a first render tree.
    pub fn new(boxes: &[Aabb], options: PhrOptions) -> Self {
        let aux = build_lbvh(boxes, PHR_AUX);
        let (render, _) = build_phr_with(&Aux::new(&aux), &options);
        Self { aux, render, options }
    }

    /// Refits the auxiliary tree to `boxes` (same primitives, moved) and rebuilds the render
    /// tree from it.
    pub fn update(&mut self, boxes: &[Aabb]) -> FrameTimings {
        assert_eq!(boxes.len(), self.aux.prim_count(), "a dynamic scene keeps its primitives");
        let start = Instant::now();
        refit(&mut self.aux, boxes);
        let refit_time = start.elapsed();
        let (render, stats) = build_phr_with(&Aux::new(&self.aux), &self.options);
        self.render = render;
        FrameTimings { refit: refit_time, build: start.elapsed() - refit_time, build_cost: stats.build_cost }
    }

    pub fn set_options(&mut self, options: PhrOptions) {
        self.options = options;
    }

    pub fn render_bvh(&self) -> &Bvh {
        &self.render
    }

    pub fn aux(&self) -> &Bvh {
        &self.aux
    }
}
