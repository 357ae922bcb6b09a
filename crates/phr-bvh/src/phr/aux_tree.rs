//! The auxiliary tree PHR refines: the full binary radix tree of the primitives' Morton codes
//! (an LBVH with one primitive per leaf, thesis section 4.1), in a layout made for the two
//! things done with it: opening nodes during PHR, and refitting it every frame of a dynamic
//! scene.
//!
//! - **Siblings share a cache line.** The two children of a node are one `AuxPair` of
//!   64 bytes, aligned: opening a node reads one line. A node carries its primitive count,
//!   which is all PHR needs besides the box (the thesis's auxiliary-node weight is
//!   `2·prims − 1` in a full binary tree), so there is no second array to miss in.
//! - **Leaves hold their primitive.** A leaf is a node with `prims == 1` whose `first` is
//!   the primitive's index: no index array, no second walk.
//! - **Refit without atomics.** A tree of `n` primitives has exactly `n` pairs (the root's,
//!   and one per interior node). The top of the tree is expanded sequentially; each remaining
//!   range of `m` primitives is a task that owns the next `m − 1` pairs, known in advance, so
//!   tasks write their final place directly. Children always come after their parent, so a
//!   reverse sweep over a task's pairs refits its subtree, tasks in parallel, and a reverse
//!   sweep over the top finishes the job: every box written once, memory read in order.

use crate::aabb::Aabb;
use crate::lbvh::{find_split, sorted_morton_codes};
use crate::node::{Bvh, Node};
use rayon::prelude::*;

/// Ranges of at most this many primitives are built and refit by one task.
const TASK_GRAIN: usize = 1 << 12;

/// A node of the auxiliary tree.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct AuxNode {
    pub bounds: Aabb,
    /// Interior node: the id of its first child (even; the second child is `first + 1`).
    /// Leaf: its primitive.
    pub first: u32,
    /// Primitives under the node: 1 for a leaf, at least 2 for an interior node.
    pub prims: u32,
}

impl AuxNode {
    const EMPTY: AuxNode = AuxNode { bounds: Aabb::EMPTY, first: 0, prims: 0 };

    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.prims <= 1
    }
}

/// Two sibling nodes in one cache line.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
struct AuxPair([AuxNode; 2]);

impl AuxPair {
    const EMPTY: AuxPair = AuxPair([AuxNode::EMPTY; 2]);
}

/// A range of primitives built (and refit) by one task: its root node (in the top part) and
/// the pairs it owns.
#[derive(Clone, Copy, Debug)]
struct Task {
    first_prim: usize,
    end_prim: usize,
    root: u32,
    first_pair: usize,
}

/// The auxiliary tree: node `id` is `pairs[id / 2].0[id % 2]`; the root is node 0 (its
/// pair's other slot is unused).
#[derive(Clone, Debug, Default)]
pub struct AuxTree {
    pairs: Vec<AuxPair>,
    /// Pairs `[0, top_pairs)` belong to the sequentially built top.
    top_pairs: usize,
    tasks: Vec<Task>,
}

impl AuxTree {
    /// Builds the radix tree over the primitives' boxes (Morton codes of their centres) and
    /// fits its boxes.
    pub fn build(boxes: &[Aabb]) -> Self {
        if boxes.is_empty() {
            return Self::default();
        }
        let pairs = sorted_morton_codes(boxes);
        let (codes, order): (Vec<u64>, Vec<u32>) = pairs.into_par_iter().unzip();
        Self::build_sorted(&codes, &order, boxes)
    }

    /// The tree over the sorted codes and their primitives, boxes fitted: each task fits its
    /// own subtree right after building it, while its pairs are still in the cache.
    fn build_sorted(codes: &[u64], order: &[u32], boxes: &[Aabb]) -> Self {
        let n = codes.len();
        // Filled on both cores: `vec!` writes the 64 bytes of each of the n pairs (56 MB for
        // the dragon) on one thread, taking their pages' first-touch faults there too.
        let mut pairs = Vec::with_capacity(n);
        (0..n).into_par_iter().map(|_| AuxPair::EMPTY).collect_into_vec(&mut pairs);
        let mut tasks = Vec::new();
        let mut next_pair = 1usize;
        // The top: ranges larger than a task are split here, in order.
        let mut stack = vec![(0usize, n, 0u32)];
        while let Some((first, end, id)) = stack.pop() {
            let m = end - first;
            if m == 1 {
                *node_mut(&mut pairs, id) = AuxNode { bounds: Aabb::EMPTY, first: order[first], prims: 1 };
            } else if m <= TASK_GRAIN {
                tasks.push(Task { first_prim: first, end_prim: end, root: id, first_pair: 0 });
            } else {
                let split = find_split(codes, first, end);
                let child = 2 * next_pair as u32;
                next_pair += 1;
                *node_mut(&mut pairs, id) = AuxNode { bounds: Aabb::EMPTY, first: child, prims: m as u32 };
                stack.push((split, end, child + 1));
                stack.push((first, split, child));
            }
        }
        let top_pairs = next_pair;
        // Each task's range of m primitives has m - 1 interior nodes, one pair each.
        for t in &mut tasks {
            t.first_pair = next_pair;
            next_pair += t.end_prim - t.first_prim - 1;
        }
        debug_assert_eq!(next_pair, n.max(1));
        for t in &tasks {
            let m = (t.end_prim - t.first_prim) as u32;
            *node_mut(&mut pairs, t.root) = AuxNode { bounds: Aabb::EMPTY, first: 2 * t.first_pair as u32, prims: m };
        }
        task_pairs(&mut pairs, top_pairs, &tasks).into_par_iter().with_max_len(1).for_each(|(t, own)| {
            build_task(codes, order, t, own);
            refit_backwards(own, t.first_pair, own.len(), boxes);
        });
        refit_backwards(&mut pairs, 0, top_pairs, boxes);
        Self { pairs, top_pairs, tasks }
    }

    /// Recomputes every box from the primitives' current `boxes` (same primitives, moved):
    /// the topology stays. Tasks sweep their pairs backwards in parallel, then the top.
    pub fn refit(&mut self, boxes: &[Aabb]) {
        if self.pairs.is_empty() {
            return;
        }
        task_pairs(&mut self.pairs, self.top_pairs, &self.tasks)
            .into_par_iter()
            .with_max_len(1)
            .for_each(|(t, own)| refit_backwards(own, t.first_pair, own.len(), boxes));
        refit_backwards(&mut self.pairs, 0, self.top_pairs, boxes);
    }

    /// Number of nodes (`2n − 1` for `n` primitives).
    pub fn node_count(&self) -> usize {
        (2 * self.pairs.len()).saturating_sub(1)
    }

    /// Number of primitives.
    pub fn prim_count(&self) -> usize {
        self.pairs.len()
    }

    /// The root (`None` for an empty tree).
    pub fn root(&self) -> Option<&AuxNode> {
        self.pairs.first().map(|p| &p.0[0])
    }

    /// The two children of an interior node, read together (one cache line).
    #[inline(always)]
    pub fn children(&self, node: &AuxNode) -> &[AuxNode; 2] {
        debug_assert!(!node.is_leaf());
        &self.pairs[(node.first >> 1) as usize].0
    }

    /// Asks for the children of `node` to be loaded into the cache (a hint; nothing for a
    /// leaf).
    #[inline(always)]
    pub fn prefetch_children(&self, node: &AuxNode) {
        #[cfg(target_arch = "x86_64")]
        if !node.is_leaf() {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let p = self.pairs.as_ptr().wrapping_add((node.first >> 1) as usize).cast::<i8>();
            // SAFETY: prefetching is a hint and never faults, whatever the address.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p) };
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = node;
    }

    /// The same tree as a [`Bvh`] (one primitive per leaf), for validation and statistics.
    pub fn to_bvh(&self) -> Bvh {
        let Some(root) = self.root() else { return Bvh::default() };
        let mut bvh = Bvh { nodes: vec![Node::default()], prim_indices: Vec::new(), parents: Vec::new() };
        let mut stack = vec![(*root, 0usize)];
        while let Some((n, slot)) = stack.pop() {
            if n.is_leaf() {
                bvh.nodes[slot] = Node::leaf(n.bounds, bvh.prim_indices.len() as u32, 1);
                bvh.prim_indices.push(n.first);
            } else {
                let first = bvh.nodes.len();
                bvh.nodes[slot] = Node::interior(n.bounds, first as u32);
                bvh.nodes.extend([Node::default(); 2]);
                let [a, b] = *self.children(&n);
                stack.push((b, first + 1));
                stack.push((a, first));
            }
        }
        bvh.compute_parents();
        bvh
    }
}

#[inline(always)]
fn node_mut(pairs: &mut [AuxPair], id: u32) -> &mut AuxNode {
    &mut pairs[(id >> 1) as usize].0[(id & 1) as usize]
}

/// Builds a task's subtree into the pairs it owns (`own[0]` is pair `t.first_pair`), depth
/// first, as the top does.
fn build_task(codes: &[u64], order: &[u32], t: &Task, own: &mut [AuxPair]) {
    let base = t.first_pair;
    let split = find_split(codes, t.first_prim, t.end_prim);
    let mut next = 1usize;
    let mut stack = vec![(split, t.end_prim, 2 * base as u32 + 1), (t.first_prim, split, 2 * base as u32)];
    while let Some((first, end, id)) = stack.pop() {
        let m = end - first;
        let node = &mut own[(id >> 1) as usize - base].0[(id & 1) as usize];
        if m == 1 {
            *node = AuxNode { bounds: Aabb::EMPTY, first: order[first], prims: 1 };
            continue;
        }
        let split = find_split(codes, first, end);
        let child = 2 * (base + next) as u32;
        next += 1;
        *node = AuxNode { bounds: Aabb::EMPTY, first: child, prims: m as u32 };
        stack.push((split, end, child + 1));
        stack.push((first, split, child));
    }
    debug_assert_eq!(next, own.len());
}

/// Each task with the pairs it owns: the pairs after the top, in task order.
fn task_pairs<'a>(pairs: &'a mut [AuxPair], top_pairs: usize, tasks: &'a [Task]) -> Vec<(&'a Task, &'a mut [AuxPair])> {
    let mut rest = &mut pairs[top_pairs..];
    tasks
        .iter()
        .map(|t| {
            let (own, tail) = std::mem::take(&mut rest).split_at_mut(t.end_prim - t.first_prim - 1);
            rest = tail;
            (t, own)
        })
        .collect()
}

/// Refits the first `count` pairs of `pairs` (whose first element is pair `first_pair`),
/// backwards: the children of their interior nodes lie in `pairs`, after them. A task refits
/// the pairs it owns; the top (pairs `[0, top_pairs)`) is refit last, its children being in
/// the top or in the tasks' pairs.
fn refit_backwards(pairs: &mut [AuxPair], first_pair: usize, count: usize, boxes: &[Aabb]) {
    for q in (0..count).rev() {
        for s in 0..2 {
            let n = pairs[q].0[s];
            pairs[q].0[s].bounds = match n.prims {
                // The root pair's unused slot.
                0 => continue,
                1 => boxes[n.first as usize],
                _ => {
                    let [a, b] = &pairs[(n.first >> 1) as usize - first_pair].0;
                    a.bounds.union(b.bounds)
                }
            };
        }
    }
}
