//! Progressive Hierarchical Refinement (Hendrich, Meister & Bittner 2017, "Parallel BVH
//! Construction using Progressive Hierarchical Refinement"; thesis chapter 5): a top-down
//! SAH builder that splits *cuts* through an auxiliary tree (the LBVH) instead of primitives.
//!
//! The root's cut is the auxiliary tree's nodes at the scale of `t(0) = S / 2^δ`
//! ([`cut::initial_cut`]). Each node splits its cut with a full-sweep SAH over the cut's nodes
//! ([`split::best_split`]), then refines each half: nodes with area at or above
//! `t(d) = S / 2^(α d + δ)` are replaced by their children ([`cut::refine`]). Larger α and δ
//! refine sooner, so the splits see more, smaller nodes: better trees, slower builds. The
//! build cost `b = Σ |cut|` over all processed cuts is the thesis's proxy for build time.
//!
//! Not copied from the thesis code: there, a cut that shrank to one interior node became one
//! leaf holding the node's whole subtree, which made leaves of hundreds of triangles. Here a
//! single-node cut is opened until the shared leaf policy (SAH and maximum leaf size) allows a
//! leaf.
//!
//! With a branching factor k > 2 (a multi-BVH), a node splits the largest of its child cuts
//! again until it has k children or no split pays off.

pub mod cut;
pub mod split;

use crate::aabb::Aabb;
use crate::node::Bvh;
use crate::sah::LeafPolicy;
use crate::topdown::{assemble, Built, Piece};
use split::{best_split, SweepScratch};
use std::sync::atomic::{AtomicU64, Ordering};

/// What a cut node's weight counts in the sweep.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CutWeight {
    /// Auxiliary nodes in its subtree, the thesis's choice (default).
    #[default]
    AuxNodes,
    /// Primitives in its subtree: the SAH's own measure.
    Primitives,
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhrOptions {
    /// Refinement speed with depth (the thesis's α).
    pub alpha: f32,
    /// Refinement offset (the thesis's δ): the initial cut is at `S / 2^δ`.
    pub delta: f32,
    /// Children per node: 2 (binary) to 16.
    pub branching: u32,
    pub leaf: LeafPolicy,
    pub weight: CutWeight,
    /// Cap on the initial cut's size (the thesis uses 2500); `None` for no cap.
    pub max_initial_cut: Option<usize>,
}

impl PhrOptions {
    /// PHR-Fast: α = 0.5, δ = 6.
    pub const FAST: PhrOptions = PhrOptions::with(0.5, 6.0);
    /// PHR-HQ: α = 0.55, δ = 9.
    pub const HQ: PhrOptions = PhrOptions::with(0.55, 9.0);

    pub const fn with(alpha: f32, delta: f32) -> Self {
        PhrOptions {
            alpha,
            delta,
            branching: 2,
            leaf: LeafPolicy { max_leaf_size: 8, sah: crate::metrics::SahConstants::UNIT },
            weight: CutWeight::AuxNodes,
            max_initial_cut: Some(2500),
        }
    }
}

impl Default for PhrOptions {
    fn default() -> Self {
        Self::FAST
    }
}

/// What a build did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PhrStats {
    /// `Σ |cut|` over every cut processed: the thesis's build cost `b`.
    pub build_cost: u64,
    /// Size of the root's cut.
    pub initial_cut: usize,
}

/// The auxiliary tree with the per-node counts PHR needs.
pub struct Aux<'a> {
    pub bvh: &'a Bvh,
    /// Primitives under each node.
    pub prim_count: Vec<u32>,
    /// Nodes in each node's subtree (itself included).
    pub node_count: Vec<u32>,
}

impl<'a> Aux<'a> {
    /// Counts per node, in one reverse sweep (children always follow their parent).
    pub fn new(bvh: &'a Bvh) -> Self {
        let n = bvh.nodes.len();
        let mut prim_count = vec![0u32; n];
        let mut node_count = vec![1u32; n];
        for i in (0..n).rev() {
            let node = &bvh.nodes[i];
            if node.is_leaf() {
                prim_count[i] = node.count;
            } else {
                for c in node.children() {
                    prim_count[i] += prim_count[c as usize];
                    node_count[i] += node_count[c as usize];
                }
            }
        }
        Self { bvh, prim_count, node_count }
    }
}

/// Above this many primitives a node's children are built as separate rayon tasks.
const PARALLEL_GRAIN: u32 = 1 << 12;

struct Ctx<'a> {
    aux: &'a Aux<'a>,
    options: PhrOptions,
    scene_area: f32,
    build_cost: AtomicU64,
}

/// Builds a BVH from the auxiliary tree `aux_bvh` (any BVH of ours; the LBVH with one
/// primitive per leaf is the intended input). The output indexes the same primitives.
pub fn build_phr(aux_bvh: &Bvh, options: &PhrOptions) -> (Bvh, PhrStats) {
    let aux = Aux::new(aux_bvh);
    build_phr_with(&aux, options)
}

/// [`build_phr`] with precomputed counts (they stay valid while only the bounds change, as in
/// a dynamic scene's refit-then-rebuild loop).
pub fn build_phr_with(aux: &Aux, options: &PhrOptions) -> (Bvh, PhrStats) {
    if aux.bvh.nodes.is_empty() {
        return (Bvh::default(), PhrStats::default());
    }
    let options = PhrOptions { branching: options.branching.clamp(2, crate::node::MAX_BRANCHING as u32), ..*options };
    let scene_area = aux.bvh.nodes[0].bounds.surface_area();
    let ctx = Ctx { aux, options, scene_area, build_cost: AtomicU64::new(0) };
    let t0 = cut::threshold(scene_area, options.alpha, options.delta, 0);
    let root_cut = cut::initial_cut(aux, t0, options.max_initial_cut);
    let initial_cut = root_cut.len();
    let built = ctx.build(root_cut, 0);
    let bvh = assemble(built);
    (bvh, PhrStats { build_cost: ctx.build_cost.into_inner(), initial_cut })
}

/// How a node's cut is divided among its children.
enum Partition {
    Leaf,
    Children(Vec<Vec<u32>>),
}

impl Ctx<'_> {
    fn prims(&self, cut: &[u32]) -> u32 {
        cut.iter().map(|&i| self.aux.prim_count[i as usize]).sum()
    }

    /// Builds the subtree of `cut` at `depth`: in parallel while it is large, else as a piece.
    fn build(&self, cut: Vec<u32>, depth: u32) -> Built {
        if self.prims(&cut) <= PARALLEL_GRAIN {
            let mut piece = Piece::new();
            self.build_piece(&mut piece, cut, depth);
            return Built::Piece(piece);
        }
        let mut scratch = SweepScratch::default();
        let bounds = cut::cut_bounds(self.aux, &cut);
        match self.partition(cut, bounds, &mut scratch) {
            (cut, Partition::Leaf) => {
                let mut piece = Piece::new();
                piece.set_leaf(0, bounds, self.leaf_prims(&cut));
                Built::Piece(piece)
            }
            (_, Partition::Children(children)) => {
                use rayon::prelude::*;
                let children =
                    children.into_par_iter().map(|c| self.build(self.refine(c, depth + 1), depth + 1)).collect();
                Built::Split { bounds, children }
            }
        }
    }

    /// Builds a subtree sequentially into `piece`, its root at slot 0.
    fn build_piece(&self, piece: &mut Piece, cut: Vec<u32>, depth: u32) {
        let mut scratch = SweepScratch::default();
        let mut stack = vec![(cut, depth, 0u32)];
        while let Some((cut, depth, slot)) = stack.pop() {
            let bounds = cut::cut_bounds(self.aux, &cut);
            match self.partition(cut, bounds, &mut scratch) {
                (cut, Partition::Leaf) => piece.set_leaf(slot, bounds, self.leaf_prims(&cut)),
                (_, Partition::Children(children)) => {
                    let k = children.len() as u32;
                    let first = piece.alloc_children(k);
                    piece.set_interior(slot, bounds, first, k);
                    for (i, c) in children.into_iter().enumerate().rev() {
                        stack.push((self.refine(c, depth + 1), depth + 1, first + i as u32));
                    }
                }
            }
        }
    }

    fn refine(&self, cut: Vec<u32>, depth: u32) -> Vec<u32> {
        let t = cut::threshold(self.scene_area, self.options.alpha, self.options.delta, depth);
        cut::refine(self.aux, cut, t)
    }

    /// Decides leaf or children for a node with `cut` and `bounds`; counts the cut's size
    /// into the build cost. Returns the (possibly opened) cut for leaves.
    fn partition(&self, mut cut: Vec<u32>, bounds: Aabb, scratch: &mut SweepScratch) -> (Vec<u32>, Partition) {
        self.build_cost.fetch_add(cut.len() as u64, Ordering::Relaxed);
        open_singletons(self.aux, &mut cut);
        if cut.len() < 2 {
            return (cut, Partition::Leaf);
        }
        let n = self.prims(&cut);
        let area = bounds.surface_area();
        let first = best_split(self.aux, &cut, self.options.weight, scratch);
        if !self.options.leaf.must_split(n) && self.options.leaf.prefers_leaf(n, area, first.area_count) {
            return (cut, Partition::Leaf);
        }
        let mut children = vec![first.left, first.right];
        // Multi-BVH: split the largest child cut again while that helps.
        let mut final_children = Vec::new();
        while children.len() + final_children.len() < self.options.branching as usize && !children.is_empty() {
            let largest = (0..children.len())
                .max_by(|&a, &b| {
                    let area = |c: &Vec<u32>| cut::cut_bounds(self.aux, c).surface_area();
                    area(&children[a]).total_cmp(&area(&children[b]))
                })
                .unwrap_or(0);
            let mut c = children.swap_remove(largest);
            open_singletons(self.aux, &mut c);
            let n = self.prims(&c);
            if c.len() < 2 {
                final_children.push(c);
                continue;
            }
            let area = cut::cut_bounds(self.aux, &c).surface_area();
            let s = best_split(self.aux, &c, self.options.weight, scratch);
            if self.options.leaf.must_split(n) || !self.options.leaf.prefers_leaf(n, area, s.area_count) {
                children.push(s.left);
                children.push(s.right);
            } else {
                final_children.push(c);
            }
        }
        children.extend(final_children);
        (Vec::new(), Partition::Children(children))
    }

    /// The primitives under the cut's nodes.
    fn leaf_prims(&self, cut: &[u32]) -> Vec<u32> {
        let bvh = self.aux.bvh;
        let mut prims = Vec::new();
        let mut stack: Vec<u32> = cut.to_vec();
        while let Some(i) = stack.pop() {
            let n = &bvh.nodes[i as usize];
            if n.is_leaf() {
                prims.extend_from_slice(bvh.leaf_prims(n));
            } else {
                stack.extend(n.children());
            }
        }
        prims
    }
}

/// A cut of one interior node is opened (repeatedly): a node with a single child cut would
/// only add a traversal step, and keeping it whole is the thesis code's giant-leaf defect.
fn open_singletons(aux: &Aux, cut: &mut Vec<u32>) {
    while cut.len() == 1 {
        let n = &aux.bvh.nodes[cut[0] as usize];
        if n.is_leaf() {
            return;
        }
        *cut = n.children().collect();
    }
}
