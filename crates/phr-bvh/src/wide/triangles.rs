//! Triangles laid out for intersection: in the leaf order of a [`super::WideBvh`], with the
//! edges precomputed.

use super::{Lanes, WideBvh, Width};
use crate::ray::Ray;
use crate::triangle::{intersect_triangle_edges, TriangleHit};
use glam::Vec3;

/// `[v0, e1 = v1 - v0, e2 = v2 - v0]` per entry of a wide tree's `prim_indices`, so the
/// triangles of a leaf are contiguous (one or two cache lines instead of one per triangle,
/// and no indirection through the primitive index) and the two edge subtractions are done
/// once. The edges are computed as [`crate::triangle::intersect_triangle`] computes them, so
/// [`PackedTriangles::intersect`] returns the same bits.
///
/// Primitives that are not triangles (the renderer's spheres, numbered after its triangles)
/// get a zero entry, which no ray hits; callers test them their own way.
#[derive(Clone, Debug, Default)]
pub struct PackedTriangles {
    pub tris: Vec<[Vec3; 3]>,
}

impl PackedTriangles {
    /// Packs `triangles` (by the caller's primitive index) in the order of `prim_indices`;
    /// indices `>= triangles.len()` get a never-hit entry.
    pub fn new(prim_indices: &[u32], triangles: &[[Vec3; 3]]) -> Self {
        let tris = prim_indices
            .iter()
            .map(|&p| match triangles.get(p as usize) {
                Some(&[v0, v1, v2]) => [v0, v1 - v0, v2 - v0],
                None => [Vec3::ZERO; 3],
            })
            .collect();
        Self { tris }
    }

    /// Möller–Trumbore on entry `i` (a position in the tree's `prim_indices`).
    #[inline(always)]
    pub fn intersect(&self, i: u32, ray: &Ray) -> Option<TriangleHit> {
        let [v0, e1, e2] = self.tris[i as usize];
        intersect_triangle_edges(ray, v0, e1, e2)
    }
}

impl<const N: usize> WideBvh<N>
where
    Lanes<N>: Width<N>,
{
    /// Closest hit over triangles only (`tris` packed from this tree): the caller's primitive
    /// index and the hit. Ties (equal `t`) go to the lowest primitive index, whatever the
    /// visit order, so the result equals brute force's.
    #[inline]
    pub fn closest_triangle(&self, tris: &PackedTriangles, ray: &Ray) -> Option<(u32, TriangleHit)> {
        let mut r = *ray;
        let mut best: Option<(u32, TriangleHit)> = None;
        let prims = &self.prim_indices;
        self.closest_hit_leaves(&mut r, |first, count, r| {
            let mut hit = false;
            for i in first..first + count {
                if let Some(h) = tris.intersect(i, r) {
                    let p = prims[i as usize];
                    // Hits at exactly tmax are reported too; they win if their index is lower.
                    if h.t < r.tmax || best.is_none_or(|(bp, _)| p < bp) {
                        r.tmax = h.t;
                        best = Some((p, h));
                        hit = true;
                    }
                }
            }
            hit
        });
        best
    }

    /// Whether any triangle is hit within the ray's interval.
    #[inline]
    pub fn any_triangle(&self, tris: &PackedTriangles, ray: &Ray) -> bool {
        self.any_hit_leaves(ray, |first, count, r| (first..first + count).any(|i| tris.intersect(i, r).is_some()))
    }
}
