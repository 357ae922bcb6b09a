//! Stack-based traversal of the BVH (binary or wide): closest hit and any hit.
//!
//! The caller supplies the primitive test as a closure, so the tree knows nothing about
//! triangles or spheres. Both children of an interior node are tested with the slab test;
//! the nearer one is visited first and the farther one is pushed with its entry distance, so
//! that it is skipped when popped if a closer hit was found meanwhile (the classic ordered
//! traversal of pbrt and tinybvh). The counting variant records traversal steps (nodes
//! visited) and primitive tests per ray, for the heatmap of thesis Figure 5.3.

use crate::aabb::ROBUST_SLAB;
use crate::node::{Bvh, MAX_BRANCHING};
use crate::ray::Ray;

/// Per-ray work counters.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraversalStats {
    /// Nodes visited (popped and processed), the thesis's "traversal steps".
    pub nodes: u32,
    /// Primitive intersection tests.
    pub prims: u32,
}

/// A small stack on the call stack, spilling to the heap only for pathologically deep trees.
struct Stack {
    inline: [(u32, f32); 64],
    len: usize,
    spill: Vec<(u32, f32)>,
}

impl Stack {
    #[inline(always)]
    fn new() -> Self {
        Self { inline: [(0, 0.0); 64], len: 0, spill: Vec::new() }
    }

    #[inline(always)]
    fn push(&mut self, item: (u32, f32)) {
        if self.len < self.inline.len() {
            self.inline[self.len] = item;
            self.len += 1;
        } else {
            self.spill.push(item);
        }
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, f32)> {
        if let Some(item) = self.spill.pop() {
            return Some(item);
        }
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        Some(self.inline[self.len])
    }
}

/// Closest hit. `intersect(prim, ray)` must test primitive `prim` against `ray` and, on a
/// hit closer than `ray.tmax`, shrink `ray.tmax` (and record whatever it needs); it returns
/// whether it did. Returns true if any primitive was hit.
#[inline]
pub fn closest_hit(bvh: &Bvh, ray: &mut Ray, intersect: impl FnMut(u32, &mut Ray) -> bool) -> bool {
    let mut stats = TraversalStats::default();
    traverse::<false>(bvh, ray, intersect, &mut stats)
}

/// [`closest_hit`], also counting nodes visited and primitives tested into `stats`.
#[inline]
pub fn closest_hit_counted(
    bvh: &Bvh,
    ray: &mut Ray,
    intersect: impl FnMut(u32, &mut Ray) -> bool,
    stats: &mut TraversalStats,
) -> bool {
    traverse::<true>(bvh, ray, intersect, stats)
}

/// Any hit (shadow rays): stops at the first primitive for which `intersect` returns true.
pub fn any_hit(bvh: &Bvh, ray: &Ray, mut intersect: impl FnMut(u32, &Ray) -> bool) -> bool {
    let mut r = *ray;
    let mut found = false;
    let mut stats = TraversalStats::default();
    traverse_until::<false>(
        bvh,
        &mut r,
        |p, r| {
            found = intersect(p, r);
            found
        },
        &mut stats,
        true,
    );
    found
}

#[inline(always)]
fn traverse<const COUNT: bool>(
    bvh: &Bvh,
    ray: &mut Ray,
    intersect: impl FnMut(u32, &mut Ray) -> bool,
    stats: &mut TraversalStats,
) -> bool {
    traverse_until::<COUNT>(bvh, ray, intersect, stats, false)
}

#[inline(always)]
fn traverse_until<const COUNT: bool>(
    bvh: &Bvh,
    ray: &mut Ray,
    mut intersect: impl FnMut(u32, &mut Ray) -> bool,
    stats: &mut TraversalStats,
    stop_at_first: bool,
) -> bool {
    let nodes = &bvh.nodes;
    let Some(root) = nodes.first() else { return false };
    if root.bounds.intersect(ray) == f32::INFINITY {
        return false;
    }
    let mut hit = false;
    let mut stack = Stack::new();
    let mut current = 0u32;
    loop {
        let node = &nodes[current as usize];
        if COUNT {
            stats.nodes += 1;
        }
        if node.is_leaf() {
            for &prim in bvh.leaf_prims(node) {
                if COUNT {
                    stats.prims += 1;
                }
                if intersect(prim, ray) {
                    hit = true;
                    if stop_at_first {
                        return true;
                    }
                }
            }
        } else if node.child_count() == 2 {
            let (a, b) = (node.first, node.first + 1);
            let ta = nodes[a as usize].bounds.intersect(ray);
            let tb = nodes[b as usize].bounds.intersect(ray);
            let ((near, t_near), (far, t_far)) = if ta <= tb { ((a, ta), (b, tb)) } else { ((b, tb), (a, ta)) };
            if t_near != f32::INFINITY {
                if t_far != f32::INFINITY {
                    stack.push((far, t_far));
                }
                current = near;
                continue;
            }
        } else {
            // A wide node: push the children that are hit, farthest first, so the nearest
            // is popped next.
            let mut hit_children = [(0u32, 0.0f32); MAX_BRANCHING];
            let mut k = 0;
            for c in node.children() {
                let t = nodes[c as usize].bounds.intersect(ray);
                if t != f32::INFINITY {
                    let mut j = k;
                    while j > 0 && hit_children[j - 1].1 < t {
                        hit_children[j] = hit_children[j - 1];
                        j -= 1;
                    }
                    hit_children[j] = (c, t);
                    k += 1;
                }
            }
            for &child in &hit_children[..k] {
                stack.push(child);
            }
        }
        // Pop the next node whose box still starts before the closest hit so far.
        loop {
            match stack.pop() {
                None => return hit,
                Some((index, t_entry)) if t_entry <= ray.tmax * ROBUST_SLAB => {
                    current = index;
                    break;
                }
                Some(_) => {}
            }
        }
    }
}
