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
//! Leaves are not split or merged. Wide nodes are stored depth-first, the children of a node
//! consecutively; leaf primitives are renumbered in the order the leaves are written, so each
//! leaf is a contiguous range of [`super::WideBvh::prim_indices`].

use super::WideNode;
use crate::aabb::Aabb;
use crate::node::Bvh;

/// A node of the binary view: a leaf (`count > 0`, a range of the source's `prim_indices`)
/// or an interior node with children `a` and `b`.
#[derive(Clone, Copy, Debug)]
struct Bin {
    bounds: Aabb,
    area: f32,
    a: u32,
    b: u32,
    first: u32,
    count: u32,
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
fn binary_view(src: &Bvh) -> Vec<Bin> {
    let placeholder = Bin { bounds: Aabb::EMPTY, area: 0.0, a: 0, b: 0, first: 0, count: 0 };
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
        bins[slot] = Bin { bounds, area: bounds.surface_area(), a: a as u32, b: b as u32, first: 0, count: 0 };
        work.push((right, b));
        work.push((left, a));
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
pub(crate) fn collapse<const N: usize>(src: &Bvh) -> (Vec<WideNode<N>>, Vec<u32>, usize) {
    assert!(N >= 2, "a wide node needs at least two slots");
    if src.nodes.is_empty() {
        return (Vec::new(), Vec::new(), 0);
    }
    let bins = binary_view(src);
    let mut nodes = Vec::with_capacity(src.nodes.len() / (N - 1) + 1);
    nodes.push(WideNode::<N>::EMPTY);
    let mut prims = Vec::with_capacity(src.prim_indices.len());
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
                node.child[slot] = prims.len() as u32;
                node.count[slot] = kid_bin.count;
                let range = kid_bin.first as usize..(kid_bin.first + kid_bin.count) as usize;
                prims.extend_from_slice(&src.prim_indices[range]);
            } else {
                node.child[slot] = nodes.len() as u32;
                work.push((kid, nodes.len(), depth));
                nodes.push(WideNode::<N>::EMPTY);
            }
        }
        nodes[w] = node;
    }
    (nodes, prims, bound)
}
