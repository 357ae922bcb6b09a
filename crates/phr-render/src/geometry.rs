//! The renderable geometry: every triangle and sphere of a scene in one primitive array, the
//! BVH over it, and the closest-hit query the integrator calls.
//!
//! Primitives `0..triangles.len()` are triangles, the rest spheres. Closest-hit ties (two
//! primitives at exactly the same distance, as at a shared edge) go to the lower primitive
//! index, so the hit, and hence the image, does not depend on the tree's visit order: every
//! builder gives the same image for the same seed.
//!
//! Rendering traces through a wide BVH ([`phr_bvh::wide`]) collapsed from the builder's tree
//! whenever the tree is set ([`Geometry::build`], [`Geometry::set_bvh`]), with the triangles
//! packed in its leaf order: width 8, the faster of 4 and 8 on every shared scene in
//! `phr bench-rays`. The tree is private so that the wide copy can never be stale; the
//! counting query for heatmaps ([`Geometry::intersect_counted`]) keeps the binary reference
//! traversal, whose node counts are the thesis's traversal steps.

use crate::scene::{Scene, SphereObject};
use glam::Vec3;
use phr_bvh::triangle::{intersect_triangle, triangle_bounds};
use phr_bvh::{closest_hit_counted, Aabb, Bvh, PackedTriangles, Ray, TraversalStats, WideBvh};

/// A closest hit: distance, primitive, and barycentrics for triangles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
    /// Where the wide tree's leaf order holds the triangle ([`NO_SLOT`] if unknown): shading
    /// reads its vertices from the packed block the intersection test has just loaded,
    /// instead of from the scene-order array (a cache miss per hit).
    pub slot: u32,
}

/// [`Hit::slot`] of hits found without the wide tree (spheres, the counting traversal).
pub const NO_SLOT: u32 = u32::MAX;

/// What shading needs to know about a hit point.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub position: Vec3,
    /// Unit geometric normal (outward for spheres, `(v1-v0)×(v2-v0)` for triangles).
    pub normal: Vec3,
    /// The ray arrived on the side the normal points to.
    pub front: bool,
    pub material: u32,
    /// How far to move a secondary ray's origin off the surface, along the normal.
    pub offset: f32,
}

/// What [`Geometry::memory`] counts, in bytes.
#[derive(Clone, Copy, Debug)]
pub struct GeometryMemory {
    pub triangles: usize,
    pub boxes: usize,
    pub tree: usize,
    pub wide: usize,
}

impl GeometryMemory {
    pub fn total(&self) -> usize {
        self.triangles + self.boxes + self.tree + self.wide
    }
}

pub struct Geometry {
    pub triangles: Vec<[Vec3; 3]>,
    pub triangle_material: Vec<u32>,
    pub spheres: Vec<SphereObject>,
    pub boxes: Vec<Aabb>,
    /// The builder's tree (binary or k-ary).
    bvh: Bvh,
    /// `bvh` collapsed to [`WIDTH`] children, and the triangles in its leaf order.
    wide: WideBvh<WIDTH>,
    packed: PackedTriangles,
}

/// The width of the wide BVH the renderer traces (see the module documentation).
pub const WIDTH: usize = 8;

/// Secondary-ray offsets, relative to `1 + max|p|` (see `shared/reference/README.md`): a few
/// hundred float32 ulps for triangles, whose hit points come from barycentrics and are
/// accurate; Mitsuba's `2⁻²⁴ · 1500` for spheres, whose `o + t d` points are less so.
const TRIANGLE_OFFSET: f32 = 1.0e-6;
const SPHERE_OFFSET: f32 = 1500.0 / (1u32 << 24) as f32;

impl Geometry {
    /// Flattens the scene's meshes and spheres. The BVH is empty until [`Geometry::build`].
    pub fn new(scene: &Scene) -> Self {
        let n = scene.triangle_count();
        let mut triangles = Vec::with_capacity(n);
        let mut triangle_material = Vec::with_capacity(n);
        for mesh in &scene.meshes {
            for (t, &m) in mesh.triangles.iter().zip(&mesh.triangle_material) {
                triangles.push(t.map(|i| mesh.positions[i as usize]));
                triangle_material.push(m);
            }
        }
        let mut g = Self {
            triangles,
            triangle_material,
            spheres: scene.spheres.clone(),
            boxes: Vec::new(),
            bvh: Bvh::default(),
            wide: WideBvh::default(),
            packed: PackedTriangles::default(),
        };
        g.update_boxes();
        g
    }

    pub fn prim_count(&self) -> usize {
        self.triangles.len() + self.spheres.len()
    }

    /// Recomputes the primitive boxes (after vertices moved).
    pub fn update_boxes(&mut self) {
        use rayon::prelude::*;
        // Into the previous frame's memory (a dynamic scene does this every frame).
        let mut boxes = std::mem::take(&mut self.boxes);
        self.triangles.par_iter().map(|&[a, b, c]| triangle_bounds(a, b, c)).collect_into_vec(&mut boxes);
        boxes.extend(self.spheres.iter().map(|s| s.sphere.bounds()));
        self.boxes = boxes;
    }

    /// Builds the BVH with `build` (any of phr-bvh's builders) over the current boxes.
    pub fn build(&mut self, build: impl FnOnce(&[Aabb]) -> Bvh) {
        let bvh = build(&self.boxes);
        self.set_bvh(bvh);
    }

    /// Sets the BVH (built over [`Geometry::boxes`] of the current triangles) and derives the
    /// wide tree and the packed triangles the queries use. Call it again after the triangles
    /// move. Returns the time the collapse and the packing took: the one measurement of that
    /// step, which the frame pipeline and the benchmarks report.
    pub fn set_bvh(&mut self, bvh: Bvh) -> std::time::Duration {
        let start = std::time::Instant::now();
        // Into the previous frame's memory: in a dynamic scene this runs every frame.
        self.wide.rebuild(&bvh);
        self.packed.repack(&self.wide.prim_indices, &self.triangles);
        let elapsed = start.elapsed();
        self.bvh = bvh;
        elapsed
    }

    /// Bytes held, by part: the triangles (vertices and material indices), the primitive
    /// boxes, the builder's tree (nodes, leaf order, parents), and what the renderer traces
    /// (the wide tree and the packed triangles). Capacities, not lengths: what is allocated.
    pub fn memory(&self) -> GeometryMemory {
        use std::mem::size_of;
        let bytes = |capacity: usize, size: usize| capacity * size;
        GeometryMemory {
            triangles: bytes(self.triangles.capacity(), size_of::<[Vec3; 3]>())
                + bytes(self.triangle_material.capacity(), size_of::<u32>()),
            boxes: bytes(self.boxes.capacity(), size_of::<Aabb>()),
            tree: bytes(self.bvh.nodes.capacity(), size_of::<phr_bvh::Node>())
                + bytes(self.bvh.prim_indices.capacity(), size_of::<u32>())
                + bytes(self.bvh.parents.capacity(), size_of::<u32>()),
            wide: bytes(self.wide.nodes.capacity(), size_of::<phr_bvh::wide::WideNode<WIDTH>>())
                + bytes(self.wide.prim_indices.capacity(), size_of::<u32>())
                + bytes(self.packed.blocks.capacity(), size_of::<phr_bvh::wide::triangles::TriangleBlock>()),
        }
    }

    /// The builder's tree.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// Takes the tree out (leaving an empty one: nothing is hit until the next
    /// [`Geometry::set_bvh`]).
    pub fn take_bvh(&mut self) -> Bvh {
        self.wide = WideBvh::default();
        self.packed = PackedTriangles::default();
        std::mem::take(&mut self.bvh)
    }

    /// The wide tree the queries trace.
    pub fn wide_bvh(&self) -> &WideBvh<WIDTH> {
        &self.wide
    }

    #[inline(always)]
    fn test_prim(&self, prim: u32, ray: &mut Ray, best: &mut Option<Hit>) -> bool {
        // The primitive tests report hits at exactly `ray.tmax` too, for the tie rule.
        let probe = &*ray;
        let hit = if (prim as usize) < self.triangles.len() {
            let [a, b, c] = self.triangles[prim as usize];
            intersect_triangle(probe, a, b, c).map(|h| Hit { t: h.t, prim, u: h.u, v: h.v, slot: NO_SLOT })
        } else {
            let s = &self.spheres[prim as usize - self.triangles.len()].sphere;
            s.intersect(probe).map(|t| Hit { t, prim, u: 0.0, v: 0.0, slot: NO_SLOT })
        };
        Self::keep_closest(hit, ray, best)
    }

    /// [`Geometry::test_prim`] for entry `i` of the wide tree's leaf order: triangles from
    /// the packed copy (bit-identical hits), spheres as before.
    #[inline(always)]
    fn test_packed(&self, i: u32, ray: &mut Ray, best: &mut Option<Hit>) -> bool {
        let prim = self.wide.prim_indices[i as usize];
        let probe = &*ray;
        let hit = if (prim as usize) < self.triangles.len() {
            self.packed.intersect(i, probe).map(|h| Hit { t: h.t, prim, u: h.u, v: h.v, slot: i })
        } else {
            let s = &self.spheres[prim as usize - self.triangles.len()].sphere;
            s.intersect(probe).map(|t| Hit { t, prim, u: 0.0, v: 0.0, slot: NO_SLOT })
        };
        Self::keep_closest(hit, ray, best)
    }

    /// The tie rule: a hit closer than `ray.tmax`, or at exactly `ray.tmax` with a lower
    /// primitive index than the best so far, becomes the best.
    #[inline(always)]
    fn keep_closest(hit: Option<Hit>, ray: &mut Ray, best: &mut Option<Hit>) -> bool {
        match hit {
            Some(h) if h.t < ray.tmax || best.is_none_or(|b| h.prim < b.prim) => {
                ray.tmax = h.t;
                *best = Some(h);
                true
            }
            _ => false,
        }
    }

    /// The closest hit along `ray` within its interval.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if self.spheres.is_empty() {
            // Triangles only: whole leaves at once (4-lane Möller–Trumbore, same bits), the
            // leaf test compiled into the traversal loop.
            return self.wide.closest_triangle_slot(&self.packed, ray).map(|h| Hit {
                t: h.hit.t,
                prim: h.prim,
                u: h.hit.u,
                v: h.hit.v,
                slot: h.slot,
            });
        }
        let mut r = *ray;
        let mut best = None;
        self.wide.closest_hit_leaves(&mut r, |first, count, r| {
            let mut hit = false;
            for i in first..first + count {
                hit |= self.test_packed(i, r, &mut best);
            }
            hit
        });
        best
    }

    /// Whether anything lies along `ray` within its interval (shadow rays): stops at the
    /// first hit.
    pub fn occluded(&self, ray: &Ray) -> bool {
        if self.spheres.is_empty() {
            return self.wide.any_triangle(&self.packed, ray);
        }
        self.wide.any_hit_leaves(ray, |first, count, r| {
            (first..first + count).any(|i| {
                let prim = self.wide.prim_indices[i as usize] as usize;
                if prim < self.triangles.len() {
                    self.packed.intersect(i, r).is_some()
                } else if prim - self.triangles.len() < self.spheres.len() {
                    self.spheres[prim - self.triangles.len()].sphere.intersect(r).is_some()
                } else {
                    false
                }
            })
        })
    }

    /// [`Geometry::intersect`], also counting traversal steps.
    pub fn intersect_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> Option<Hit> {
        let mut r = *ray;
        let mut best = None;
        closest_hit_counted(&self.bvh, &mut r, |p, r| self.test_prim(p, r, &mut best), stats);
        best
    }

    /// Position, normal and side of a hit.
    pub fn surface_point(&self, ray: &Ray, hit: &Hit) -> SurfacePoint {
        let n_tris = self.triangles.len();
        let (position, normal, material, rel) = if (hit.prim as usize) < n_tris {
            // `v0 + u e1 + v e2` and `e1 × e2`, from the packed copy when the hit says where
            // it is (the same values: the packed edges are computed as here).
            let [v0, e1, e2] = match hit.slot {
                NO_SLOT => {
                    let [a, b, c] = self.triangles[hit.prim as usize];
                    [a, b - a, c - a]
                }
                slot => self.packed.get(slot),
            };
            let p = v0 + e1 * hit.u + e2 * hit.v;
            let n = e1.cross(e2).normalize_or(Vec3::Z);
            (p, n, self.triangle_material[hit.prim as usize], TRIANGLE_OFFSET)
        } else {
            let s = &self.spheres[hit.prim as usize - n_tris];
            let c = s.sphere.center;
            let r = s.sphere.radius.abs();
            // Re-project onto the sphere: o + t d is off by the error of t.
            let p = ray.at(hit.t);
            let p = c + (p - c) * (r / (p - c).length());
            (p, s.sphere.normal(p).normalize_or(Vec3::Y), s.material, SPHERE_OFFSET)
        };
        let front = ray.dir.dot(normal) < 0.0;
        let offset = rel * (1.0 + position.abs().max_element());
        SurfacePoint { position, normal, front, material, offset }
    }
}

impl SurfacePoint {
    /// Origin for a ray leaving towards `dir`: moved off the surface on the side it leaves to.
    #[inline]
    pub fn spawn_origin(&self, dir: Vec3) -> Vec3 {
        let side = if dir.dot(self.normal) >= 0.0 { self.normal } else { -self.normal };
        self.position + self.offset * side
    }
}
