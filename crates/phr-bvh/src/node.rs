//! The binary BVH layout every builder produces: a flat array of 32-byte nodes.
//!
//! Interior nodes store the index of their first child; the second child is always the next
//! slot (`first + 1`), as in tinybvh's `BVHNode`, so a node needs no second pointer and both
//! children's boxes share a cache line more often than not. Leaves store a range of
//! `prim_indices`.

use crate::aabb::Aabb;

/// Sentinel parent index of the root.
pub const NO_PARENT: u32 = u32::MAX;

#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct Node {
    pub bounds: Aabb,
    /// Interior: index of the left child (the right one is `first + 1`).
    /// Leaf: index of the first primitive reference in [`Bvh::prim_indices`].
    pub first: u32,
    /// Number of primitives; 0 marks an interior node.
    pub count: u32,
}

impl Node {
    #[inline(always)]
    pub fn is_leaf(&self) -> bool {
        self.count > 0
    }

    pub fn leaf(bounds: Aabb, first: u32, count: u32) -> Self {
        debug_assert!(count > 0);
        Self { bounds, first, count }
    }

    pub fn interior(bounds: Aabb, first_child: u32) -> Self {
        Self { bounds, first: first_child, count: 0 }
    }
}

/// A binary BVH over primitives numbered `0..n` by the caller.
#[derive(Clone, Debug, Default)]
pub struct Bvh {
    /// `nodes[0]` is the root.
    pub nodes: Vec<Node>,
    /// Leaves index into this array; it holds every primitive index exactly once.
    pub prim_indices: Vec<u32>,
    /// Parent of each node ([`NO_PARENT`] for the root); used by the bottom-up refit.
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
            if !n.is_leaf() {
                parents[n.first as usize] = i as u32;
                parents[n.first as usize + 1] = i as u32;
            }
        }
        self.parents = parents;
    }
}
