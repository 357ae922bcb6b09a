//! The one throughput measurement and the one traversal-work count of the ray benchmarks.

use phr_bvh::Ray;
use rayon::prelude::*;
use std::time::Instant;

/// Mrays/s of `trace` over `rays` on the current rayon pool (chunks of 256 rays), best of
/// `repeats` passes. `trace` returns whether the ray hit, so the work cannot be optimised away.
pub fn throughput(rays: &[Ray], repeats: usize, trace: impl Fn(&Ray) -> bool + Sync) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..repeats.max(1) {
        let start = Instant::now();
        let hits: usize = rays.par_chunks(256).map(|c| c.iter().filter(|r| trace(r)).count()).sum();
        std::hint::black_box(hits);
        best = best.min(start.elapsed().as_secs_f64());
    }
    rays.len() as f64 / best / 1e6
}

/// [`throughput`] of a tracer that takes a chunk of 256 rays at once and returns how many hit.
pub fn throughput_batched(rays: &[Ray], repeats: usize, trace: impl Fn(&[Ray]) -> usize + Sync) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..repeats.max(1) {
        let start = Instant::now();
        let hits: usize = rays.par_chunks(256).map(&trace).sum();
        std::hint::black_box(hits);
        best = best.min(start.elapsed().as_secs_f64());
    }
    rays.len() as f64 / best / 1e6
}

/// Mean per ray of the `K` counts `count` returns for each ray (nodes visited, leaves,
/// primitives tested, ...).
pub fn mean_counts<const K: usize>(rays: &[Ray], count: impl Fn(&Ray) -> [u64; K] + Sync) -> [f64; K] {
    let sums = rays.par_iter().map(&count).reduce(|| [0; K], |a, b| std::array::from_fn(|k| a[k] + b[k]));
    let n = rays.len().max(1) as f64;
    sums.map(|s| s as f64 / n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn mean_counts_averages_each_count() {
        let rays: Vec<Ray> = (0..4).map(|i| Ray::new(Vec3::splat(i as f32), Vec3::X)).collect();
        let m = mean_counts(&rays, |r| [r.origin.x as u64, 2]);
        assert_eq!(m, [1.5, 2.0]);
        assert!(throughput(&rays, 2, |r| r.origin.x > 1.0) > 0.0);
    }
}
