//! Cuts through the auxiliary tree: the initial cut (thesis 5.1) and the adaptive refinement
//! after each split (thesis 5.2), both driven by the threshold `t(d) = S / 2^(α d + δ)`.
//!
//! A cut is a set of auxiliary nodes whose subtrees together hold a node's primitives; here it
//! is a slice of [`CutNode`]s, copies of the nodes, which carry what the split needs (box and
//! primitive count) so the hot loops never chase indices into the auxiliary tree. Opening a
//! node replaces it by its children. Large nodes are opened early, near the root, where their size would spoil
//! the split decisions; small ones only when the recursion has come down to their scale,
//! which is where PHR saves its time.

use super::aux_tree::{AuxNode, AuxTree};
use crate::aabb::Aabb;
use glam::Vec3A;
use rayon::prelude::*;
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// Below this many primitives the initial cut is collected sequentially.
const PARALLEL_CUT_GRAIN: u32 = 1 << 14;

/// One auxiliary node in a cut: a copy of the node itself (box, children or primitive, and
/// primitive count).
pub type CutNode = AuxNode;

/// A key that tells the nodes of one tree apart (for deterministic tie-breaks): leaves have
/// one primitive and interior nodes more, and `first` is unique within each kind.
#[inline]
pub fn node_key(n: &CutNode) -> (u32, u32) {
    (n.prims, n.first)
}

/// Opening nodes of the auxiliary tree, as cuts do.
impl AuxTree {
    /// Appends the children of `node` (an interior auxiliary node) to `out`.
    #[inline]
    pub fn push_children(&self, node: &CutNode, out: &mut Vec<CutNode>) {
        let children = self.children(node);
        // Most cut nodes are opened later: start loading their children now.
        self.prefetch_children(&children[0]);
        self.prefetch_children(&children[1]);
        // Two pushes, not a slice copy: the compiler made that a call to memmove.
        out.push(children[0]);
        out.push(children[1]);
    }

    /// Appends to `out` what `node` becomes when every node at or above area `t` in its
    /// subtree is opened. `stack` is scratch space.
    #[inline]
    pub fn refine_into(&self, node: CutNode, t: f32, out: &mut Vec<CutNode>, stack: &mut Vec<CutNode>) {
        if node.bounds.surface_area() < t || node.is_leaf() {
            out.push(node);
            return;
        }
        stack.clear();
        stack.push(node);
        while let Some(n) = stack.pop() {
            if n.bounds.surface_area() < t || n.is_leaf() {
                out.push(n);
            } else {
                self.push_children(&n, stack);
            }
        }
    }

    /// The primitives under `node`, appended to `out`.
    pub fn gather_prims(&self, node: &CutNode, out: &mut Vec<u32>, stack: &mut Vec<CutNode>) {
        stack.clear();
        stack.push(*node);
        while let Some(n) = stack.pop() {
            if n.is_leaf() {
                out.push(n.first);
            } else {
                self.push_children(&n, stack);
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
pub fn initial_cut(aux: &AuxTree, t0: f32, max_size: Option<usize>) -> Vec<CutNode> {
    let Some(&root) = aux.root() else { return Vec::new() };
    let cut = collect_below(aux, root, t0);
    match max_size {
        Some(cap) if cut.len() > cap => capped_cut(aux, t0, cap),
        _ => cut,
    }
}

fn collect_below(aux: &AuxTree, node: CutNode, t: f32) -> Vec<CutNode> {
    if node.is_leaf() || node.bounds.surface_area() < t {
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
fn capped_cut(aux: &AuxTree, t0: f32, cap: usize) -> Vec<CutNode> {
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
            self.0.total_cmp(&o.0).then(node_key(&o.1).cmp(&node_key(&self.1)))
        }
    }
    let Some(&root) = aux.root() else { return Vec::new() };
    let mut heap = BinaryHeap::from([ByArea(root.bounds.surface_area(), root)]);
    let mut done = Vec::new();
    let mut children = Vec::new();
    while let Some(ByArea(a, n)) = heap.pop() {
        if n.is_leaf() || a < t0 || done.len() + heap.len() + 2 > cap {
            done.push(n);
            continue;
        }
        children.clear();
        aux.push_children(&n, &mut children);
        heap.extend(children.iter().map(|c| ByArea(c.bounds.surface_area(), *c)));
    }
    done
}

/// The union of the cut's boxes, in SIMD registers (one `min` and one `max` per node where
/// [`Aabb::union`] takes three of each; the same box, as boxes hold no NaN).
#[inline]
pub fn cut_bounds(cut: &[CutNode]) -> Aabb {
    let (lo, hi) = cut.iter().fold((Vec3A::INFINITY, Vec3A::NEG_INFINITY), |(lo, hi), n| {
        (lo.min(Vec3A::from(n.bounds.min)), hi.max(Vec3A::from(n.bounds.max)))
    });
    Aabb::new(lo.into(), hi.into())
}

/// Primitives under the cut.
#[inline]
pub fn cut_prims(cut: &[CutNode]) -> u32 {
    cut.iter().map(|n| n.prims).sum()
}
