//! Refitting a wide tree to moved primitives: the topology is kept, every slot's box is
//! recomputed, the leaf slots in parallel, then the interior slots bottom up (last to first,
//! which is bottom up because every builder here stores a node's children after it, as
//! [`WideBvh::validate`] checks).
//!
//! A refitted tree is valid but its quality decays as the primitives move; a dynamic scene
//! traces it while a new tree is built (`phr_render::pipeline`).
//!
//! Two sources for the leaves' boxes: the primitives' boxes ([`WideBvh::refit`]), or, for a
//! deforming mesh, the triangles just packed in leaf order ([`WideBvh::refit_packed`], with
//! [`PackedTriangles::bounds`]). The second needs no boxes at all: on the 871k-triangle
//! dragon, computing them, storing them in scene order and gathering them back by primitive
//! index took 7 ms of a frame on 2 threads (`docs/dynamic/history.md`). While the tree stays,
//! [`WideBvh::refit_repacking`] packs each leaf's triangles as it boxes them, so the packed
//! triangles are not read back: on the dragon, 11.8 ms of packing and refitting became 10.4
//! (the triangles are read in the nodes' order, more scattered than packing's; the pass
//! waits on memory either way).

use super::triangles::{prefetch_read, widened, PackedTriangles, SharedEntries, LANES};
use super::WideBvh;
use crate::aabb::Aabb;
use glam::Vec3;
use std::ops::Range;

/// The box areas a refit has just computed, summed: what [`crate::wide_sah_cost`] adds up
/// over the refitted tree, without reading its nodes from memory again (a dynamic scene costs
/// its refitted tree every frame to decide when to rebuild it; on the 871k-triangle dragon
/// the separate pass and its rayon tasks took about 1.9 ms of a 256² frame on 2 threads).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RefitAreas {
    /// The root's box.
    pub root: f64,
    /// Every other node's box: the interior slots.
    pub interior: f64,
    /// Each leaf slot's box times its primitives.
    pub leaves: f64,
}

impl<const N: usize> WideBvh<N> {
    /// Recomputes every slot's box from `boxes` (the primitives' boxes by the indices in
    /// [`WideBvh::prim_indices`]).
    pub fn refit(&mut self, boxes: &[Aabb]) -> RefitAreas {
        self.refit_with(|_, prims| prims.iter().fold(Aabb::EMPTY, |b, &p| b.union(boxes[p as usize])))
    }

    /// Recomputes every slot's box from `packed`, this tree's triangles packed in its leaf
    /// order ([`PackedTriangles::repack`] after the triangles moved): a leaf's box encloses
    /// its triangles as the packed test sees them ([`PackedTriangles::bounds`]). Entries
    /// that are not triangles (the primitives `p >= triangle_count`, which a renderer tests
    /// its own way) get `other(p)`.
    pub fn refit_packed(
        &mut self,
        packed: &PackedTriangles,
        triangle_count: usize,
        other: impl Fn(u32) -> Aabb + Sync,
    ) -> RefitAreas {
        let is_triangle = |p: u32| (p as usize) < triangle_count;
        self.refit_prefetched(
            |entries, prims| match prims.iter().all(|&p| is_triangle(p)) {
                true => packed.bounds(entries),
                false => entries.zip(prims).fold(Aabb::EMPTY, |b, (i, &p)| {
                    b.union(if is_triangle(p) { packed.bounds(i..i + 1) } else { other(p) })
                }),
            },
            |entries, _| {
                packed.prefetch(entries.start as u32);
                if entries.end - entries.start > LANES {
                    packed.prefetch((entries.end - 1) as u32);
                }
            },
        )
    }

    /// Recomputes every slot's box: a leaf slot's is `leaf_bounds(entries, prims)`, the box
    /// of its primitives `prims` (at positions `entries` of [`WideBvh::prim_indices`]). The
    /// leaf slots, which read the primitives and are most of the work, are refitted in
    /// parallel; then the interior slots, bottom up.
    pub fn refit_with(&mut self, leaf_bounds: impl Fn(Range<usize>, &[u32]) -> Aabb + Sync) -> RefitAreas {
        self.refit_prefetched(leaf_bounds, |_, _| {})
    }

    /// [`PackedTriangles::repack`] and then [`WideBvh::refit_packed`] in one pass, for the
    /// frames of a deforming mesh whose tree stays: each leaf's triangles are packed and
    /// boxed in the same visit, so the packed triangles are not read back. The leaves' and
    /// the packed entries' values are those of the two passes, to the bit.
    ///
    /// `packed` must hold this tree's entries from an earlier [`PackedTriangles::repack`]:
    /// only the leaves' entries are written, not the padding between them (zero, as packed
    /// before). Entries `p >= triangles.len()` are not triangles and get `other(p)` (and stay
    /// zero in `packed`). A `packed` of another size is packed in full first.
    pub fn refit_repacking(
        &mut self,
        packed: &mut PackedTriangles,
        triangles: &[[Vec3; 3]],
        other: impl Fn(u32) -> Aabb + Sync,
    ) -> RefitAreas {
        if packed.blocks.len() != self.prim_indices.len().div_ceil(LANES) {
            packed.repack(&self.prim_indices, triangles);
            return self.refit_packed(packed, triangles.len(), other);
        }
        debug_assert!(
            self.prim_indices
                .iter()
                .enumerate()
                .all(|(i, &p)| (p as usize) < triangles.len() || packed.get(i as u32) == [Vec3::ZERO; 3]),
            "`packed` holds a triangle where this tree has padding or a non-triangle: another tree's"
        );
        let entries_out = SharedEntries::new(packed);
        self.refit_prefetched(
            |entries, prims| {
                let (mut min, mut max) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
                let mut others = Aabb::EMPTY;
                for (i, &p) in entries.zip(prims) {
                    match triangles.get(p as usize) {
                        Some(&triangle) => {
                            let [a, b, c] = entries_out.store(i, triangle);
                            (min, max) = (min.min(a.min(b).min(c)), max.max(a.max(b).max(c)));
                        }
                        None => others = others.union(other(p)),
                    }
                }
                match min.x <= max.x {
                    true => widened(min, max).union(others),
                    false => others,
                }
            },
            |entries, prims| {
                entries_out.prefetch(entries.start);
                if entries.len() > LANES {
                    entries_out.prefetch(entries.end - 1);
                }
                for &p in prims {
                    prefetch_read(triangles.as_ptr().wrapping_add(p as usize));
                }
            },
        )
    }

    /// [`WideBvh::refit_with`], asking for the data of the leaves a few nodes ahead with
    /// `prefetch(entries, prims)`. Every refit returns the areas it computed
    /// ([`RefitAreas`]). A node's leaves are not next to its neighbours' in the leaf
    /// order (a node's children are stored together, their leaves where each subtree was
    /// built), so without the hint every leaf's first load waits for memory.
    pub fn refit_prefetched(
        &mut self,
        leaf_bounds: impl Fn(Range<usize>, &[u32]) -> Aabb + Sync,
        prefetch: impl Fn(Range<usize>, &[u32]) + Sync,
    ) -> RefitAreas {
        use rayon::prelude::*;
        const GRAIN: usize = 256;
        const AHEAD: usize = 8;
        let prims = &self.prim_indices;
        let prefetch_leaves = |node: &super::WideNode<N>| {
            for s in 0..N {
                if node.count[s] > 0 {
                    let first = node.child[s] as usize;
                    let entries = first..first + node.count[s] as usize;
                    prefetch(entries.clone(), &prims[entries]);
                }
            }
        };
        // Each node's box (the union of its slots), complete after the leaf pass for the
        // nodes with leaves only, which are most of them; the others are listed by chunk.
        // Each chunk sums the areas of its leaf slots and of its complete nodes but the root.
        let mut own = vec![Aabb::EMPTY; self.nodes.len()];
        let chunks: Vec<(Vec<u32>, f64, f64)> = self
            .nodes
            .par_chunks_mut(GRAIN)
            .zip(own.par_chunks_mut(GRAIN))
            .enumerate()
            .map(|(c, (chunk, own))| {
                let mut with_interior = Vec::new();
                let (mut interior_areas, mut leaf_areas) = (0.0f64, 0.0f64);
                for node in &chunk[..AHEAD.min(chunk.len())] {
                    prefetch_leaves(node);
                }
                for k in 0..chunk.len() {
                    if let Some(ahead) = chunk.get(k + AHEAD) {
                        prefetch_leaves(ahead);
                    }
                    let node = &mut chunk[k];
                    let (mut interior, mut union) = (false, Aabb::EMPTY);
                    for s in 0..N {
                        let (first, count) = (node.child[s] as usize, node.count[s] as usize);
                        if count > 0 {
                            let entries = first..first + count;
                            let b = leaf_bounds(entries.clone(), &prims[entries]);
                            node.set_child_bounds(s, b);
                            leaf_areas += f64::from(b.surface_area()) * count as f64;
                            union = union.union(b);
                        } else {
                            // By its child, not its box: a subtree whose box was empty for a
                            // frame (its primitives' boxes all empty) is refitted again.
                            interior |= node.child[s] != 0;
                        }
                    }
                    let i = c * GRAIN + k;
                    match interior {
                        true => with_interior.push(i as u32),
                        false => {
                            own[k] = union;
                            if i != 0 {
                                interior_areas += f64::from(union.surface_area());
                            }
                        }
                    }
                }
                (with_interior, interior_areas, leaf_areas)
            })
            .collect();
        let mut areas = RefitAreas::default();
        for (_, interior, leaves) in &chunks {
            areas.interior += interior;
            areas.leaves += leaves;
        }
        // Bottom up: a node's children come after it. Only the nodes with interior slots are
        // visited, and their children's boxes are read from `own`, not from the children.
        let order: Vec<u32> = chunks.iter().rev().flat_map(|(list, _, _)| list.iter().rev().copied()).collect();
        for (k, &i) in order.iter().enumerate() {
            if let Some(&ahead) = order.get(k + AHEAD) {
                super::traverse::prefetch_node(&self.nodes, ahead);
            }
            let node = &mut self.nodes[i as usize];
            let mut union = Aabb::EMPTY;
            for s in 0..N {
                let mut b = node.child_bounds(s);
                if node.count[s] == 0 && node.child[s] != 0 {
                    b = own[node.child[s] as usize];
                    node.set_child_bounds(s, b);
                }
                union = union.union(b);
            }
            own[i as usize] = union;
            if i != 0 {
                areas.interior += f64::from(union.surface_area());
            }
        }
        areas.root = own.first().map_or(0.0, |b| f64::from(b.surface_area()));
        areas
    }
}
