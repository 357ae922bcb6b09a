//! Leaf collapsing: every subtree with at most `max_leaf_size` primitives becomes one leaf.
//!
//! The LBVH's radix tree has one primitive per leaf; a leaf of a few primitives trades a
//! few more primitive tests for fewer node visits and a tree half the size. The output keeps
//! the sibling-adjacent layout of [`crate::node`] in depth-first order.

use crate::node::{Bvh, Node};

/// A new tree where every subtree of at most `max_leaf_size` primitives is a single leaf.
pub fn collapse_small_subtrees(bvh: &Bvh, max_leaf_size: u32) -> Bvh {
    if bvh.nodes.is_empty() {
        return Bvh::default();
    }
    let counts = subtree_prim_counts(bvh);
    let mut nodes = Vec::with_capacity(bvh.nodes.len());
    let mut prim_indices = Vec::with_capacity(bvh.prim_indices.len());
    nodes.push(bvh.nodes[0]);
    // (old index, new index) pairs still to be written.
    let mut stack = vec![(0usize, 0usize)];
    while let Some((old, new)) = stack.pop() {
        let node = bvh.nodes[old];
        if node.is_leaf() || counts[old] <= max_leaf_size {
            let first = prim_indices.len() as u32;
            gather_prims(bvh, old, &mut prim_indices);
            nodes[new] = Node::leaf(node.bounds, first, counts[old]);
        } else {
            let child = nodes.len();
            nodes[new] = Node::interior(node.bounds, child as u32);
            nodes.push(bvh.nodes[node.first as usize]);
            nodes.push(bvh.nodes[node.first as usize + 1]);
            stack.push((node.first as usize + 1, child + 1));
            stack.push((node.first as usize, child));
        }
    }
    let mut out = Bvh { nodes, prim_indices, parents: Vec::new() };
    out.compute_parents();
    out
}

/// Number of primitives under each node. Children always have larger indices than their
/// parent in our layouts, so one reverse sweep suffices.
pub fn subtree_prim_counts(bvh: &Bvh) -> Vec<u32> {
    let mut counts = vec![0u32; bvh.nodes.len()];
    for i in (0..bvh.nodes.len()).rev() {
        let n = &bvh.nodes[i];
        counts[i] = if n.is_leaf() { n.count } else { counts[n.first as usize] + counts[n.first as usize + 1] };
    }
    counts
}

fn gather_prims(bvh: &Bvh, root: usize, out: &mut Vec<u32>) {
    let mut stack = vec![root];
    while let Some(i) = stack.pop() {
        let n = &bvh.nodes[i];
        if n.is_leaf() {
            out.extend_from_slice(bvh.leaf_prims(n));
        } else {
            stack.push(n.first as usize + 1);
            stack.push(n.first as usize);
        }
    }
}
