//! The split of a cut: a full-sweep SAH over the cut's nodes (thesis 5.2; Hendrich et al.
//! 2017, section 4.2), as the full-sweep SAH builder does over primitives, but with each
//! auxiliary node standing for its whole subtree.
//!
//! On each axis the nodes are sorted by the centre of their box; one sweep from the right
//! stores the area of every suffix's union, one from the left evaluates
//! `A_L · n_L + A_R · n_R` at every position. `n` is the node's weight: the number of auxiliary
//! nodes under it (the thesis's choice, [`CutWeight::AuxNodes`]) or of primitives
//! ([`CutWeight::Primitives`]). Whether to split at all is decided by the shared
//! [`crate::sah::LeafPolicy`] on primitive counts, as for every other builder.

use super::{Aux, CutWeight};
use crate::aabb::Aabb;

/// A split of a cut into two non-empty halves.
pub struct CutSplit {
    pub left: Vec<u32>,
    pub right: Vec<u32>,
    /// `Σ A_child · N_child` over both halves, with N in primitives.
    pub area_count: f32,
}

/// Scratch vectors reused across splits of one task.
#[derive(Default)]
pub struct SweepScratch {
    sorted: Vec<(f32, u32)>,
    best_sorted: Vec<(f32, u32)>,
    right_area: Vec<f32>,
}

/// The best full-sweep split of `cut` (at least two nodes), on all three axes.
pub fn best_split(aux: &Aux, cut: &[u32], weight: CutWeight, scratch: &mut SweepScratch) -> CutSplit {
    debug_assert!(cut.len() >= 2);
    let m = cut.len();
    let w = |i: u32| -> f32 {
        match weight {
            CutWeight::AuxNodes => aux.node_count[i as usize] as f32,
            CutWeight::Primitives => aux.prim_count[i as usize] as f32,
        }
    };
    let bounds = |i: u32| aux.bvh.nodes[i as usize].bounds;
    let total_weight: f32 = cut.iter().map(|&i| w(i)).sum();
    let mut best = (f32::INFINITY, 0usize);
    let mut found = false;
    for axis in 0..3 {
        scratch.sorted.clear();
        scratch.sorted.extend(cut.iter().map(|&i| (bounds(i).center()[axis], i)));
        scratch.sorted.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        scratch.right_area.resize(m, 0.0);
        let mut acc = Aabb::EMPTY;
        for k in (1..m).rev() {
            acc = acc.union(bounds(scratch.sorted[k].1));
            scratch.right_area[k] = acc.surface_area();
        }
        let mut left = Aabb::EMPTY;
        let mut left_weight = 0.0;
        let mut improved = false;
        for k in 1..m {
            let node = scratch.sorted[k - 1].1;
            left = left.union(bounds(node));
            left_weight += w(node);
            let cost = left.surface_area() * left_weight + scratch.right_area[k] * (total_weight - left_weight);
            if cost < best.0 {
                best = (cost, k);
                improved = true;
            }
        }
        if improved {
            std::mem::swap(&mut scratch.sorted, &mut scratch.best_sorted);
            found = true;
        }
    }
    if !found {
        // Only non-finite costs (impossible with finite boxes): split by position.
        scratch.best_sorted.clear();
        scratch.best_sorted.extend(cut.iter().map(|&i| (0.0, i)));
        best.1 = m / 2;
    }
    let k = best.1.max(1);
    let left: Vec<u32> = scratch.best_sorted[..k].iter().map(|p| p.1).collect();
    let right: Vec<u32> = scratch.best_sorted[k..].iter().map(|p| p.1).collect();
    let side = |half: &[u32]| {
        let b = half.iter().fold(Aabb::EMPTY, |b, &i| b.union(bounds(i)));
        b.surface_area() * half.iter().map(|&i| aux.prim_count[i as usize]).sum::<u32>() as f32
    };
    let area_count = side(&left) + side(&right);
    CutSplit { left, right, area_count }
}
