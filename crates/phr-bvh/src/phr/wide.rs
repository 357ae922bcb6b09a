//! PHR straight to the wide layout the renderer traces (direct k-ary output).
//!
//! [`build_phr`](super::build_phr) makes a binary tree, which
//! [`WideBvh::rebuild`] then collapses: it reads the whole tree again, keeps a second copy of
//! it, merges the subtrees of at most 4 primitives into leaves and fills each wide node by the
//! greedy rule (open the interior slot of largest area while its children fit). On the
//! dragon that collapse took about as long as PHR itself.
//!
//! Here PHR fills the wide nodes as it splits, by the same rule: a wide node starts with the
//! two halves of a cut's split; while there is room, the interior slot of largest area is
//! split in turn (refined at its depth, as binary PHR refines it). A cut of at most 4
//! primitives becomes a leaf at once, without the splits binary PHR spends on it and the
//! collapse then undoes. The result is the tree the collapse makes of binary PHR's: the same
//! wide nodes with the same boxes and the same leaves (only the order of nodes in memory and
//! of primitives within a leaf may differ), which `tests/phr_wide.rs` checks. `Σ |cut|` counts
//! the cuts split, so it is smaller than binary PHR's by those small cuts.
//!
//! Near the root the interior slots of a wide node are built as rayon tasks; below
//! [`PARALLEL_GRAIN`] primitives one task builds its subtree into a piece, keeping all its
//! cuts in one vector used as a stack, as [`build_phr`](super::build_phr) does.

use super::cut::{cut_bounds, cut_prims, CutNode};
use super::{AuxTree, Ctx, PhrOptions, PhrStats, Ranges, Scratch, THRESHOLD_TABLE};
use crate::aabb::Aabb;
use crate::wide::pieces::{assemble, build_piece, place_leaf, slots_by_size, WideBuilt, WidePiece};
use crate::wide::{CollapseOptions, WideBvh, WideNode};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};

/// Above this many primitives a wide node's interior slots are built as separate tasks.
const PARALLEL_GRAIN: u32 = 1 << 15;

/// A node of the binary PHR tree, held as a slot of the wide node being filled. (Small: the
/// greedy fill copies slots around; its children's ranges live in [`WideScratch`].)
#[derive(Clone, Copy, Default)]
struct Slot {
    bounds: Aabb,
    area: f32,
    prims: u32,
    /// Its cut is `pool[start..end]`, ordered by its split.
    start: u32,
    end: u32,
    /// Its depth in the binary tree (what PHR's thresholds count).
    depth: u32,
    /// Its children are the ranges `children[first_child..first_child + kids]` of its cut
    /// (relative to `start`); no children for a leaf.
    first_child: u32,
    kids: u32,
}

impl Slot {
    fn is_leaf(&self) -> bool {
        self.kids == 0
    }
}

/// Scratch space of one task.
#[derive(Default)]
struct WideScratch {
    phr: Scratch,
    /// Where [`Ctx::partition`] puts a split's ranges.
    ranges: Ranges,
    /// The children's ranges of every slot of this task.
    children: Vec<(u32, u32)>,
}

impl Default for Ranges {
    fn default() -> Self {
        Ranges::LEAF
    }
}

/// Builds an `N`-wide tree from the auxiliary tree `aux` with PHR into `into` (its memory
/// reused), leaves of up to 4 primitives within one 4-lane triangle block each, as
/// [`WideBvh::rebuild`] makes them from [`build_phr`](super::build_phr)'s tree. A branching
/// factor above `N` is taken as `N`.
pub fn build_phr_wide<const N: usize>(aux: &AuxTree, options: &PhrOptions, into: &mut WideBvh<N>) -> PhrStats {
    let mut nodes = std::mem::take(&mut into.nodes);
    let mut prims = std::mem::take(&mut into.prim_indices);
    nodes.clear();
    prims.clear();
    into.stack_bound = 0;
    let Some(root) = aux.root() else {
        (into.nodes, into.prim_indices) = (nodes, prims);
        return PhrStats::default();
    };
    let options = PhrOptions { branching: options.branching.clamp(2, N as u32), ..*options };
    let scene_area = root.bounds.surface_area();
    let thresholds =
        (0..THRESHOLD_TABLE).map(|d| super::cut::threshold(scene_area, options.alpha, options.delta, d)).collect();
    let ctx = Ctx { aux, options, scene_area, thresholds, build_cost: AtomicU64::new(0) };
    let collapse = CollapseOptions::default();
    let wide = WideCtx { ctx: &ctx, merge: collapse.merge_leaves, align: collapse.leaf_align as usize };
    let mut pool = super::cut::initial_cut(aux, ctx.threshold(0), options.max_initial_cut);
    let initial_cut = pool.len();
    let mut scratch = WideScratch::default();
    let root = wide.slot(&mut pool, 0, 0, &mut scratch);
    ctx.build_cost.fetch_add(scratch.phr.build_cost, Ordering::Relaxed);
    let built = wide.build::<N>(pool, root, scratch.children, 0);
    assemble(&built, &mut nodes, &mut prims, wide.align);
    (into.nodes, into.prim_indices, into.stack_bound) = (nodes, prims, built.bound());
    PhrStats { build_cost: ctx.build_cost.into_inner(), initial_cut }
}

struct WideCtx<'a, 'b> {
    ctx: &'b Ctx<'a>,
    /// Cuts of at most this many primitives become leaves.
    merge: u32,
    /// The block of entries no small leaf crosses ([`place_leaf`]).
    align: usize,
}

impl WideCtx<'_, '_> {
    /// The slot of the cut `pool[start..]` (the top of the pool) at `depth`: a leaf if it is
    /// small enough to merge, else split by PHR.
    fn slot(&self, pool: &mut Vec<CutNode>, start: usize, depth: u32, scratch: &mut WideScratch) -> Slot {
        let prims = cut_prims(&pool[start..]);
        let first_child = scratch.children.len() as u32;
        let bounds = if prims <= self.merge {
            scratch.ranges.len = 0;
            cut_bounds(&pool[start..])
        } else {
            let bounds = self.ctx.partition(pool, start, depth, &mut scratch.phr, &mut scratch.ranges);
            scratch.children.extend_from_slice(scratch.ranges.as_slice());
            bounds
        };
        let (start, end) = (start as u32, pool.len() as u32);
        let kids = scratch.ranges.len as u32;
        Slot { bounds, area: bounds.surface_area(), prims, start, end, depth, first_child, kids }
    }

    /// The slots of the wide node made from `root` (an interior slot whose cut is in
    /// `pool`), into `slots`: its children, then greedily the children of the interior slot
    /// of largest area while they fit. A root that is a leaf gives one slot, itself. Returns
    /// the number of slots.
    fn slots<const N: usize>(
        &self,
        pool: &mut Vec<CutNode>,
        root: Slot,
        slots: &mut [Slot; N],
        scratch: &mut WideScratch,
    ) -> usize {
        slots[0] = root;
        if root.is_leaf() {
            return 1;
        }
        let mut k = self.open(pool, root, slots, 0, 1, scratch);
        loop {
            let open = (0..k)
                .filter(|&i| !slots[i].is_leaf() && k - 1 + slots[i].kids as usize <= N)
                .max_by(|&i, &j| slots[i].area.total_cmp(&slots[j].area));
            let Some(i) = open else { return k };
            k = self.open(pool, slots[i], slots, i, k, scratch);
        }
    }

    /// Refines the children of interior slot `s` at their depth and makes each a slot: the
    /// first goes to `slots[at]`, the others to `slots[k..]`. Returns the new slot count.
    fn open<const N: usize>(
        &self,
        pool: &mut Vec<CutNode>,
        s: Slot,
        slots: &mut [Slot; N],
        at: usize,
        mut k: usize,
        scratch: &mut WideScratch,
    ) -> usize {
        let t = self.ctx.threshold(s.depth + 1);
        for c in 0..s.kids {
            let (a, b) = scratch.children[(s.first_child + c) as usize];
            let child_start = pool.len();
            for j in (s.start + a) as usize..(s.start + b) as usize {
                let n = pool[j];
                self.ctx.aux.refine_into(n, t, pool, &mut scratch.phr.cut_stack);
            }
            let child = self.slot(pool, child_start, s.depth + 1, scratch);
            if c == 0 {
                slots[at] = child;
            } else {
                slots[k] = child;
                k += 1;
            }
        }
        k
    }

    /// Appends the primitives of leaf slot `s` to `prims`, placed within a block
    /// ([`place_leaf`]); returns where they start and how many there are.
    fn emit_leaf(&self, pool: &[CutNode], s: &Slot, prims: &mut Vec<u32>, scratch: &mut Scratch) -> (u32, u32) {
        self.ctx.gather(&pool[s.start as usize..s.end as usize], scratch);
        let start = prims.len();
        prims.extend_from_slice(&scratch.leaf_prims);
        (place_leaf(prims, start, self.align) as u32, scratch.leaf_prims.len() as u32)
    }

    /// The wide node over `slots`, each in the node slot [`slots_by_size`] gives it: every
    /// slot's box, leaves emitted into `prims`, and for each interior slot the child index
    /// that `interior(node slot, slot)` returns (called in the order of `slots`).
    fn node<const N: usize>(
        &self,
        pool: &[CutNode],
        slots: &[Slot],
        prims: &mut Vec<u32>,
        scratch: &mut WideScratch,
        mut interior: impl FnMut(usize, &Slot) -> u32,
    ) -> WideNode<N> {
        let mut node = WideNode::<N>::EMPTY;
        let at = slots_by_size::<N>(slots.iter().map(|s| s.prims));
        for (&i, s) in at.iter().zip(slots) {
            node.set_child_bounds(i, s.bounds);
            if s.is_leaf() {
                (node.child[i], node.count[i]) = self.emit_leaf(pool, s, prims, &mut scratch.phr);
            } else {
                node.child[i] = interior(i, s);
            }
        }
        node
    }

    /// Builds the subtree of `root` (whose cut is in `pool`, its children's ranges in
    /// `children`) at stack depth `depth`: in parallel while it is large, else as a piece.
    fn build<const N: usize>(
        &self,
        mut pool: Vec<CutNode>,
        root: Slot,
        children: Vec<(u32, u32)>,
        depth: usize,
    ) -> WideBuilt<N> {
        let mut scratch = WideScratch { children, ..WideScratch::default() };
        if root.prims <= PARALLEL_GRAIN || root.is_leaf() {
            return WideBuilt::Piece(self.piece(pool, root, depth, scratch));
        }
        let mut slots = [Slot::default(); N];
        let k = self.slots(&mut pool, root, &mut slots, &mut scratch);
        let depth = depth + k - 1;
        let (mut leaf_prims, mut interior) = (Vec::new(), Vec::new());
        let node = self.node(&pool, &slots[..k], &mut leaf_prims, &mut scratch, |i, s| {
            // The slot's cut moves to a vector of its own, its ranges relative to it.
            let cut = pool[s.start as usize..s.end as usize].to_vec();
            interior.push((i, cut, *s));
            0
        });
        let interior: Vec<_> = interior
            .into_iter()
            .map(|(i, cut, s)| {
                let ranges = scratch.children[s.first_child as usize..(s.first_child + s.kids) as usize].to_vec();
                (i, cut, Slot { start: 0, end: s.end - s.start, first_child: 0, ..s }, ranges)
            })
            .collect();
        self.ctx.build_cost.fetch_add(scratch.phr.build_cost, Ordering::Relaxed);
        drop(pool);
        let children: Vec<(usize, WideBuilt<N>)> =
            interior.into_par_iter().map(|(i, cut, s, ranges)| (i, self.build(cut, s, ranges, depth))).collect();
        let bound = children.iter().map(|(_, c)| c.bound()).max().unwrap_or(0).max(depth);
        WideBuilt::Split { node, leaf_prims, children, bound }
    }

    /// Builds the subtree of `root` sequentially, depth first (children of a node stored
    /// consecutively).
    ///
    /// All cuts live in `pool`, used as a stack: a wide node's slots are refined above the
    /// cut it was made from. Its interior slots are then taken highest in the pool first, so
    /// when one is taken everything above its cut is dead (opened slots, leaves already
    /// emitted, finished siblings) and is dropped.
    fn piece<const N: usize>(
        &self,
        mut pool: Vec<CutNode>,
        root: Slot,
        depth: usize,
        mut scratch: WideScratch,
    ) -> WidePiece<N> {
        let mut slots = [Slot::default(); N];
        // Items: a slot whose children fill a wide node.
        let piece = build_piece(
            root,
            depth,
            self.align,
            |slot, prims, children| {
                pool.truncate(slot.end as usize);
                let k = self.slots(&mut pool, slot, &mut slots, &mut scratch);
                (self.node(&pool, &slots[..k], prims, &mut scratch, |_, s| children.push(*s)), k)
            },
            // The slot highest in the pool is built next: everything above its cut is dead.
            |pushed| pushed.sort_unstable_by_key(|(s, _, _)| s.start),
        );
        self.ctx.build_cost.fetch_add(scratch.phr.build_cost, Ordering::Relaxed);
        piece
    }
}
