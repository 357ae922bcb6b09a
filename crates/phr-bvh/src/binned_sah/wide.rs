//! The binned SAH straight to the wide layout the renderer traces, as Embree's builders make
//! their BVH4 and BVH8 (direct k-ary output).
//!
//! [`build_binned_sah`](super::build_binned_sah) makes a binary tree that
//! [`WideBvh::rebuild`] then collapses: a second pass over the whole tree, and a second copy
//! of it (on the dragon the collapse took a sixth of the build). Here the wide nodes are
//! filled as the builder splits, by the collapse's own rule: a wide node starts with the two
//! halves of a split; while there is room, the slot of largest area that the SAH splits is
//! split in turn. A slot of at most 4 primitives becomes a leaf at once, without the splits
//! the collapse would undo. The tree is the collapse of the binary builder's: the same wide
//! nodes with the same boxes and leaves (only the order of nodes in memory and of primitives
//! within a leaf may differ), which `tests/binned_sah_wide.rs` checks.
//!
//! The references are partitioned in place as in the binary build, so every slot is a range
//! of them. Near the root the interior slots of a wide node are built as rayon tasks, each
//! on its own range; below [`PARALLEL_GRAIN`] primitives one task builds its subtree into a
//! piece.

use super::{BinnedSahOptions, Bins, Bounds, Ctx, Decision, PrimRef, MAX_PRIMS};
use crate::aabb::Aabb;
use crate::wide::pieces::{assemble, build_piece, place_leaf, slots_by_size, WideBuilt, WidePiece};
use crate::wide::{CollapseOptions, WideBvh, WideNode};
use rayon::prelude::*;

/// Above this many primitives a wide node's interior slots are built as separate tasks.
const PARALLEL_GRAIN: usize = 1 << 12;

/// A node of the binary tree, held as a slot of the wide node being filled: the references
/// `start..end` (of the task's range) with their bounds.
#[derive(Clone, Copy)]
struct Slot {
    bounds: Bounds,
    area: f32,
    start: u32,
    end: u32,
    /// Its depth in the binary tree (what the builder's depth cap counts).
    depth: u32,
    /// Whether it is a leaf: small enough to merge, or the SAH keeps it whole.
    leaf: bool,
}

/// How the SAH split an interior slot: its left side is `start..mid`.
#[derive(Clone, Copy)]
struct Split {
    mid: u32,
    left: Bounds,
    right: Bounds,
}

/// A slot split beforehand ([`WideCtx::presplit`]).
struct Known {
    start: u32,
    end: u32,
    split: Option<Split>,
}

impl Slot {
    fn len(&self) -> usize {
        (self.end - self.start) as usize
    }

    /// The slot moved to the start of a range of its own.
    fn rebased(self, split: Option<Split>) -> (Slot, Option<Split>) {
        let split = split.map(|s| Split { mid: s.mid - self.start, ..s });
        (Slot { start: 0, end: self.end - self.start, ..self }, split)
    }
}

/// Builds an `N`-wide tree over `boxes` with the binned SAH into `into` (its memory reused),
/// leaves of up to 4 primitives within one 4-lane triangle block each: the tree
/// [`WideBvh::rebuild`] makes from [`build_binned_sah`](super::build_binned_sah)'s.
pub fn build_binned_sah_wide<const N: usize>(boxes: &[Aabb], options: &BinnedSahOptions, into: &mut WideBvh<N>) {
    let mut nodes = std::mem::take(&mut into.nodes);
    let mut prims = std::mem::take(&mut into.prim_indices);
    nodes.clear();
    prims.clear();
    into.stack_bound = 0;
    if boxes.is_empty() {
        (into.nodes, into.prim_indices) = (nodes, prims);
        return;
    }
    assert!(boxes.len() < MAX_PRIMS, "the binned SAH builder takes fewer than 2^30 primitives");
    let mut refs: Vec<PrimRef> = boxes.par_iter().enumerate().map(|(i, b)| PrimRef::new(i, b)).collect();
    let collapse = CollapseOptions::default();
    let wide =
        WideCtx { ctx: Ctx::new(options), merge: collapse.merge_leaves as usize, align: collapse.leaf_align as usize };
    let root = wide.slot(Bounds::of(&refs), 0, refs.len(), 0);
    let split = wide.split(&mut refs, &root, &mut Bins::boxed());
    let built = wide.build::<N>(&mut refs, root, split, Vec::new(), 0);
    assemble(&built, &mut nodes, &mut prims, wide.align);
    (into.nodes, into.prim_indices, into.stack_bound) = (nodes, prims, built.bound());
}

struct WideCtx {
    ctx: Ctx,
    /// Slots of at most this many primitives become leaves.
    merge: usize,
    /// The block of entries no small leaf crosses ([`place_leaf`]).
    align: usize,
}

impl WideCtx {
    fn slot(&self, bounds: Bounds, start: usize, end: usize, depth: u32) -> Slot {
        let leaf = end - start <= self.merge;
        Slot { bounds, area: bounds.aabb().surface_area(), start: start as u32, end: end as u32, depth, leaf }
    }

    /// Splits slot `s` (of `refs`) if it is no leaf and the SAH says so.
    fn split(&self, refs: &mut [PrimRef], s: &Slot, bins: &mut Bins) -> Option<Split> {
        if s.leaf {
            return None;
        }
        match self.ctx.decide(&mut refs[s.start as usize..s.end as usize], &s.bounds, s.depth, bins) {
            Decision::Leaf => None,
            Decision::Split(k, left, right) => Some(Split { mid: s.start + k as u32, left, right }),
        }
    }

    /// The two slots of `split`, the split of `s`.
    fn halves(&self, s: &Slot, split: &Split) -> [Slot; 2] {
        let (start, mid, end) = (s.start as usize, split.mid as usize, s.end as usize);
        [self.slot(split.left, start, mid, s.depth + 1), self.slot(split.right, mid, end, s.depth + 1)]
    }

    /// The slots of the wide node made from `root` and its split: the two halves, then
    /// greedily the halves of the slot of largest area that splits, while there is room.
    /// Leaves the split of each interior slot in `splits`; returns the number of slots.
    /// Slots split beforehand are taken from `known`.
    fn slots<const N: usize>(
        &self,
        refs: &mut [PrimRef],
        (root, split): (Slot, Option<Split>),
        slots: &mut [Slot; N],
        splits: &mut [Option<Split>; N],
        known: &[Known],
        bins: &mut Bins,
    ) -> usize {
        let mut split_slot =
            |s: &Slot, bins: &mut Bins| match known.iter().find(|k| (k.start, k.end) == (s.start, s.end)) {
                Some(k) => k.split,
                None => self.split(refs, s, bins),
            };
        let Some(split) = split else {
            (slots[0], splits[0]) = (Slot { leaf: true, ..root }, None);
            return 1;
        };
        [slots[0], slots[1]] = self.halves(&root, &split);
        splits[..2].fill(None);
        let mut k = 2;
        // Slots are split when chosen: one the SAH keeps whole is a leaf and is passed over,
        // so the choice is the collapse's, which knows the leaves beforehand.
        while k < N {
            let open = (0..k).filter(|&i| !slots[i].leaf).max_by(|&i, &j| slots[i].area.total_cmp(&slots[j].area));
            let Some(i) = open else { break };
            match split_slot(&slots[i], bins) {
                None => slots[i].leaf = true,
                Some(split) => {
                    [slots[i], slots[k]] = self.halves(&slots[i], &split);
                    k += 1;
                }
            }
        }
        for i in 0..k {
            splits[i] = split_slot(&slots[i], bins);
            slots[i].leaf = splits[i].is_none();
        }
        k
    }

    /// Appends the primitives of leaf slot `s` to `prims`, placed within a block
    /// ([`place_leaf`]); returns where they start and how many there are.
    fn emit_leaf(&self, refs: &[PrimRef], s: &Slot, prims: &mut Vec<u32>) -> (u32, u32) {
        let start = prims.len();
        prims.extend(refs[s.start as usize..s.end as usize].iter().map(PrimRef::index));
        (place_leaf(prims, start, self.align) as u32, s.len() as u32)
    }

    /// The wide node over `slots`, each in the node slot [`slots_by_size`] gives it: every
    /// slot's box, leaves emitted into `prims`, and for each interior slot the child index
    /// that `interior(index in slots, node slot)` returns (called in the order of `slots`).
    fn node<const N: usize>(
        &self,
        refs: &[PrimRef],
        slots: &[Slot],
        prims: &mut Vec<u32>,
        mut interior: impl FnMut(usize, usize) -> u32,
    ) -> WideNode<N> {
        let mut node = WideNode::<N>::EMPTY;
        let at = slots_by_size::<N>(slots.iter().map(|s| s.len() as u32));
        for (i, (&slot, s)) in at.iter().zip(slots).enumerate() {
            node.set_child_bounds(slot, s.bounds.aabb());
            if s.leaf {
                (node.child[slot], node.count[slot]) = self.emit_leaf(refs, s, prims);
            } else {
                node.child[slot] = interior(i, slot);
            }
        }
        node
    }

    /// Splits slot `s` (all of `refs`) and its halves, `levels` levels deep, on both sides in
    /// parallel, unless `known` has the split: what the wide node above will ask for, made
    /// beforehand (filling a wide node asks for its splits one after the other, the largest
    /// slot first, which left one core idle through the first levels of the tree). Returns the
    /// splits it made. Every one is used: by the wide node, or by its interior slots' own.
    fn presplit(&self, refs: &mut [PrimRef], s: Slot, levels: u32, known: &[Known]) -> Vec<Known> {
        let mut made = Vec::new();
        let split = match known.iter().find(|k| (k.start, k.end) == (s.start, s.end)) {
            Some(k) => k.split,
            None => {
                let relative = Slot { start: 0, end: s.len() as u32, ..s };
                let split = self.split(refs, &relative, &mut Bins::boxed());
                let split = split.map(|sp| Split { mid: sp.mid + s.start, ..sp });
                made.push(Known { start: s.start, end: s.end, split });
                split
            }
        };
        if let (Some(split), true) = (split, levels > 1) {
            let [l, r] = self.halves(&s, &split);
            let (a, b) = refs.split_at_mut((split.mid - s.start) as usize);
            let (left, right) =
                rayon::join(|| self.presplit(a, l, levels - 1, known), || self.presplit(b, r, levels - 1, known));
            made.extend(left);
            made.extend(right);
        }
        made
    }

    /// Builds the subtree of `root` (all of `refs`), split by `split`, at stack depth
    /// `depth`, with the splits in `known` made before: in parallel while it is large, else as
    /// a piece.
    fn build<const N: usize>(
        &self,
        refs: &mut [PrimRef],
        root: Slot,
        split: Option<Split>,
        mut known: Vec<Known>,
        depth: usize,
    ) -> WideBuilt<N> {
        let Some(root_split) = split.filter(|_| root.len() > PARALLEL_GRAIN) else {
            return WideBuilt::Piece(self.piece(refs, root, split, &known, depth));
        };
        let [l, r] = self.halves(&root, &root_split);
        let (a, b) = refs.split_at_mut(root_split.mid as usize);
        let levels = N.ilog2();
        let (left, right) = rayon::join(|| self.presplit(a, l, levels, &known), || self.presplit(b, r, levels, &known));
        known.extend(left);
        known.extend(right);
        let (mut slots, mut splits) = ([root; N], [None; N]);
        let k = self.slots(refs, (root, split), &mut slots, &mut splits, &known, &mut Bins::boxed());
        let depth = depth + k - 1;
        let mut leaf_prims = Vec::new();
        let mut interior = Vec::new();
        let node = self.node(refs, &slots[..k], &mut leaf_prims, |i, slot| {
            interior.push((i, slot));
            0
        });
        // Each interior slot gets its own range of the references (they are disjoint), and
        // the splits made within it.
        interior.sort_unstable_by_key(|&(i, _)| slots[i].start);
        let (mut rest, mut offset) = (refs, 0usize);
        let mut jobs = Vec::with_capacity(interior.len());
        for (i, slot) in interior {
            let s = slots[i];
            let (_, tail) = std::mem::take(&mut rest).split_at_mut(s.start as usize - offset);
            let (mine, tail) = tail.split_at_mut(s.len());
            (rest, offset) = (tail, s.end as usize);
            let within = known
                .iter()
                .filter(|k| k.start >= s.start && k.end <= s.end)
                .map(|k| Known {
                    start: k.start - s.start,
                    end: k.end - s.start,
                    split: k.split.map(|sp| Split { mid: sp.mid - s.start, ..sp }),
                })
                .collect();
            let (s, split) = s.rebased(splits[i]);
            jobs.push((slot, mine, s, split, within));
        }
        let children: Vec<(usize, WideBuilt<N>)> = jobs
            .into_par_iter()
            .map(|(slot, mine, s, split, within)| (slot, self.build(mine, s, split, within, depth)))
            .collect();
        let bound = children.iter().map(|(_, c)| c.bound()).max().unwrap_or(0).max(depth);
        WideBuilt::Split { node, leaf_prims, children, bound }
    }

    /// Builds the subtree of `root` sequentially, depth first (children of a node stored
    /// consecutively).
    fn piece<const N: usize>(
        &self,
        refs: &mut [PrimRef],
        root: Slot,
        split: Option<Split>,
        known: &[Known],
        depth: usize,
    ) -> WidePiece<N> {
        let mut bins = Bins::boxed();
        let (mut slots, mut splits) = ([root; N], [None; N]);
        // Items: a slot whose halves fill a wide node, and its split.
        build_piece(
            (root, split),
            depth,
            self.align,
            |item, prims, children| {
                let k = self.slots(refs, item, &mut slots, &mut splits, known, &mut bins);
                (self.node(refs, &slots[..k], prims, |i, _| children.push((slots[i], splits[i]))), k)
            },
            // The first slot made (not node slot 0: see `slots_by_size`) is built first.
            |pushed| pushed.reverse(),
        )
    }
}
