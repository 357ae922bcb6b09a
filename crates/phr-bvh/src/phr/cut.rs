//! Cuts through the auxiliary tree: the initial cut (thesis 5.1) and the adaptive refinement
//! after each split (thesis 5.2), both driven by the threshold `t(d) = S / 2^(α d + δ)`.
//!
//! A cut is a set of auxiliary nodes whose subtrees together hold a node's primitives. Opening
//! a node replaces it by its children. Large nodes are opened early, near the root, where
//! their size would spoil the split decisions; small ones only when the recursion has come
//! down to their scale, which is where PHR saves its time.

use super::Aux;
use crate::aabb::Aabb;
use rayon::prelude::*;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Below this many primitives the initial cut is collected sequentially.
const PARALLEL_CUT_GRAIN: u32 = 1 << 14;

/// The threshold `S / 2^(α d + δ)` for a node at depth `d`.
#[inline]
pub fn threshold(scene_area: f32, alpha: f32, delta: f32, depth: u32) -> f32 {
    scene_area / (alpha * depth as f32 + delta).exp2()
}

/// The initial cut: every auxiliary node whose area is below `t0` while its parent's is not,
/// plus the leaves reached above it. Walked top-down in parallel. If that is more than
/// `max_size` nodes, the largest nodes are opened first, until the cap is reached.
pub fn initial_cut(aux: &Aux, t0: f32, max_size: Option<usize>) -> Vec<u32> {
    let cut = collect_below(aux, 0, t0);
    match max_size {
        Some(cap) if cut.len() > cap => capped_cut(aux, t0, cap),
        _ => cut,
    }
}

fn collect_below(aux: &Aux, node: u32, t: f32) -> Vec<u32> {
    let n = &aux.bvh.nodes[node as usize];
    if n.is_leaf() || n.bounds.surface_area() < t {
        return vec![node];
    }
    if aux.prim_count[node as usize] < PARALLEL_CUT_GRAIN {
        let mut out = Vec::new();
        refine_into(aux, node, t, &mut out);
        return out;
    }
    let children: Vec<u32> = n.children().collect();
    children.par_iter().flat_map_iter(|&c| collect_below(aux, c, t)).collect()
}

/// Opens the largest nodes first while they are above `t0` and the cut stays within `cap`.
fn capped_cut(aux: &Aux, t0: f32, cap: usize) -> Vec<u32> {
    #[derive(PartialEq)]
    struct ByArea(f32, u32);
    impl Eq for ByArea {}
    impl PartialOrd for ByArea {
        fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
            Some(self.cmp(o))
        }
    }
    impl Ord for ByArea {
        fn cmp(&self, o: &Self) -> Ordering {
            self.0.total_cmp(&o.0).then(o.1.cmp(&self.1))
        }
    }
    let area = |i: u32| aux.bvh.nodes[i as usize].bounds.surface_area();
    let mut heap = BinaryHeap::from([ByArea(area(0), 0)]);
    let mut done = Vec::new();
    while let Some(ByArea(a, i)) = heap.pop() {
        let n = &aux.bvh.nodes[i as usize];
        let k = n.child_count() as usize;
        if n.is_leaf() || a < t0 || done.len() + heap.len() + k > cap {
            done.push(i);
            continue;
        }
        heap.extend(n.children().map(|c| ByArea(area(c), c)));
    }
    done
}

/// Appends to `out` the nodes of `node`'s subtree reached by opening every node with area at
/// or above `t`.
pub fn refine_into(aux: &Aux, node: u32, t: f32, out: &mut Vec<u32>) {
    let mut stack = vec![node];
    while let Some(i) = stack.pop() {
        let n = &aux.bvh.nodes[i as usize];
        if n.is_leaf() || n.bounds.surface_area() < t {
            out.push(i);
        } else {
            stack.extend(n.children().rev());
        }
    }
}

/// Refinement of a child's cut: every node with area at or above `t` is opened.
pub fn refine(aux: &Aux, cut: Vec<u32>, t: f32) -> Vec<u32> {
    if cut.iter().all(|&i| {
        let n = &aux.bvh.nodes[i as usize];
        n.is_leaf() || n.bounds.surface_area() < t
    }) {
        return cut;
    }
    let mut out = Vec::with_capacity(cut.len() * 2);
    for i in cut {
        refine_into(aux, i, t, &mut out);
    }
    out
}

/// The union of the cut's boxes.
pub fn cut_bounds(aux: &Aux, cut: &[u32]) -> Aabb {
    cut.iter().fold(Aabb::EMPTY, |b, &i| b.union(aux.bvh.nodes[i as usize].bounds))
}
