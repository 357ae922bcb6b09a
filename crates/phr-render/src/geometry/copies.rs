//! Meshes placed many times ([`crate::scene::InstancedMesh`], a scene file's `instances`):
//! each mesh's triangles and tree are stored once, in its object space, and every copy is an
//! [`Instance`] of it under a top-level tree of its own. This is the instancing of Embree's
//! and OptiX's scene graphs: a thousand bunnies cost one bunny's tree plus a thousand
//! transforms, and a ray meets only the copies whose boxes it crosses.
//!
//! Copies do not emit light: the scene file copies emitting meshes triangle by triangle
//! instead, so that light sampling finds each emitter where it is. A copy's hit has
//! [`COPY`] set in [`Hit::part`], the copy's number in the other bits, and its triangle's
//! number within its mesh in [`Hit::prim`].

use super::{Hit, Part, TRIANGLE_OFFSET, WIDTH};
use crate::scene::Scene;
use glam::{Affine3A, Vec2, Vec3};
use phr_bvh::instance::{Instance, TopLevel};
use phr_bvh::triangle::triangle_bounds;
use phr_bvh::wide::WideBvh;
use phr_bvh::{Aabb, Builder, Ray};

/// The bit of [`Hit::part`] that marks a copy's hit.
pub const COPY: u32 = 1 << 31;

/// One mesh placed many times: its triangles in object space and its tree.
struct CopiedMesh {
    triangles: Vec<[Vec3; 3]>,
    triangle_material: Vec<u32>,
    /// Empty when the mesh has no texture coordinates.
    triangle_uv: Vec<[Vec2; 3]>,
    /// Its wide tree and packed triangles, in object space (built by [`Copies::build`]).
    part: Part,
}

/// A mesh placed many times, as devices that trace it themselves read it: its wide tree (leaf
/// entries number its triangles from 0), and its triangles, their materials and texture
/// coordinates (empty: none), in its object space.
pub struct CopiedMeshView<'a> {
    pub wide: &'a WideBvh<WIDTH>,
    pub triangles: &'a [[Vec3; 3]],
    pub triangle_material: &'a [u32],
    pub triangle_uv: &'a [[Vec2; 3]],
}

/// Every mesh placed many times, and the top-level tree over their copies.
#[derive(Default)]
pub(super) struct Copies {
    meshes: Vec<CopiedMesh>,
    /// The mesh of each copy; copy `i` is instance `i` of `top`.
    mesh_of: Vec<u32>,
    /// The copies' placements until [`Copies::build`] builds the meshes' trees and hands
    /// these to `top` (empty: built, or no copies).
    placements: Vec<Instance>,
    top: TopLevel,
}

impl Copies {
    pub fn new(scene: &Scene) -> Self {
        let mut copies = Copies::default();
        for (m, instanced) in scene.instanced.iter().enumerate() {
            let mesh = &instanced.mesh;
            copies.meshes.push(CopiedMesh {
                triangles: mesh.triangles.iter().map(|t| t.map(|i| mesh.positions[i as usize])).collect(),
                triangle_material: mesh.triangle_material.clone(),
                triangle_uv: mesh.uvs.clone(),
                part: Part::default(),
            });
            copies.mesh_of.extend(std::iter::repeat_n(m as u32, instanced.copies.len()));
            copies.placements.extend_from_slice(&instanced.copies);
        }
        copies
    }

    pub fn is_empty(&self) -> bool {
        self.mesh_of.is_empty()
    }

    /// Number of copies.
    pub fn len(&self) -> usize {
        self.mesh_of.len()
    }

    /// Builds the tree of every mesh with `builder`, then the top level over the copies, the
    /// first time; later calls do nothing.
    pub fn build(&mut self, builder: &Builder) {
        if self.placements.is_empty() {
            return;
        }
        for mesh in &mut self.meshes {
            let boxes: Vec<Aabb> = mesh.triangles.iter().map(|&[a, b, c]| triangle_bounds(a, b, c)).collect();
            let bvh = builder.build_with_triangles(&boxes, &mesh.triangles);
            mesh.part.wide.rebuild(&bvh);
            mesh.part.packed.repack(&mesh.part.wide.prim_indices, &mesh.triangles);
        }
        let boxes: Vec<Aabb> = self
            .mesh_of
            .iter()
            .zip(&self.placements)
            .map(|(&m, placement)| self.meshes[m as usize].part.bounds_placed(placement))
            .collect();
        self.top.rebuild(std::mem::take(&mut self.placements), &boxes);
    }

    /// [`super::Geometry::move_copies`]: before [`Copies::build`] the placements change, after
    /// it the top level is rebuilt over them.
    pub fn place(&mut self, moves: &[(usize, Affine3A)]) {
        if moves.is_empty() {
            return;
        }
        let built = self.placements.is_empty();
        let mut instances = if built { self.top.instances().to_vec() } else { std::mem::take(&mut self.placements) };
        for &(k, to_world) in moves {
            if let Some(instance) = Instance::new(to_world) {
                instances[k] = instance;
            }
        }
        if !built {
            self.placements = instances;
            return;
        }
        let boxes: Vec<Aabb> = self
            .mesh_of
            .iter()
            .zip(&instances)
            .map(|(&m, placement)| self.meshes[m as usize].part.bounds_placed(placement))
            .collect();
        self.top.rebuild(instances, &boxes);
    }

    /// The mesh tree and the placement of copy `copy`.
    #[inline]
    pub fn copy(&self, copy: u32) -> (&Part, &Instance) {
        (&self.meshes[self.mesh_of[copy as usize] as usize].part, &self.top.instances()[copy as usize])
    }

    /// Calls `search(copy, object_ray)` for the copies the ray may hit, nearest first, with
    /// the ray in the copy's object space and its `tmax` the closest hit so far; `search`
    /// shrinks `tmax` on a hit and returns true. `ANY`: stop at the first hit.
    #[inline]
    pub fn search<const ANY: bool>(&self, ray: &mut Ray, mut search: impl FnMut(u32, &mut Ray) -> bool) -> bool {
        if self.is_empty() {
            return false;
        }
        if ANY {
            self.top.any_hit(ray, |i, r| search(i, &mut r.clone()))
        } else {
            self.top.closest_hit(ray, search)
        }
    }

    /// Whether the meshes' trees and the top level are built ([`Copies::build`]).
    pub fn is_built(&self) -> bool {
        self.placements.is_empty()
    }

    pub fn mesh_count(&self) -> usize {
        self.meshes.len()
    }

    /// Mesh `m` as [`CopiedMeshView`] shows it.
    pub fn mesh(&self, m: usize) -> CopiedMeshView<'_> {
        let mesh = &self.meshes[m];
        CopiedMeshView {
            wide: &mesh.part.wide,
            triangles: &mesh.triangles,
            triangle_material: &mesh.triangle_material,
            triangle_uv: &mesh.triangle_uv,
        }
    }

    /// Copy `copy`'s mesh, placement and box in the world (once built).
    pub fn placed(&self, copy: usize) -> (usize, &Instance, Aabb) {
        let m = self.mesh_of[copy] as usize;
        let instance = &self.top.instances()[copy];
        (m, instance, self.meshes[m].part.bounds_placed(instance))
    }

    /// Position, unit normal, material and relative offset of copy `copy`'s hit, in the
    /// mesh's object space.
    pub fn local_surface(&self, copy: u32, hit: &Hit) -> (Vec3, Vec3, u32, f32) {
        let mesh = &self.meshes[self.mesh_of[copy as usize] as usize];
        let [v0, e1, e2] = mesh.part.packed.get(hit.slot);
        let (p, n) = super::triangle_surface(v0, e1, e2, hit.u, hit.v);
        (p, n, mesh.triangle_material[hit.prim as usize], TRIANGLE_OFFSET)
    }

    /// The texture coordinates of copy `copy`'s hit.
    pub fn uv(&self, copy: u32, hit: &Hit) -> Option<Vec2> {
        let mesh = &self.meshes[self.mesh_of[copy as usize] as usize];
        mesh.triangle_uv.get(hit.prim as usize).map(|corners| super::interpolate_uv(corners, hit.u, hit.v))
    }

    /// Bytes held: the meshes' triangles (with materials and texture coordinates) and what
    /// is traced (their wide trees, packed triangles, and the copies with their top level).
    pub fn memory(&self) -> (usize, usize) {
        use std::mem::size_of;
        let triangles = self
            .meshes
            .iter()
            .map(|m| {
                m.triangles.capacity() * size_of::<[Vec3; 3]>()
                    + m.triangle_material.capacity() * size_of::<u32>()
                    + m.triangle_uv.capacity() * size_of::<[Vec2; 3]>()
            })
            .sum();
        let traced = self.meshes.iter().map(|m| m.part.traced_bytes()).sum::<usize>()
            + self.mesh_of.capacity() * size_of::<u32>()
            + self.top.memory();
        (triangles, traced)
    }
}
