//! Progressive Hierarchical Refinement (Hendrich, Meister & Bittner 2017, "Parallel BVH
//! Construction using Progressive Hierarchical Refinement"; thesis chapter 5): a top-down
//! SAH builder that splits *cuts* through an auxiliary tree (the LBVH) instead of primitives.
//!
//! The root's cut is the auxiliary tree's nodes at the scale of `t(0) = S / 2^δ`
//! ([`cut::initial_cut`]). Each node splits its cut with a full-sweep SAH over the cut's nodes
//! ([`split::best_split`]; a large cut along one axis, chosen by binning), then refines each half: nodes with area at or above
//! `t(d) = S / 2^(α d + δ)` are replaced by their children ([`AuxTree::refine_into`]). Larger α and δ
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

pub mod aux_tree;
pub mod cut;
mod key_sort;
pub mod split;
pub mod wide;

use crate::aabb::Aabb;
use crate::node::{Bvh, MAX_BRANCHING};
use crate::sah::{LeafPolicy, MEDIAN_SPLIT_DEPTH};
use crate::topdown::{assemble, Built, Piece};
pub use aux_tree::AuxTree;
use cut::{cut_bounds, cut_prims, CutNode};
use rayon::prelude::*;
use split::{best_split, median_split, CutSplit, SplitScratch};
use std::sync::atomic::{AtomicU64, Ordering};
pub use wide::build_phr_wide;

/// What a cut node's weight counts in the sweep.
///
/// The default is [`CutWeight::Primitives`], the SAH's own measure. The thesis weighted by
/// auxiliary nodes; with one primitive per auxiliary leaf a node of `p` primitives then weighs
/// `2p - 1`, so large unopened clusters count twice as much as the single primitives next to
/// them and the splits lean away from them. Measured (`phr-fast`, SAH cost vs the full sweep):
/// Sponza +3.5 % with node weights, +1.7 % with primitive weights; bunny and conference
/// equal or slightly better too.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CutWeight {
    /// Auxiliary nodes in its subtree, the thesis's choice.
    AuxNodes,
    /// Primitives in its subtree (default).
    #[default]
    Primitives,
}

impl CutWeight {
    /// The weight of a node with `prims` primitives under it. In the auxiliary tree (a full
    /// binary tree with one primitive per leaf) such a node has `2 · prims − 1` nodes.
    #[inline(always)]
    pub fn of(self, prims: u32) -> f32 {
        match self {
            CutWeight::AuxNodes => (2 * prims - 1) as f32,
            CutWeight::Primitives => prims as f32,
        }
    }
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
    /// Cap on the initial cut's size (the thesis uses 2500); `None` (default) for no cap. The
    /// cap bounds the work of the first split, but a capped cut splits the root coarsely:
    /// Sponza's PHR-HQ tree costs +4.2 % over the full sweep with the cap, +0.7 % without.
    pub max_initial_cut: Option<usize>,
}

impl PhrOptions {
    /// PHR-Fast: α = 0.5, δ = 6.
    pub const FAST: PhrOptions = PhrOptions::with(0.5, 6.0);
    /// PHR-HQ: α = 0.55, δ = 9.
    pub const HQ: PhrOptions = PhrOptions::with(0.55, 9.0);

    /// As the thesis ran it: auxiliary-node weights and an initial cut of at most 2500 nodes.
    pub const fn thesis(alpha: f32, delta: f32) -> Self {
        PhrOptions { weight: CutWeight::AuxNodes, max_initial_cut: Some(2500), ..PhrOptions::with(alpha, delta) }
    }

    pub const fn with(alpha: f32, delta: f32) -> Self {
        PhrOptions {
            alpha,
            delta,
            branching: 2,
            leaf: LeafPolicy { max_leaf_size: 8, sah: crate::metrics::SahConstants::UNIT },
            weight: CutWeight::Primitives,
            max_initial_cut: None,
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

/// Above this many primitives a node's children are built as separate rayon tasks.
const PARALLEL_GRAIN: u32 = 1 << 12;

/// Builds a BVH from the auxiliary tree `aux` (see [`AuxTree`]). The output indexes the same
/// primitives.
pub fn build_phr(aux: &AuxTree, options: &PhrOptions) -> (Bvh, PhrStats) {
    let Some(root) = aux.root() else {
        return (Bvh::default(), PhrStats::default());
    };
    let options = PhrOptions { branching: options.branching.clamp(2, MAX_BRANCHING as u32), ..*options };
    let scene_area = root.bounds.surface_area();
    let thresholds =
        (0..THRESHOLD_TABLE).map(|d| cut::threshold(scene_area, options.alpha, options.delta, d)).collect();
    let ctx = Ctx { aux, options, scene_area, thresholds, build_cost: AtomicU64::new(0) };
    let root_cut = cut::initial_cut(aux, ctx.threshold(0), options.max_initial_cut);
    let initial_cut = root_cut.len();
    let built = ctx.build(root_cut, 0);
    (assemble(built), PhrStats { build_cost: ctx.build_cost.into_inner(), initial_cut })
}

/// A node's children as ranges of its (reordered) cut; none for a leaf.
#[derive(Clone, Copy)]
struct Ranges {
    ranges: [(u32, u32); MAX_BRANCHING],
    len: usize,
}

impl Ranges {
    const LEAF: Ranges = Ranges { ranges: [(0, 0); MAX_BRANCHING], len: 0 };

    fn as_slice(&self) -> &[(u32, u32)] {
        &self.ranges[..self.len]
    }
}

/// Scratch space of one task.
#[derive(Default)]
struct Scratch {
    /// This task's share of `Σ |cut|` (one shared atomic counter would bounce between cores).
    build_cost: u64,
    split: SplitScratch,
    cut_stack: Vec<CutNode>,
    gather_stack: Vec<CutNode>,
    /// The primitives of the leaf being made.
    leaf_prims: Vec<u32>,
}

/// Depths whose threshold is computed once per build (an `exp2` per node was 3 % of PHR).
const THRESHOLD_TABLE: u32 = 128;

struct Ctx<'a> {
    aux: &'a AuxTree,
    options: PhrOptions,
    scene_area: f32,
    /// `t(d)` for `d < THRESHOLD_TABLE`.
    thresholds: Vec<f32>,
    build_cost: AtomicU64,
}

impl Ctx<'_> {
    fn threshold(&self, depth: u32) -> f32 {
        match self.thresholds.get(depth as usize) {
            Some(&t) => t,
            None => cut::threshold(self.scene_area, self.options.alpha, self.options.delta, depth),
        }
    }

    /// Builds the subtree of `cut` at `depth`: in parallel while it is large, else as a piece.
    fn build(&self, mut cut: Vec<CutNode>, depth: u32) -> Built {
        if cut_prims(&cut) <= PARALLEL_GRAIN {
            let mut piece = Piece::new();
            self.build_piece(&mut piece, cut, depth);
            return Built::Piece(piece);
        }
        let mut scratch = Scratch::default();
        let mut ranges = Ranges::LEAF;
        let bounds = self.partition(&mut cut, 0, depth, &mut scratch, &mut ranges);
        self.build_cost.fetch_add(scratch.build_cost, Ordering::Relaxed);
        if ranges.len == 0 {
            let mut piece = Piece::new();
            self.gather(&cut, &mut scratch);
            piece.set_leaf(0, bounds, scratch.leaf_prims.iter().copied());
            return Built::Piece(piece);
        }
        let t = self.threshold(depth + 1);
        let child_cuts: Vec<Vec<CutNode>> = ranges
            .as_slice()
            .iter()
            .map(|&(a, b)| {
                let mut child = Vec::with_capacity((b - a) as usize * 2);
                for &n in &cut[a as usize..b as usize] {
                    self.aux.refine_into(n, t, &mut child, &mut scratch.cut_stack);
                }
                child
            })
            .collect();
        drop(cut);
        let children = child_cuts.into_par_iter().map(|c| self.build(c, depth + 1)).collect();
        Built::Split { bounds, children }
    }

    /// Builds a subtree sequentially into `piece`, its root at slot 0.
    ///
    /// All cuts live in one vector used as a stack. Children's refined cuts are pushed above
    /// their parent's and processed last first; when a task is popped, everything above its
    /// segment is the dead cuts of finished nodes and is dropped, so its cut is the top
    /// segment `pool[start..]`.
    fn build_piece(&self, piece: &mut Piece, cut: Vec<CutNode>, depth: u32) {
        let mut scratch = Scratch::default();
        let mut pool = cut;
        let mut tasks = vec![(0usize, pool.len(), depth, 0u32)];
        let mut ranges = Ranges::LEAF;
        while let Some((start, end, depth, slot)) = tasks.pop() {
            pool.truncate(end);
            let bounds = self.partition(&mut pool, start, depth, &mut scratch, &mut ranges);
            if ranges.len == 0 {
                self.gather(&pool[start..], &mut scratch);
                piece.set_leaf(slot, bounds, scratch.leaf_prims.iter().copied());
                pool.truncate(start);
                continue;
            }
            let k = ranges.len as u32;
            let first = piece.alloc_children(k);
            piece.set_interior(slot, bounds, first, k);
            let t = self.threshold(depth + 1);
            // Pushed last child first, so the first child is built next: the children of
            // auxiliary nodes then come in the order the auxiliary tree stores them (first
            // child's subtree right after its parent), and the walk reads memory forwards.
            for (i, &(a, b)) in ranges.as_slice().iter().enumerate().rev() {
                let child_start = pool.len();
                for j in start + a as usize..start + b as usize {
                    let n = pool[j];
                    self.aux.refine_into(n, t, &mut pool, &mut scratch.cut_stack);
                }
                tasks.push((child_start, pool.len(), depth + 1, first + i as u32));
            }
        }
        self.build_cost.fetch_add(scratch.build_cost, Ordering::Relaxed);
    }

    /// The split of a node's cut at `depth`: the full sweep, or the median past
    /// [`MEDIAN_SPLIT_DEPTH`].
    fn split(&self, cut: &mut [CutNode], depth: u32, scratch: &mut Scratch) -> CutSplit {
        if depth >= MEDIAN_SPLIT_DEPTH {
            median_split(cut)
        } else {
            best_split(cut, self.options.weight, &mut scratch.split)
        }
    }

    /// Decides leaf or children for the node at `depth` whose cut is `pool[start..]`, and
    /// counts the cut into the build cost. Returns the node's box; its children go to `ranges`
    /// (an out-parameter: returned by value, the 136-byte array cost a memcpy per node) as ranges
    /// of the (reordered) cut, relative to `start`.
    fn partition(
        &self,
        pool: &mut Vec<CutNode>,
        start: usize,
        depth: u32,
        scratch: &mut Scratch,
        ranges: &mut Ranges,
    ) -> Aabb {
        ranges.len = 0;
        scratch.build_cost += (pool.len() - start) as u64;
        // A cut of one interior node is opened: a node with a single child would only add a
        // traversal step, and keeping it whole is the thesis code's giant-leaf defect.
        while pool.len() - start == 1 && !pool[start].is_leaf() {
            let n = pool.pop().expect("non-empty");
            self.aux.push_children(&n, pool);
        }
        let cut = &mut pool[start..];
        let bounds = cut_bounds(cut);
        if cut.len() < 2 {
            return bounds;
        }
        let leaf = &self.options.leaf;
        let n = cut_prims(cut);
        let first = self.split(cut, depth, scratch);
        if !leaf.must_split(n) && leaf.prefers_leaf(n, bounds.surface_area(), first.area_count) {
            return bounds;
        }
        ranges.ranges[0] = (0, first.left_len as u32);
        ranges.ranges[1] = (first.left_len as u32, cut.len() as u32);
        ranges.len = 2;
        // Multi-BVH: split the largest child cut again while that helps.
        let mut done = [false; MAX_BRANCHING];
        while ranges.len < self.options.branching as usize {
            let candidate = (0..ranges.len)
                .filter(|&i| !done[i] && ranges.ranges[i].1 - ranges.ranges[i].0 >= 2)
                .map(|i| {
                    let (a, b) = ranges.ranges[i];
                    (cut_bounds(&cut[a as usize..b as usize]).surface_area(), i)
                })
                .max_by(|x, y| x.0.total_cmp(&y.0).then(y.1.cmp(&x.1)));
            let Some((area, i)) = candidate else { break };
            let (a, b) = ranges.ranges[i];
            let sub = &mut cut[a as usize..b as usize];
            let n = cut_prims(sub);
            let s = self.split(sub, depth, scratch);
            if leaf.must_split(n) || !leaf.prefers_leaf(n, area, s.area_count) {
                let mid = a + s.left_len as u32;
                ranges.ranges[i] = (a, mid);
                ranges.ranges[ranges.len] = (mid, b);
                ranges.len += 1;
            } else {
                done[i] = true;
            }
        }
        bounds
    }

    /// The primitives under the cut's nodes, into `scratch.leaf_prims`.
    fn gather(&self, cut: &[CutNode], scratch: &mut Scratch) {
        scratch.leaf_prims.clear();
        for n in cut {
            self.aux.gather_prims(n, &mut scratch.leaf_prims, &mut scratch.gather_stack);
        }
    }
}
