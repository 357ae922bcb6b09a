//! From a [`Bvh`] (binary or k-ary) to a [`WideNode`] array.
//!
//! 1. **Binary view.** Binary nodes and leaves are taken as they are. A node with `k > 2`
//!    children (PHR's multi-BVHs) is regrouped into a binary subtree over those children:
//!    recursively, the children are split in two by a SAH sweep (each axis, children sorted
//!    by box centre, cost `A(left)·|left| + A(right)·|right|`, the cheapest split wins).
//! 2. **Greedy collapse** (the rule of Embree's BVH4/BVH8 builders and tinybvh's converters):
//!    a wide node starts with the two children of a binary node; while it has fewer than `N`
//!    children and one of them is interior, the interior child with the largest surface area
//!    (the one a random ray is most likely to enter) is replaced by its two children. The
//!    node's slots then get the resulting boxes; interior ones become wide nodes in turn.
//!
//! 3. **Leaves.** A subtree with at most [`CollapseOptions::merge_leaves`] primitives becomes
//!    one leaf (as Embree's leaves of 4 triangles: [`super::PackedTriangles`] tests 4
//!    triangles with one SIMD Möller–Trumbore, so a leaf of 4 costs about what a leaf of 1
//!    does, and the nodes above the small leaves disappear). Larger source leaves are kept.
//!
//! Wide nodes are stored depth-first, the children of a node consecutively; leaf primitives
//! are renumbered in the order the leaves are written, so each leaf is a contiguous range of
//! [`super::WideBvh::prim_indices`]. Each leaf starts at a multiple of
//! [`CollapseOptions::leaf_align`] (the gaps hold [`PAD`]), so a leaf of up to 4 triangles is
//! one 4-lane block of the packed triangles.

use super::{WideNode, PAD};
use crate::aabb::Aabb;
use crate::node::Bvh;

/// A node of the binary view: a leaf (`count > 0`, a range of the source's `prim_indices`)
/// or an interior node with children `a` and `b`.
/// How to collapse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CollapseOptions {
    /// Subtrees with at most this many primitives become one leaf (1: keep the source's).
    pub merge_leaves: u32,
    /// Leaves start at multiples of this in `prim_indices` (1: no padding).
    pub leaf_align: u32,
}

impl Default for CollapseOptions {
    /// Leaves of up to 4 primitives, aligned to the 4-lane triangle blocks.
    fn default() -> Self {
        Self { merge_leaves: 4, leaf_align: super::triangles::LANES as u32 }
    }
}

impl CollapseOptions {
    /// Keep the source tree's leaves, no padding.
    pub const KEEP_LEAVES: CollapseOptions = CollapseOptions { merge_leaves: 1, leaf_align: 1 };
}

#[derive(Clone, Copy, Debug)]
struct Bin {
    bounds: Aabb,
    area: f32,
    a: u32,
    b: u32,
    first: u32,
    count: u32,
    /// Primitives in the subtree.
    prims: u32,
}

impl Bin {
    fn is_leaf(&self) -> bool {
        self.count > 0
    }
}

/// Work items of the binary view's construction: a source node, or a group of sibling
/// source nodes to regroup, each writing the binary node at `slot`.
enum Task {
    Node(u32),
    Group(Vec<u32>),
}

/// The binary view of `src`, root at index 0.
fn binary_view(src: &Bvh, scratch: Vec<Bin>) -> Vec<Bin> {
    if src.max_branching() <= 2 {
        return binary_view_of_binary(src, scratch);
    }
    let placeholder = Bin { bounds: Aabb::EMPTY, area: 0.0, a: 0, b: 0, first: 0, count: 0, prims: 0 };
    let mut bins = Vec::with_capacity(src.nodes.len() + src.nodes.len() / 2);
    bins.push(placeholder);
    let mut work = vec![(Task::Node(0), 0usize)];
    let new_bin = |bins: &mut Vec<Bin>| {
        bins.push(placeholder);
        bins.len() - 1
    };
    while let Some((task, slot)) = work.pop() {
        let (bounds, children) = match task {
            Task::Node(i) => {
                let n = &src.nodes[i as usize];
                if n.is_leaf() {
                    bins[slot] = Bin {
                        bounds: n.bounds,
                        area: n.bounds.surface_area(),
                        a: 0,
                        b: 0,
                        first: n.first,
                        count: n.count,
                        prims: n.count,
                    };
                    continue;
                }
                if n.child_count() == 2 {
                    (n.bounds, [Task::Node(n.first), Task::Node(n.first + 1)])
                } else {
                    let (left, right) = sah_split(src, n.children().collect());
                    (n.bounds, [left, right])
                }
            }
            Task::Group(members) => {
                let bounds = members.iter().fold(Aabb::EMPTY, |b, &m| b.union(src.nodes[m as usize].bounds));
                let (left, right) = sah_split(src, members);
                (bounds, [left, right])
            }
        };
        let [left, right] = children;
        let (a, b) = (new_bin(&mut bins), new_bin(&mut bins));
        bins[slot] =
            Bin { bounds, area: bounds.surface_area(), a: a as u32, b: b as u32, first: 0, count: 0, prims: 0 };
        work.push((right, b));
        work.push((left, a));
    }
    // Children come after their parents: count primitives bottom-up.
    for i in (0..bins.len()).rev() {
        if !bins[i].is_leaf() {
            bins[i].prims = bins[bins[i].a as usize].prims + bins[bins[i].b as usize].prims;
        }
    }
    bins
}

/// Appends the primitives of the subtree at `b` (in tree order) to `out`.
fn subtree_prims(bins: &[Bin], src: &Bvh, b: u32, out: &mut Vec<u32>) {
    let mut stack = vec![b];
    while let Some(i) = stack.pop() {
        let bin = &bins[i as usize];
        if bin.is_leaf() {
            out.extend_from_slice(&src.prim_indices[bin.first as usize..(bin.first + bin.count) as usize]);
        } else {
            stack.push(bin.b);
            stack.push(bin.a);
        }
    }
}

/// The binary view of a binary tree: the same nodes at the same indices (children always
/// follow their parent, so one backward pass counts the primitives).
fn binary_view_of_binary(src: &Bvh, mut bins: Vec<Bin>) -> Vec<Bin> {
    use rayon::prelude::*;
    bins.clear();
    src.nodes
        .par_iter()
        .map(|n| {
            let (first, count) = if n.is_leaf() { (n.first, n.count) } else { (0, 0) };
            Bin {
                bounds: n.bounds,
                area: n.bounds.surface_area(),
                a: n.first,
                b: n.first + 1,
                first,
                count,
                prims: count,
            }
        })
        .collect_into_vec(&mut bins);
    for i in (0..bins.len()).rev() {
        if !bins[i].is_leaf() {
            bins[i].prims = bins[bins[i].a as usize].prims + bins[bins[i].b as usize].prims;
        }
    }
    bins
}

/// Splits at least two sibling source nodes into two non-empty groups by a SAH sweep; a
/// group of one becomes that node.
fn sah_split(src: &Bvh, mut members: Vec<u32>) -> (Task, Task) {
    debug_assert!(members.len() >= 2);
    let bounds = |m: u32| src.nodes[m as usize].bounds;
    let weight = |m: u32| src.nodes[m as usize].prim_count().max(1) as f32;
    let mut best: (f32, usize, usize) = (f32::INFINITY, 0, 1);
    let n = members.len();
    for axis in 0..3 {
        members.sort_by(|&x, &y| bounds(x).center()[axis].total_cmp(&bounds(y).center()[axis]));
        let mut right_cost = vec![0.0f32; n];
        let (mut b, mut w) = (Aabb::EMPTY, 0.0);
        for i in (1..n).rev() {
            b = b.union(bounds(members[i]));
            w += weight(members[i]);
            right_cost[i] = b.surface_area() * w;
        }
        let (mut b, mut w) = (Aabb::EMPTY, 0.0);
        for i in 1..n {
            b = b.union(bounds(members[i - 1]));
            w += weight(members[i - 1]);
            let cost = b.surface_area() * w + right_cost[i];
            if cost < best.0 {
                best = (cost, axis, i);
            }
        }
    }
    let (_, axis, split) = best;
    members.sort_by(|&x, &y| bounds(x).center()[axis].total_cmp(&bounds(y).center()[axis]));
    let right = members.split_off(split);
    let task = |g: Vec<u32>| if g.len() == 1 { Task::Node(g[0]) } else { Task::Group(g) };
    (task(members), task(right))
}

/// Collapses `src` into `N`-wide nodes; returns the nodes, the primitive indices in leaf
/// order and the traversal stack bound (the largest number of entries the ordered traversal
/// can have on its stack: along any root-to-node path, the sum of `children - 1`).
/// `nodes` and `prims` are cleared and filled: passing the previous frame's arrays reuses
/// their memory (fresh arrays of tens of MB cost more in page faults than the collapse).
pub(crate) fn collapse<const N: usize>(
    src: &Bvh,
    options: CollapseOptions,
    mut nodes: Vec<WideNode<N>>,
    mut prims: Vec<u32>,
) -> (Vec<WideNode<N>>, Vec<u32>, usize) {
    assert!(N >= 2, "a wide node needs at least two slots");
    let align = options.leaf_align.max(1) as usize;
    nodes.clear();
    prims.clear();
    if src.nodes.is_empty() {
        return (nodes, prims, 0);
    }
    // The binary view's memory is kept per thread from one collapse to the next (a dynamic
    // scene collapses every frame).
    thread_local! {
        static SCRATCH: std::cell::Cell<Vec<Bin>> = const { std::cell::Cell::new(Vec::new()) };
    }
    let mut bins = binary_view(src, SCRATCH.take());
    // Small subtrees become leaves: mark them (count > 0) and remember where their
    // primitives are, in a second reference array.
    let mut merged: Vec<u32> = Vec::new();
    let merged_base = src.prim_indices.len() as u32;
    if options.merge_leaves > 1 {
        let mut stack = vec![0u32];
        while let Some(i) = stack.pop() {
            let bin = bins[i as usize];
            if bin.is_leaf() {
                continue;
            }
            if bin.prims <= options.merge_leaves {
                let first = merged.len() as u32;
                subtree_prims(&bins, src, i, &mut merged);
                bins[i as usize].first = merged_base + first;
                bins[i as usize].count = bin.prims;
            } else {
                stack.push(bin.a);
                stack.push(bin.b);
            }
        }
    }
    let refs = |first: u32, count: u32| -> &[u32] {
        if first >= merged_base {
            &merged[(first - merged_base) as usize..(first - merged_base + count) as usize]
        } else {
            &src.prim_indices[first as usize..(first + count) as usize]
        }
    };
    nodes.reserve(src.nodes.len() / (N - 1) + 1);
    nodes.push(WideNode::<N>::EMPTY);
    prims.reserve(src.prim_indices.len());
    let mut bound = 0;
    // (binary node whose children fill the wide node, wide node, stack depth above it)
    let mut work = vec![(0u32, 0usize, 0usize)];
    while let Some((b, w, depth)) = work.pop() {
        let mut kids = [0u32; N];
        let mut k;
        let bin = &bins[b as usize];
        if bin.is_leaf() {
            // Only for a tree that is a single leaf: the root holds it in slot 0.
            kids[0] = b;
            k = 1;
        } else {
            kids[0] = bin.a;
            kids[1] = bin.b;
            k = 2;
            while k < N {
                let open = (0..k)
                    .filter(|&i| !bins[kids[i] as usize].is_leaf())
                    .max_by(|&i, &j| bins[kids[i] as usize].area.total_cmp(&bins[kids[j] as usize].area));
                let Some(i) = open else { break };
                let opened = bins[kids[i] as usize];
                kids[i] = opened.a;
                kids[k] = opened.b;
                k += 1;
            }
        }
        let depth = depth + k - 1;
        bound = bound.max(depth);
        let mut node = WideNode::<N>::EMPTY;
        for (slot, &kid) in kids[..k].iter().enumerate() {
            let kid_bin = &bins[kid as usize];
            node.set_child_bounds(slot, kid_bin.bounds);
            if kid_bin.is_leaf() {
                prims.resize(prims.len().next_multiple_of(align), PAD);
                node.child[slot] = prims.len() as u32;
                node.count[slot] = kid_bin.count;
                prims.extend_from_slice(refs(kid_bin.first, kid_bin.count));
            } else {
                node.child[slot] = nodes.len() as u32;
                work.push((kid, nodes.len(), depth));
                nodes.push(WideNode::<N>::EMPTY);
            }
        }
        nodes[w] = node;
    }
    SCRATCH.set(bins);
    (nodes, prims, bound)
}
