//! Refitting a wide tree to moved primitives: the topology is kept, every slot's box is
//! recomputed. Nodes are visited last to first, which is bottom up because every builder
//! here stores a node's children after it (checked by [`WideBvh::validate`]).
//!
//! A refitted tree is valid but its quality decays as the primitives move; a dynamic scene
//! traces it while a new tree is built (`phr_render::pipeline`).

use super::WideBvh;
use crate::aabb::Aabb;

impl<const N: usize> WideBvh<N> {
    /// Recomputes every slot's box from `boxes` (the primitives' boxes by the indices in
    /// [`WideBvh::prim_indices`]). The leaf slots, which read the primitives' boxes and are
    /// most of the work, are refitted in parallel; then the interior slots, bottom up.
    pub fn refit(&mut self, boxes: &[Aabb]) {
        use rayon::prelude::*;
        let prims = &self.prim_indices;
        self.nodes.par_iter_mut().with_min_len(256).for_each(|node| {
            for s in 0..N {
                let (first, count) = (node.child[s] as usize, node.count[s] as usize);
                if count > 0 {
                    let leaf = &prims[first..first + count];
                    node.set_child_bounds(s, leaf.iter().fold(Aabb::EMPTY, |b, &p| b.union(boxes[p as usize])));
                }
            }
        });
        for i in (0..self.nodes.len()).rev() {
            let mut node = self.nodes[i];
            for s in 0..N {
                if node.count[s] == 0 && node.is_used(s) {
                    node.set_child_bounds(s, self.nodes[node.child[s] as usize].bounds());
                }
            }
            self.nodes[i] = node;
        }
    }
}
