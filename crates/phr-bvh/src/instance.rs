//! Two-level BVHs: instances of bottom-level trees under a small top-level tree.
//!
//! A scene whose objects move rigidly need not rebuild anything but the top: each object keeps
//! its own bottom-level tree, built once in its object space, and an [`Instance`] places it in
//! the world with an affine transform. Each frame only the transforms change and the
//! [`TopLevel`] tree over the instances' world boxes is rebuilt (microseconds for a handful of
//! instances). This is the scheme of Embree's, OptiX's and OSPRay's scene graphs.
//!
//! A ray enters an instance by moving into its object space: origin by the inverse transform,
//! direction by its linear part, **not renormalised**, so a distance `t` along the object ray
//! is the same `t` along the world ray and the interval `[tmin, tmax]` carries over unchanged.
//! The top level is a [`WideBvh`] of width 8 (built by the binned SAH builder and collapsed
//! like any other tree), so it is traversed by the same SIMD kernels as the bottom level.
//!
//! What an instance holds is the caller's business: [`TopLevel::closest_hit`] and
//! [`TopLevel::any_hit`] call back with the instance's index and the ray in its object space.

use crate::aabb::Aabb;
use crate::binned_sah::{build_binned_sah, BinnedSahOptions};
use crate::ray::Ray;
use crate::sah::LeafPolicy;
use crate::wide::{CollapseOptions, LeafVisitor, WideBvh, PAD};
use glam::{Affine3A, Vec3, Vec3A};

/// An affine placement of an object in the world, with its inverse.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Instance {
    /// Object space to world space.
    pub to_world: Affine3A,
    /// World space to object space.
    pub to_object: Affine3A,
    /// `to_world` is the identity: rays pass unchanged.
    identity: bool,
    /// `to_world` mirrors (negative determinant): a triangle's `e1 × e2` turns around.
    mirrors: bool,
}

impl Default for Instance {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Instance {
    pub const IDENTITY: Instance =
        Instance { to_world: Affine3A::IDENTITY, to_object: Affine3A::IDENTITY, identity: true, mirrors: false };

    /// The instance placed by `to_world`; `None` if it cannot be inverted (a zero scale, a
    /// non-finite entry), since rays could not be taken into its object space.
    pub fn new(to_world: Affine3A) -> Option<Instance> {
        let det = to_world.matrix3.determinant();
        let finite = to_world.matrix3.is_finite() && to_world.translation.is_finite();
        if !finite || det == 0.0 || !det.is_finite() {
            return None;
        }
        let to_object = to_world.inverse();
        if !(to_object.matrix3.is_finite() && to_object.translation.is_finite()) {
            return None;
        }
        let identity = to_world == Affine3A::IDENTITY;
        Some(Instance { to_world, to_object, identity, mirrors: det < 0.0 })
    }

    /// Rays pass unchanged.
    #[inline]
    pub fn is_identity(&self) -> bool {
        self.identity
    }

    /// The transform has a negative determinant.
    #[inline]
    pub fn mirrors(&self) -> bool {
        self.mirrors
    }

    /// `ray` in object space, with the same interval (the direction is not renormalised).
    #[inline]
    pub fn object_ray(&self, ray: &Ray) -> Ray {
        if self.identity {
            return *ray;
        }
        let origin = self.to_object.transform_point3(ray.origin);
        let dir = self.to_object.transform_vector3(ray.dir);
        Ray::with_interval(origin, dir, ray.tmin, ray.tmax)
    }

    /// A point of object space in the world.
    #[inline]
    pub fn world_point(&self, p: Vec3) -> Vec3 {
        self.to_world.transform_point3(p)
    }

    /// A surface normal of object space in the world (by the inverse transpose; not
    /// normalised).
    #[inline]
    pub fn world_normal(&self, n: Vec3) -> Vec3 {
        self.to_object.matrix3.transpose() * n
    }

    /// The world box enclosing `object` placed by this instance (Arvo's method: the centre
    /// transformed, the half extents through the absolute linear part).
    pub fn world_box(&self, object: Aabb) -> Aabb {
        if object.is_empty() || self.identity {
            return object;
        }
        let m = self.to_world.matrix3;
        let abs = glam::Mat3A::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs());
        let centre = self.to_world.transform_point3a(Vec3A::from(object.center()));
        let half = abs * Vec3A::from(0.5 * object.extent());
        Aabb::new(Vec3::from(centre - half), Vec3::from(centre + half))
    }
}

/// The 8-wide tree over instances within `world_boxes` that [`TopLevel`] traces: one
/// instance per leaf slot (its primitive index the instance's), no padding. One instance per
/// leaf, so that a ray enters only the instances whose world box it crosses, nearest first,
/// instead of every instance of a shared leaf in index order (which on a scene of two
/// instances cost 15 to 30 % of the frame).
pub fn top_level_tree(world_boxes: &[Aabb]) -> WideBvh<8> {
    let leaf = LeafPolicy { max_leaf_size: 1, ..LeafPolicy::default() };
    let bvh = build_binned_sah(world_boxes, &BinnedSahOptions { leaf, ..BinnedSahOptions::default() });
    WideBvh::from_bvh_with(&bvh, CollapseOptions { merge_leaves: 1, leaf_align: 1 })
}

/// The top-level tree: instances by their world boxes, in an 8-wide BVH.
#[derive(Clone, Debug, Default)]
pub struct TopLevel {
    instances: Vec<Instance>,
    tree: WideBvh<8>,
}

impl TopLevel {
    /// The tree over `instances`, instance `i` within `world_boxes[i]` (for example
    /// [`Instance::world_box`] of its object's box; the union of its root's children's
    /// world boxes is tighter under a rotation).
    pub fn build(instances: Vec<Instance>, world_boxes: &[Aabb]) -> TopLevel {
        let mut top = TopLevel::default();
        top.rebuild(instances, world_boxes);
        top
    }

    /// [`TopLevel::build`] again (every frame of a moving scene).
    pub fn rebuild(&mut self, instances: Vec<Instance>, world_boxes: &[Aabb]) {
        assert_eq!(instances.len(), world_boxes.len(), "one world box per instance");
        self.tree = top_level_tree(world_boxes);
        self.instances = instances;
    }

    /// Bytes held: the instances and the tree.
    pub fn memory(&self) -> usize {
        use std::mem::size_of;
        self.instances.capacity() * size_of::<Instance>()
            + self.tree.nodes.capacity() * size_of::<crate::wide::WideNode<8>>()
            + self.tree.prim_indices.capacity() * size_of::<u32>()
    }

    pub fn instances(&self) -> &[Instance] {
        &self.instances
    }

    /// The 8-wide tree over the instances (its primitive indices are instance indices).
    pub fn tree(&self) -> &WideBvh<8> {
        &self.tree
    }

    /// Closest hit: `hit(i, object_ray)` searches instance `i` with the ray in its object space
    /// (its `tmax` the closest hit so far); on a hit it shrinks `object_ray.tmax` and returns
    /// true. Returns whether anything was hit; `ray.tmax` ends at the closest hit.
    #[inline]
    pub fn closest_hit(&self, ray: &mut Ray, hit: impl FnMut(u32, &mut Ray) -> bool) -> bool {
        let mut visitor = Instances { top: self, hit };
        self.tree.closest_hit_visit(ray, &mut visitor)
    }

    /// Any hit: stops at the first instance for which `hit(i, object_ray)` returns true.
    #[inline]
    pub fn any_hit(&self, ray: &Ray, mut hit: impl FnMut(u32, &Ray) -> bool) -> bool {
        let mut visitor = Instances { top: self, hit: |i, r: &mut Ray| hit(i, r) };
        self.tree.any_hit_visit(ray, &mut visitor)
    }
}

/// The top level's leaves: each instance entered in its object space.
struct Instances<'a, F> {
    top: &'a TopLevel,
    hit: F,
}

impl<F: FnMut(u32, &mut Ray) -> bool> LeafVisitor for Instances<'_, F> {
    #[inline(always)]
    fn visit(&mut self, first: u32, count: u32, ray: &mut Ray) -> bool {
        let mut found = false;
        for &i in &self.top.tree.prim_indices[first as usize..(first + count) as usize] {
            if i == PAD {
                continue;
            }
            let mut object_ray = self.top.instances[i as usize].object_ray(ray);
            if (self.hit)(i, &mut object_ray) {
                ray.tmax = object_ray.tmax;
                found = true;
            }
        }
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    #[test]
    fn object_rays_keep_distances() {
        let to_world = Affine3A::from_scale_rotation_translation(
            Vec3::new(2.0, -0.5, 3.0),
            Quat::from_rotation_y(0.7),
            Vec3::new(1.0, 2.0, 3.0),
        );
        let inst = Instance::new(to_world).unwrap();
        assert!(inst.mirrors());
        let ray = Ray::new(Vec3::new(-4.0, 1.0, 0.5), Vec3::new(1.0, 0.2, -0.3));
        let object = inst.object_ray(&ray);
        for t in [0.0, 0.5, 3.0] {
            let back = inst.world_point(object.at(t));
            assert!((back - ray.at(t)).length() < 1e-4, "t = {t}: {back} vs {}", ray.at(t));
        }
        assert!(Instance::new(Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0))).is_none());
        assert!(Instance::new(Affine3A::from_translation(Vec3::splat(f32::NAN))).is_none());
    }

    #[test]
    fn world_boxes_enclose_the_transformed_corners() {
        let to_world = Affine3A::from_rotation_translation(Quat::from_rotation_z(0.3), Vec3::X);
        let inst = Instance::new(to_world).unwrap();
        let b = Aabb::new(Vec3::new(-1.0, 0.0, 2.0), Vec3::new(0.5, 3.0, 2.5));
        let w = inst.world_box(b);
        for k in 0..8 {
            let c = Vec3::new(
                if k & 1 == 0 { b.min.x } else { b.max.x },
                if k & 2 == 0 { b.min.y } else { b.max.y },
                if k & 4 == 0 { b.min.z } else { b.max.z },
            );
            let p = inst.world_point(c);
            assert!(w.grown(p) == w || (w.grown(p).extent() - w.extent()).max_element() < 1e-5, "{p} outside {w:?}");
        }
    }
}
