//! The renderable geometry: every triangle and sphere of a scene in one primitive array, the
//! BVHs over it, and the closest-hit query the integrator calls.
//!
//! Primitives `0..triangle_count()` are triangles, the rest spheres. Closest-hit ties (two
//! primitives at exactly the same distance, as at a shared edge) go to the lower primitive
//! index, so the hit, and hence the image, does not depend on the tree's visit order: every
//! builder gives the same image for the same seed.
//!
//! # One tree or several
//!
//! The thesis's layout is one tree over the whole scene ([`Geometry::set_bvh`]). For scenes
//! whose objects move rigidly, [`Geometry::split`] cuts the primitives into **parts**, each with
//! its own tree, placed by an [`Instance`] under a [`TopLevel`] tree ([`phr_bvh::instance`]):
//! moving a rigid part is then a new transform ([`Geometry::place`]), not a rebuild, and a
//! deforming part rebuilds its own tree alone ([`Geometry::set_part_bvh`]). The primitive
//! arrays hold each part's primitives in its object space (the scene's rest pose for rigid
//! parts; [`Geometry::world_triangle`] places them); hits, surface points and shadow queries
//! are in world space either way.
//!
//! Rendering traces through a wide BVH ([`phr_bvh::wide`]) collapsed from the builder's tree
//! whenever the tree is set ([`Geometry::build`], [`Geometry::set_bvh`]), with the triangles
//! packed in its leaf order: width 8, the faster of 4 and 8 on every shared scene in
//! `phr bench-rays`. A part that PHR rebuilds every frame gets its wide tree straight from
//! PHR instead ([`Geometry::set_part_wide`]), with no binary tree and no collapse. The tree
//! is private so that the wide copy can never be stale; the
//! counting query for heatmaps ([`Geometry::intersect_counted`]) keeps the binary reference
//! traversal, whose node counts are the thesis's traversal steps.
//!
//! Meshes the scene places many times ([`crate::scene::InstancedMesh`]) are kept apart from
//! all of this, each stored and built once ([`copies`]): every query searches them after the
//! parts.

mod copies;

use crate::scene::{Scene, SphereObject};
use crate::texture::AlphaMask;
use glam::{Affine3A, Vec2, Vec3};
use phr_bvh::builder::BuildReport;
use phr_bvh::instance::{Instance, TopLevel};
use phr_bvh::sphere::Sphere;
use phr_bvh::triangle::{intersect_triangle_edges, triangle_bounds};
use phr_bvh::wide::triangles::{AnyTriangle, ClosestTriangle};
use phr_bvh::wide::LeafVisitor;
use phr_bvh::wide::{WideStats, PAD};
use phr_bvh::RefitAreas;
use phr_bvh::{closest_hit_counted, Aabb, Builder, Bvh, PackedTriangles, Ray, TraversalStats, WideBvh};
use std::borrow::Cow;

use copies::Copies;
pub use copies::{CopiedMeshView, COPY};

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
    /// The part whose tree found it (0 with one tree): its instance places the hit. With
    /// [`COPY`] set: the copy of a mesh placed many times, and `prim` numbers the triangle
    /// within that mesh.
    pub part: u32,
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
    /// Scene order; in the object space of the part holding them (see the module documentation).
    /// Empty after [`Geometry::release_triangles`]: read them through
    /// [`Geometry::triangle_edges`] and count them with [`Geometry::triangle_count`].
    pub triangles: Vec<[Vec3; 3]>,
    pub triangle_material: Vec<u32>,
    /// Texture coordinates of each triangle's corners, in scene order; empty when no mesh
    /// has any (meshes without them get zeros).
    pub triangle_uv: Vec<[Vec2; 3]>,
    pub spheres: Vec<SphereObject>,
    /// The primitives' boxes, in the same space as the primitives, as of the last build: a
    /// deforming part whose tree is only refitted ([`Geometry::refit_part`]) leaves its
    /// entries behind ([`Geometry::primitive_boxes`] computes them afresh).
    pub boxes: Vec<Aabb>,
    /// One part (the whole scene, in place) or the parts of [`Geometry::split`].
    parts: Vec<Part>,
    /// How rays reach the parts, after [`Geometry::split`]; `None`: `parts[0]` alone, in place.
    placement: Option<Placement>,
    /// The part of each primitive (empty while there is one part).
    prim_part: Vec<u32>,
    /// The meshes placed many times, apart from the primitives above.
    copies: Copies,
    /// After [`Geometry::release_triangles`]: where the packed blocks hold each triangle.
    released: Option<Released>,
    /// The scene's alpha masks, and each material's (empty if no material has one): a
    /// triangle hit where its material's mask does not cover it is no hit.
    masks: Vec<AlphaMask>,
    material_mask: Vec<Option<u32>>,
}

/// Parts packed so far, by every geometry of the process: the last one's
/// [`Part::generation`] (so that a new geometry, such as a pipeline switched to another
/// layout makes, never repeats a number a device has seen).
static PACKINGS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// A [`Part::generation`] no part has had.
fn next_generation() -> u64 {
    PACKINGS.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1
}

/// What replaces the scene-order triangles once they are released: their number, and for
/// each one the entry of its part's packed triangles that holds it.
struct Released {
    count: usize,
    slot: Vec<u32>,
}

/// Which parts a ray visits, and how.
#[derive(Default)]
struct Placement {
    /// Parts in place (identity instances), with their boxes: searched first, with the world
    /// ray as it is.
    in_place: Vec<(u32, Aabb)>,
    /// Parts moved by a transform, with their world boxes; instance `i` of `top` is part
    /// `moved[i].0`.
    ///
    /// A ray that misses a part's box, or meets it beyond its closest hit so far, skips the
    /// part: no transform into it, no traversal setup, no root visit (most rays miss a small
    /// moving object; measured in `docs/dynamic/history.md`).
    moved: Vec<(u32, Aabb)>,
    /// Over the moved parts, when there are more than [`DIRECT_MOVED`].
    top: TopLevel,
}

impl Placement {
    /// Part `k`'s tree changed: its box (in place or moved) becomes `bounds`.
    fn update_bounds(&mut self, k: u32, bounds: Aabb) {
        if let Some(entry) = self.in_place.iter_mut().chain(&mut self.moved).find(|(p, _)| *p == k) {
            entry.1 = bounds;
        }
    }
}

/// Up to this many moved parts are searched one after the other without a top-level tree.
/// Its traversal (a kernel call, a node test, ordering) cost about 10 % of the frame on
/// scenes with one moving object, which the parts' boxes cull as well.
const DIRECT_MOVED: usize = 2;

/// Some of the primitives with their own trees, placed in the world by an instance.
#[derive(Default)]
struct Part {
    /// The primitives, ascending; `None`: all of them.
    prims: Option<Vec<u32>>,
    /// The builder's tree (binary or k-ary), with scene-order primitive indices; empty if
    /// the wide tree was built directly ([`Geometry::set_part_wide`]).
    bvh: Bvh,
    /// `bvh` collapsed to [`WIDTH`] children, and the triangles in its leaf order.
    wide: WideBvh<WIDTH>,
    packed: PackedTriangles,
    /// Some of the primitives are spheres or triangles with an alpha mask: the leaf test
    /// then takes each entry on its own ([`Part::test_packed`]) instead of a block of 4.
    entry_tests: bool,
    instance: Instance,
    /// Changes whenever the part's tree or primitives do ([`Geometry::part_generation`]).
    generation: u64,
}

/// Renumbers a part's primitive indices (its order, from 0) to the scene's (`prims`);
/// [`PAD`] entries stay. (In parallel: a deforming part does this every frame.)
fn to_scene_order(indices: &mut [u32], prims: &[u32]) {
    use rayon::prelude::*;
    indices.par_iter_mut().with_min_len(1 << 14).filter(|p| **p != PAD).for_each(|p| *p = prims[*p as usize]);
}

/// `dst[indices[i] - offset] = src[i]` for ascending, distinct `indices`, in parallel: the
/// indices split `dst` into disjoint ranges. (A deforming part's boxes go back into the
/// scene's array every frame.)
fn scatter_ascending(dst: &mut [Aabb], offset: usize, indices: &[u32], src: &[Aabb]) {
    if indices.len() <= 1 << 14 {
        for (&i, b) in indices.iter().zip(src) {
            dst[i as usize - offset] = *b;
        }
        return;
    }
    let mid = indices.len() / 2;
    let cut = indices[mid] as usize - offset;
    let (low, high) = dst.split_at_mut(cut);
    rayon::join(
        || scatter_ascending(low, offset, &indices[..mid], &src[..mid]),
        || scatter_ascending(high, offset + cut, &indices[mid..], &src[mid..]),
    );
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
        let triangle_uv = if scene.meshes.iter().any(|m| !m.uvs.is_empty()) {
            let mut uv = Vec::with_capacity(n);
            for mesh in &scene.meshes {
                match mesh.uvs.len() {
                    0 => uv.extend(std::iter::repeat_n([Vec2::ZERO; 3], mesh.triangles.len())),
                    _ => uv.extend_from_slice(&mesh.uvs),
                }
            }
            uv
        } else {
            Vec::new()
        };
        let mut g = Self {
            triangles,
            triangle_material,
            triangle_uv,
            spheres: scene.spheres.clone(),
            boxes: Vec::new(),
            parts: vec![Part::default()],
            placement: None,
            prim_part: Vec::new(),
            copies: Copies::new(scene),
            released: None,
            masks: scene.masks.clone(),
            material_mask: if scene.masks.is_empty() { Vec::new() } else { scene.material_mask.clone() },
        };
        g.update_boxes();
        g
    }

    pub fn prim_count(&self) -> usize {
        self.triangle_count() + self.spheres.len()
    }

    /// Number of triangles (primitives `0..triangle_count()`; the spheres follow).
    #[inline(always)]
    pub fn triangle_count(&self) -> usize {
        self.released.as_ref().map_or(self.triangles.len(), |r| r.count)
    }

    /// The scene-order triangles, for what builds, packs or moves them.
    ///
    /// # Panics
    /// After [`Geometry::release_triangles`]: a released geometry is only traced.
    fn scene_triangles(&self) -> &[[Vec3; 3]] {
        assert!(self.released.is_none(), "the triangles were released: this geometry can only be traced");
        &self.triangles
    }

    /// Drops the scene-order triangles of a geometry that will only be traced from now on:
    /// the parts' packed triangles, which hold the same vertex and edges, become the only
    /// copy ([`Geometry::triangle_edges`] reads them), which saves 32 bytes a triangle (36 for
    /// the vertices, less 4 for where they are packed). What builds, refits, splits or packs
    /// primitives panics afterwards; parts can still be placed. The meshes placed many
    /// times keep theirs. Returns false, and keeps them, if some triangle is in no part's tree
    /// (nothing is then saved).
    pub fn release_triangles(&mut self) -> bool {
        if self.released.is_some() {
            return true;
        }
        let count = self.triangles.len();
        let mut slot = vec![NO_SLOT; count];
        for part in &self.parts {
            for (i, &p) in part.wide.prim_indices.iter().enumerate() {
                // Spatial splits put a triangle in several leaves: any of them holds it.
                if (p as usize) < count && slot[p as usize] == NO_SLOT {
                    slot[p as usize] = i as u32;
                }
            }
        }
        if slot.contains(&NO_SLOT) {
            return false;
        }
        self.triangles = Vec::new();
        self.released = Some(Released { count, slot });
        true
    }

    /// Triangle `prim` in the object space of its part, as `[v0, e1 = v1 - v0, e2 = v2 - v0]`:
    /// the values the packed intersection test uses, the same bits whether or not the
    /// triangles were released.
    #[inline]
    pub fn triangle_edges(&self, prim: usize) -> [Vec3; 3] {
        match &self.released {
            None => {
                let [a, b, c] = self.triangles[prim];
                [a, b - a, c - a]
            }
            Some(r) => self.parts[self.prim_part.get(prim).map_or(0, |&k| k as usize)].packed.get(r.slot[prim]),
        }
    }

    /// [`Geometry::triangle_edges`] in the world: the vertex placed, the edges turned.
    pub fn world_triangle_edges(&self, prim: usize) -> [Vec3; 3] {
        let [v0, e1, e2] = self.triangle_edges(prim);
        match self.prim_part.get(prim).and_then(|&k| self.parts.get(k as usize)) {
            Some(part) if !part.instance.is_identity() => {
                let m = &part.instance.to_world;
                [part.instance.world_point(v0), m.transform_vector3(e1), m.transform_vector3(e2)]
            }
            _ => [v0, e1, e2],
        }
    }

    /// Recomputes the primitive boxes (after vertices moved).
    pub fn update_boxes(&mut self) {
        // Into the previous frame's memory (a dynamic scene does this every frame).
        let mut boxes = std::mem::take(&mut self.boxes);
        self.primitive_boxes_into(&mut boxes);
        self.boxes = boxes;
    }

    /// The primitives' boxes where the primitives are now (what [`Geometry::update_boxes`]
    /// stores; after [`Geometry::release_triangles`], which nothing moves, the stored ones).
    pub fn primitive_boxes(&self) -> Vec<Aabb> {
        if self.released.is_some() {
            return self.boxes.clone();
        }
        let mut boxes = Vec::new();
        self.primitive_boxes_into(&mut boxes);
        boxes
    }

    fn primitive_boxes_into(&self, boxes: &mut Vec<Aabb>) {
        use rayon::prelude::*;
        self.scene_triangles().par_iter().map(|&[a, b, c]| triangle_bounds(a, b, c)).collect_into_vec(boxes);
        boxes.extend(self.spheres.iter().map(|s| s.sphere.bounds()));
    }

    /// Builds one BVH over the whole scene with `builder` and sets it ([`Geometry::set_bvh`]),
    /// and the trees of the meshes placed many times ([`Geometry::build_copies`]).
    pub fn build(&mut self, builder: &Builder) {
        let report = self.build_report(builder);
        self.set_bvh(report.bvh);
        self.build_copies(builder);
    }

    /// Builds the tree of each mesh the scene places many times, once (later calls return at
    /// once), and the top-level tree over their copies: what rays need besides the trees of
    /// [`Geometry::set_bvh`] or [`Geometry::split`], which leave the copies alone. Returns the
    /// time it took.
    pub fn build_copies(&mut self, builder: &Builder) -> std::time::Duration {
        let start = std::time::Instant::now();
        self.copies.build(builder);
        start.elapsed()
    }

    /// Places copies of meshes placed many times anew: `(k, to_world)` puts copy `k` there
    /// (a transform that cannot be inverted leaves it where it was), and the top level over
    /// the copies is rebuilt. Their meshes' trees stay as they are.
    pub fn move_copies(&mut self, moves: &[(usize, Affine3A)]) {
        self.copies.place(moves);
    }

    /// Number of copies of meshes placed many times.
    pub fn copy_count(&self) -> usize {
        self.copies.len()
    }

    /// Number of meshes placed many times (each traced through its copies).
    pub fn copied_mesh_count(&self) -> usize {
        self.copies.mesh_count()
    }

    /// Mesh `m` of those placed many times: its tree and triangles in its object space.
    pub fn copied_mesh(&self, m: usize) -> CopiedMeshView<'_> {
        self.copies.mesh(m)
    }

    /// Copy `copy`: its mesh, its placement and its box in the world; `None` until the
    /// copies are built ([`Geometry::build_copies`]).
    pub fn copy_placement(&self, copy: usize) -> Option<(usize, &Instance, Aabb)> {
        self.copies.is_built().then(|| self.copies.placed(copy))
    }

    /// A BVH over the whole scene by `builder`, with its timings, from the current boxes (and
    /// the triangles, which the SBVH clips); not set.
    pub fn build_report(&self, builder: &Builder) -> BuildReport {
        builder.build_timed_with_triangles(&self.boxes, self.scene_triangles())
    }

    /// Sets one BVH over the whole scene (built over [`Geometry::boxes`] of the current
    /// triangles; undoes [`Geometry::split`]) and derives the wide tree and the packed
    /// triangles the queries use. Call it again after the triangles move. Returns the time the
    /// collapse and the packing took: the one measurement of that step, which the frame
    /// pipeline and the benchmarks report.
    pub fn set_bvh(&mut self, bvh: Bvh) -> std::time::Duration {
        if self.parts.len() != 1 || self.parts[0].prims.is_some() {
            // Keep the first part's memory for the whole scene.
            self.parts.truncate(1);
            self.parts[0].prims = None;
            self.parts[0].instance = Instance::IDENTITY;
            self.placement = None;
            self.prim_part = Vec::new();
        }
        self.set_part_bvh(0, bvh)
    }

    /// Cuts the primitives into parts, each with its own tree built by `builder` over its
    /// boxes (local indices), placed in the world as they are until [`Geometry::place`] moves
    /// them. Part `k` is `groups[k]`; groups must be non-empty and must not share primitives;
    /// primitives in none of them are left out.
    pub fn split(&mut self, groups: Vec<Vec<u32>>, builder: &Builder) {
        assert!(!groups.is_empty() && groups.iter().all(|g| !g.is_empty()), "parts must not be empty");
        self.prim_part = vec![u32::MAX; self.prim_count()];
        self.parts = Vec::with_capacity(groups.len());
        for (k, mut prims) in groups.into_iter().enumerate() {
            prims.sort_unstable();
            for &p in &prims {
                assert_eq!(self.prim_part[p as usize], u32::MAX, "primitive {p} is in two parts");
                self.prim_part[p as usize] = k as u32;
            }
            self.parts.push(Part { prims: Some(prims), ..Part::default() });
            let boxes = self.part_boxes(k);
            let bvh = builder.build_with_triangles(&boxes, &self.part_triangles(k));
            self.set_part_bvh(k, bvh);
        }
        self.place(&[]);
        self.build_copies(builder);
    }

    /// Number of parts (1 unless [`Geometry::split`]).
    pub fn part_count(&self) -> usize {
        self.parts.len()
    }

    /// The boxes of part `k`'s primitives, in its order (what its tree is built over);
    /// recomputed from the primitives, and written to [`Geometry::boxes`] too.
    pub fn part_boxes(&mut self, k: usize) -> Vec<Aabb> {
        let mut boxes = Vec::new();
        self.part_boxes_into(k, &mut boxes);
        boxes
    }

    /// [`Geometry::part_boxes`] into `boxes`' memory (a deforming part's boxes are recomputed
    /// every frame).
    pub fn part_boxes_into(&mut self, k: usize, boxes: &mut Vec<Aabb>) {
        use rayon::prelude::*;
        let Some(prims) = &self.parts[k].prims else {
            self.update_boxes();
            boxes.clone_from(&self.boxes);
            return;
        };
        let (triangles, spheres) = (self.scene_triangles(), &self.spheres);
        prims
            .par_iter()
            .map(|&p| match triangles.get(p as usize) {
                Some(&[a, b, c]) => triangle_bounds(a, b, c),
                None => spheres[p as usize - triangles.len()].sphere.bounds(),
            })
            .collect_into_vec(boxes);
        scatter_ascending(&mut self.boxes, 0, prims, boxes);
    }

    /// The triangles of part `k`, in its order: the first primitives of
    /// [`Geometry::part_boxes`] (the spheres come after them).
    pub fn part_triangles(&self, k: usize) -> Cow<'_, [[Vec3; 3]]> {
        let triangles = self.scene_triangles();
        match &self.parts[k].prims {
            None => Cow::Borrowed(triangles),
            Some(prims) => {
                let n = triangles.len() as u32;
                Cow::Owned(prims.iter().take_while(|&&p| p < n).map(|&p| triangles[p as usize]).collect())
            }
        }
    }

    /// Sets part `k`'s tree, built over [`Geometry::part_boxes`] (its primitives numbered
    /// from 0 in its order), and derives its wide tree and packed triangles. Returns the time
    /// of the collapse and the packing. The part's box for culling is updated, the top level
    /// is not: [`Geometry::place`].
    pub fn set_part_bvh(&mut self, k: usize, mut bvh: Bvh) -> std::time::Duration {
        let start = std::time::Instant::now();
        let part = &mut self.parts[k];
        if let Some(prims) = &part.prims {
            to_scene_order(&mut bvh.prim_indices, prims);
        }
        // Into the previous frame's memory: in a dynamic scene this runs every frame.
        part.wide.rebuild(&bvh);
        self.pack_part(k);
        let elapsed = start.elapsed();
        self.parts[k].bvh = bvh;
        self.update_part_bounds(k);
        elapsed
    }

    /// Sets part `k`'s wide tree without a builder's tree: `build` fills it (into the
    /// previous tree's memory) over [`Geometry::part_boxes`], primitives numbered from 0 in
    /// the part's order, as PHR does straight from its auxiliary tree
    /// ([`phr_bvh::dynamic::DynamicBvh::update_wide`]). The part then has no binary tree:
    /// [`Geometry::part_bvh`] is empty and [`Geometry::intersect_counted`] counts the wide
    /// traversal's nodes in it. Returns what `build` returns and the time of the rest (the
    /// primitive numbering and the packing).
    pub fn set_part_wide<T>(
        &mut self,
        k: usize,
        build: impl FnOnce(&mut WideBvh<WIDTH>) -> T,
    ) -> (T, std::time::Duration) {
        let part = &mut self.parts[k];
        part.bvh = Bvh::default();
        let built = build(&mut part.wide);
        let start = std::time::Instant::now();
        if let Some(prims) = &part.prims {
            to_scene_order(&mut part.wide.prim_indices, prims);
        }
        self.pack_part(k);
        let elapsed = start.elapsed();
        self.update_part_bounds(k);
        (built, elapsed)
    }

    /// Packs part `k`'s triangles again and refits its wide tree to its primitives where they
    /// are now: the tree keeps its topology and stays valid, though its quality decays with
    /// the motion. The leaves' boxes come from the packed triangles
    /// ([`WideBvh::refit_packed`]), so [`Geometry::boxes`] is neither read nor updated; when
    /// the tree stays, the triangles are packed as the leaves are boxed, in one pass
    /// ([`WideBvh::refit_repacking`], which needs the part's packed triangles to be its tree's,
    /// as every method here that gives a part a tree packs them).
    ///
    /// With `landed`, a tree built meanwhile (over the part's primitives numbered in its
    /// order, as [`Geometry::set_part_wide`] takes it) replaces the part's first, and the
    /// replaced tree is left in `landed`. Returns the time taken and the refitted tree's box
    /// areas, which give its SAH cost ([`RefitAreas::sah_cost`]).
    pub fn refit_part(&mut self, k: usize, landed: Option<&mut WideBvh<WIDTH>>) -> (std::time::Duration, RefitAreas) {
        let start = std::time::Instant::now();
        let n_tris = self.triangle_count();
        let sphere_bounds = |spheres: &[SphereObject], p: u32| spheres[p as usize - n_tris].sphere.bounds();
        // The binary tree (if the part was built through one) no longer fits the primitives.
        self.parts[k].bvh = Bvh::default();
        let areas = if let Some(tree) = landed {
            let part = &mut self.parts[k];
            std::mem::swap(&mut part.wide, tree);
            if let Some(prims) = &part.prims {
                to_scene_order(&mut part.wide.prim_indices, prims);
            }
            self.pack_part(k);
            let Part { wide, packed, .. } = &mut self.parts[k];
            wide.refit_packed(packed, n_tris, |p| sphere_bounds(&self.spheres, p))
        } else {
            // The same tree: packed again as it is refitted, in one pass.
            let part = &mut self.parts[k];
            let (mut wide, mut packed) = (std::mem::take(&mut part.wide), std::mem::take(&mut part.packed));
            let areas = wide.refit_repacking(&mut packed, self.scene_triangles(), |p| sphere_bounds(&self.spheres, p));
            let part = &mut self.parts[k];
            (part.wide, part.packed, part.generation) = (wide, packed, next_generation());
            areas
        };
        self.update_part_bounds(k);
        (start.elapsed(), areas)
    }

    /// Packs part `k`'s triangles in its wide tree's leaf order (into the previous frame's
    /// memory: in a dynamic scene this runs every frame).
    fn pack_part(&mut self, k: usize) {
        let mut packed = std::mem::take(&mut self.parts[k].packed);
        packed.repack(&self.parts[k].wide.prim_indices, self.scene_triangles());
        self.parts[k].packed = packed;
        self.parts[k].entry_tests = self.needs_entry_tests(k);
        self.parts[k].generation = next_generation();
    }

    /// Whether part `k` holds spheres or triangles with an alpha mask ([`Part::entry_tests`]).
    fn needs_entry_tests(&self, k: usize) -> bool {
        let n_tris = self.triangle_count() as u32;
        let masked = |p: u32| self.mask_of(p).is_some();
        let masks = !self.masks.is_empty();
        match &self.parts[k].prims {
            Some(prims) => prims.last().is_some_and(|&p| p >= n_tris) || (masks && prims.iter().any(|&p| masked(p))),
            None => !self.spheres.is_empty() || (masks && (0..n_tris).any(masked)),
        }
    }

    /// The alpha mask of primitive `prim`'s material (`None` for unmasked triangles and for
    /// spheres).
    #[inline]
    fn mask_of(&self, prim: u32) -> Option<&AlphaMask> {
        let material = *self.triangle_material.get(prim as usize)?;
        let mask = (*self.material_mask.get(material as usize)?)?;
        Some(&self.masks[mask as usize])
    }

    /// Gives the top level part `k`'s new box (for culling; the top-level tree over the
    /// moved parts is rebuilt by [`Geometry::place`]).
    fn update_part_bounds(&mut self, k: usize) {
        if let Some(placement) = &mut self.placement {
            placement.update_bounds(k as u32, self.parts[k].world_bounds());
        }
    }

    /// Moves parts: `(k, to_world)` places part `k`'s object space in the world (parts not
    /// named keep their place), then rebuilds the top level over the moved parts. A transform
    /// that cannot be inverted leaves its part where it was. Without [`Geometry::split`]
    /// there is nothing to move.
    pub fn place(&mut self, moves: &[(usize, Affine3A)]) {
        if self.parts.len() == 1 && self.parts[0].prims.is_none() {
            return;
        }
        for &(k, to_world) in moves {
            if let Some(instance) = Instance::new(to_world) {
                self.parts[k].instance = instance;
            }
        }
        let mut placement = self.placement.take().unwrap_or_default();
        let parts = self.parts.iter().enumerate().map(|(k, part)| (k as u32, part.world_bounds()));
        (placement.moved, placement.in_place) =
            parts.partition(|&(k, _)| !self.parts[k as usize].instance.is_identity());
        if placement.moved.len() > DIRECT_MOVED {
            let instances = placement.moved.iter().map(|&(k, _)| self.parts[k as usize].instance).collect();
            let boxes: Vec<Aabb> = placement.moved.iter().map(|&(_, b)| b).collect();
            placement.top.rebuild(instances, &boxes);
        }
        self.placement = Some(placement);
    }

    /// Bytes held, by part: the triangles (vertices, material indices and texture
    /// coordinates), the primitive boxes, the builders' trees (nodes, leaf order, parents), and
    /// what the renderer traces (the wide trees and the packed triangles, and the copies of
    /// meshes placed many times). Capacities, not lengths: what is allocated.
    pub fn memory(&self) -> GeometryMemory {
        use std::mem::size_of;
        let bytes = |capacity: usize, size: usize| capacity * size;
        let parts = |f: &dyn Fn(&Part) -> usize| self.parts.iter().map(f).sum::<usize>();
        let (copies_triangles, copies_traced) = self.copies.memory();
        GeometryMemory {
            triangles: bytes(self.triangles.capacity(), size_of::<[Vec3; 3]>())
                + self.released.as_ref().map_or(0, |r| bytes(r.slot.capacity(), size_of::<u32>()))
                + bytes(self.triangle_material.capacity(), size_of::<u32>())
                + bytes(self.triangle_uv.capacity(), size_of::<[Vec2; 3]>())
                + copies_triangles,
            boxes: bytes(self.boxes.capacity(), size_of::<Aabb>()),
            tree: parts(&|p| {
                bytes(p.bvh.nodes.capacity(), size_of::<phr_bvh::Node>())
                    + bytes(p.bvh.prim_indices.capacity(), size_of::<u32>())
                    + bytes(p.bvh.parents.capacity(), size_of::<u32>())
                    + bytes(p.prims.as_ref().map_or(0, Vec::capacity), size_of::<u32>())
            }) + bytes(self.prim_part.capacity(), size_of::<u32>()),
            wide: parts(&|p| p.traced_bytes()) + copies_traced,
        }
    }

    /// The builder's tree of the whole scene (after [`Geometry::split`]: of the first part).
    pub fn bvh(&self) -> &Bvh {
        &self.parts[0].bvh
    }

    /// The builder's tree of part `k`, with scene-order primitive indices (empty if its wide
    /// tree was built directly: [`Geometry::set_part_wide`]).
    pub fn part_bvh(&self, k: usize) -> &Bvh {
        &self.parts[k].bvh
    }

    /// The wide tree of part `k` that the queries trace.
    pub fn part_wide(&self, k: usize) -> &WideBvh<WIDTH> {
        &self.parts[k].wide
    }

    /// Changes whenever part `k`'s tree or primitives change (a build, a refit, a split),
    /// and only then: a device that keeps the parts uploads again those whose generation
    /// changed, and only the placement of the others. Never the same for two packings, in any
    /// two geometries of the process.
    pub fn part_generation(&self, k: usize) -> u64 {
        self.parts[k].generation
    }

    /// Where part `k` is placed in the world.
    pub fn part_instance(&self, k: usize) -> &Instance {
        &self.parts[k].instance
    }

    /// A box around part `k` in the world (the one rays are culled by).
    pub fn part_world_bounds(&self, k: usize) -> Aabb {
        self.parts[k].world_bounds()
    }

    /// Takes the whole scene's tree out (after [`Geometry::split`]: the first part's), leaving
    /// one empty part: nothing is hit until the next [`Geometry::set_bvh`].
    pub fn take_bvh(&mut self) -> Bvh {
        let bvh = std::mem::take(&mut self.parts[0].bvh);
        self.parts = vec![Part::default()];
        self.placement = None;
        self.prim_part = Vec::new();
        bvh
    }

    /// The wide tree the queries trace (after [`Geometry::split`]: the first part's).
    pub fn wide_bvh(&self) -> &WideBvh<WIDTH> {
        &self.parts[0].wide
    }

    /// Triangle `prim` where it is in the world (not after [`Geometry::release_triangles`]:
    /// [`Geometry::world_triangle_edges`] reads a released one).
    pub fn world_triangle(&self, prim: usize) -> [Vec3; 3] {
        let t = self.scene_triangles()[prim];
        match self.prim_part.get(prim).and_then(|&k| self.parts.get(k as usize)) {
            Some(part) if !part.instance.is_identity() => t.map(|v| part.instance.world_point(v)),
            _ => t,
        }
    }

    /// Sphere `i` (of [`Geometry::spheres`]) where it is in the world. Under a transform
    /// the radius follows its scale (the cube root of the volume's change): exact for
    /// rotations, translations and uniform scales, the rigid motions parts get.
    pub fn world_sphere(&self, i: usize) -> Sphere {
        let s = self.spheres[i].sphere;
        match self.prim_part.get(self.triangle_count() + i).and_then(|&k| self.parts.get(k as usize)) {
            Some(part) if !part.instance.is_identity() => Sphere {
                center: part.instance.world_point(s.center),
                radius: s.radius * part.instance.to_world.matrix3.determinant().abs().cbrt(),
            },
            _ => s,
        }
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

    /// Calls `search(k, ray)` for every part `k` the ray may hit, with the ray in the part's
    /// object space and its `tmax` the closest hit so far: parts in place first, then the
    /// moved ones. `search` shrinks `tmax` on a hit and returns true. `ANY`: stop at the first.
    /// `IN_PLACE` false: the moved parts under the top-level tree alone (the batch queries
    /// search the parts in place and the moved parts without a top-level tree themselves,
    /// [`Geometry::batched_parts`]).
    #[inline(always)]
    fn search_parts<const ANY: bool, const IN_PLACE: bool>(
        &self,
        ray: &mut Ray,
        mut search: impl FnMut(u32, &mut Ray) -> bool,
    ) -> bool {
        let Some(placement) = &self.placement else { return IN_PLACE && search(0, ray) };
        let mut found = false;
        for &(k, bounds) in placement.in_place.iter().filter(|_| IN_PLACE) {
            if bounds.intersect(ray) == f32::INFINITY {
                continue;
            }
            if search(k, ray) {
                found = true;
                if ANY {
                    return true;
                }
            }
        }
        if placement.moved.len() <= DIRECT_MOVED {
            for &(k, bounds) in placement.moved.iter().filter(|_| IN_PLACE) {
                if bounds.intersect(ray) == f32::INFINITY {
                    continue;
                }
                let mut object_ray = self.parts[k as usize].instance.object_ray(ray);
                if search(k, &mut object_ray) {
                    ray.tmax = object_ray.tmax;
                    found = true;
                    if ANY {
                        return true;
                    }
                }
            }
        } else if ANY {
            found |= placement.top.any_hit(ray, |i, r| search(placement.moved[i as usize].0, &mut r.clone()));
        } else {
            found |= placement.top.closest_hit(ray, |i, r| search(placement.moved[i as usize].0, r));
        }
        found
    }

    /// The closest hit along `ray` within its interval.
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        if self.is_one_tree() {
            return self.parts[0].intersect(self, 0, ray);
        }
        let mut r = *ray;
        let mut best = None;
        self.search_parts::<false, true>(&mut r, |k, object_ray| {
            let hit = self.parts[k as usize].intersect(self, k, object_ray);
            Self::keep_closest(hit, object_ray, &mut best)
        });
        self.copies.search::<false>(&mut r, |c, object_ray| {
            let hit = self.copies.copy(c).0.intersect(self, COPY | c, object_ray);
            Self::keep_closest(hit, object_ray, &mut best)
        });
        best
    }

    /// [`Geometry::intersect`] of each of `rays`, into `hits`. The parts in place (the whole
    /// scene, when it is one tree), then the moved parts searched without a top-level tree
    /// (in their object space), trace the batch 2 or 4 rays at a time through the
    /// interleaved wide traversal, whose rays overlap each other's memory waits
    /// ([`WideBvh::closest_hit_batch`]); the moved parts under a top-level tree and the copies
    /// are then searched one ray at a time. Each ray meets the parts in the same order and
    /// with the same interval as in [`Geometry::intersect`], so the hits are the same.
    pub fn intersect_batch(&self, rays: &[Ray], hits: &mut [Option<Hit>]) {
        assert_eq!(rays.len(), hits.len(), "one hit per ray");
        if self.is_one_tree() {
            return self.parts[0].closest_batch(self, 0, rays, hits);
        }
        hits.fill(None);
        let mut work = rays.to_vec();
        let mut batch = Vec::with_capacity(rays.len());
        let mut found = Vec::with_capacity(rays.len());
        for (k, bounds) in self.batched_parts() {
            let (part, which) = (&self.parts[k as usize], Self::reaching(&work, bounds));
            batch.clear();
            batch.extend(which.iter().map(|&i| part.instance.object_ray(&work[i])));
            found.clear();
            found.resize(batch.len(), None);
            part.closest_batch(self, k, &batch, &mut found);
            for (&i, &hit) in which.iter().zip(&found) {
                Self::keep_closest(hit, &mut work[i], &mut hits[i]);
            }
        }
        for (ray, best) in work.iter_mut().zip(hits.iter_mut()) {
            self.search_parts::<false, false>(ray, |k, object_ray| {
                let hit = self.parts[k as usize].intersect(self, k, object_ray);
                Self::keep_closest(hit, object_ray, best)
            });
            self.copies.search::<false>(ray, |c, object_ray| {
                let hit = self.copies.copy(c).0.intersect(self, COPY | c, object_ray);
                Self::keep_closest(hit, object_ray, best)
            });
        }
    }

    /// [`Geometry::occluded`] of each of `rays`, into `occluded`: the parts in place and the
    /// moved parts without a top-level tree as batches, interleaved as in
    /// [`Geometry::intersect_batch`], then the moved parts under a top-level tree and the copies
    /// one ray at a time for the rays not yet occluded.
    pub fn occluded_batch(&self, rays: &[Ray], occluded: &mut [bool]) {
        assert_eq!(rays.len(), occluded.len(), "one answer per ray");
        if self.is_one_tree() {
            return self.parts[0].occluded_batch(self, rays, occluded);
        }
        occluded.fill(false);
        let mut batch = Vec::with_capacity(rays.len());
        let mut answers = Vec::with_capacity(rays.len());
        for (k, bounds) in self.batched_parts() {
            let part = &self.parts[k as usize];
            let which: Vec<usize> = Self::reaching(rays, bounds).into_iter().filter(|&i| !occluded[i]).collect();
            batch.clear();
            batch.extend(which.iter().map(|&i| part.instance.object_ray(&rays[i])));
            answers.clear();
            answers.resize(batch.len(), false);
            part.occluded_batch(self, &batch, &mut answers);
            for (&i, &blocked) in which.iter().zip(&answers) {
                occluded[i] |= blocked;
            }
        }
        for (ray, answer) in rays.iter().zip(occluded.iter_mut()).filter(|(_, a)| !**a) {
            *answer = self.search_parts::<true, false>(&mut ray.clone(), |k, object_ray| {
                self.parts[k as usize].occluded(self, object_ray)
            }) || self
                .copies
                .search::<true>(&mut ray.clone(), |c, object_ray| self.copies.copy(c).0.occluded(self, object_ray));
        }
    }

    /// Whether the scene is one tree: no parts moved by instances, no copies (the batch
    /// queries then go to that tree directly).
    fn is_one_tree(&self) -> bool {
        self.placement.is_none() && self.copies.is_empty()
    }

    /// The parts the batch queries search as batches, in [`Geometry::search_parts`]'s order,
    /// with their world boxes (`None`: the whole scene is one part, without a box test): the
    /// parts in place, then the moved parts if there is no top-level tree over them.
    fn batched_parts(&self) -> Vec<(u32, Option<Aabb>)> {
        match &self.placement {
            None => vec![(0, None)],
            Some(placement) => {
                let direct = if placement.moved.len() <= DIRECT_MOVED { &placement.moved[..] } else { &[] };
                placement.in_place.iter().chain(direct).map(|&(k, bounds)| (k, Some(bounds))).collect()
            }
        }
    }

    /// The indices of `rays` that reach `bounds` within their interval (all, for `None`), as
    /// [`Geometry::search_parts`] tests the parts in place.
    fn reaching(rays: &[Ray], bounds: Option<Aabb>) -> Vec<usize> {
        (0..rays.len()).filter(|&i| bounds.is_none_or(|b| b.intersect(&rays[i]) != f32::INFINITY)).collect()
    }

    /// Whether anything lies along `ray` within its interval (shadow rays): stops at the
    /// first hit.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.search_parts::<true, true>(&mut ray.clone(), |k, object_ray| {
            self.parts[k as usize].occluded(self, object_ray)
        }) || self
            .copies
            .search::<true>(&mut ray.clone(), |c, object_ray| self.copies.copy(c).0.occluded(self, object_ray))
    }

    /// [`Geometry::intersect`] through the builders' trees (the binary reference traversal),
    /// counting their traversal steps (the top level's are not counted). A part whose wide
    /// tree was built directly ([`Geometry::set_part_wide`]) has no builder's tree: its wide
    /// nodes and primitive tests are counted instead.
    pub fn intersect_counted(&self, ray: &Ray, stats: &mut TraversalStats) -> Option<Hit> {
        let mut r = *ray;
        let mut best = None;
        self.search_parts::<false, true>(&mut r, |k, object_ray| {
            let part = &self.parts[k as usize];
            if part.bvh.nodes.is_empty() && !part.wide.nodes.is_empty() {
                let mut wide = WideStats::default();
                let prims = &part.wide.prim_indices;
                let found = part.wide.closest_hit_leaves_counted(
                    object_ray,
                    |first, count, r| {
                        let leaf = &prims[first as usize..(first + count) as usize];
                        leaf.iter().fold(false, |hit, &p| self.test_prim(p, k, r, &mut best) | hit)
                    },
                    &mut wide,
                );
                stats.nodes += wide.nodes;
                stats.prims += wide.prims;
                return found;
            }
            closest_hit_counted(&part.bvh, object_ray, |p, r| self.test_prim(p, k, r, &mut best), stats)
        });
        self.copies.search::<false>(&mut r, |c, object_ray| {
            let (part, _) = self.copies.copy(c);
            let mut wide = WideStats::default();
            let found = part.wide.closest_hit_leaves_counted(
                object_ray,
                |first, count, r| {
                    (first..first + count).fold(false, |found, slot| {
                        let prim = part.wide.prim_indices[slot as usize];
                        let hit = part.packed.intersect(slot, r).map(|h| Hit {
                            t: h.t,
                            prim,
                            u: h.u,
                            v: h.v,
                            slot,
                            part: COPY | c,
                        });
                        Self::keep_closest(hit, r, &mut best) | found
                    })
                },
                &mut wide,
            );
            stats.nodes += wide.nodes;
            stats.prims += wide.prims;
            found
        });
        best
    }

    #[inline(always)]
    fn test_prim(&self, prim: u32, part: u32, ray: &mut Ray, best: &mut Option<Hit>) -> bool {
        // The primitive tests report hits at exactly `ray.tmax` too, for the tie rule.
        let probe = &*ray;
        let n_tris = self.triangle_count();
        let hit = if (prim as usize) < n_tris {
            let [v0, e1, e2] = self.triangle_edges(prim as usize);
            intersect_triangle_edges(probe, v0, e1, e2).filter(|h| self.covers(prim, h.u, h.v)).map(|h| Hit {
                t: h.t,
                prim,
                u: h.u,
                v: h.v,
                slot: NO_SLOT,
                part,
            })
        } else {
            let s = &self.spheres[prim as usize - n_tris].sphere;
            s.intersect(probe).map(|t| Hit { t, prim, u: 0.0, v: 0.0, slot: NO_SLOT, part })
        };
        Self::keep_closest(hit, ray, best)
    }

    /// Position, normal and side of a hit, in the world.
    pub fn surface_point(&self, ray: &Ray, hit: &Hit) -> SurfacePoint {
        let copy = hit.part & COPY != 0;
        let instance =
            if copy { self.copies.copy(hit.part & !COPY).1 } else { &self.parts[hit.part as usize].instance };
        // One call of the local surface (inlined), with the ray in the object's space.
        let identity = instance.is_identity();
        let object_ray;
        let local_ray = if identity {
            ray
        } else {
            object_ray = instance.object_ray(ray);
            &object_ray
        };
        let (p, n, material, rel) = if copy {
            self.copies.local_surface(hit.part & !COPY, hit)
        } else {
            self.local_surface(&self.parts[hit.part as usize], local_ray, hit)
        };
        let (position, normal) = if identity {
            (p, n)
        } else {
            // A mirroring transform turns a triangle's e1 × e2 around; a sphere's outward
            // normal stays outward.
            let flip = instance.mirrors() && (copy || (hit.prim as usize) < self.triangle_count());
            let n = instance.world_normal(if flip { -n } else { n });
            (instance.world_point(p), n.normalize_or(Vec3::Z))
        };
        let front = ray.dir.dot(normal) < 0.0;
        let offset = rel * (1.0 + position.abs().max_element());
        SurfacePoint { position, normal, front, material, offset }
    }

    /// Whether triangle `prim`'s surface is there at barycentrics `(u, v)`: its material's
    /// alpha mask covers it, or it has none.
    #[inline]
    fn covers(&self, prim: u32, u: f32, v: f32) -> bool {
        if self.masks.is_empty() {
            return true;
        }
        let Some(mask) = self.mask_of(prim) else { return true };
        mask.covers(self.triangle_uv.get(prim as usize).map_or(Vec2::ZERO, |corners| interpolate_uv(corners, u, v)))
    }

    /// The texture coordinates at a hit (zero for spheres and meshes without any).
    #[inline]
    pub fn uv(&self, hit: &Hit) -> Vec2 {
        if hit.part & COPY != 0 {
            return self.copies.uv(hit.part & !COPY, hit).unwrap_or(Vec2::ZERO);
        }
        self.triangle_uv.get(hit.prim as usize).map_or(Vec2::ZERO, |corners| interpolate_uv(corners, hit.u, hit.v))
    }

    /// Position, unit normal, material and relative offset of a hit in `part`'s object space
    /// (`ray` in that space too).
    fn local_surface(&self, part: &Part, ray: &Ray, hit: &Hit) -> (Vec3, Vec3, u32, f32) {
        let n_tris = self.triangle_count();
        if (hit.prim as usize) < n_tris {
            // `v0 + u e1 + v e2` and `e1 × e2`, from the packed copy when the hit says where
            // it is (the same values: the packed edges are computed as here).
            let [v0, e1, e2] = match hit.slot {
                NO_SLOT => self.triangle_edges(hit.prim as usize),
                slot => part.packed.get(slot),
            };
            let (p, n) = triangle_surface(v0, e1, e2, hit.u, hit.v);
            (p, n, self.triangle_material[hit.prim as usize], TRIANGLE_OFFSET)
        } else {
            let s = &self.spheres[hit.prim as usize - n_tris];
            let c = s.sphere.center;
            let r = s.sphere.radius.abs();
            // Re-project onto the sphere: o + t d is off by the error of t.
            let p = ray.at(hit.t);
            let p = c + (p - c) * (r / (p - c).length());
            (p, s.sphere.normal(p).normalize_or(Vec3::Y), s.material, SPHERE_OFFSET)
        }
    }
}

/// The texture coordinates at a triangle hit, from its corners'.
#[inline]
fn interpolate_uv([a, b, c]: &[Vec2; 3], u: f32, v: f32) -> Vec2 {
    *a + (*b - *a) * u + (*c - *a) * v
}

/// The point at barycentrics `(u, v)` of the triangle `v0, e1, e2` and its unit normal
/// `e1 × e2`.
#[inline(always)]
fn triangle_surface(v0: Vec3, e1: Vec3, e2: Vec3, u: f32, v: f32) -> (Vec3, Vec3) {
    (v0 + e1 * u + e2 * v, e1.cross(e2).normalize_or(Vec3::Z))
}

impl Part {
    /// A box around it in the world: the union of its wide root's children's boxes placed by
    /// its instance (under a rotation, tighter than its whole object box placed).
    fn world_bounds(&self) -> Aabb {
        self.bounds_placed(&self.instance)
    }

    /// [`Part::world_bounds`] with the part placed by `instance` instead of its own.
    fn bounds_placed(&self, instance: &Instance) -> Aabb {
        let Some(root) = self.wide.nodes.first() else { return Aabb::EMPTY };
        (0..WIDTH)
            .filter(|&i| root.is_used(i))
            .fold(Aabb::EMPTY, |b, i| b.union(instance.world_box(root.child_bounds(i))))
    }

    /// [`Part::intersect`] of each of `rays` (this is part `k`), into `hits`, interleaved
    /// ([`WideBvh::closest_hit_batch`]).
    fn closest_batch(&self, g: &Geometry, k: u32, rays: &[Ray], hits: &mut [Option<Hit>]) {
        let bytes = self.wide.traced_bytes(&self.packed);
        if self.entry_tests {
            let start = |i: usize| (rays[i], PartLeaves { geometry: g, part: self, best: None });
            self.wide.closest_hit_batch(bytes, rays.len(), start, |i, _, leaves, _| {
                hits[i] = leaves.best.map(|h| Hit { part: k, ..h })
            });
        } else {
            let start = |i: usize| (rays[i], ClosestTriangle::new(&self.wide, &self.packed));
            self.wide.closest_hit_batch(bytes, rays.len(), start, |i, _, leaves, _| {
                hits[i] =
                    leaves.best.map(|h| Hit { t: h.hit.t, prim: h.prim, u: h.hit.u, v: h.hit.v, slot: h.slot, part: k })
            });
        }
    }

    /// [`Part::occluded`] of each of `rays`, into `occluded`, interleaved
    /// ([`WideBvh::any_hit_batch`]).
    fn occluded_batch(&self, g: &Geometry, rays: &[Ray], occluded: &mut [bool]) {
        let bytes = self.wide.traced_bytes(&self.packed);
        if self.entry_tests {
            let start = |i: usize| (rays[i], PartLeaves { geometry: g, part: self, best: None });
            self.wide.any_hit_batch(bytes, rays.len(), start, |i, _, _, hit| occluded[i] = hit);
        } else {
            let start = |i: usize| (rays[i], AnyTriangle(&self.packed));
            self.wide.any_hit_batch(bytes, rays.len(), start, |i, _, _, hit| occluded[i] = hit);
        }
    }

    /// Bytes of what the renderer traces: the wide tree and the packed triangles.
    fn traced_bytes(&self) -> usize {
        use std::mem::size_of;
        self.wide.nodes.capacity() * size_of::<phr_bvh::wide::WideNode<WIDTH>>()
            + self.wide.prim_indices.capacity() * size_of::<u32>()
            + self.packed.blocks.capacity() * size_of::<phr_bvh::wide::triangles::TriangleBlock>()
    }

    /// [`Geometry::keep_closest`] over the leaf entry `i` of the wide tree: triangles from
    /// the packed copy (bit-identical hits), spheres as they are.
    #[inline(always)]
    fn test_packed(&self, g: &Geometry, k: u32, i: u32, ray: &mut Ray, best: &mut Option<Hit>) -> bool {
        let prim = self.wide.prim_indices[i as usize];
        let probe = &*ray;
        let n_tris = g.triangle_count();
        let hit = if (prim as usize) < n_tris {
            self.packed.intersect(i, probe).filter(|h| g.covers(prim, h.u, h.v)).map(|h| Hit {
                t: h.t,
                prim,
                u: h.u,
                v: h.v,
                slot: i,
                part: k,
            })
        } else {
            let s = &g.spheres[prim as usize - n_tris].sphere;
            s.intersect(probe).map(|t| Hit { t, prim, u: 0.0, v: 0.0, slot: NO_SLOT, part: k })
        };
        Geometry::keep_closest(hit, ray, best)
    }

    /// The closest hit in this part (number `k`) along `ray`, in its object space.
    #[inline(always)]
    fn intersect(&self, g: &Geometry, k: u32, ray: &Ray) -> Option<Hit> {
        if !self.entry_tests {
            // Triangles only: whole leaves at once (4-lane Möller–Trumbore, same bits), the
            // leaf test compiled into the traversal loop.
            return self.wide.closest_triangle_slot(&self.packed, ray).map(|h| Hit {
                t: h.hit.t,
                prim: h.prim,
                u: h.hit.u,
                v: h.hit.v,
                slot: h.slot,
                part: k,
            });
        }
        let mut r = *ray;
        let mut leaves = PartLeaves { geometry: g, part: self, best: None };
        self.wide.closest_hit_visit(&mut r, &mut leaves);
        leaves.best.map(|h| Hit { part: k, ..h })
    }

    /// Whether anything in this part lies along `ray` (object space).
    #[inline(always)]
    fn occluded(&self, g: &Geometry, ray: &Ray) -> bool {
        if !self.entry_tests {
            return self.wide.any_triangle(&self.packed, ray);
        }
        self.wide.any_hit_visit(ray, &mut PartLeaves { geometry: g, part: self, best: None })
    }
}

/// The leaf test of a part with spheres or masked triangles, as a [`LeafVisitor`]: each
/// entry by [`Part::test_packed`], keeping the closest hit (its `part` is 0: callers set
/// theirs). As an any-hit test, whether a visit kept a hit.
struct PartLeaves<'a> {
    geometry: &'a Geometry,
    part: &'a Part,
    best: Option<Hit>,
}

impl LeafVisitor for PartLeaves<'_> {
    #[inline(always)]
    fn visit(&mut self, first: u32, count: u32, ray: &mut Ray) -> bool {
        let mut hit = false;
        for i in first..first + count {
            hit |= self.part.test_packed(self.geometry, 0, i, ray, &mut self.best);
        }
        hit
    }

    #[inline(always)]
    fn prefetch(&self, first: u32) {
        self.part.packed.prefetch(first);
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
