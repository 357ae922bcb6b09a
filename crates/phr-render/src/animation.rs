//! Dynamic scenes: the [`Animator`] poses the renderable [`Geometry`] at a given time from
//! the scene's animations ([`crate::motion`]: procedural motions and glTF node animations),
//! resolved to "rest vertices in, posed vertices out".
//!
//! Posing keeps the primitive count and order, which is what the dynamic BVH pipeline of
//! thesis section 5.3 needs: the auxiliary LBVH is refitted, not rebuilt.

use crate::geometry::Geometry;
use crate::motion::{Animation, AnimationTarget, Motion};
use crate::scene::Scene;
use glam::{Affine3A, Vec3};
use rayon::prelude::*;
use std::ops::Range;

/// One animated mesh's rest state and where its triangles sit in the geometry.
struct PosedMesh {
    /// Moved as a whole by one affine map: procedural rotations and oscillations, and no
    /// other animation of the same mesh (two animations pose it in turn).
    rigid: bool,
    triangles: Range<usize>,
    indices: Vec<[u32; 3]>,
    rest: Vec<Vec3>,
    posed: Vec<Vec3>,
    animation: Animation,
}

/// Poses a scene's geometry at any time: holds the rest vertices of everything that moves.
pub struct Animator {
    meshes: Vec<PosedMesh>,
    spheres: Vec<(usize, Vec3, Vec<Motion>)>,
}

/// An animated object's primitives (scene order, as in [`Geometry`]) and whether it moves
/// rigidly: as a whole, by one affine map of its rest pose ([`Animator::rigid_transform`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MovingObject {
    pub prims: Vec<u32>,
    pub rigid: bool,
}

impl Animator {
    /// The animations of `scene`, whose geometry was flattened by [`Geometry::new`] (meshes'
    /// triangles in scene order).
    pub fn new(scene: &Scene) -> Self {
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
                    meshes.push(PosedMesh {
                        rigid,
                        triangles: first_triangle[m]..first_triangle[m] + mesh.triangles.len(),
                        indices: mesh.triangles.clone(),
                        rest: mesh.positions.clone(),
                        posed: mesh.positions.clone(),
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
        Self { meshes, spheres }
    }

    /// Whether anything moves at all.
    pub fn is_animated(&self) -> bool {
        !self.meshes.is_empty() || !self.spheres.is_empty()
    }

    /// Triangles that move (for statistics).
    pub fn moving_triangles(&self) -> usize {
        self.meshes.iter().map(|m| m.triangles.len()).sum()
    }

    /// The animated objects: the meshes, then the spheres (`triangle_count`: where the spheres'
    /// primitive indices start). Object `k` of this list is the `k` of
    /// [`Animator::rigid_transform`].
    pub fn objects(&self, triangle_count: usize) -> Vec<MovingObject> {
        let meshes = self.meshes.iter().map(|m| MovingObject {
            prims: (m.triangles.start as u32..m.triangles.end as u32).collect(),
            rigid: m.rigid,
        });
        let spheres =
            self.spheres.iter().map(|(s, ..)| MovingObject { prims: vec![(triangle_count + s) as u32], rigid: true });
        meshes.chain(spheres).collect()
    }

    /// Where rigid object `k` of [`Animator::objects`] is at time `t`: the map from its rest
    /// pose. `None` for a deforming object.
    pub fn rigid_transform(&self, k: usize, t: f32) -> Option<Affine3A> {
        match self.meshes.get(k) {
            Some(mesh) => mesh.rigid_transform(t),
            None => {
                // A sphere moves with its centre (its turning does not show).
                let (_, centre, motions) = &self.spheres[k - self.meshes.len()];
                Some(Affine3A::from_translation(Motion::apply_all(motions, *centre, t) - *centre))
            }
        }
    }

    /// Moves the vertices of the deforming meshes alone to time `t` (the rigid objects are
    /// placed by [`Animator::rigid_transform`]). Boxes are not recomputed.
    pub fn pose_deforming(&mut self, geometry: &mut Geometry, t: f32) {
        for mesh in &mut self.meshes {
            if !mesh.rigid {
                mesh.pose(geometry, t);
            }
        }
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
    }
}

impl PosedMesh {
    /// Moves its triangles in `geometry` to time `t`.
    fn pose(&mut self, geometry: &mut Geometry, t: f32) {
        match &self.animation {
            Animation::Procedural(motions) => {
                self.posed.par_iter_mut().zip(&self.rest).for_each(|(p, &r)| *p = Motion::apply_all(motions, r, t));
            }
            Animation::Nodes(nodes) => nodes.pose(&mut self.posed, t),
        }
        let posed = &self.posed;
        geometry.triangles[self.triangles.clone()]
            .par_iter_mut()
            .zip(&self.indices)
            .for_each(|(tri, idx)| *tri = idx.map(|k| posed[k as usize]));
    }

    /// The map from its rest pose at time `t`, if it moves rigidly. (glTF node animations
    /// count as deformations: their parts move differently.)
    fn rigid_transform(&self, t: f32) -> Option<Affine3A> {
        match &self.animation {
            Animation::Procedural(motions) if self.rigid => Motion::affine_all(motions, t),
            _ => None,
        }
    }
}
