//! Rebuilding a deforming part's tree on a worker thread, after Ize, Wald & Parker (2007),
//! "Asynchronous BVH construction for ray tracing dynamic scenes". While the worker refits
//! PHR's auxiliary tree to a copy of the boxes of frame `f` and builds a new wide tree from
//! it, the frames after `f` trace the previous tree refitted to their own boxes. The new tree
//! is swapped in at the next frame boundary after it is done, and refitted to that frame's
//! boxes (its primitives have moved since `f`). Then the next rebuild starts.
//!
//! The worker's PHR runs on rayon's pool, which the renderer uses too: the two share the
//! cores, and the frame only waits for the refit and the packing.

use crate::geometry::WIDTH;
use phr_bvh::dynamic::{DynamicBvh, FrameTimings};
use phr_bvh::phr::PhrOptions;
use phr_bvh::{Aabb, WideBvh};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::Mutex;
use std::thread::JoinHandle;

/// A tree the worker built.
pub struct Rebuilt {
    /// Over the part's primitives numbered in its order ([`crate::geometry::Geometry::set_part_wide`]).
    pub wide: WideBvh<WIDTH>,
    /// The frame whose boxes it was built over.
    pub frame: u64,
    pub timings: FrameTimings,
}

struct Request {
    boxes: Vec<Aabb>,
    into: WideBvh<WIDTH>,
    frame: u64,
}

/// The worker thread and what is under way on it.
pub struct AsyncRebuilder {
    requests: Option<Sender<Request>>,
    /// (In a mutex only so that the pipeline, which renders from several threads, is `Sync`.)
    results: Mutex<Receiver<(Rebuilt, Vec<Aabb>)>>,
    worker: Option<JoinHandle<()>>,
    busy: bool,
    /// Memory for the next request: the boxes the last one copied, the tree a landed one
    /// replaced.
    spare_boxes: Vec<Aabb>,
    spare_tree: WideBvh<WIDTH>,
}

impl AsyncRebuilder {
    /// Builds PHR's auxiliary tree over `boxes` (the part's, in its order, of frame `frame`)
    /// and a first tree from it, here, and starts the worker that keeps the auxiliary tree.
    pub fn new(boxes: &[Aabb], options: PhrOptions, frame: u64) -> (Self, Rebuilt) {
        let mut dynamic = DynamicBvh::new(boxes, options);
        let mut wide = WideBvh::default();
        let timings = dynamic.update_wide(boxes, &mut wide);
        let first = Rebuilt { wide, frame, timings };
        let (requests, incoming) = channel::<Request>();
        let (outgoing, results) = channel();
        let worker = std::thread::Builder::new()
            .name("phr-rebuild".into())
            .spawn(move || {
                for mut r in incoming {
                    let timings = dynamic.update_wide(&r.boxes, &mut r.into);
                    if outgoing.send((Rebuilt { wide: r.into, frame: r.frame, timings }, r.boxes)).is_err() {
                        break;
                    }
                }
            })
            .expect("start the rebuild worker thread");
        let rebuilder = Self {
            requests: Some(requests),
            results: Mutex::new(results),
            worker: Some(worker),
            busy: false,
            spare_boxes: Vec::new(),
            spare_tree: WideBvh::default(),
        };
        (rebuilder, first)
    }

    /// Starts a rebuild over a copy of `boxes` (frame `frame`'s), unless one is under way.
    pub fn start(&mut self, boxes: &[Aabb], frame: u64) {
        if self.busy {
            return;
        }
        let mut copy = std::mem::take(&mut self.spare_boxes);
        copy.clear();
        copy.extend_from_slice(boxes);
        let into = std::mem::take(&mut self.spare_tree);
        if let Some(requests) = &self.requests {
            self.busy = requests.send(Request { boxes: copy, into, frame }).is_ok();
        }
    }

    /// Whether a rebuild is under way ([`AsyncRebuilder::start`] would do nothing).
    pub fn busy(&self) -> bool {
        self.busy
    }

    /// The tree of the rebuild under way if it is done, without waiting.
    pub fn finished(&mut self) -> Option<Rebuilt> {
        if !self.busy {
            return None;
        }
        let (rebuilt, boxes) = self.results.get_mut().ok()?.try_recv().ok()?;
        self.busy = false;
        self.spare_boxes = boxes;
        Some(rebuilt)
    }

    /// Takes back the tree a landed one replaced, as memory for the next build.
    pub fn recycle(&mut self, tree: WideBvh<WIDTH>) {
        self.spare_tree = tree;
    }
}

impl Drop for AsyncRebuilder {
    /// Closes the channel, which ends the worker's loop after the build under way, and waits
    /// for that build. On one of rayon's workers (a frame drops the rebuilder when the online
    /// tuner switches builders) the wait runs the pool's pending jobs meanwhile: the build
    /// needs the pool, and with one thread, that very worker.
    fn drop(&mut self) {
        self.requests = None;
        if let Some(worker) = self.worker.take() {
            if rayon::current_thread_index().is_some() {
                while !worker.is_finished() {
                    if rayon::yield_now() != Some(rayon::Yield::Executed) {
                        std::thread::yield_now();
                    }
                }
            }
            let _ = worker.join();
        }
    }
}
