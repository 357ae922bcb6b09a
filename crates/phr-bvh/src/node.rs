//! The BVH layout every builder produces: a flat array of 32-byte nodes.
//!
//! Interior nodes store the index of their first child and how many children they have (2
//! for binary trees, up to 16 for PHR's multi-BVHs); siblings are always stored next to each
//! other, as in tinybvh's `BVHNode`, so a node needs one child index only and siblings' boxes
//! share cache lines. Leaves store a range of `prim_indices`.

use crate::aabb::Aabb;

/// Sentinel parent index of the root.
pub const NO_PARENT: u32 = u32::MAX;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct Node {
    pub bounds: Aabb,
    /// Interior: index of the first child (the others follow it).
    /// Leaf: index of the first primitive reference in [`Bvh::prim_indices`].
    pub first: u32,
    /// Leaf: number of primitives. Interior: [`INTERIOR`] | number of children.
    pub count: u32,
}

/// The widest node any builder makes (PHR's multi-BVH with branching factor 16).
pub const MAX_BRANCHING: usize = 16;

/// The flag that marks an interior node's `count`.
pub const INTERIOR: u32 = 1 << 31;

impl Node {
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.count & INTERIOR == 0
    }

    /// Primitives of a leaf (0 for interior nodes).
    #[inline(always)]
    pub fn prim_count(&self) -> u32 {
        if self.is_leaf() {
            self.count
        } else {
            0
        }
    }

    /// Children of an interior node (0 for leaves).
    #[inline(always)]
    pub fn child_count(&self) -> u32 {
        if self.is_leaf() {
            0
        } else {
            self.count & !INTERIOR
        }
    }

    /// Indices of the children (empty for leaves).
    #[inline(always)]
    pub fn children(&self) -> std::ops::Range<u32> {
        self.first..self.first + self.child_count()
    }

    pub fn leaf(bounds: Aabb, first: u32, count: u32) -> Self {
        debug_assert!(count > 0 && count < INTERIOR);
        Self { bounds, first, count }
    }

    /// A binary interior node: children at `first_child` and `first_child + 1`.
    pub fn interior(bounds: Aabb, first_child: u32) -> Self {
        Self::interior_k(bounds, first_child, 2)
    }

    /// An interior node with `children` consecutive children starting at `first_child`.
    pub fn interior_k(bounds: Aabb, first_child: u32, children: u32) -> Self {
        debug_assert!(children >= 2);
        Self { bounds, first: first_child, count: INTERIOR | children }
    }
}

/// A BVH over primitives numbered `0..n` by the caller; binary unless a builder was asked for
/// wider nodes (see [`Bvh::max_branching`]).
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    /// `nodes[0]` is the root.
    pub nodes: Vec<Node>,
    /// Leaves index into this array; it holds every primitive index exactly once.
    pub prim_indices: Vec<u32>,
    /// Parent of each node ([`NO_PARENT`] for the root), for the bottom-up refit; empty when
    /// the builder had no use for it (the top-down builders), and then computed by the refit.
    pub parents: Vec<u32>,
}

impl Bvh {
    pub fn root_bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::EMPTY, |n| n.bounds)
    }

    pub fn prim_count(&self) -> usize {
        self.prim_indices.len()
    }

    /// The primitive indices of a leaf.
    #[inline(always)]
    pub fn leaf_prims(&self, node: &Node) -> &[u32] {
        &self.prim_indices[node.first as usize..(node.first + node.count) as usize]
    }

    /// Recomputes `parents` from the child links.
    pub fn compute_parents(&mut self) {
        let mut parents = vec![NO_PARENT; self.nodes.len()];
        for (i, n) in self.nodes.iter().enumerate() {
            for c in n.children() {
                parents[c as usize] = i as u32;
            }
        }
        self.parents = parents;
    }

    /// The largest number of children of any node (2 for binary trees, 0 for a lone leaf).
    pub fn max_branching(&self) -> u32 {
        self.nodes.iter().map(Node::child_count).max().unwrap_or(0)
    }
}
