//! From a [`Bvh`] (binary or k-ary) to a [`WideNode`] array.
//!
//! 1. **View.** A tree whose nodes have at most `N` children (binary trees, PHR's multi-BVHs
//!    up to `k = N`) is taken as it is. In a wider tree every node is regrouped into a binary
//!    subtree over its children: recursively, the children are split in two by a SAH sweep
//!    (each axis, children sorted by box centre, cost `A(left)·|left| + A(right)·|right|`,
//!    the cheapest split wins).
//! 2. **Greedy collapse** (the rule of Embree's BVH4/BVH8 builders and tinybvh's converters):
//!    a wide node starts with the children of a node of the view; while an interior child's
//!    children fit in the remaining slots, the interior child with the largest surface area
//!    (the one a random ray is most likely to enter) is replaced by its children. The
//!    node's slots then get the resulting boxes; interior ones become wide nodes in turn.
//!    PHR's k = 8 nodes thus map to wide nodes one to one. Measured against regrouping them
//!    first (2 threads): the dragon's PHR-Fast k = 8 tree collapses in 40 ms instead of
//!    76 ms; diffuse rays trace within ±6 % (Sponza PHR-Fast +4 %, PHR-HQ −6 %; Conference
//!    PHR-HQ −3.5 %; the dragon equal).
//!
//! 3. **Leaves.** A subtree with at most [`CollapseOptions::merge_leaves`] primitives becomes
//!    one leaf (as Embree's leaves of 4 triangles: [`super::PackedTriangles`] tests 4
//!    triangles with one SIMD Möller–Trumbore, so a leaf of 4 costs about what a leaf of 1
//!    does, and the nodes above the small leaves disappear). Larger source leaves are kept.
//!
//! 4. **In parallel near the root.** While a subtree holds more than `PIECE_GRAIN`
//!    primitives, the interior slots of its wide node are collapsed as separate rayon tasks;
//!    smaller subtrees are collapsed by one task each, depth first, into a piece with local
//!    indices. The top nodes are laid out first, the pieces after them (copied in parallel,
//!    indices relocated), in an order that does not depend on the thread count. A dynamic
//!    scene collapses every frame, so this is on its critical path.
//!
//! Within a piece, wide nodes are stored depth-first, the children of a node consecutively;
//! leaf primitives are renumbered in the order the leaves are written, so each leaf is a
//! contiguous range of [`super::WideBvh::prim_indices`]. No leaf of up to 4 triangles crosses
//! a boundary of the packed triangles' 4-lane blocks ([`CollapseOptions::leaf_align`]; the
//! gaps hold [`super::PAD`]), so it is one SIMD test; small leaves share blocks.

use super::pieces::{assemble, build_piece, place_leaf, slots_by_size, WideBuilt, WidePiece};
use super::WideNode;
use crate::aabb::Aabb;
use crate::node::Bvh;

/// How to collapse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CollapseOptions {
    /// Subtrees with at most this many primitives become one leaf (1: keep the source's).
    pub merge_leaves: u32,
    /// Blocks of this many entries in `prim_indices` that a leaf crosses no more of than it
    /// must: a leaf of at most this many primitives lies within one, a larger one starts
    /// one (1: no padding).
    pub leaf_align: u32,
}

impl Default for CollapseOptions {
    /// Leaves of up to 4 primitives, each within one 4-lane triangle block.
    fn default() -> Self {
        Self { merge_leaves: 4, leaf_align: super::triangles::LANES as u32 }
    }
}

impl CollapseOptions {
    /// Keep the source tree's leaves, no padding.
    pub const KEEP_LEAVES: CollapseOptions = CollapseOptions { merge_leaves: 1, leaf_align: 1 };
}

/// A node of the binary view: a leaf (`count > 0`, a range of the source's `prim_indices`)
/// or an interior node with children `a` and `b`.
#[derive(Clone, Copy, Debug)]
struct Bin {
    bounds: Aabb,
    area: f32,
    /// Interior: the first child; the others follow it.
    child: u32,
    /// Interior: the number of children.
    kids: u32,
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

/// The view of `src` the collapse works on, root at index 0: `src` itself when no node has
/// more than `width` children, else its binary regrouping.
fn view(src: &Bvh, scratch: Vec<Bin>, width: usize) -> Vec<Bin> {
    if src.max_branching() as usize <= width {
        return direct_view(src, scratch);
    }
    let placeholder = Bin { bounds: Aabb::EMPTY, area: 0.0, child: 0, kids: 0, first: 0, count: 0, prims: 0 };
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
                        child: 0,
                        kids: 0,
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
            Bin { bounds, area: bounds.surface_area(), child: a as u32, kids: 2, first: 0, count: 0, prims: 0 };
        work.push((right, b));
        work.push((left, a));
    }
    count_prims(&mut bins);
    bins
}

/// Primitives per subtree, bottom-up (children always come after their parents).
fn count_prims(bins: &mut [Bin]) {
    for i in (0..bins.len()).rev() {
        if !bins[i].is_leaf() {
            let (c, k) = (bins[i].child as usize, bins[i].kids as usize);
            bins[i].prims = bins[c..c + k].iter().map(|b| b.prims).sum();
        }
    }
}

/// Appends the primitives of the subtree at `b` (in tree order) to `out`.
fn subtree_prims(bins: &[Bin], src: &Bvh, b: u32, out: &mut Vec<u32>, stack: &mut Vec<u32>) {
    stack.clear();
    stack.push(b);
    while let Some(i) = stack.pop() {
        let bin = &bins[i as usize];
        if bin.is_leaf() {
            out.extend_from_slice(&src.prim_indices[bin.first as usize..(bin.first + bin.count) as usize]);
        } else {
            stack.extend((bin.child..bin.child + bin.kids).rev());
        }
    }
}

/// The view of a tree whose nodes have at most as many children as a wide node has slots:
/// the same nodes at the same indices.
fn direct_view(src: &Bvh, mut bins: Vec<Bin>) -> Vec<Bin> {
    use rayon::prelude::*;
    bins.clear();
    src.nodes
        .par_iter()
        .map(|n| {
            let (first, count) = if n.is_leaf() { (n.first, n.count) } else { (0, 0) };
            Bin {
                bounds: n.bounds,
                area: n.bounds.surface_area(),
                child: n.first,
                kids: n.child_count(),
                first,
                count,
                prims: count,
            }
        })
        .collect_into_vec(&mut bins);
    count_prims(&mut bins);
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

/// Subtrees of at most this many primitives are collapsed by one task.
const PIECE_GRAIN: u32 = 1 << 13;

/// What the emission reads: the binary view, the source's primitives, the options.
struct Emit<'a> {
    bins: &'a [Bin],
    src: &'a Bvh,
    merge: u32,
    align: usize,
}

impl Emit<'_> {
    /// A bin that becomes a leaf: a source leaf, or a subtree small enough to merge.
    #[inline]
    fn is_leaf(&self, b: u32) -> bool {
        let bin = &self.bins[b as usize];
        bin.is_leaf() || bin.prims <= self.merge
    }

    /// Asks for the children of bin `b` to be loaded into the cache (a hint).
    #[inline(always)]
    fn prefetch_children(&self, b: u32) {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            let child = self.bins[b as usize].child as usize;
            let p = self.bins.as_ptr().wrapping_add(child).cast::<i8>();
            // SAFETY: prefetching is a hint and never faults, whatever the address.
            unsafe {
                _mm_prefetch::<_MM_HINT_T0>(p);
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64));
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = b;
    }

    /// The slots of the wide node that `b` (an interior node of the view) becomes: its
    /// children, then greedily the children of the largest interior slot while they fit. A
    /// tree that is a single leaf gives one slot, the leaf itself.
    fn slots<const N: usize>(&self, b: u32) -> ([u32; N], usize) {
        let mut kids = [0u32; N];
        if self.is_leaf(b) {
            kids[0] = b;
            return (kids, 1);
        }
        let bin = &self.bins[b as usize];
        let mut k = bin.kids as usize;
        for (i, kid) in kids[..k].iter_mut().enumerate() {
            *kid = bin.child + i as u32;
        }
        loop {
            let open = (0..k)
                .filter(|&i| !self.is_leaf(kids[i]) && k - 1 + self.bins[kids[i] as usize].kids as usize <= N)
                .max_by(|&i, &j| self.bins[kids[i] as usize].area.total_cmp(&self.bins[kids[j] as usize].area));
            let Some(i) = open else { break };
            let opened = self.bins[kids[i] as usize];
            kids[i] = opened.child;
            for c in 1..opened.kids {
                kids[k] = opened.child + c;
                k += 1;
            }
        }
        (kids, k)
    }

    /// Appends the primitives of leaf bin `b` to `out`, placed within a block
    /// ([`place_leaf`]); returns where they start and how many there are. A merged subtree of a tree with
    /// spatial splits may hold two parts of one primitive: it is written once.
    fn emit_leaf(&self, b: u32, out: &mut Vec<u32>, stack: &mut Vec<u32>) -> (u32, u32) {
        let start = out.len();
        let bin = &self.bins[b as usize];
        if bin.is_leaf() {
            out.extend_from_slice(&self.src.prim_indices[bin.first as usize..(bin.first + bin.count) as usize]);
        } else {
            subtree_prims(self.bins, self.src, b, out, stack);
            let mut end = start;
            for i in start..out.len() {
                if !out[start..end].contains(&out[i]) {
                    out[end] = out[i];
                    end += 1;
                }
            }
            out.truncate(end);
        }
        let count = out.len() - start;
        (place_leaf(out, start, self.align) as u32, count as u32)
    }

    /// The wide node over the slots `kids`, each in the node slot [`slots_by_size`] gives it:
    /// every slot's box, leaves emitted into `prims`, and for each interior slot the child
    /// index that `interior(node slot, kid)` returns (called in the order of `kids`).
    fn node<const N: usize>(
        &self,
        kids: &[u32],
        prims: &mut Vec<u32>,
        stack: &mut Vec<u32>,
        mut interior: impl FnMut(usize, u32) -> u32,
    ) -> WideNode<N> {
        let mut node = WideNode::<N>::EMPTY;
        let at = slots_by_size::<N>(kids.iter().map(|&kid| self.bins[kid as usize].prims));
        for (&slot, &kid) in at.iter().zip(kids) {
            node.set_child_bounds(slot, self.bins[kid as usize].bounds);
            if self.is_leaf(kid) {
                (node.child[slot], node.count[slot]) = self.emit_leaf(kid, prims, stack);
            } else {
                node.child[slot] = interior(slot, kid);
            }
        }
        node
    }

    /// Collapses the subtree whose wide root is made from binary node `b`, at stack depth
    /// `depth`: in parallel while it is large.
    fn build<const N: usize>(&self, b: u32, depth: usize) -> WideBuilt<N> {
        if self.bins[b as usize].prims <= PIECE_GRAIN || self.is_leaf(b) {
            return WideBuilt::Piece(self.piece(b, depth));
        }
        let (kids, k) = self.slots::<N>(b);
        let depth = depth + k - 1;
        let (mut leaf_prims, mut interior) = (Vec::new(), Vec::new());
        let node = self.node(&kids[..k], &mut leaf_prims, &mut Vec::new(), |slot, kid| {
            interior.push((slot, kid));
            0
        });
        use rayon::prelude::*;
        let children: Vec<(usize, WideBuilt<N>)> =
            interior.into_par_iter().map(|(slot, kid)| (slot, self.build(kid, depth))).collect();
        let bound = children.iter().map(|(_, c)| c.bound()).max().unwrap_or(0).max(depth);
        WideBuilt::Split { node, leaf_prims, children, bound }
    }

    /// Collapses the subtree at `b` sequentially, depth first (children of a node stored
    /// consecutively).
    fn piece<const N: usize>(&self, b: u32, depth: usize) -> WidePiece<N> {
        let mut stack = Vec::new();
        build_piece(
            b,
            depth,
            self.align,
            |b, prims, children| {
                let (kids, k) = self.slots::<N>(b);
                let node = self.node(&kids[..k], prims, &mut stack, |_, kid| {
                    self.prefetch_children(kid);
                    children.push(kid)
                });
                (node, k)
            },
            // The first interior slot made (not node slot 0: see `slots_by_size`) is collapsed
            // next.
            |pushed| pushed.reverse(),
        )
    }
}

/// Collapses `src` into `N`-wide nodes; returns the nodes, the primitive indices in leaf
/// order and the traversal stack bound (the largest number of entries the ordered traversal
/// can have on its stack: along any root-to-node path, the sum of `children - 1`).
/// `nodes` and `prims` are cleared and filled: passing the previous frame's arrays reuses
/// their memory (fresh arrays of tens of MB cost more in page faults than the collapse).
///
/// Near the root, where subtrees hold more than `PIECE_GRAIN` primitives, each wide node's
/// interior slots are collapsed as separate rayon tasks; below, a task collapses its subtree
/// depth first into a piece of its own. The top is then laid out first and the pieces after
/// it, in an order that does not depend on the thread count.
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
    let bins = view(src, SCRATCH.take(), N);
    let emit = Emit { bins: &bins, src, merge: options.merge_leaves.max(1), align };
    let built = emit.build::<N>(0, 0);
    assemble(&built, &mut nodes, &mut prims, align);
    let bound = built.bound();
    drop(built);
    SCRATCH.set(bins);
    (nodes, prims, bound)
}
