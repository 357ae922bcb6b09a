//! Cuts through the auxiliary tree: the initial cut (thesis 5.1) and the adaptive refinement
//! after each split (thesis 5.2), both driven by the threshold `t(d) = S / 2^(α d + δ)`.
//!
//! A cut is a set of auxiliary nodes whose subtrees together hold a node's primitives; here it
//! is a slice of [`CutNode`]s, which carry what the split needs (box, weight, primitive count)
//! so the hot loops never chase indices into the auxiliary tree. Opening a node replaces it
//! by its children. Large nodes are opened early, near the root, where their size would spoil
//! the split decisions; small ones only when the recursion has come down to their scale,
//! which is where PHR saves its time.

use super::{AuxCounts, CutWeight};
use crate::aabb::Aabb;
use crate::node::Bvh;
use rayon::prelude::*;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Below this many primitives the initial cut is collected sequentially.
const PARALLEL_CUT_GRAIN: u32 = 1 << 14;

/// One auxiliary node in a cut.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutNode {
    pub bounds: Aabb,
    /// Index in the auxiliary tree.
    pub index: u32,
    /// Primitives under it.
    pub prims: u32,
    /// Its weight in the sweep (see [`CutWeight`]).
    pub weight: f32,
}

/// The auxiliary tree and its per-node counts, with the weight the build uses.
#[derive(Clone, Copy)]
pub struct AuxView<'a> {
    pub bvh: &'a Bvh,
    pub counts: &'a AuxCounts,
    pub weight: CutWeight,
}

impl AuxView<'_> {
    #[inline]
    pub fn cut_node(&self, index: u32) -> CutNode {
        let i = index as usize;
        let [prims, nodes] = self.counts.counts[i];
        let weight = match self.weight {
            CutWeight::AuxNodes => nodes as f32,
            CutWeight::Primitives => prims as f32,
        };
        CutNode { bounds: self.bvh.nodes[i].bounds, index, prims, weight }
    }

    #[inline]
    pub fn is_leaf(&self, node: &CutNode) -> bool {
        self.bvh.nodes[node.index as usize].is_leaf()
    }

    /// Appends the children of `node` (an interior auxiliary node) to `out`.
    #[inline]
    pub fn push_children(&self, node: &CutNode, out: &mut Vec<CutNode>) {
        out.extend(self.bvh.nodes[node.index as usize].children().map(|c| self.cut_node(c)));
    }

    /// Appends to `out` what `node` becomes when every node at or above area `t` in its
    /// subtree is opened. `stack` is scratch space.
    #[inline]
    pub fn refine_into(&self, node: CutNode, t: f32, out: &mut Vec<CutNode>, stack: &mut Vec<CutNode>) {
        if node.bounds.surface_area() < t || self.is_leaf(&node) {
            out.push(node);
            return;
        }
        stack.clear();
        stack.push(node);
        while let Some(n) = stack.pop() {
            if n.bounds.surface_area() < t || self.is_leaf(&n) {
                out.push(n);
            } else {
                self.push_children(&n, stack);
            }
        }
    }

    /// The primitives under `node`, appended to `out`.
    pub fn gather_prims(&self, node: &CutNode, out: &mut Vec<u32>, stack: &mut Vec<u32>) {
        stack.clear();
        stack.push(node.index);
        while let Some(i) = stack.pop() {
            let n = &self.bvh.nodes[i as usize];
            if n.is_leaf() {
                out.extend_from_slice(self.bvh.leaf_prims(n));
            } else {
                stack.extend(n.children());
            }
        }
    }
}

/// The threshold `S / 2^(α d + δ)` for a node at depth `d`.
#[inline]
pub fn threshold(scene_area: f32, alpha: f32, delta: f32, depth: u32) -> f32 {
    scene_area / (alpha * depth as f32 + delta).exp2()
}

/// The initial cut: every auxiliary node whose area is below `t0` while its parent's is not,
/// plus the leaves reached above it. Walked top-down in parallel. If that is more than
/// `max_size` nodes, the largest nodes are opened first, until the cap is reached.
pub fn initial_cut(aux: &AuxView, t0: f32, max_size: Option<usize>) -> Vec<CutNode> {
    let cut = collect_below(aux, aux.cut_node(0), t0);
    match max_size {
        Some(cap) if cut.len() > cap => capped_cut(aux, t0, cap),
        _ => cut,
    }
}

fn collect_below(aux: &AuxView, node: CutNode, t: f32) -> Vec<CutNode> {
    if aux.is_leaf(&node) || node.bounds.surface_area() < t {
        return vec![node];
    }
    if node.prims < PARALLEL_CUT_GRAIN {
        let mut out = Vec::new();
        aux.refine_into(node, t, &mut out, &mut Vec::new());
        return out;
    }
    let mut children = Vec::new();
    aux.push_children(&node, &mut children);
    children.into_par_iter().flat_map_iter(|c| collect_below(aux, c, t)).collect()
}

/// Opens the largest nodes first while they are above `t0` and the cut stays within `cap`.
fn capped_cut(aux: &AuxView, t0: f32, cap: usize) -> Vec<CutNode> {
    struct ByArea(f32, CutNode);
    impl PartialEq for ByArea {
        fn eq(&self, o: &Self) -> bool {
            self.cmp(o) == Ordering::Equal
        }
    }
    impl Eq for ByArea {}
    impl PartialOrd for ByArea {
        fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
            Some(self.cmp(o))
        }
    }
    impl Ord for ByArea {
        fn cmp(&self, o: &Self) -> Ordering {
            self.0.total_cmp(&o.0).then(o.1.index.cmp(&self.1.index))
        }
    }
    let root = aux.cut_node(0);
    let mut heap = BinaryHeap::from([ByArea(root.bounds.surface_area(), root)]);
    let mut done = Vec::new();
    let mut children = Vec::new();
    while let Some(ByArea(a, n)) = heap.pop() {
        let k = aux.bvh.nodes[n.index as usize].child_count() as usize;
        if aux.is_leaf(&n) || a < t0 || done.len() + heap.len() + k > cap {
            done.push(n);
            continue;
        }
        children.clear();
        aux.push_children(&n, &mut children);
        heap.extend(children.iter().map(|c| ByArea(c.bounds.surface_area(), *c)));
    }
    done
}

/// The union of the cut's boxes.
#[inline]
pub fn cut_bounds(cut: &[CutNode]) -> Aabb {
    cut.iter().fold(Aabb::EMPTY, |b, n| b.union(n.bounds))
}

/// Primitives under the cut.
#[inline]
pub fn cut_prims(cut: &[CutNode]) -> u32 {
    cut.iter().map(|n| n.prims).sum()
}
