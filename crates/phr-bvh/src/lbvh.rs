//! The LBVH, "linear BVH" (Lauterbach et al. 2009; Karras 2012 for the radix-tree split;
//! thesis section 4.1): the fast, lower-quality builder.
//!
//! 1. Morton codes of the primitive centroids, quantised to the centroid bounds (parallel).
//! 2. A parallel radix sort of (code, primitive) pairs ([`crate::radix_sort`]).
//! 3. The binary radix tree, top down: a range of sorted codes is split where its highest
//!    differing bit flips (found by binary search); a run of identical codes is split in the
//!    middle, by count; a range of at most `max_leaf_size` primitives becomes a leaf. The top
//!    of the tree is expanded sequentially until ranges are small (`PARALLEL_GRAIN`); each
//!    small range is then built as an independent rayon task into its own vector, and the
//!    pieces are concatenated in task order. No locks, no atomics, and the same layout
//!    whatever the thread count.
//! 4. Bounds bottom up, in parallel, with one atomic counter per node ([`crate::refit()`]), the
//!    routine that also refits the tree when vertices move.
//!
//! With `max_leaf_size == 1` the result is the full radix tree (one primitive per leaf). PHR
//! refines the same tree, built from the same sorted codes and splits ([`find_split`]) but laid
//! out for its own use: [`crate::phr::AuxTree`].

use crate::aabb::Aabb;
use crate::morton::MortonQuantizer;
use crate::node::{Bvh, Node, NO_PARENT};
use crate::radix_sort::radix_sort_pairs;
use crate::refit::refit;
use rayon::prelude::*;

/// Ranges of at most this many primitives are built sequentially inside one task.
const PARALLEL_GRAIN: usize = 1 << 12;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LbvhOptions {
    /// Ranges of at most this many primitives become one leaf (1 = the full radix tree).
    pub max_leaf_size: u32,
}

impl Default for LbvhOptions {
    fn default() -> Self {
        Self { max_leaf_size: 4 }
    }
}

/// Builds an LBVH over primitives given by their bounding boxes.
pub fn build_lbvh(boxes: &[Aabb], options: LbvhOptions) -> Bvh {
    let mut bvh = build_topology(boxes, options.max_leaf_size.max(1) as usize);
    refit(&mut bvh, boxes);
    bvh
}

/// Steps 1–3: the tree's topology; bounds are left empty.
pub fn build_topology(boxes: &[Aabb], max_leaf_size: usize) -> Bvh {
    if boxes.is_empty() {
        return Bvh::default();
    }
    let pairs = sorted_morton_codes(boxes);
    let codes: Vec<u64> = pairs.par_iter().map(|p| p.0).collect();
    let prim_indices: Vec<u32> = pairs.par_iter().map(|p| p.1).collect();
    drop(pairs);
    let top = TopOfTree::expand(&codes, max_leaf_size);
    let pieces: Vec<Piece> =
        top.tasks.par_iter().map(|t| Piece::build(&codes, t.first, t.end, max_leaf_size)).collect();
    let (nodes, parents) = top.assemble(pieces);
    Bvh { nodes, prim_indices, parents }
}

/// Morton codes of the box centres, sorted, paired with their primitive index.
pub(crate) fn sorted_morton_codes(boxes: &[Aabb]) -> Vec<(u64, u32)> {
    let centroid_bounds =
        boxes.par_iter().fold(|| Aabb::EMPTY, |acc, b| acc.grown(b.center())).reduce(|| Aabb::EMPTY, Aabb::union);
    let quantizer = MortonQuantizer::new(&centroid_bounds);
    let mut pairs: Vec<(u64, u32)> =
        boxes.par_iter().enumerate().map(|(i, b)| (quantizer.code(b.center()), i as u32)).collect();
    radix_sort_pairs(&mut pairs, 63);
    pairs
}

/// A range of sorted primitives `[first, end)` whose node already has a slot.
#[derive(Clone, Copy)]
struct Range {
    first: usize,
    end: usize,
    node: u32,
}

/// The sequentially expanded top of the tree, and the small ranges left for tasks.
struct TopOfTree {
    nodes: Vec<Node>,
    parents: Vec<u32>,
    tasks: Vec<Range>,
}

impl TopOfTree {
    fn expand(codes: &[u64], max_leaf_size: usize) -> Self {
        let mut top = TopOfTree { nodes: vec![Node::default()], parents: vec![NO_PARENT], tasks: Vec::new() };
        let mut stack = vec![Range { first: 0, end: codes.len(), node: 0 }];
        while let Some(r) = stack.pop() {
            let n = r.end - r.first;
            if n <= max_leaf_size {
                top.nodes[r.node as usize] = Node::leaf(Aabb::EMPTY, r.first as u32, n as u32);
            } else if n <= PARALLEL_GRAIN {
                top.tasks.push(r);
            } else {
                let split = find_split(codes, r.first, r.end);
                let child = top.nodes.len() as u32;
                top.nodes[r.node as usize] = Node::interior(Aabb::EMPTY, child);
                top.nodes.extend([Node::default(); 2]);
                top.parents.extend([r.node; 2]);
                stack.push(Range { first: split, end: r.end, node: child + 1 });
                stack.push(Range { first: r.first, end: split, node: child });
            }
        }
        top
    }

    /// Places every task's piece after the top nodes, in task order, relocating its indices.
    fn assemble(mut self, pieces: Vec<Piece>) -> (Vec<Node>, Vec<u32>) {
        let top_len = self.nodes.len();
        let mut offsets = Vec::with_capacity(pieces.len());
        let mut total = top_len;
        for p in &pieces {
            offsets.push(total);
            total += p.nodes.len() - 1;
        }
        self.nodes.resize(total, Node::default());
        self.parents.resize(total, NO_PARENT);
        let (top_nodes, mut rest_nodes) = self.nodes.split_at_mut(top_len);
        let mut rest_parents = &mut self.parents[top_len..];
        let mut slots = Vec::with_capacity(pieces.len());
        for p in &pieces {
            let (n, tail) = std::mem::take(&mut rest_nodes).split_at_mut(p.nodes.len() - 1);
            let (q, tail_p) = std::mem::take(&mut rest_parents).split_at_mut(p.nodes.len() - 1);
            slots.push((n, q));
            rest_nodes = tail;
            rest_parents = tail_p;
        }
        // Task roots live in the top part; write them first (cheap, sequential).
        for ((task, piece), &offset) in self.tasks.iter().zip(&pieces).zip(&offsets) {
            top_nodes[task.node as usize] = piece.relocated(0, task.node, offset);
        }
        slots.into_par_iter().zip(pieces.par_iter()).zip(self.tasks.par_iter().zip(offsets.par_iter())).for_each(
            |(((nodes, parents), piece), (task, &offset))| {
                for i in 1..piece.nodes.len() {
                    nodes[i - 1] = piece.relocated(i, task.node, offset);
                    parents[i - 1] = piece.relocate_index(piece.parents[i], task.node, offset);
                }
            },
        );
        (self.nodes, self.parents)
    }
}

/// A subtree built by one task with local indices: its root at 0, the rest after.
struct Piece {
    nodes: Vec<Node>,
    parents: Vec<u32>,
}

impl Piece {
    fn build(codes: &[u64], first: usize, end: usize, max_leaf_size: usize) -> Piece {
        let capacity = 2 * (end - first).div_ceil(max_leaf_size.max(1)) + 1;
        let mut piece = Piece { nodes: Vec::with_capacity(capacity), parents: Vec::with_capacity(capacity) };
        piece.nodes.push(Node::default());
        piece.parents.push(NO_PARENT);
        let mut stack = vec![(first, end, 0u32)];
        while let Some((first, end, node)) = stack.pop() {
            let n = end - first;
            if n <= max_leaf_size {
                piece.nodes[node as usize] = Node::leaf(Aabb::EMPTY, first as u32, n as u32);
                continue;
            }
            let split = find_split(codes, first, end);
            let child = piece.nodes.len() as u32;
            piece.nodes[node as usize] = Node::interior(Aabb::EMPTY, child);
            piece.nodes.extend([Node::default(); 2]);
            piece.parents.extend([node; 2]);
            stack.push((split, end, child + 1));
            stack.push((first, split, child));
        }
        piece
    }

    /// Local index → global: the root is the task's node, the others follow `offset`.
    #[inline]
    fn relocate_index(&self, local: u32, root: u32, offset: usize) -> u32 {
        if local == 0 {
            root
        } else {
            (offset + local as usize - 1) as u32
        }
    }

    fn relocated(&self, i: usize, root: u32, offset: usize) -> Node {
        let mut n = self.nodes[i];
        if !n.is_leaf() {
            n.first = self.relocate_index(n.first, root, offset);
        }
        n
    }
}

/// The first index of the right half of `[first, end)`: where the highest bit that differs
/// between the first and last code flips from 0 to 1; the middle for identical codes.
pub fn find_split(codes: &[u64], first: usize, end: usize) -> usize {
    let first_code = codes[first];
    let last_code = codes[end - 1];
    if first_code == last_code {
        return (first + end) / 2;
    }
    let common_prefix = (first_code ^ last_code).leading_zeros();
    // Binary search for the last index whose code shares more than `common_prefix` bits
    // with the first code.
    let (mut lo, mut hi) = (first, end - 1); // invariant: lo shares more, hi does not
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if (first_code ^ codes[mid]).leading_zeros() > common_prefix {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hi
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_at_highest_differing_bit() {
        let codes = [0b0001, 0b0010, 0b0100, 0b0101, 0b1000];
        assert_eq!(find_split(&codes, 0, 5), 4);
        assert_eq!(find_split(&codes, 0, 4), 2);
        assert_eq!(find_split(&codes, 0, 2), 1);
        let same = [7u64; 6];
        assert_eq!(find_split(&same, 0, 6), 3);
        assert_eq!(find_split(&same, 1, 3), 2);
    }
}
