//! The LBVH, "linear BVH" (Lauterbach et al. 2009; Karras 2012 for the radix-tree split;
//! thesis section 4.1): the fast, lower-quality builder, and the auxiliary tree PHR refines.
//!
//! 1. Morton codes of the primitive centroids, quantised to the centroid bounds (parallel).
//! 2. A parallel radix sort of (code, primitive) pairs ([`crate::radix_sort`]).
//! 3. The binary radix tree, top down: a range of sorted codes is split where its highest
//!    differing bit flips (found by binary search); a run of identical codes is split in the
//!    middle, by count. Subtrees are built as rayon tasks. A range of `n` primitives always
//!    owns exactly `2n - 1` nodes, so each task gets its own disjoint slice of the node array
//!    up front (`split_at_mut`): no allocation, no atomics, no locks, and the layout is the
//!    same whatever the thread count.
//! 4. Bounds bottom up, in parallel, with one atomic counter per node ([`crate::refit`]).
//! 5. If leaves of more than one primitive are asked for, subtrees of at most that many
//!    primitives are collapsed into leaves ([`crate::collapse`]).
//!
//! The result with `max_leaf_size == 1` is the full radix tree (one primitive per leaf), the
//! auxiliary hierarchy PHR starts from.

use crate::aabb::Aabb;
use crate::collapse::collapse_small_subtrees;
use crate::morton::MortonQuantizer;
use crate::node::{Bvh, Node, NO_PARENT};
use crate::radix_sort::radix_sort_pairs;
use crate::refit::refit;
use rayon::prelude::*;

/// Ranges smaller than this are built sequentially inside one task.
const PARALLEL_GRAIN: usize = 1 << 12;

#[derive(Clone, Copy, Debug)]
pub struct LbvhOptions {
    /// Subtrees with at most this many primitives become one leaf (1 = the full radix tree).
    pub max_leaf_size: u32,
}

impl Default for LbvhOptions {
    fn default() -> Self {
        Self { max_leaf_size: 4 }
    }
}

/// Builds an LBVH over primitives given by their bounding boxes.
pub fn build_lbvh(boxes: &[Aabb], options: LbvhOptions) -> Bvh {
    let mut bvh = build_radix_tree(boxes);
    refit(&mut bvh, boxes);
    if options.max_leaf_size > 1 {
        bvh = collapse_small_subtrees(&bvh, options.max_leaf_size);
    }
    bvh
}

/// Steps 1–3: the topology of the full radix tree (bounds are left empty).
pub fn build_radix_tree(boxes: &[Aabb]) -> Bvh {
    let n = boxes.len();
    if n == 0 {
        return Bvh::default();
    }
    let pairs = sorted_morton_codes(boxes);
    let codes: Vec<u64> = pairs.par_iter().map(|p| p.0).collect();
    let prim_indices: Vec<u32> = pairs.par_iter().map(|p| p.1).collect();

    let node_count = 2 * n - 1;
    let mut nodes = vec![Node::default(); node_count];
    let mut parents = vec![NO_PARENT; node_count];
    let (root, descendants) = nodes.split_at_mut(1);
    let (_, descendant_parents) = parents.split_at_mut(1);
    let task = Subtree { codes: &codes, first: 0, end: n, index: 0 };
    task.build(&mut root[0], descendants, descendant_parents, 1);
    Bvh { nodes, prim_indices, parents }
}

/// Morton codes of the box centres, sorted, paired with their primitive index.
fn sorted_morton_codes(boxes: &[Aabb]) -> Vec<(u64, u32)> {
    let centroid_bounds = boxes.par_iter().map(|b| Aabb::EMPTY.grown(b.center())).reduce(|| Aabb::EMPTY, Aabb::union);
    let quantizer = MortonQuantizer::new(&centroid_bounds);
    let mut pairs: Vec<(u64, u32)> =
        boxes.par_iter().enumerate().map(|(i, b)| (quantizer.code(b.center()), i as u32)).collect();
    radix_sort_pairs(&mut pairs, 63);
    pairs
}

/// A range `[first, end)` of sorted codes whose node sits at `index`.
struct Subtree<'a> {
    codes: &'a [u64],
    first: usize,
    end: usize,
    index: u32,
}

impl Subtree<'_> {
    /// Writes this range's node into `slot`, its children into `descendants[0..2]` (node
    /// indices `base` and `base + 1`), and their subtrees after them: `2 nl - 2` slots for the
    /// left one, then the right one's. `parents` is aligned with `descendants`.
    fn build(&self, slot: &mut Node, descendants: &mut [Node], parents: &mut [u32], base: u32) {
        let n = self.end - self.first;
        if n == 1 {
            *slot = Node::leaf(Aabb::EMPTY, self.first as u32, 1);
            return;
        }
        let split = find_split(self.codes, self.first, self.end);
        *slot = Node::interior(Aabb::EMPTY, base);
        parents[0] = self.index;
        parents[1] = self.index;
        let left_len = split - self.first;
        let (children, rest) = descendants.split_at_mut(2);
        let (_, rest_parents) = parents.split_at_mut(2);
        let (left_desc, right_desc) = rest.split_at_mut(2 * left_len - 2);
        let (left_par, right_par) = rest_parents.split_at_mut(2 * left_len - 2);
        let (left_slot, right_slot) = children.split_at_mut(1);
        let left = Subtree { codes: self.codes, first: self.first, end: split, index: base };
        let right = Subtree { codes: self.codes, first: split, end: self.end, index: base + 1 };
        let left_base = base + 2;
        let right_base = left_base + (2 * left_len - 2) as u32;
        let (left_slot, right_slot) = (&mut left_slot[0], &mut right_slot[0]);
        if n >= PARALLEL_GRAIN {
            rayon::join(
                || left.build(left_slot, left_desc, left_par, left_base),
                || right.build(right_slot, right_desc, right_par, right_base),
            );
        } else {
            left.build(left_slot, left_desc, left_par, left_base);
            right.build(right_slot, right_desc, right_par, right_base);
        }
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
