//! The static rebuild: better trees for the geometry that never moves, built in the
//! background by a second builder (the viewer's `--static-builder`).
//!
//! A viewer builds its trees with a fast builder so that the first frame comes quickly
//! (PHR-Fast: Sponza's tree in about 20 ms on 2 threads, the SBVH's in about 85). The parts
//! whose primitives never move (the static scene; a rigid object, which moves by its
//! transform only) keep that tree for as long as the scene is shown, and every frame pays
//! for its quality: on Sponza a frame traced through the SBVH took 59–62 ms against 66–67
//! through PHR-Fast's tree (256², 2 threads, `docs/dynamic/history.md`). So once the first
//! frame is out, a worker thread builds those parts' trees again with a better builder, and
//! the pipeline swaps them in at a frame boundary.
//!
//! The swap does not restart the accumulation: every traversal returns the closest hit, ties
//! going to the lowest primitive index, and the packed triangles hold the same values in any
//! tree, so the same rays find the same hits and the image does not change
//! (`tests/static_rebuild.rs` checks it bit for bit).
//!
//! The worker's builder runs on rayon's pool, which the renderer uses too: the two share the
//! cores for the few frames the build takes.

use crate::geometry::WIDTH;
use glam::Vec3;
use phr_bvh::{sah_cost, Aabb, Builder, SahConstants, WideBvh};
use std::thread::JoinHandle;

/// One part to build again: its index, its primitives' boxes and its triangles (in its
/// order, as [`crate::geometry::Geometry::part_boxes`] and
/// [`crate::geometry::Geometry::part_triangles`] give them).
pub struct StaticJob {
    pub part: usize,
    pub boxes: Vec<Aabb>,
    pub triangles: Vec<[Vec3; 3]>,
}

/// A part's new tree: the builder's, collapsed to the renderer's width on the worker too
/// (Sponza's collapse takes about 8 ms), over the part's primitives numbered in its order
/// ([`crate::geometry::Geometry::set_part_wide`] takes it so).
pub struct StaticTree {
    pub part: usize,
    pub wide: WideBvh<WIDTH>,
    /// The SAH cost of the builder's binary tree (unit constants), the thesis's measure.
    pub sah: f64,
}

/// The worker building the parts' new trees.
pub struct StaticRebuilder {
    worker: Option<JoinHandle<Vec<StaticTree>>>,
}

impl StaticRebuilder {
    /// Starts building `jobs` with `builder` on a worker thread.
    pub fn start(builder: Builder, jobs: Vec<StaticJob>) -> Self {
        let worker = std::thread::Builder::new()
            .name("phr-static-rebuild".into())
            .spawn(move || {
                jobs.into_iter()
                    .map(|job| {
                        let bvh = builder.build_with_triangles(&job.boxes, &job.triangles);
                        let mut wide = WideBvh::default();
                        wide.rebuild(&bvh);
                        StaticTree { part: job.part, wide, sah: sah_cost(&bvh, SahConstants::UNIT) }
                    })
                    .collect()
            })
            .expect("start the static rebuild thread");
        Self { worker: Some(worker) }
    }

    /// The parts' new trees if they are done, without waiting.
    pub fn finished(&mut self) -> Option<Vec<StaticTree>> {
        if !self.worker.as_ref()?.is_finished() {
            return None;
        }
        self.wait()
    }

    /// Waits for the parts' new trees (`None` if the worker failed, or they were taken).
    ///
    /// Not from one of rayon's worker threads: the build needs the pool, and with one thread,
    /// that very worker.
    pub fn wait(&mut self) -> Option<Vec<StaticTree>> {
        self.worker.take()?.join().ok()
    }
}
