//! The static rebuild: better trees for the geometry that never moves, built in the
//! background by a second builder (the viewer's `--static-builder`).
//!
//! A viewer builds its trees with a fast builder so that the first frame comes quickly: on
//! Sponza the first frame's build took 18–21 ms with PHR-Fast and 85–86 ms with the SBVH
//! (`phr view --headless`, 2 threads). The parts whose primitives never move (the static
//! scene; a rigid object, which moves by its transform only) keep that tree for as long as
//! the scene is shown, and every frame pays for its quality: on Sponza at 256² a frame traced
//! through the SBVH took 57–60 ms against 66–68 through PHR-Fast's tree
//! (`docs/dynamic/history.md`). So once the first frame is out, a worker thread builds those
//! parts' trees again with a better builder, and the pipeline swaps them in at a frame
//! boundary.
//!
//! The swap does not restart the accumulation: every traversal returns the closest hit, ties
//! going to the lowest primitive index, and the packed triangles hold the same values in any
//! tree, so the same rays find the same hits and the image does not change
//! (`tests/static_rebuild.rs` checks it bit for bit).
//!
//! The worker is a thread of its own, as [`crate::rebuild`]'s is: the builder's parallel
//! parts run on rayon's pool, which the renderer uses too, its serial parts (the top of the
//! tree, the collapse) beside it. The frames are slower for the few frames the build takes.

use crate::geometry::WIDTH;
use glam::Vec3;
use phr_bvh::{sah_cost, Aabb, Builder, SahConstants, WideBvh};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

/// One part to build again: its index, its primitives' boxes and its triangles (in its
/// order, as [`crate::geometry::Geometry::part_boxes`] and
/// [`crate::geometry::Geometry::part_triangles`] give them).
pub struct StaticJob {
    pub part: usize,
    pub boxes: Vec<Aabb>,
    pub triangles: Vec<[Vec3; 3]>,
}

/// A part's new tree: the builder's, collapsed to the renderer's width on the worker too,
/// over the part's primitives numbered in its order
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
    /// Set when it is dropped: the worker then skips the jobs it has not started.
    cancelled: Arc<AtomicBool>,
}

impl StaticRebuilder {
    /// Starts building `jobs` with `builder` on a worker thread.
    pub fn start(builder: Builder, jobs: Vec<StaticJob>) -> Self {
        let cancelled = Arc::new(AtomicBool::new(false));
        let cancel = Arc::clone(&cancelled);
        let worker = std::thread::Builder::new()
            .name("phr-static-rebuild".into())
            .spawn(move || {
                let mut trees = Vec::with_capacity(jobs.len());
                for job in jobs {
                    if cancel.load(Ordering::Relaxed) {
                        break;
                    }
                    let bvh = builder.build_with_triangles(&job.boxes, &job.triangles);
                    let mut wide = WideBvh::default();
                    wide.rebuild(&bvh);
                    trees.push(StaticTree { part: job.part, wide, sah: sah_cost(&bvh, SahConstants::UNIT) });
                }
                trees
            })
            .expect("start the static rebuild thread");
        Self { worker: Some(worker), cancelled }
    }

    /// The parts' new trees if they are done, without waiting.
    pub fn finished(&mut self) -> Option<Vec<StaticTree>> {
        self.worker.as_ref().is_some_and(JoinHandle::is_finished).then(|| self.wait())
    }

    /// Waits for the parts' new trees: none if the worker failed (which is said on stderr),
    /// or if they were taken already.
    ///
    /// Not from one of rayon's worker threads: the build needs the pool, and with one thread,
    /// that very worker.
    pub fn wait(&mut self) -> Vec<StaticTree> {
        let Some(worker) = self.worker.take() else { return Vec::new() };
        worker.join().unwrap_or_else(|_| {
            eprintln!("warning: the static rebuild failed: the builder's trees stay");
            Vec::new()
        })
    }
}

impl Drop for StaticRebuilder {
    /// Lets the worker go (a frame does not wait for it) after telling it to stop at the
    /// next part: a layout that changed while it built makes its trees useless.
    fn drop(&mut self) {
        self.cancelled.store(true, Ordering::Relaxed);
    }
}
