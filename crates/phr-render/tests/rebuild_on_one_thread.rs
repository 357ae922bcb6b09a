//! The asynchronous rebuilder dropped inside a frame, on rayon's only worker, while its
//! worker thread builds: the build runs its parallel parts on that pool, so waiting for it
//! there must keep the pool going. (Its own test binary: it needs a global pool of one
//! thread.)

use glam::Vec3;
use phr_bvh::phr::PhrOptions;
use phr_bvh::Aabb;
use phr_render::rebuild::AsyncRebuilder;
use std::sync::mpsc;
use std::time::Duration;

#[test]
fn a_rebuilder_dropped_on_the_only_worker_finishes_its_build() {
    rayon::ThreadPoolBuilder::new().num_threads(1).build_global().expect("the first pool of this test binary");
    // 100k boxes on a twisted grid: a build of some tens of milliseconds.
    let boxes: Vec<Aabb> = (0..100_000)
        .map(|i| {
            let p = Vec3::new((i % 100) as f32, ((i / 100) % 100) as f32, (i / 10_000) as f32);
            let p = p + Vec3::new((i as f32 * 0.37).sin(), (i as f32 * 0.11).cos(), 0.0);
            Aabb::new(p, p + Vec3::splat(0.5))
        })
        .collect();
    let (done, finished) = mpsc::channel();
    std::thread::spawn(move || {
        rayon::scope(|_| {
            let (mut rebuilder, _) = AsyncRebuilder::new(&boxes, PhrOptions::HQ, 0);
            rebuilder.start(&boxes, 1);
            assert!(rebuilder.busy());
            drop(rebuilder);
        });
        let _ = done.send(());
    });
    // A deadlock leaves the thread stuck; the test fails instead of hanging.
    finished.recv_timeout(Duration::from_secs(60)).expect("the drop returned within a minute");
}
