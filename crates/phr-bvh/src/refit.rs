//! Bottom-up bounds computation ("refit"), in parallel with one atomic counter per node
//! (Karras 2012, section 4; thesis sections 4.1 and 5.3).
//!
//! One task per leaf computes the leaf's box and climbs towards the root. At each parent it
//! increments the parent's counter: every child but the last to arrive stops there, the last
//! (which then knows all children are final) writes the union and climbs on. Every node's box is thus
//! written exactly once, by exactly one thread, with no lock. The LBVH builder uses it for its
//! initial bounds, and it refits any of our trees after its primitives move: the topology
//! stays, only the boxes change. (Dynamic scenes refit PHR's auxiliary tree, whose layout lets
//! it do without atomics: [`crate::phr::AuxTree::refit`].)

use crate::aabb::Aabb;
use crate::node::{Bvh, Node, INTERIOR, NO_PARENT};
use crate::parallel::UnsafeSlice;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};

/// Leaves handed to one rayon task at a time.
const LEAF_CHUNK: usize = 1024;

/// Recomputes every node's bounds from the primitives' current `boxes`.
pub fn refit(bvh: &mut Bvh, boxes: &[Aabb]) {
    if bvh.nodes.is_empty() {
        return;
    }
    if bvh.parents.len() != bvh.nodes.len() {
        bvh.compute_parents();
    }
    let node_count = bvh.nodes.len();
    let arrivals: Vec<AtomicU32> = std::iter::repeat_with(|| AtomicU32::new(0)).take(node_count).collect();
    let (parents, prims) = (&bvh.parents, &bvh.prim_indices);
    let nodes = UnsafeSlice::new(&mut bvh.nodes);
    (0..node_count).into_par_iter().with_min_len(LEAF_CHUNK).for_each(|i| {
        // SAFETY: topology fields (`first`, `count`) are never written during the refit, so
        // reading them races with nothing; bounds are written by exactly one task per node
        // (argued at each write below).
        let node: *mut Node = unsafe { nodes.ptr(i) };
        let (first, count) = unsafe { ((*node).first as usize, (*node).count) };
        if count & INTERIOR != 0 {
            return;
        }
        let count = count as usize;
        let leaf_box = prims[first..first + count].iter().fold(Aabb::EMPTY, |b, &p| b.union(boxes[p as usize]));
        // SAFETY: leaf `i` is visited by this task only.
        unsafe { (&raw mut (*node).bounds).write(leaf_box) };
        let mut parent = parents[i];
        while parent != NO_PARENT {
            // SAFETY: topology fields are read-only during the refit.
            let children = unsafe { (*nodes.ptr(parent as usize)).children() };
            // AcqRel: the last arrival sees the earlier arrivals' writes of their children's boxes.
            if arrivals[parent as usize].fetch_add(1, Ordering::AcqRel) + 1 < children.len() as u32 {
                return;
            }
            // SAFETY: all children's boxes are final (each was written before its task's
            // fetch_add on this counter), and only the last arrival, this task, writes the
            // parent's box.
            unsafe {
                let union = children.fold(Aabb::EMPTY, |b, c| b.union((*nodes.ptr(c as usize)).bounds));
                (&raw mut (*nodes.ptr(parent as usize)).bounds).write(union);
            }
            parent = parents[parent as usize];
        }
    });
}
