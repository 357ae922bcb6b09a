//! Plumbing shared by the top-down builders (PHR, full-sweep SAH, binned SAH): how subtrees
//! built in parallel become one flat node array with a deterministic layout.
//!
//! The top levels of a build are split as rayon tasks and recorded as a small skeleton
//! ([`Built::Split`]); below a size threshold each task builds its whole subtree sequentially
//! into a [`Piece`] with local indices. [`assemble`] then lays the skeleton out first and
//! copies each piece after it (in parallel, each into its own slice), relocating indices. Each
//! node is copied once, no locks or atomics are needed, and the layout does not depend on the
//! thread count.

use crate::aabb::Aabb;
use crate::node::{Bvh, Node};
use rayon::prelude::*;

/// A subtree with local indices: root at 0; leaves index `prims`.
#[derive(Default)]
pub(crate) struct Piece {
    pub nodes: Vec<Node>,
    pub prims: Vec<u32>,
}

impl Piece {
    pub fn new() -> Self {
        Self { nodes: vec![Node::default()], prims: Vec::new() }
    }

    /// Reserves `k` consecutive child slots and returns the first.
    pub fn alloc_children(&mut self, k: u32) -> u32 {
        let first = self.nodes.len() as u32;
        self.nodes.resize(self.nodes.len() + k as usize, Node::default());
        first
    }

    pub fn set_leaf(&mut self, slot: u32, bounds: Aabb, prims: impl IntoIterator<Item = u32>) {
        let first = self.prims.len() as u32;
        self.prims.extend(prims);
        let count = self.prims.len() as u32 - first;
        self.nodes[slot as usize] = Node::leaf(bounds, first, count);
    }

    pub fn set_interior(&mut self, slot: u32, bounds: Aabb, first_child: u32, k: u32) {
        self.nodes[slot as usize] = Node::interior_k(bounds, first_child, k);
    }
}

/// The result of a (sub)build.
pub(crate) enum Built {
    Piece(Piece),
    /// An interior node of the parallel top, with its children.
    Split {
        bounds: Aabb,
        children: Vec<Built>,
    },
}

struct Placement<'a> {
    piece: &'a Piece,
    root_slot: u32,
    node_offset: usize,
    prim_offset: usize,
}

/// Lays out the skeleton, then every piece after it.
pub(crate) fn assemble(root: Built) -> Bvh {
    let mut skeleton: Vec<Node> = vec![Node::default()];
    let mut placements = Vec::new();
    let (mut node_total, mut prim_total) = (0usize, 0usize);
    // Breadth-first over the skeleton, so siblings get consecutive slots.
    let mut queue = std::collections::VecDeque::from([(&root, 0u32)]);
    while let Some((built, slot)) = queue.pop_front() {
        match built {
            Built::Split { bounds, children } => {
                let first = skeleton.len() as u32;
                skeleton[slot as usize] = Node::interior_k(*bounds, first, children.len() as u32);
                skeleton.extend(std::iter::repeat_n(Node::default(), children.len()));
                for (i, c) in children.iter().enumerate() {
                    queue.push_back((c, first + i as u32));
                }
            }
            Built::Piece(piece) => {
                placements.push(Placement { piece, root_slot: slot, node_offset: node_total, prim_offset: prim_total });
                node_total += piece.nodes.len() - 1;
                prim_total += piece.prims.len();
            }
        }
    }
    let base = skeleton.len();
    for p in &mut placements {
        p.node_offset += base;
    }
    let mut nodes = skeleton;
    nodes.resize(base + node_total, Node::default());
    let mut prim_indices = vec![0u32; prim_total];
    for p in &placements {
        nodes[p.root_slot as usize] = relocate(p, 0);
    }
    // Hand each piece its own slices of the output.
    let mut node_rest = &mut nodes[base..];
    let mut prim_rest = &mut prim_indices[..];
    let mut jobs = Vec::with_capacity(placements.len());
    for p in &placements {
        let (n, tail) = std::mem::take(&mut node_rest).split_at_mut(p.piece.nodes.len() - 1);
        let (q, prim_tail) = std::mem::take(&mut prim_rest).split_at_mut(p.piece.prims.len());
        jobs.push((p, n, q));
        node_rest = tail;
        prim_rest = prim_tail;
    }
    jobs.into_par_iter().for_each(|(p, out_nodes, out_prims)| {
        for (i, slot) in out_nodes.iter_mut().enumerate() {
            *slot = relocate(p, i + 1);
        }
        out_prims.copy_from_slice(&p.piece.prims);
    });
    // No parents: a top-down tree is rebuilt, not refit (`refit` computes them if needed).
    Bvh { nodes, prim_indices, parents: Vec::new() }
}

fn relocate(p: &Placement, local: usize) -> Node {
    let mut n = p.piece.nodes[local];
    if n.is_leaf() {
        n.first += p.prim_offset as u32;
    } else {
        n.first = (p.node_offset + n.first as usize - 1) as u32;
    }
    n
}
