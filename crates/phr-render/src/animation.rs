//! Dynamic scenes: the [`Animator`] poses the renderable [`Geometry`] at a given time from
//! the scene's animations ([`crate::motion`]: procedural motions and glTF node animations),
//! resolved to "rest vertices in, posed vertices out".
//!
//! Posing keeps the primitive count and order, which is what the dynamic BVH pipeline of
//! thesis section 5.3 needs: the auxiliary LBVH is refitted, not rebuilt.

use crate::geometry::Geometry;
use crate::motion::{Animation, AnimationTarget, Motion};
use crate::scene::Scene;
use glam::{Affine3A, Mat4, Vec3};
use rayon::prelude::*;
use std::ops::Range;

/// One animated mesh's rest state and where its triangles sit in the geometry.
struct PosedMesh {
    /// Moved as a whole by one affine map: procedural rotations and oscillations, and no
    /// other animation of the same mesh (two animations pose it in turn).
    rigid: bool,
    /// A mesh moved by its glTF nodes alone: the triangles of each moving node, which move as
    /// a whole with it (each a rigid object of [`Animator::objects`]); empty otherwise.
    node_parts: Vec<NodePart>,
    triangles: Range<usize>,
    indices: Vec<[u32; 3]>,
    rest: Vec<Vec3>,
    posed: Vec<Vec3>,
    /// When the first procedural motion is a wave: its [`Motion::rest_phases`] of `rest`.
    wave_phases: Option<Vec<[f32; 2]>>,
    animation: Animation,
}

/// The triangles a glTF node places, and the map from the world to the node's rest frame.
struct NodePart {
    node: usize,
    /// The triangles' indices in the geometry.
    prims: Vec<u32>,
    rest_inverse: Mat4,
}

/// What object `k` of [`Animator::objects`] is.
#[derive(Clone, Copy)]
enum ObjectRef {
    /// A whole mesh of `meshes`.
    Mesh(usize),
    /// Node part `.1` of mesh `.0`.
    Part(usize, usize),
    /// Sphere `k` of `spheres`.
    Sphere(usize),
}

/// Poses a scene's geometry at any time: holds the rest vertices of everything that moves.
pub struct Animator {
    meshes: Vec<PosedMesh>,
    spheres: Vec<(usize, Vec3, Vec<Motion>)>,
    objects: Vec<ObjectRef>,
    copies: Vec<MovingCopy>,
}

/// A moving copy of a mesh placed many times ([`crate::scene::InstancedMesh::motions`]): its
/// number among the geometry's copies, its placement at rest and its motions in the world.
/// Only its transform changes: the mesh's tree is shared and never refitted.
struct MovingCopy {
    copy: usize,
    rest: Affine3A,
    motions: Vec<Motion>,
}

/// An animated object's primitives (scene order, as in [`Geometry`]) and whether it moves
/// rigidly: as a whole, by one affine map of its rest pose ([`Animator::rigid_transform`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MovingObject {
    pub prims: Vec<u32>,
    pub rigid: bool,
}

/// A mesh moved by its glTF nodes is moved as rigid parts, one per moving node, only when
/// each has at least this many triangles; smaller ones deform as one mesh. A part of its own
/// saves posing, refitting and packing its triangles every frame (about 0.05 µs a triangle on
/// 2 cores), but every ray that meets its box enters one more tree: on the carousel
/// (`scenes/dynamic/carousel.json`, four riders of 2,048 triangles) the moving frame stayed
/// at 13.6 ms and the paused one rose from 11.8 to 12.7 ms at 256² (`docs/dynamic/history.md`).
pub const NODE_PART_MIN_TRIANGLES: usize = 16_384;

impl Animator {
    /// The animations of `scene`, whose geometry was flattened by [`Geometry::new`] (meshes'
    /// triangles in scene order).
    pub fn new(scene: &Scene) -> Self {
        Self::with_node_part_minimum(scene, NODE_PART_MIN_TRIANGLES)
    }

    /// [`Animator::new`] with another [`NODE_PART_MIN_TRIANGLES`].
    pub fn with_node_part_minimum(scene: &Scene, min_triangles: usize) -> Self {
        let mut first_triangle = Vec::with_capacity(scene.meshes.len());
        let mut next = 0;
        for mesh in &scene.meshes {
            first_triangle.push(next);
            next += mesh.triangles.len();
        }
        let mut meshes = Vec::new();
        let mut spheres = Vec::new();
        for a in &scene.animations {
            match a.target {
                AnimationTarget::Mesh(m) => {
                    let mesh = &scene.meshes[m];
                    let rigid = matches!(&a.animation, Animation::Procedural(m) if Motion::affine_all(m, 0.0).is_some())
                        && scene.animations.iter().filter(|b| b.target == a.target).count() == 1;
                    let alone = scene.animations.iter().filter(|b| b.target == a.target).count() == 1;
                    let node_parts = match &a.animation {
                        Animation::Nodes(nodes) if alone => node_parts(mesh, nodes, first_triangle[m], min_triangles),
                        _ => Vec::new(),
                    };
                    let (indices, rest) = match &a.animation {
                        Animation::Procedural(_) => in_first_use_order(&mesh.triangles, &mesh.positions),
                        // Node animations pose vertices by their number in the mesh.
                        Animation::Nodes(_) => (mesh.triangles.clone(), mesh.positions.clone()),
                    };
                    let wave_phases = match &a.animation {
                        Animation::Procedural(motions) => motions.first().and_then(|m| m.rest_phases(&rest)),
                        Animation::Nodes(_) => None,
                    };
                    meshes.push(PosedMesh {
                        rigid,
                        node_parts,
                        triangles: first_triangle[m]..first_triangle[m] + mesh.triangles.len(),
                        indices,
                        posed: rest.clone(),
                        rest,
                        wave_phases,
                        animation: a.animation.clone(),
                    });
                }
                AnimationTarget::Sphere(s) => {
                    if let Animation::Procedural(motions) = &a.animation {
                        spheres.push((s, scene.spheres[s].sphere.center, motions.clone()));
                    }
                }
            }
        }
        let mut objects = Vec::new();
        for (k, mesh) in meshes.iter().enumerate() {
            match mesh.node_parts.len() {
                0 => objects.push(ObjectRef::Mesh(k)),
                n => objects.extend((0..n).map(|p| ObjectRef::Part(k, p))),
            }
        }
        objects.extend((0..spheres.len()).map(ObjectRef::Sphere));
        let mut copies = Vec::new();
        let mut copy = 0;
        for instanced in &scene.instanced {
            for placement in &instanced.copies {
                if !instanced.motions.is_empty() {
                    let motions = Motion::placed_by(&instanced.motions, placement.to_world);
                    copies.push(MovingCopy { copy, rest: placement.to_world, motions });
                }
                copy += 1;
            }
        }
        Self { meshes, spheres, objects, copies }
    }

    /// Whether anything moves at all.
    pub fn is_animated(&self) -> bool {
        !self.meshes.is_empty() || !self.spheres.is_empty() || !self.copies.is_empty()
    }

    /// Places the moving copies of meshes placed many times where they are at time `t`
    /// ([`Geometry::move_copies`]; every pose does).
    pub fn place_copies(&self, geometry: &mut Geometry, t: f32) {
        if self.copies.is_empty() {
            return;
        }
        let moves: Vec<(usize, Affine3A)> = self
            .copies
            .iter()
            .map(|c| (c.copy, Motion::affine_all(&c.motions, t).expect("copies move rigidly") * c.rest))
            .collect();
        geometry.move_copies(&moves);
    }

    /// Triangles that move (for statistics).
    pub fn moving_triangles(&self) -> usize {
        self.meshes.iter().map(|m| m.triangles.len()).sum()
    }

    /// The animated objects: the meshes (a mesh moved by its glTF nodes alone: the triangles
    /// of each moving node, as objects of their own), then the spheres (`triangle_count`:
    /// where the spheres' primitive indices start). Object `k` of this list is the `k` of
    /// [`Animator::rigid_transform`].
    pub fn objects(&self, triangle_count: usize) -> Vec<MovingObject> {
        self.objects
            .iter()
            .map(|&o| match o {
                ObjectRef::Mesh(k) => {
                    let m = &self.meshes[k];
                    MovingObject { prims: (m.triangles.start as u32..m.triangles.end as u32).collect(), rigid: m.rigid }
                }
                ObjectRef::Part(k, p) => {
                    MovingObject { prims: self.meshes[k].node_parts[p].prims.clone(), rigid: true }
                }
                ObjectRef::Sphere(s) => {
                    MovingObject { prims: vec![(triangle_count + self.spheres[s].0) as u32], rigid: true }
                }
            })
            .collect()
    }

    /// Where rigid object `k` of [`Animator::objects`] is at time `t`: the map from its rest
    /// pose. `None` for a deforming object.
    pub fn rigid_transform(&self, k: usize, t: f32) -> Option<Affine3A> {
        match self.objects[k] {
            ObjectRef::Mesh(m) => self.meshes[m].rigid_transform(t),
            ObjectRef::Part(m, p) => {
                let part = &self.meshes[m].node_parts[p];
                let Animation::Nodes(nodes) = &self.meshes[m].animation else { unreachable!("node parts of nodes") };
                Some(Affine3A::from_mat4(nodes.world_at(part.node, t) * part.rest_inverse))
            }
            ObjectRef::Sphere(s) => {
                // A sphere moves with its centre (its turning does not show).
                let (_, centre, motions) = &self.spheres[s];
                Some(Affine3A::from_translation(Motion::apply_all(motions, *centre, t) - *centre))
            }
        }
    }

    /// Moves the vertices of the deforming meshes alone to time `t` (the rigid objects, and
    /// the node parts of meshes moved by their glTF nodes, are placed by
    /// [`Animator::rigid_transform`]). Boxes are not recomputed.
    pub fn pose_deforming(&mut self, geometry: &mut Geometry, t: f32) {
        for mesh in &mut self.meshes {
            if !mesh.rigid && mesh.node_parts.is_empty() {
                mesh.pose(geometry, t);
            }
        }
        self.place_copies(geometry, t);
    }

    /// Moves the geometry's triangles and spheres to time `t` (seconds) and recomputes the
    /// primitive boxes. The BVH is left alone: refit or rebuild it next.
    pub fn pose(&mut self, geometry: &mut Geometry, t: f32) {
        for mesh in &mut self.meshes {
            mesh.pose(geometry, t);
        }
        for (s, centre, motions) in &self.spheres {
            geometry.spheres[*s].sphere.center = Motion::apply_all(motions, *centre, t);
        }
        geometry.update_boxes();
        self.place_copies(geometry, t);
    }
}

/// The mesh's vertices renumbered in the order its triangles first use them (unused ones
/// dropped), and its triangles in those numbers: posing then reads the vertices of
/// consecutive triangles from nearby memory instead of wherever the file put them. The same
/// triangles, corner for corner.
fn in_first_use_order(triangles: &[[u32; 3]], positions: &[Vec3]) -> (Vec<[u32; 3]>, Vec<Vec3>) {
    let mut number = vec![u32::MAX; positions.len()];
    let mut order = Vec::with_capacity(positions.len());
    let indices = triangles
        .iter()
        .map(|tri| {
            tri.map(|k| {
                let n = &mut number[k as usize];
                if *n == u32::MAX {
                    *n = order.len() as u32;
                    order.push(positions[k as usize]);
                }
                *n
            })
        })
        .collect();
    (indices, order)
}

impl PosedMesh {
    /// Moves its triangles in `geometry` to time `t`.
    fn pose(&mut self, geometry: &mut Geometry, t: f32) {
        match &self.animation {
            Animation::Procedural(motions) => match (&self.wave_phases, motions.first().and_then(|m| m.wave_at(t))) {
                (Some(phases), Some(wave)) => {
                    let others = &motions[1..];
                    self.posed
                        .par_iter_mut()
                        .zip(&self.rest)
                        .zip(phases)
                        .for_each(|((p, &r), &phase)| *p = Motion::apply_all(others, wave.apply(r, phase), t));
                }
                _ => {
                    self.posed.par_iter_mut().zip(&self.rest).for_each(|(p, &r)| *p = Motion::apply_all(motions, r, t))
                }
            },
            Animation::Nodes(nodes) => nodes.pose(&mut self.posed, t),
        }
        let posed = &self.posed;
        geometry.triangles[self.triangles.clone()]
            .par_iter_mut()
            .zip(&self.indices)
            // Indexed corner by corner: `idx.map(|k| posed[k])` went through an out-of-line
            // `array::try_map` per triangle and took 6.0 ms of the 871k-triangle dragon's
            // frame on 2 threads, against 2.6 ms this way.
            .for_each(|(tri, &[a, b, c])| *tri = [posed[a as usize], posed[b as usize], posed[c as usize]]);
    }

    /// The map from its rest pose at time `t`, if it moves rigidly as a whole. (A glTF node
    /// animation moves its parts differently: see [`PosedMesh::node_parts`].)
    fn rigid_transform(&self, t: f32) -> Option<Affine3A> {
        match &self.animation {
            Animation::Procedural(motions) if self.rigid => Motion::affine_all(motions, t),
            _ => None,
        }
    }
}

/// The triangles of `mesh` (its first in the geometry: `first_triangle`) that each moving node
/// of `nodes` places, with the node's rest frame; empty (the mesh then deforms as a whole) if
/// a part has fewer than `min_triangles`, a triangle joins vertices of different nodes, or a
/// node's vertices do not sit where its rest frame puts them.
fn node_parts(
    mesh: &crate::scene::Mesh,
    nodes: &crate::motion::NodeAnimation,
    first_triangle: usize,
    min_triangles: usize,
) -> Vec<NodePart> {
    let moving: Vec<_> = nodes.parts.iter().filter(|p| nodes.moves(p.node)).collect();
    let mut part_of_vertex = vec![usize::MAX; mesh.positions.len()];
    for (k, part) in moving.iter().enumerate() {
        let rest = nodes.rest_world(part.node);
        for (i, &local) in part.local.iter().enumerate() {
            let v = part.first_vertex + i;
            let (placed, at) = (rest.transform_point3(local), mesh.positions[v]);
            if (placed - at).length() > 1e-4 * (1.0 + at.length()) {
                return Vec::new();
            }
            part_of_vertex[v] = k;
        }
    }
    let mut prims = vec![Vec::new(); moving.len()];
    for (t, tri) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = tri.map(|v| part_of_vertex[v as usize]);
        if a != b || b != c {
            return Vec::new();
        }
        if a != usize::MAX {
            prims[a].push((first_triangle + t) as u32);
        }
    }
    if prims.iter().any(|p| p.len() < min_triangles) {
        return Vec::new();
    }
    moving
        .iter()
        .zip(prims)
        .map(|(part, prims)| NodePart { node: part.node, prims, rest_inverse: nodes.rest_world(part.node).inverse() })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_use_order_keeps_every_corner() {
        let positions: Vec<Vec3> = (0..6).map(|i| Vec3::splat(i as f32)).collect();
        // Vertex 5 unused; 4 used first.
        let triangles = [[4, 0, 2], [2, 3, 0], [1, 4, 3]];
        let (indices, rest) = in_first_use_order(&triangles, &positions);
        assert_eq!(indices, vec![[0, 1, 2], [2, 3, 1], [4, 0, 3]]);
        assert_eq!(rest.len(), 5);
        for (old, new) in triangles.iter().zip(&indices) {
            assert_eq!(old.map(|k| positions[k as usize]), new.map(|k| rest[k as usize]));
        }
    }
}
