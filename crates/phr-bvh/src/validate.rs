//! Structural invariants every built tree must satisfy; the tests run this on every tree.
//!
//! - every node is reachable from the root exactly once (no cycles, no sharing, no orphans);
//! - every primitive appears in exactly one leaf;
//! - every parent's box encloses its children's, every leaf's box encloses its primitives';
//! - leaves hold between 1 and `max_leaf_size` primitives, interior nodes at least 2 children;
//! - `parents` (when present) matches the child links.
//!
//! Trees with spatial splits ([`crate::sbvh`]) are checked by [`validate_split`]: a primitive
//! may be in several leaves (never twice in one), and a leaf's box need only meet its
//! primitives' boxes (it encloses the part of the primitive inside it). Whether those parts
//! cover the whole primitive depends on its shape, which this module does not know: the
//! tests check it with the triangles, and against brute-force hits.

use crate::aabb::Aabb;
use crate::node::{Bvh, NO_PARENT};

/// Checks the invariants above; the error says which one failed, and where.
pub fn validate(bvh: &Bvh, boxes: &[Aabb], max_leaf_size: u32) -> Result<(), String> {
    check(bvh, boxes, max_leaf_size, false)
}

/// [`validate()`] for trees whose primitives may be cut into parts in several leaves.
pub fn validate_split(bvh: &Bvh, boxes: &[Aabb], max_leaf_size: u32) -> Result<(), String> {
    check(bvh, boxes, max_leaf_size, true)
}

fn check(bvh: &Bvh, boxes: &[Aabb], max_leaf_size: u32, split: bool) -> Result<(), String> {
    if boxes.is_empty() {
        return if bvh.nodes.is_empty() { Ok(()) } else { Err("nodes without primitives".into()) };
    }
    if bvh.nodes.is_empty() {
        return Err(format!("{} primitives but no nodes", boxes.len()));
    }
    let references = bvh.prim_indices.len();
    if if split { references < boxes.len() } else { references != boxes.len() } {
        return Err(format!("{references} primitive references for {} primitives", boxes.len()));
    }
    let mut visited = vec![false; bvh.nodes.len()];
    let mut prim_seen = vec![false; boxes.len()];
    let mut stack = vec![0usize];
    while let Some(i) = stack.pop() {
        if std::mem::replace(&mut visited[i], true) {
            return Err(format!("node {i} reached twice"));
        }
        let n = &bvh.nodes[i];
        if n.is_leaf() {
            if n.count == 0 || n.count > max_leaf_size {
                return Err(format!("leaf {i} holds {} primitives (allowed: 1 to {max_leaf_size})", n.count));
            }
            let end = n.first as usize + n.count as usize;
            let refs = bvh.prim_indices.get(n.first as usize..end).ok_or(format!("leaf {i} range out of bounds"))?;
            for (k, &p) in refs.iter().enumerate() {
                let seen = prim_seen.get_mut(p as usize).ok_or(format!("leaf {i}: primitive {p} out of range"))?;
                if std::mem::replace(seen, true) && !split {
                    return Err(format!("primitive {p} in more than one leaf"));
                }
                if split && refs[..k].contains(&p) {
                    return Err(format!("leaf {i} holds primitive {p} twice"));
                }
                let prim_box = boxes[p as usize];
                if split && !prim_box.is_empty() && n.bounds.overlap(prim_box).is_empty() {
                    return Err(format!("leaf {i} does not meet primitive {p}"));
                }
                if !split && !n.bounds.contains(&prim_box) {
                    return Err(format!("leaf {i} does not enclose primitive {p}"));
                }
            }
        } else {
            let children = n.children();
            if n.child_count() < 2 || children.end as usize > bvh.nodes.len() || children.start as usize <= i {
                return Err(format!("node {i}: children {children:?} invalid"));
            }
            for child in children.map(|c| c as usize) {
                if !n.bounds.contains(&bvh.nodes[child].bounds) {
                    return Err(format!("node {i} does not enclose child {child}"));
                }
                if !bvh.parents.is_empty() && bvh.parents[child] != i as u32 {
                    return Err(format!("parents[{child}] = {} but its parent is {i}", bvh.parents[child]));
                }
                stack.push(child);
            }
        }
    }
    if let Some(i) = visited.iter().position(|v| !v) {
        return Err(format!("node {i} is unreachable"));
    }
    if let Some(p) = prim_seen.iter().position(|s| !s) {
        return Err(format!("primitive {p} is in no leaf"));
    }
    if !bvh.parents.is_empty() && bvh.parents[0] != NO_PARENT {
        return Err("root has a parent".into());
    }
    Ok(())
}
