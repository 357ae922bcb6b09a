//! Wide trees built in pieces, by the collapse ([`super::collapse`]) and by PHR's direct
//! wide output ([`crate::phr::wide`]).
//!
//! Near the root, where subtrees are large, each wide node's interior slots are built as
//! separate rayon tasks ([`WideBuilt::Split`]); below, one task builds a whole subtree depth
//! first into a [`WidePiece`] with local indices. [`assemble`] lays the top out first and the
//! pieces after it, in an order that does not depend on the thread count, and copies the
//! pieces in parallel, relocating their indices.

use super::{WideNode, PAD};

impl<const N: usize> WidePiece<N> {
    /// A piece whose root (node 0) is still to be filled.
    pub fn new() -> Self {
        WidePiece { nodes: vec![WideNode::<N>::EMPTY], prims: Vec::new(), bound: 0 }
    }
}

/// Places the leaf just appended at `prims[start..]` so that it straddles no more blocks of
/// `block` entries than it must: a leaf of at most `block` primitives lies within one block
/// (it is moved past [`PAD`] entries to the next block if it would cross a boundary), a
/// larger one starts a block. Small leaves thus share blocks instead of each padding one out.
/// Returns where the leaf starts.
#[inline]
pub(crate) fn place_leaf(prims: &mut Vec<u32>, start: usize, block: usize) -> usize {
    let (count, offset) = (prims.len() - start, start % block);
    if offset == 0 || offset + count <= block {
        return start;
    }
    let pad = block - offset;
    prims.splice(start..start, std::iter::repeat_n(PAD, pad));
    start + pad
}

/// Where each of a wide node's children goes: the slots ordered by the number of primitives
/// under each child, largest first (equal sizes keep their order), given the sizes in the
/// order the builder made the children. This is Embree's order "for faster shadow ray
/// traversal": an any-hit query visits the last hit slot first, the smallest subtree, which
/// is the one most likely to end the query soonest; closest-hit queries sort the hit
/// children by distance and do not care. Only the slots move: the builders still lay the
/// children's subtrees out in the order they made them, which keeps their memory order.
#[inline]
pub(crate) fn slots_by_size<const N: usize>(sizes: impl Iterator<Item = u32>) -> [usize; N] {
    let mut size = [0u32; N];
    let mut k = 0;
    for s in sizes {
        size[k] = s;
        k += 1;
    }
    // A child's slot is the number of children before it in the order: larger ones, and
    // equal ones made before it. (Entries past the children keep their own index.)
    std::array::from_fn(|i| {
        if i >= k {
            return i;
        }
        (0..k).filter(|&j| size[j] > size[i] || (size[j] == size[i] && j < i)).count()
    })
}

/// Pads `prims` to a whole number of blocks of `block` entries (the end of a piece, so the
/// next piece starts a block).
#[inline]
pub(crate) fn pad_to_block(prims: &mut Vec<u32>, block: usize) {
    prims.resize(prims.len().next_multiple_of(block), PAD);
}

/// Where the wide node being filled by [`build_piece`] puts its interior slots' subtrees.
pub(crate) struct Children<'a, W, const N: usize> {
    /// Each interior slot's item, the node it fills and the stack depth above it (set when
    /// the node is made).
    work: &'a mut Vec<(W, usize, usize)>,
    nodes: &'a mut Vec<WideNode<N>>,
}

impl<W, const N: usize> Children<'_, W, N> {
    /// Reserves the node of an interior slot whose subtree `item` makes; returns its index.
    #[inline]
    pub fn push(&mut self, item: W) -> u32 {
        self.work.push((item, self.nodes.len(), 0));
        self.nodes.push(WideNode::<N>::EMPTY);
        (self.nodes.len() - 1) as u32
    }
}

/// Builds a subtree sequentially into a piece, depth first, the children of a node stored
/// consecutively: what the collapse and the direct wide builders share below their parallel
/// top. `fill(item, prims, children)` makes an item's wide node, emitting its leaves into
/// `prims` and [`Children::push`]ing each interior slot's item, and returns the node and its
/// number of slots (the stack depth grows by that less one). `order` arranges one node's
/// pushed items, of which the last is built next.
pub(crate) fn build_piece<W, const N: usize>(
    root: W,
    depth: usize,
    align: usize,
    mut fill: impl FnMut(W, &mut Vec<u32>, &mut Children<'_, W, N>) -> (WideNode<N>, usize),
    order: impl Fn(&mut [(W, usize, usize)]),
) -> WidePiece<N> {
    let mut piece = WidePiece::new();
    let mut work = vec![(root, 0usize, depth)];
    while let Some((item, w, depth)) = work.pop() {
        let pending = work.len();
        let (node, k) = fill(item, &mut piece.prims, &mut Children { work: &mut work, nodes: &mut piece.nodes });
        let depth = depth + k - 1;
        piece.bound = piece.bound.max(depth);
        work[pending..].iter_mut().for_each(|(_, _, d)| *d = depth);
        order(&mut work[pending..]);
        piece.nodes[w] = node;
    }
    pad_to_block(&mut piece.prims, align);
    piece
}

/// Wide nodes and leaf primitives of one subtree, with local indices: its root is node 0,
/// interior slots index `nodes`, leaf slots index `prims` (whose length is a whole number of
/// blocks, so the piece can be placed at any block boundary). `bound` is the stack bound
/// of the subtree, counted from the depth it was built at.
pub(crate) struct WidePiece<const N: usize> {
    pub nodes: Vec<WideNode<N>>,
    pub prims: Vec<u32>,
    pub bound: usize,
}

/// A built subtree: a piece, or (near the root, where subtrees are large) one wide node
/// whose interior slots were built as separate tasks.
pub(crate) enum WideBuilt<const N: usize> {
    Piece(WidePiece<N>),
    Split {
        /// The node, with its leaf slots indexing `leaf_prims` and interior slots unset.
        node: WideNode<N>,
        leaf_prims: Vec<u32>,
        /// Interior slots and what fills them.
        children: Vec<(usize, WideBuilt<N>)>,
        bound: usize,
    },
}

impl<const N: usize> WideBuilt<N> {
    pub fn bound(&self) -> usize {
        match self {
            WideBuilt::Piece(p) => p.bound,
            WideBuilt::Split { bound, .. } => *bound,
        }
    }
}

/// Where a piece goes in the output.
struct Placement<'a, const N: usize> {
    piece: &'a WidePiece<N>,
    node_offset: usize,
    prim_offset: usize,
}

/// Lays out the parallel top first (depth first), then every piece after it, and copies
/// the pieces in parallel, relocating their indices. `nodes` and `prims` start empty.
pub(crate) fn assemble<const N: usize>(
    root: &WideBuilt<N>,
    nodes: &mut Vec<WideNode<N>>,
    prims: &mut Vec<u32>,
    align: usize,
) {
    // The top: (built, node index it fills). Pieces get their offsets in a second pass.
    let mut stack = vec![(root, None::<(usize, usize)>)];
    let mut pieces: Vec<(&WidePiece<N>, Option<(usize, usize)>)> = Vec::new();
    while let Some((built, parent)) = stack.pop() {
        match built {
            WideBuilt::Piece(p) => pieces.push((p, parent)),
            WideBuilt::Split { node, leaf_prims, children, .. } => {
                let index = nodes.len();
                if let Some((pn, slot)) = parent {
                    nodes[pn].child[slot] = index as u32;
                }
                let mut node = *node;
                let base = prims.len() as u32;
                for s in 0..N {
                    if node.count[s] > 0 {
                        node.child[s] += base;
                    }
                }
                prims.extend_from_slice(leaf_prims);
                pad_to_block(prims, align);
                nodes.push(node);
                for (slot, c) in children.iter().rev() {
                    stack.push((c, Some((index, *slot))));
                }
            }
        }
    }
    let (mut node_total, mut prim_total) = (nodes.len(), prims.len());
    let mut placements = Vec::with_capacity(pieces.len());
    for (p, parent) in &pieces {
        if let Some((pn, slot)) = *parent {
            nodes[pn].child[slot] = node_total as u32;
        }
        placements.push(Placement { piece: p, node_offset: node_total, prim_offset: prim_total });
        node_total += p.nodes.len();
        prim_total += p.prims.len();
    }
    let top = nodes.len();
    let top_prims = prims.len();
    nodes.resize(node_total, WideNode::<N>::EMPTY);
    prims.resize(prim_total, PAD);
    let (mut node_rest, mut prim_rest) = (&mut nodes[top..], &mut prims[top_prims..]);
    let mut jobs = Vec::with_capacity(placements.len());
    for p in &placements {
        let (n, tail) = std::mem::take(&mut node_rest).split_at_mut(p.piece.nodes.len());
        let (q, prim_tail) = std::mem::take(&mut prim_rest).split_at_mut(p.piece.prims.len());
        jobs.push((p, n, q));
        node_rest = tail;
        prim_rest = prim_tail;
    }
    use rayon::prelude::*;
    jobs.into_par_iter().for_each(|(p, out_nodes, out_prims)| {
        for (out, node) in out_nodes.iter_mut().zip(&p.piece.nodes) {
            let mut node = *node;
            for s in 0..N {
                // Leaf slots count primitives; interior ones index a node other than the
                // piece's root (0), which is what empty slots hold.
                if node.count[s] > 0 {
                    node.child[s] += p.prim_offset as u32;
                } else if node.child[s] != 0 {
                    node.child[s] += p.node_offset as u32;
                }
            }
            *out = node;
        }
        out_prims.copy_from_slice(&p.piece.prims);
    });
}

#[cfg(test)]
mod tests {
    use super::slots_by_size;

    #[test]
    fn slots_by_size_is_a_stable_largest_first_order() {
        assert_eq!(slots_by_size::<8>([3, 9, 3, 1, 9].into_iter()), [2, 0, 3, 4, 1, 5, 6, 7]);
        assert_eq!(slots_by_size::<4>([5, 5].into_iter()), [0, 1, 2, 3]);
        assert_eq!(slots_by_size::<4>(std::iter::empty()), [0, 1, 2, 3]);
    }
}
