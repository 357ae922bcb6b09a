//! Tree metrics: the SAH cost (Goldsmith & Salmon 1987; MacDonald & Booth 1990), depth and
//! leaf statistics.
//!
//! The SAH cost of a tree is the expected cost of a random ray that hits the root box:
//! `(c_t Σ_interior A(n) + c_i Σ_leaf A(n)·|n|) / A(root)`, for any branching factor. The thesis uses `c_t = 2`,
//! `c_i = 1`; the issue tables also report `c_t = c_i = 1`.

use crate::node::Bvh;
use crate::wide::{WideBvh, WideNode, MAX_X, MAX_Y, MAX_Z, MIN_X, MIN_Y, MIN_Z};

/// The constants of the surface area heuristic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SahConstants {
    /// Cost of one traversal step (a node visit).
    pub traversal: f32,
    /// Cost of one primitive intersection.
    pub intersection: f32,
}

impl SahConstants {
    /// The thesis's constants (traversal 2, intersection 1).
    pub const THESIS: SahConstants = SahConstants { traversal: 2.0, intersection: 1.0 };
    /// Traversal 1, intersection 1.
    pub const UNIT: SahConstants = SahConstants { traversal: 1.0, intersection: 1.0 };
}

impl Default for SahConstants {
    fn default() -> Self {
        Self::UNIT
    }
}

/// SAH cost normalised by the root's surface area (0 for an empty tree).
///
/// Summed in parallel over fixed chunks, then over the chunks in order: the same bits for
/// any thread count. (The viewer shows it every frame of a dynamic scene.)
pub fn sah_cost(bvh: &Bvh, c: SahConstants) -> f64 {
    use rayon::prelude::*;
    let root_area = bvh.root_bounds().surface_area() as f64;
    if bvh.nodes.is_empty() || root_area <= 0.0 {
        return 0.0;
    }
    let chunk_sums: Vec<f64> = bvh
        .nodes
        .par_chunks(1 << 14)
        .map(|chunk| {
            chunk
                .iter()
                .map(|n| {
                    let a = n.bounds.surface_area() as f64;
                    if n.is_leaf() {
                        c.intersection as f64 * a * n.prim_count() as f64
                    } else {
                        c.traversal as f64 * a
                    }
                })
                .sum::<f64>()
        })
        .collect();
    chunk_sums.iter().sum::<f64>() / root_area
}

/// [`sah_cost`] of a wide tree: each node is one traversal step (its root included), each
/// leaf slot costs its primitives. (A wide tree has fewer, larger steps than the binary tree
/// it was collapsed from, so its cost is lower: compare wide trees with wide trees.) Summed
/// as [`sah_cost`] is: the same bits for any thread count.
pub fn wide_sah_cost<const N: usize>(wide: &WideBvh<N>, c: SahConstants) -> f64 {
    use rayon::prelude::*;
    let Some(root) = wide.nodes.first() else { return 0.0 };
    let root_area = root.bounds().surface_area() as f64;
    if root_area <= 0.0 {
        return 0.0;
    }
    let (traversal, intersection) = (c.traversal as f64, c.intersection as f64);
    let chunk_sums: Vec<f64> = wide
        .nodes
        .par_chunks(1 << 11)
        .map(|chunk| {
            let mut sum = 0.0;
            for n in chunk {
                for (i, area) in slot_areas(n).into_iter().enumerate() {
                    match (area.map(f64::from), n.count[i]) {
                        (None, _) => {}
                        (Some(a), 0) => sum += traversal * a,
                        (Some(a), count) => sum += intersection * a * f64::from(count),
                    }
                }
            }
            sum
        })
        .collect();
    (traversal * root_area + chunk_sums.iter().sum::<f64>()) / root_area
}

impl crate::wide::RefitAreas {
    /// [`wide_sah_cost`] of the tree a refit returned these areas for: the same terms, summed
    /// in another order (within rounding of it; the same bits for any thread count).
    pub fn sah_cost(&self, c: SahConstants) -> f64 {
        if self.root <= 0.0 {
            return 0.0;
        }
        (c.traversal as f64 * (self.root + self.interior) + c.intersection as f64 * self.leaves) / self.root
    }
}

/// The surface areas of a node's slots, `None` for the empty ones: what
/// [`crate::Aabb::surface_area`] gives each slot's box, lane by lane so that the compiler
/// can vectorise it (one box at a time, the sum took 1.6 ms of a dragon's frame in the
/// viewer, which costed its refitted tree this way every frame before it took the cost from
/// the refit itself, [`crate::RefitAreas`]).
#[inline]
fn slot_areas<const N: usize>(node: &WideNode<N>) -> [Option<f32>; N] {
    let b = &node.bounds;
    let mut areas = [0.0f32; N];
    let mut empty = [false; N];
    for i in 0..N {
        let (ex, ey, ez) = (b[MAX_X][i] - b[MIN_X][i], b[MAX_Y][i] - b[MIN_Y][i], b[MAX_Z][i] - b[MIN_Z][i]);
        areas[i] = 2.0 * (ex * ey + ey * ez + ez * ex);
        empty[i] = b[MIN_X][i] > b[MAX_X][i] || b[MIN_Y][i] > b[MAX_Y][i] || b[MIN_Z][i] > b[MAX_Z][i];
    }
    std::array::from_fn(|i| (!empty[i]).then_some(areas[i]))
}

/// Shape statistics of a tree.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TreeStats {
    pub nodes: usize,
    pub leaves: usize,
    pub max_depth: usize,
    /// Mean depth of the leaves (root = 0).
    pub mean_leaf_depth: f64,
    pub max_leaf_size: u32,
    pub mean_leaf_size: f64,
}

pub fn tree_stats(bvh: &Bvh) -> TreeStats {
    let mut s = TreeStats { nodes: bvh.nodes.len(), ..Default::default() };
    if bvh.nodes.is_empty() {
        return s;
    }
    let mut depth_sum = 0usize;
    let mut prim_sum = 0usize;
    let mut stack = vec![(0usize, 0usize)];
    while let Some((i, d)) = stack.pop() {
        let n = &bvh.nodes[i];
        s.max_depth = s.max_depth.max(d);
        if n.is_leaf() {
            s.leaves += 1;
            depth_sum += d;
            prim_sum += n.prim_count() as usize;
            s.max_leaf_size = s.max_leaf_size.max(n.prim_count());
        } else {
            stack.extend(n.children().map(|c| (c as usize, d + 1)));
        }
    }
    s.mean_leaf_depth = depth_sum as f64 / s.leaves as f64;
    s.mean_leaf_size = prim_sum as f64 / s.leaves as f64;
    s
}
