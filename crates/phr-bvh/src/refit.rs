//! Bottom-up bounds computation ("refit"), in parallel with one atomic counter per node
//! (Karras 2012, section 4; thesis sections 4.1 and 5.3).
//!
//! One task per leaf computes the leaf's box and climbs towards the root. At each parent it
//! increments the parent's counter: the first child to arrive stops, the second (which then
//! knows both children are final) writes the union and climbs on. Every node is thus written
//! exactly once, by exactly one thread, with no lock. The LBVH builder uses it for its
//! initial bounds, and dynamic scenes use it every frame after vertices move: the topology
//! stays, only the boxes change.

use crate::aabb::Aabb;
use crate::node::{Bvh, NO_PARENT};
use crate::parallel::UnsafeSlice;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};

/// Recomputes every node's bounds from the primitives' current `boxes`.
pub fn refit(bvh: &mut Bvh, boxes: &[Aabb]) {
    if bvh.nodes.is_empty() {
        return;
    }
    if bvh.parents.len() != bvh.nodes.len() {
        bvh.compute_parents();
    }
    let leaves: Vec<u32> =
        bvh.nodes.par_iter().enumerate().filter(|(_, n)| n.is_leaf()).map(|(i, _)| i as u32).collect();
    let mut bounds = vec![Aabb::EMPTY; bvh.nodes.len()];
    let arrivals: Vec<AtomicU32> = (0..bvh.nodes.len()).map(|_| AtomicU32::new(0)).collect();
    {
        let out = UnsafeSlice::new(&mut bounds);
        let (nodes, parents, prims) = (&bvh.nodes, &bvh.parents, &bvh.prim_indices);
        leaves.par_iter().for_each(|&leaf| {
            let node = &nodes[leaf as usize];
            let prim_range = node.first as usize..(node.first + node.count) as usize;
            let leaf_box = prims[prim_range].iter().fold(Aabb::EMPTY, |b, &p| b.union(boxes[p as usize]));
            // SAFETY: leaf `leaf` is written only by this task.
            unsafe { out.write(leaf as usize, leaf_box) };
            let mut parent = parents[leaf as usize];
            while parent != NO_PARENT {
                // AcqRel: the second arrival sees the first arrival's write of its child.
                if arrivals[parent as usize].fetch_add(1, Ordering::AcqRel) == 0 {
                    return;
                }
                let first = nodes[parent as usize].first as usize;
                // SAFETY: both children are final (each was written before its task's
                // fetch_add on this counter), and only the second arrival, this task,
                // writes `parent`.
                unsafe {
                    let union = out.read(first).union(out.read(first + 1));
                    out.write(parent as usize, union);
                }
                parent = parents[parent as usize];
            }
        });
    }
    bvh.nodes.par_iter_mut().zip(bounds.par_iter()).for_each(|(n, b)| n.bounds = *b);
}
