//! The scene on the GPU: the CPU's own 8-wide BVH (the tree its renderer traces), the
//! primitives in that tree's leaf order (so a leaf is a run of consecutive records, one 48-byte
//! load each), the materials and, for light sampling, the emitters of a [`LightSet`], as
//! storage buffers (`shaders/common.wgsl` and `shaders/path.wgsl` read them).

use crate::device::{Binding, Gpu, GpuError};
use bytemuck::{Pod, Zeroable};
use phr_bvh::instance::{top_level_tree, Instance};
use phr_bvh::wide::{WideBvh, WideNode, PAD};
use phr_bvh::Aabb;
use phr_render::geometry::{CopiedMeshView, Geometry, WIDTH};
use phr_render::lights::LightSet;
use phr_render::material::Material;
use phr_render::scene::{Background, Scene};
use rayon::prelude::*;

/// The kernels' traversal stack (`STACK` in `shaders/common.wgsl`): a tree whose stack bound
/// (plus one node's children) exceeds it is refused.
pub const STACK: usize = 128;
/// The same for the top-level tree over the instances (`TOP_STACK`).
pub const TOP_STACK: usize = 64;
/// Up to this many instances the kernels search one after the other, without a top-level
/// tree (none is uploaded): its walk (a node, its children ordered, a stack in private
/// memory) cost lavapipe 4-17 % of the frame on the dynamic scenes, whose few parts the
/// instances' boxes cull as well.
pub const DIRECT_INSTANCES: usize = 8;

/// The WGSL every kernel starts with.
pub(crate) const COMMON_WGSL: &str = include_str!("shaders/common.wgsl");

/// The bit of a primitive's material word that marks a sphere (`SPHERE` in the shader).
const SPHERE: u32 = 1 << 31;
/// The bit of a triangle's material word that says its material has an alpha mask to test
/// (`MASKED` in the shader).
const MASKED: u32 = 1 << 30;

/// The count of an empty child slot (`EMPTY_SLOT` in the shader; the CPU marks one by an
/// inverted box instead, whose infinities the shader is spared).
pub const EMPTY_SLOT: u32 = u32::MAX;

/// A node as the shader reads it: [`phr_bvh::wide::WideNode`]`<8>` (its boxes' rows `min_x,
/// max_x, min_y, max_y, min_z, max_z`, one lane per child slot; each slot's child and
/// primitive count), with empty slots marked by [`EMPTY_SLOT`] and zero boxes.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct GpuNode {
    pub bounds: [[f32; WIDTH]; 6],
    /// Interior slot: the child's node index; leaf slot: its first primitive record.
    pub child: [u32; WIDTH],
    /// Leaf slot: its number of primitives; interior slot: 0; empty slot: [`EMPTY_SLOT`].
    pub count: [u32; WIDTH],
}

/// A part of a two-level scene (see `Instance` in the shader): where its tree starts and how
/// it is placed in the world, the matrices by columns as glam holds them, so that the shader
/// transforms rays, points and normals with the CPU's operations in the CPU's order.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct GpuInstance {
    /// World to object space: the linear part's columns, then the translation (`w` unused).
    pub to_object: [[f32; 4]; 4],
    /// Object to world space, the same way.
    pub to_world: [[f32; 4]; 4],
    /// Normals into the world: the columns of the transpose of `to_object`'s linear part.
    pub normal: [[f32; 4]; 3],
    /// The part's box in the world; `lo[3]`: the bits of its root node's index; `hi[3]`: the
    /// bits of its flags ([`INSTANCE_IDENTITY`], [`INSTANCE_MIRRORS`], [`INSTANCE_EMPTY`]).
    pub lo: [f32; 4],
    pub hi: [f32; 4],
}

/// Flags of a [`GpuInstance`] (the same in the shader): rays pass unchanged; the transform
/// mirrors (a triangle's normal turns around); the part holds nothing to hit.
pub const INSTANCE_IDENTITY: u32 = 1;
pub const INSTANCE_MIRRORS: u32 = 2;
pub const INSTANCE_EMPTY: u32 = 4;

impl GpuInstance {
    /// Its flags ([`INSTANCE_IDENTITY`], ...).
    pub fn flags(&self) -> u32 {
        self.hi[3].to_bits()
    }

    fn new(instance: &Instance, world: Aabb, root: u32) -> Self {
        let column = |v: glam::Vec3A| [v.x, v.y, v.z, 0.0];
        let affine = |a: &glam::Affine3A| {
            [column(a.matrix3.x_axis), column(a.matrix3.y_axis), column(a.matrix3.z_axis), column(a.translation)]
        };
        let normal = instance.to_object.matrix3.transpose();
        let flags = if instance.is_identity() { INSTANCE_IDENTITY } else { 0 }
            | if instance.mirrors() { INSTANCE_MIRRORS } else { 0 }
            | if world.is_empty() { INSTANCE_EMPTY } else { 0 };
        let (lo, hi) = if world.is_empty() { (glam::Vec3::ZERO, glam::Vec3::ZERO) } else { (world.min, world.max) };
        Self {
            to_object: affine(&instance.to_object),
            to_world: affine(&instance.to_world),
            normal: [column(normal.x_axis), column(normal.y_axis), column(normal.z_axis)],
            lo: [lo.x, lo.y, lo.z, f32::from_bits(root)],
            hi: [hi.x, hi.y, hi.z, f32::from_bits(flags)],
        }
    }
}

/// A primitive (see `Prim` in the shader). `c[3]`: the bits of its emitter's number plus one
/// (0: not a light to sample).
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct GpuPrim {
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub c: [f32; 4],
}

/// A material (see `Material` in `shaders/path.wgsl`).
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct GpuMaterial {
    pub a: [f32; 4],
    pub b: [f32; 4],
}

/// An emitter to sample (see `Light` in `shaders/path.wgsl`): a triangle as its primitive
/// record, a sphere as centre and radius; `a[3]` the bits of its material (with the sphere
/// flag), `b[3]` its area, `c[3]` the probability of picking it.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct GpuLight {
    pub a: [f32; 4],
    pub b: [f32; 4],
    pub c: [f32; 4],
}

/// What is uploaded, laid out on the CPU (no GPU needed: the tests check it apart).
#[derive(Clone, Debug, Default)]
pub struct Packed {
    pub nodes: Vec<GpuNode>,
    pub prims: Vec<GpuPrim>,
    /// The parts of a two-level scene, each with its tree among `nodes` and its primitives
    /// among `prims` (empty: one tree over the scene, rooted at node 0).
    pub instances: Vec<GpuInstance>,
    pub materials: Vec<GpuMaterial>,
    /// The emitters of the light set, and its cumulative selection weights (both empty
    /// without light sampling).
    pub lights: Vec<GpuLight>,
    pub light_cdf: Vec<f32>,
    /// Probability of sampling the sky; `None`: no light sampling (the implicit estimator).
    pub sky_probability: Option<f32>,
    /// Where each tree lies among `nodes` and `prims` (one per part, in order).
    pub slots: Vec<TreeSlot>,
    /// Each primitive's emitter number plus one, as the records hold it ([`Emitters`]).
    pub emitter_of: Vec<u32>,
    /// The root node of each mesh placed many times (the copies' instances follow the
    /// parts').
    pub mesh_roots: Vec<u32>,
    /// Where the top-level tree over the instances lies (`None`: none needed, for no more
    /// than [`DIRECT_INSTANCES`]).
    pub top: Option<TreeSlot>,
    /// Every colour texture's texels (sRGB, `r | g << 8 | b << 16`), one after the other, and
    /// each texture's first texel, width and height.
    pub texels: Vec<u32>,
    pub textures: Vec<[u32; 4]>,
    /// Each triangle's corners' texture coordinates, three per triangle in scene order (empty
    /// when no material has a texture).
    pub uvs: Vec<[f32; 2]>,
    /// An environment map's linear texels, and its tables one after the other: over rows,
    /// over each row's cells, each cell's probability (`EnvironmentTables`); empty without one.
    pub environment_texels: Vec<[f32; 4]>,
    pub environment_tables: Vec<f32>,
    /// The environment map's width and height, and its rotation's cosine and sine.
    pub environment: Option<([u32; 2], [f32; 2])>,
}

impl Packed {
    /// Lays out `geometry` (its primitives and the wide tree its queries trace,
    /// [`Geometry::wide_bvh`]), the materials of `scene` and, for light sampling, `lights`
    /// (made for `geometry`). Refuses what the kernels cannot draw yet rather than drawing it
    /// wrong.
    pub fn new(scene: &Scene, geometry: &Geometry, lights: Option<&LightSet>) -> Result<Self, GpuError> {
        let mut packed = Self::moved_geometry(scene, geometry, lights)?;
        packed.add_materials(scene, geometry);
        Ok(packed)
    }

    /// What moves when `geometry` moves ([`Packed::moved`]), with its own trees: the wide
    /// tree over the scene, or each part's under its instance.
    pub fn moved_geometry(scene: &Scene, geometry: &Geometry, lights: Option<&LightSet>) -> Result<Self, GpuError> {
        Self::moved_parts(scene, geometry, lights, |_| false)
    }

    /// [`Packed::moved_geometry`], with room for the trees of the parts `grows` names to grow
    /// into ([`TreeSlot`]): their next trees can be written in place ([`Packed::part_records`]).
    pub fn moved_parts(
        scene: &Scene,
        geometry: &Geometry,
        lights: Option<&LightSet>,
        grows: impl Fn(usize) -> bool,
    ) -> Result<Self, GpuError> {
        // One tree in place: no instance to pass through. (A scene split into one part, a
        // single moving object, has its part placed by an instance like any other.)
        if !is_instanced(geometry) {
            return Self::lay_out(scene, geometry, &[(geometry.wide_bvh(), None, grows(0))], lights);
        }
        let parts: Vec<_> = (0..geometry.part_count())
            .map(|k| {
                (geometry.part_wide(k), Some((geometry.part_instance(k), geometry.part_world_bounds(k))), grows(k))
            })
            .collect();
        Self::lay_out(scene, geometry, &parts, lights)
    }

    /// [`Packed::new`] with `tree` over `geometry`'s primitives (scene numbers) instead of the
    /// one it holds.
    pub fn with_tree(
        scene: &Scene,
        geometry: &Geometry,
        tree: &WideBvh<WIDTH>,
        lights: Option<&LightSet>,
    ) -> Result<Self, GpuError> {
        let mut packed = Self::moved(scene, geometry, tree, lights)?;
        packed.add_materials(scene, geometry);
        Ok(packed)
    }

    /// The materials, textures and environment map of `scene`.
    fn add_materials(&mut self, scene: &Scene, geometry: &Geometry) {
        self.materials = scene
            .materials
            .iter()
            .enumerate()
            .map(|(m, material)| {
                let mut record = material_record(material);
                let texture = scene.material_texture.get(m).copied().flatten();
                record.b[2] = f32::from_bits(texture.unwrap_or(NO_TEXTURE));
                // Masks follow the colour textures in the texture table.
                let mask = scene.material_mask.get(m).copied().flatten();
                record.b[3] = f32::from_bits(mask.map_or(NO_TEXTURE, |k| k + scene.textures.len() as u32));
                record
            })
            .collect();
        (self.texels, self.textures, self.uvs) = texture_records(scene, geometry);
        if !self.uvs.is_empty() && geometry.copy_count() > 0 {
            // The copied meshes' triangles are numbered after the spheres (`add_copies`).
            self.uvs.resize(3 * geometry.prim_count(), [0.0; 2]);
            for m in 0..geometry.copied_mesh_count() {
                let mesh = geometry.copied_mesh(m);
                match mesh.triangle_uv.is_empty() {
                    true => self.uvs.resize(self.uvs.len() + 3 * mesh.triangles.len(), [0.0; 2]),
                    false => self.uvs.extend(mesh.triangle_uv.iter().flat_map(|c| c.map(|uv| uv.to_array()))),
                }
            }
        }
        if let Background::Environment(map) = &scene.background {
            let t = map.tables();
            self.environment_texels = t.texels.iter().map(|c| [c.x, c.y, c.z, 0.0]).collect();
            self.environment = Some(([t.width as u32, t.height as u32], [t.rotation.0, t.rotation.1]));
            self.environment_tables = [t.row_cdf, t.cell_cdf, t.cell_probability].concat();
        }
    }

    /// What moves when `geometry` moves and is rebuilt into `tree`: nodes, primitives, lights
    /// (the rest empty): what [`GpuScene::update`] writes, laid out without the materials,
    /// textures and environment map a moving scene keeps. Refuses what the kernels cannot
    /// trace yet.
    pub fn moved(
        scene: &Scene,
        geometry: &Geometry,
        tree: &WideBvh<WIDTH>,
        lights: Option<&LightSet>,
    ) -> Result<Self, GpuError> {
        Self::lay_out(scene, geometry, &[(tree, None, false)], lights)
    }

    /// Lays out `trees` over `geometry`'s primitives, one after the other (node links and
    /// leaves moved by where each tree's nodes and records begin, with room to grow for those
    /// marked), each with its instance and world box if the scene has parts, and the emitters
    /// of `lights`, in the world.
    #[allow(clippy::type_complexity)]
    fn lay_out(
        scene: &Scene,
        geometry: &Geometry,
        trees: &[(&WideBvh<WIDTH>, Option<(&Instance, Aabb)>, bool)],
        lights: Option<&LightSet>,
    ) -> Result<Self, GpuError> {
        check_supported(geometry)?;
        for (tree, _, _) in trees {
            check_tree(tree)?;
        }
        let emitters = Emitters::new(geometry, lights);
        let mut packed = Self {
            lights: emitters.records,
            light_cdf: emitters.cdf,
            sky_probability: emitters.sky_probability,
            ..Self::default()
        };
        // Copies are reached through instances: a tree in place then gets one too.
        let instanced = geometry.copy_count() > 0 || trees.iter().any(|(_, placed, _)| placed.is_some());
        for &(tree, placed, grows) in trees {
            let slot = packed.add_tree(grows, |packed, bases| {
                tree_records(scene, geometry, tree, &emitters.of_prim, bases, packed);
            });
            packed.slots.push(slot);
            let placed = placed.or(instanced.then(|| (&Instance::IDENTITY, tree_bounds(tree))));
            if let Some((instance, world)) = placed {
                packed.instances.push(GpuInstance::new(instance, world, slot.first_node));
            }
        }
        packed.emitter_of = emitters.of_prim;
        packed.add_copies(geometry)?;
        // (Up to DIRECT_INSTANCES the kernels search the instances one after the other.)
        if packed.instances.len() > DIRECT_INSTANCES {
            let top = top_records(&packed.instances, packed.nodes.len() as u32)?;
            packed.top = Some(packed.add_tree(true, |packed, _| packed.nodes.extend(top)));
        }
        Ok(packed)
    }

    /// Appends a tree (`records` appends its nodes and primitive records, given where they
    /// begin) with room to grow if `grows`, and returns its slot.
    fn add_tree(&mut self, grows: bool, records: impl FnOnce(&mut Self, (u32, u32))) -> TreeSlot {
        let (nodes, prims) = (self.nodes.len(), self.prims.len());
        records(self, (nodes as u32, prims as u32));
        let room = |n: usize| if grows { n + n / 8 + 64 } else { n };
        let slot = TreeSlot {
            first_node: nodes as u32,
            node_room: room(self.nodes.len() - nodes) as u32,
            first_prim: prims as u32,
            prim_room: room(self.prims.len() - prims) as u32,
        };
        // The room beyond the tree: nodes and records nothing links to.
        self.nodes.resize((slot.first_node + slot.node_room) as usize, GpuNode::zeroed());
        self.prims.resize((slot.first_prim + slot.prim_room) as usize, GpuPrim::zeroed());
        slot
    }

    /// The meshes placed many times, each tree once ([`Packed::mesh_roots`]), their triangles
    /// numbered after the scene's primitives, mesh after mesh; and an instance per copy.
    fn add_copies(&mut self, geometry: &Geometry) -> Result<(), GpuError> {
        let mut number = geometry.prim_count() as u32;
        for m in 0..geometry.copied_mesh_count() {
            let mesh = geometry.copied_mesh(m);
            check_tree(mesh.wide)?;
            let slot = self.add_tree(false, |packed, bases| copied_mesh_records(&mesh, number, bases, packed));
            self.mesh_roots.push(slot.first_node);
            number += mesh.triangles.len() as u32;
        }
        self.instances.extend(copy_instances(geometry, &self.mesh_roots)?);
        Ok(())
    }

    /// Part `k`'s tree laid out alone for `slot` (its nodes linked and its leaves pointing
    /// where the slot begins; only `nodes` and `prims` filled), for [`GpuScene::write_part`];
    /// `None` if it does not fit the slot's room. `emitter_of` is [`Packed::emitter_of`] of
    /// the layout the slot is in.
    pub fn part_records(
        scene: &Scene,
        geometry: &Geometry,
        k: usize,
        slot: TreeSlot,
        emitter_of: &[u32],
    ) -> Result<Option<Self>, GpuError> {
        let tree = geometry.part_wide(k);
        check_supported(geometry)?;
        check_tree(tree)?;
        if tree.nodes.len().max(1) > slot.node_room as usize || tree.prim_indices.len() > slot.prim_room as usize {
            return Ok(None);
        }
        let mut part = Self::default();
        tree_records(scene, geometry, tree, emitter_of, (slot.first_node, slot.first_prim), &mut part);
        Ok(Some(part))
    }

    /// The instances of `geometry`'s parts, each rooted where `slots` put its tree, and of its
    /// copies, rooted at their meshes' `mesh_roots` (empty for one tree in place).
    pub fn instance_records(
        geometry: &Geometry,
        slots: &[TreeSlot],
        mesh_roots: &[u32],
    ) -> Result<Vec<GpuInstance>, GpuError> {
        if !is_instanced(geometry) {
            return Ok(Vec::new());
        }
        let placed =
            |k: usize| GpuInstance::new(geometry.part_instance(k), geometry.part_world_bounds(k), slots[k].first_node);
        let mut instances: Vec<GpuInstance> = (0..geometry.part_count()).map(placed).collect();
        instances.extend(copy_instances(geometry, mesh_roots)?);
        Ok(instances)
    }
}

/// Whether `geometry` is traced through instances (its parts, or copies of meshes placed many
/// times), not as one tree in place.
pub fn is_instanced(geometry: &Geometry) -> bool {
    geometry.part_count() > 1 || !geometry.part_instance(0).is_identity() || geometry.copy_count() > 0
}

/// An instance per copy of `geometry`'s meshes placed many times, rooted at its mesh's tree.
fn copy_instances(geometry: &Geometry, mesh_roots: &[u32]) -> Result<Vec<GpuInstance>, GpuError> {
    (0..geometry.copy_count())
        .map(|c| match geometry.copy_placement(c) {
            Some((m, instance, world)) => Ok(GpuInstance::new(instance, world, mesh_roots[m])),
            None => Err(GpuError::Unsupported("copies of meshes whose trees are not built yet".into())),
        })
        .collect()
}

/// The box of `tree`'s root's children.
fn tree_bounds(tree: &WideBvh<WIDTH>) -> Aabb {
    let Some(root) = tree.nodes.first() else { return Aabb::EMPTY };
    (0..WIDTH).filter(|&i| root.is_used(i)).fold(Aabb::EMPTY, |b, i| b.union(root.child_bounds(i)))
}

/// The top-level tree over `instances` by their world boxes (those with nothing to hit left
/// out), as nodes linked from `node_base` on, a leaf slot's child the instance's number
/// ([`phr_bvh::instance::top_level_tree`], the tree the CPU's top levels trace).
pub fn top_records(instances: &[GpuInstance], node_base: u32) -> Result<Vec<GpuNode>, GpuError> {
    let hittable: Vec<u32> =
        (0..instances.len() as u32).filter(|&k| instances[k as usize].flags() & INSTANCE_EMPTY == 0).collect();
    let boxes: Vec<Aabb> = hittable
        .iter()
        .map(|&k| {
            let i = &instances[k as usize];
            Aabb::new(glam::Vec3::from_slice(&i.lo[..3]), glam::Vec3::from_slice(&i.hi[..3]))
        })
        .collect();
    if boxes.is_empty() {
        return Ok(vec![EMPTY_ROOT]);
    }
    let tree = top_level_tree(&boxes);
    // The top level's walk pushes every hit child but the nearest.
    let needed = tree.stack_bound() + WIDTH;
    if needed > TOP_STACK {
        return Err(GpuError::Unsupported(format!(
            "a top-level tree whose traversal may need {needed} stack entries (the GPU's holds {TOP_STACK})"
        )));
    }
    Ok(tree
        .nodes
        .iter()
        .map(|node| {
            let mut gpu = gpu_node(node, node_base, 0);
            for i in (0..WIDTH).filter(|&i| node.is_used(i) && node.count[i] > 0) {
                // One instance per leaf slot: the slot holds its number.
                debug_assert_eq!(node.count[i], 1);
                gpu.child[i] = hittable[tree.prim_indices[node.child[i] as usize] as usize];
            }
            gpu
        })
        .collect())
}

/// Where one tree lies in the uploaded nodes and records: its first of each, and how many
/// of each are kept for it. A tree that changes from frame to frame gets room to grow (an
/// eighth more), so that its next tree, rebuilt with a few more nodes or leaves, is written
/// in place rather than the whole scene laid out again.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TreeSlot {
    pub first_node: u32,
    pub node_room: u32,
    pub first_prim: u32,
    pub prim_room: u32,
}

/// The emitters of a light set as the kernels sample them, and each primitive's emitter.
pub struct Emitters {
    /// Each primitive's emitter number plus one (0: none), up to the last emitter.
    pub of_prim: Vec<u32>,
    pub records: Vec<GpuLight>,
    pub cdf: Vec<f32>,
    pub sky_probability: Option<f32>,
}

impl Emitters {
    /// The emitters of `lights` (made for `geometry`) where they are in the world; none
    /// without light sampling.
    pub fn new(geometry: &Geometry, lights: Option<&LightSet>) -> Self {
        let n_tris = geometry.triangle_count();
        let mut of_prim = Vec::new();
        let mut records = Vec::new();
        for (k, (p, area, selection)) in lights.iter().flat_map(|l| l.emitters()).enumerate() {
            of_prim.resize(of_prim.len().max(p as usize + 1), 0);
            of_prim[p as usize] = k as u32 + 1;
            // Sampled where it is in the world (a part's primitives are in its object space).
            let GpuPrim { a, b, c } = world_record(geometry, n_tris, p);
            let b = if (p as usize) < n_tris { [b[0], b[1], b[2], area] } else { [b[0], 0.0, 0.0, area] };
            records.push(GpuLight { a, b, c: [c[0], c[1], c[2], selection] });
        }
        Self {
            of_prim,
            records,
            cdf: lights.map_or(Vec::new(), |l| l.cdf().to_vec()),
            sky_probability: lights.map(LightSet::sky_probability),
        }
    }
}

/// Appends `tree`'s nodes and records to `packed`'s, the nodes linked and the leaves
/// pointing as if they began at `(node_base, record_base)`. A leaf's primitives are a run of
/// `prim_indices` already: the records keep its order (the padding between leaves becomes
/// records no leaf covers).
fn tree_records(
    scene: &Scene,
    geometry: &Geometry,
    tree: &WideBvh<WIDTH>,
    emitter_of: &[u32],
    (node_base, record_base): (u32, u32),
    packed: &mut Packed,
) {
    let n_tris = geometry.triangle_count();
    let masked = |material: u32| scene.material_mask.get(material as usize).is_some_and(Option::is_some);
    packed.prims.par_extend(tree.prim_indices.par_iter().map(|&p| {
        if p == PAD {
            return GpuPrim::zeroed();
        }
        let mut record = prim_record(geometry, n_tris, p);
        record.c[3] = f32::from_bits(emitter_of.get(p as usize).copied().unwrap_or(0));
        if (p as usize) < n_tris && masked(geometry.triangle_material[p as usize]) {
            record.a[3] = f32::from_bits(record.a[3].to_bits() | MASKED);
        }
        record
    }));
    packed.nodes.par_extend(tree.nodes.par_iter().map(|node| gpu_node(node, node_base, record_base)));
    if tree.nodes.is_empty() {
        packed.nodes.push(EMPTY_ROOT);
    }
}

/// A root with nothing to hit: its slots all empty.
const EMPTY_ROOT: GpuNode = GpuNode { bounds: [[0.0; WIDTH]; 6], child: [0; WIDTH], count: [EMPTY_SLOT; WIDTH] };

/// `node` as the shader reads it, its interior slots linked from `node_base` on and its leaf
/// slots from `record_base` on, empty slots marked.
fn gpu_node(node: &WideNode<WIDTH>, node_base: u32, record_base: u32) -> GpuNode {
    let mut gpu = GpuNode { bounds: node.bounds, child: node.child, count: node.count };
    for i in 0..WIDTH {
        if !node.is_used(i) {
            for row in &mut gpu.bounds {
                row[i] = 0.0;
            }
            (gpu.child[i], gpu.count[i]) = (0, EMPTY_SLOT);
        } else if node.count[i] == 0 {
            gpu.child[i] += node_base;
        } else {
            gpu.child[i] += record_base;
        }
    }
    gpu
}

/// [`tree_records`] for a mesh placed many times: its triangles (never masked, never
/// emitting: such meshes are written out instead) numbered from `first_number` on.
fn copied_mesh_records(
    mesh: &CopiedMeshView,
    first_number: u32,
    (node_base, record_base): (u32, u32),
    packed: &mut Packed,
) {
    packed.prims.par_extend(mesh.wide.prim_indices.par_iter().map(|&p| {
        if p == PAD {
            return GpuPrim::zeroed();
        }
        triangle_record(mesh.triangles[p as usize], mesh.triangle_material[p as usize], first_number + p)
    }));
    packed.nodes.par_extend(mesh.wide.nodes.par_iter().map(|node| gpu_node(node, node_base, record_base)));
    if mesh.wide.nodes.is_empty() {
        packed.nodes.push(EMPTY_ROOT);
    }
}

/// A material's texture word when it has none (`NO_TEXTURE` in the shader).
const NO_TEXTURE: u32 = u32::MAX;

/// The colour textures' texels and then the alpha masks' one after the other, where each
/// begins, its size and (masks) the bits of its threshold, and the triangles' texture
/// coordinates (none of the three when no material has a texture or a mask).
fn texture_records(scene: &Scene, geometry: &Geometry) -> (Vec<u32>, Vec<[u32; 4]>, Vec<[f32; 2]>) {
    if !scene.material_texture.iter().chain(&scene.material_mask).any(Option::is_some) {
        return (Vec::new(), Vec::new(), Vec::new());
    }
    let mut texels = Vec::new();
    let mut textures = Vec::new();
    for texture in &scene.textures {
        let (w, h) = texture.size();
        textures.push([texels.len() as u32, w, h, 0]);
        texels.extend(texture.srgb_texels().iter().map(|&[r, g, b]| u32::from_le_bytes([r, g, b, 0])));
    }
    for mask in &scene.masks {
        let ((w, h), coverage, threshold) = mask.parts();
        textures.push([texels.len() as u32, w, h, threshold.to_bits()]);
        texels.extend(coverage.iter().map(|&c| u32::from(c)));
    }
    let uvs = match geometry.triangle_uv.is_empty() {
        true => vec![[0.0; 2]; 3 * geometry.triangles.len()],
        false => geometry.triangle_uv.iter().flat_map(|corners| corners.map(|c| c.to_array())).collect(),
    };
    (texels, textures, uvs)
}

fn prim_record(geometry: &Geometry, n_tris: usize, p: u32) -> GpuPrim {
    let i = p as usize;
    if i < n_tris {
        return triangle_record(geometry.triangles[i], geometry.triangle_material[i], p);
    }
    let s = &geometry.spheres[i - n_tris];
    let c = s.sphere.center;
    GpuPrim {
        a: [c.x, c.y, c.z, f32::from_bits(s.material | SPHERE)],
        b: [s.sphere.radius, 0.0, 0.0, f32::from_bits(p)],
        c: [0.0; 4],
    }
}

/// Triangle `[v0, v1, v2]` with its material and number, as `v0` and the edges the CPU
/// computes (`Geometry::triangle_edges`: the same bits).
fn triangle_record([v0, v1, v2]: [glam::Vec3; 3], material: u32, number: u32) -> GpuPrim {
    let [e1, e2] = [v1 - v0, v2 - v0];
    let (material, number) = (f32::from_bits(material), f32::from_bits(number));
    GpuPrim { a: [v0.x, v0.y, v0.z, material], b: [e1.x, e1.y, e1.z, number], c: [e2.x, e2.y, e2.z, 0.0] }
}

/// [`prim_record`] placed in the world (the same for primitives of a part in place).
fn world_record(geometry: &Geometry, n_tris: usize, p: u32) -> GpuPrim {
    let mut record = prim_record(geometry, n_tris, p);
    let i = p as usize;
    if i < n_tris {
        let [v0, e1, e2] = geometry.world_triangle_edges(i);
        record.a[..3].copy_from_slice(&v0.to_array());
        record.b[..3].copy_from_slice(&e1.to_array());
        record.c[..3].copy_from_slice(&e2.to_array());
    } else {
        let s = geometry.world_sphere(i - n_tris);
        record.a[..3].copy_from_slice(&s.center.to_array());
        record.b[0] = s.radius;
    }
    record
}

fn material_record(m: &Material) -> GpuMaterial {
    let kind = |k: u32| f32::from_bits(k);
    match *m {
        Material::Lambertian { albedo } => GpuMaterial { a: [albedo.x, albedo.y, albedo.z, kind(0)], b: [0.0; 4] },
        Material::Metal { albedo, fuzz, fuzz_in_sphere } => GpuMaterial {
            a: [albedo.x, albedo.y, albedo.z, kind(1)],
            b: [fuzz, f32::from(u8::from(fuzz_in_sphere)), 0.0, 0.0],
        },
        Material::Dielectric { ior } => GpuMaterial { a: [1.0, 1.0, 1.0, kind(2)], b: [ior, 0.0, 0.0, 0.0] },
        Material::Emissive { emit, two_sided } => {
            GpuMaterial { a: [emit.x, emit.y, emit.z, kind(3)], b: [f32::from(u8::from(two_sided)), 0.0, 0.0, 0.0] }
        }
    }
}

/// What the kernels do not trace yet.
fn check_supported(geometry: &Geometry) -> Result<(), GpuError> {
    let unsupported = |what: String| Err(GpuError::Unsupported(what));
    if geometry.triangles.len() != geometry.triangle_count() {
        return unsupported("the geometry's triangles were released".into());
    }
    Ok(())
}

/// The kernels trace trees whose stack fits theirs.
fn check_tree(tree: &WideBvh<WIDTH>) -> Result<(), GpuError> {
    // The kernels push what the CPU's traversal pushes (a node's hit children but the
    // nearest), so the stack holds at most the bound; one node's children more are kept as
    // a margin.
    let needed = tree.stack_bound() + WIDTH;
    if needed > STACK {
        return Err(GpuError::Unsupported(format!(
            "a tree whose traversal may need {needed} stack entries (the GPU's stack holds {STACK})"
        )));
    }
    Ok(())
}

/// The scene's buffers on the GPU, bound as group 0 of every kernel.
pub struct GpuScene {
    pub(crate) layout: wgpu::BindGroupLayout,
    pub(crate) group: wgpu::BindGroup,
    /// The group's bindings in order ([`BUFFER_NAMES`]).
    buffers: [wgpu::Buffer; BUFFERS],
    /// How the nodes and the primitives lie across their bindings: kernels are compiled for it.
    pub(crate) split: Split,
    pub background: Background,
    /// Light sampling: the sky's probability and the number of emitters that can be picked
    /// (`None`: the implicit estimator).
    pub(crate) lights: Option<(f32, u32)>,
    /// The environment map's size and rotation (see [`Packed::environment`]).
    pub(crate) environment: Option<([u32; 2], [f32; 2])>,
    /// Bytes of the last upload (all of it, or what [`GpuScene::update`] wrote).
    pub bytes: u64,
}

const BUFFERS: usize = 17;
const BUFFER_NAMES: [&str; BUFFERS] = [
    "BVH nodes",
    "primitives",
    "materials",
    "lights",
    "light weights",
    "texels",
    "textures",
    "texture coordinates",
    "environment map",
    "environment map tables",
    "BVH nodes (2nd binding)",
    "BVH nodes (3rd binding)",
    "BVH nodes (4th binding)",
    "primitives (2nd binding)",
    "primitives (3rd binding)",
    "primitives (4th binding)",
    "instances",
];
/// The bindings that hold the nodes and the primitives, in order (`common.wgsl`: `node_at`
/// and `prim_at`).
const NODE_BINDINGS: [usize; SPLIT] = [0, 10, 11, 12];
const PRIM_BINDINGS: [usize; SPLIT] = [1, 13, 14, 15];
/// Bindings an array may be split across.
const SPLIT: usize = 4;
/// The bindings of the emissive triangles and their weights.
const LIGHT_BINDINGS: [usize; 2] = [3, 4];
/// The binding of the parts' instances.
const INSTANCE_BINDING: usize = 16;

/// The buffers a moving scene changes ([`GpuScene::update`]): nodes, primitives, lights, light
/// weights, instances.
fn moving() -> impl Iterator<Item = usize> {
    NODE_BINDINGS.into_iter().chain(PRIM_BINDINGS).chain(LIGHT_BINDINGS).chain([INSTANCE_BINDING])
}

/// How a scene's nodes and primitives lie across their bindings: what the kernels are compiled
/// for (their pipeline constants, `node_at` and `prim_at` in `shaders/common.wgsl`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Split {
    nodes_per_binding: usize,
    prims_per_binding: usize,
    node_bindings: usize,
    prim_bindings: usize,
    /// Instances: the parts of a two-level scene and the copies of meshes placed many times
    /// (0: one tree over the scene).
    instances: usize,
    /// The top-level tree's root node (0: none, the instances searched one after the other).
    top_root: usize,
}

impl Split {
    pub(crate) fn constants(&self) -> [(&'static str, f64); 6] {
        [
            ("top_root", self.top_root as f64),
            ("nodes_per_binding", self.nodes_per_binding as f64),
            ("prims_per_binding", self.prims_per_binding as f64),
            ("node_bindings", self.node_bindings as f64),
            ("prim_bindings", self.prim_bindings as f64),
            ("instance_count", self.instances as f64),
        ]
    }
}

/// The bytes of each buffer of [`GpuScene`], in binding order, and how the nodes and the
/// primitives are cut into as many bindings as they need on `gpu` ([`Gpu::per_binding`]).
fn contents<'a>(gpu: &Gpu, packed: &'a Packed) -> Result<([&'a [u8]; BUFFERS], Split), GpuError> {
    let mut data: [&[u8]; BUFFERS] = [
        &[],
        &[],
        bytemuck::cast_slice(&packed.materials),
        bytemuck::cast_slice(&packed.lights),
        bytemuck::cast_slice(&packed.light_cdf),
        bytemuck::cast_slice(&packed.texels),
        bytemuck::cast_slice(&packed.textures),
        bytemuck::cast_slice(&packed.uvs),
        bytemuck::cast_slice(&packed.environment_texels),
        bytemuck::cast_slice(&packed.environment_tables),
        &[],
        &[],
        &[],
        &[],
        &[],
        &[],
        bytemuck::cast_slice(&packed.instances),
    ];
    let (nodes_per_binding, prims_per_binding) = (gpu.per_binding::<GpuNode>(), gpu.per_binding::<GpuPrim>());
    let split = Split {
        nodes_per_binding,
        prims_per_binding,
        node_bindings: split_into(&mut data, NODE_BINDINGS, &packed.nodes, nodes_per_binding, "the BVH nodes", gpu)?,
        prim_bindings: split_into(&mut data, PRIM_BINDINGS, &packed.prims, prims_per_binding, "the primitives", gpu)?,
        instances: packed.instances.len(),
        top_root: packed.top.map_or(0, |slot| slot.first_node as usize),
    };
    Ok((data, split))
}

/// Puts `items` into the bindings `slots` of `data`, `per_binding` to each; returns how many
/// bindings that takes (at least one), refused if they need more than [`SPLIT`].
fn split_into<'a, T: bytemuck::Pod>(
    data: &mut [&'a [u8]; BUFFERS],
    slots: [usize; SPLIT],
    items: &'a [T],
    per_binding: usize,
    what: &str,
    gpu: &Gpu,
) -> Result<usize, GpuError> {
    let chunks: Vec<&[T]> = items.chunks(per_binding.max(1)).collect();
    if chunks.len() > SPLIT {
        return Err(GpuError::TooLarge(format!(
            "{what} take {} MiB, more than the {SPLIT} storage bindings of {} MiB each that {} allows",
            std::mem::size_of_val(items) >> 20,
            gpu.max_binding >> 20,
            gpu.info.name
        )));
    }
    for (slot, chunk) in slots.into_iter().zip(&chunks) {
        data[slot] = bytemuck::cast_slice(chunk);
    }
    Ok(chunks.len().max(1))
}

impl GpuScene {
    /// Uploads what [`Packed::new`] lays out.
    pub fn upload(gpu: &Gpu, scene: &Scene, geometry: &Geometry, lights: Option<&LightSet>) -> Result<Self, GpuError> {
        Self::upload_packed(gpu, &Packed::new(scene, geometry, lights)?, scene.background.clone())
    }

    pub fn upload_packed(gpu: &Gpu, packed: &Packed, background: Background) -> Result<Self, GpuError> {
        let (data, split) = contents(gpu, packed)?;
        let mut buffers = Vec::with_capacity(BUFFERS);
        for (name, bytes) in BUFFER_NAMES.iter().zip(data) {
            buffers.push(gpu.storage(name, bytes, wgpu::BufferUsages::COPY_DST)?);
        }
        let buffers: [wgpu::Buffer; BUFFERS] = buffers.try_into().expect("one buffer per binding");
        let layout = gpu.layout("scene", &[Binding::Read; BUFFERS]);
        let group = gpu.bind("scene", &layout, &buffers.each_ref());
        let bytes = data.iter().map(|d| d.len() as u64).sum();
        let lights = packed.sky_probability.map(|sky| (sky, packed.light_cdf.len() as u32));
        let environment = packed.environment;
        Ok(Self { layout, group, buffers, split, background, lights, environment, bytes })
    }

    /// Replaces the scene's contents with `packed` (the same scene moved: its tree, primitives
    /// and lights), writing into the buffers there are where the new contents fit and making
    /// larger ones where they do not; materials, textures and texture coordinates stay as they
    /// are. Returns without waiting for the GPU.
    pub fn update(&mut self, gpu: &Gpu, packed: &Packed) -> Result<(), GpuError> {
        let (data, split) = contents(gpu, packed)?;
        // The larger buffers first, all of them: a failure leaves the scene as it was.
        let mut larger = Vec::new();
        for k in moving().filter(|&k| data[k].len() as u64 > self.buffers[k].size()) {
            larger.push((k, gpu.storage(BUFFER_NAMES[k], data[k], wgpu::BufferUsages::COPY_DST)?));
        }
        let rebound = !larger.is_empty();
        for (k, buffer) in larger {
            self.buffers[k] = buffer;
        }
        let mut bytes = 0;
        for k in moving() {
            if data[k].len() as u64 <= self.buffers[k].size() && !data[k].is_empty() {
                gpu.queue.write_buffer(&self.buffers[k], 0, data[k]);
            }
            bytes += data[k].len() as u64;
        }
        if rebound {
            self.group = gpu.bind("scene", &self.layout, &self.buffers.each_ref());
        }
        self.bytes = bytes;
        self.split = split;
        self.lights = packed.sky_probability.map(|sky| (sky, packed.light_cdf.len() as u32));
        Ok(())
    }

    /// Writes a part's tree in place: its nodes and records as [`Packed::part_records`] laid
    /// them out for `slot`, a slot of the layout uploaded. Returns the bytes written, without
    /// waiting for the GPU.
    pub fn write_part(&self, gpu: &Gpu, slot: TreeSlot, part: &Packed) -> u64 {
        let (nodes, prims) = (&part.nodes[..], &part.prims[..]);
        assert!(nodes.len() <= slot.node_room as usize && prims.len() <= slot.prim_room as usize, "beyond the slot");
        self.write_items(gpu, NODE_BINDINGS, self.split.nodes_per_binding, slot.first_node as usize, nodes);
        self.write_items(gpu, PRIM_BINDINGS, self.split.prims_per_binding, slot.first_prim as usize, prims);
        (std::mem::size_of_val(nodes) + std::mem::size_of_val(prims)) as u64
    }

    /// Writes the parts' instances (as many as were uploaded) and the emitters (as many as
    /// were uploaded, their weights and the sky's probability), without waiting. Returns the
    /// bytes written, or `None` (nothing written) if they are not as many as there are.
    pub fn write_placement(&mut self, gpu: &Gpu, instances: &[GpuInstance], emitters: &Emitters) -> Option<u64> {
        let writes = [
            (INSTANCE_BINDING, bytemuck::cast_slice::<_, u8>(instances)),
            (LIGHT_BINDINGS[0], bytemuck::cast_slice(&emitters.records)),
            (LIGHT_BINDINGS[1], bytemuck::cast_slice(&emitters.cdf)),
        ];
        if instances.len() != self.split.instances
            || writes.iter().any(|(k, d)| d.len() as u64 > self.buffers[*k].size())
        {
            return None;
        }
        if self.lights.map(|(_, n)| n as usize) != emitters.sky_probability.map(|_| emitters.cdf.len()) {
            return None;
        }
        for &(k, data) in &writes {
            if !data.is_empty() {
                gpu.queue.write_buffer(&self.buffers[k], 0, data);
            }
        }
        self.lights = emitters.sky_probability.map(|sky| (sky, emitters.cdf.len() as u32));
        Some(writes.iter().map(|(_, d)| d.len() as u64).sum())
    }

    /// Writes `items` into the array cut across `bindings` (`per_binding` to each) from
    /// entry `first` on.
    fn write_items<T: Pod>(&self, gpu: &Gpu, bindings: [usize; SPLIT], per_binding: usize, first: usize, items: &[T]) {
        let per_binding = per_binding.max(1);
        let mut done = 0;
        while done < items.len() {
            let at = first + done;
            let (binding, offset) = (at / per_binding, at % per_binding);
            let n = (per_binding - offset).min(items.len() - done);
            let bytes = bytemuck::cast_slice(&items[done..done + n]);
            gpu.queue.write_buffer(&self.buffers[bindings[binding]], (offset * std::mem::size_of::<T>()) as u64, bytes);
            done += n;
        }
    }
}
