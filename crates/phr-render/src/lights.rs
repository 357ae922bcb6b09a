//! Explicit light sampling (next-event estimation), beyond the thesis's implicit lights.
//!
//! The emissive triangles of a scene form a [`LightSet`]; at every diffuse (Lambertian) hit the
//! path tracer picks one of them with probability proportional to its power (area × brightest
//! emission channel), picks a point on it uniformly and, if a shadow ray finds nothing in
//! between, adds its direct light. Paths that then hit one of these triangles after a diffuse
//! bounce do not count its emission again, so the estimator stays unbiased. Emissive spheres
//! and the sky stay implicit. Small lights (the Cornell box's) converge many times faster.

use crate::geometry::Geometry;
use crate::material::Material;
use crate::sampler::Pcg32;
use glam::Vec3;
use phr_bvh::triangle::triangle_normal;

/// The emissive triangles of a scene and a power-proportional distribution over them.
#[derive(Clone, Debug, Default)]
pub struct LightSet {
    /// Primitive indices of the emissive triangles.
    triangles: Vec<u32>,
    /// Cumulative selection weights (the last is the total).
    cdf: Vec<f32>,
    /// Whether primitive `p` is one of them (for the no-double-counting rule).
    is_light: Vec<bool>,
}

/// A point sampled on a light.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    pub point: Vec3,
    /// Unit normal (the emitting side for one-sided lights is the one it points to).
    pub normal: Vec3,
    pub material: u32,
    /// Probability density of the sample with respect to area.
    pub pdf_area: f32,
}

impl LightSet {
    pub fn new(geometry: &Geometry, materials: &[Material]) -> Self {
        let mut set = Self { is_light: vec![false; geometry.triangles.len()], ..Self::default() };
        for (i, &m) in geometry.triangle_material.iter().enumerate() {
            if matches!(materials[m as usize], Material::Emissive { emit, .. } if emit.max_element() > 0.0) {
                set.triangles.push(i as u32);
                set.is_light[i] = true;
            }
        }
        set.refresh(geometry, materials);
        set
    }

    /// Recomputes the selection weights after the triangles moved (animated lights change
    /// area when they deform or scale).
    pub fn refresh(&mut self, geometry: &Geometry, materials: &[Material]) {
        self.cdf.clear();
        let mut total = 0.0f32;
        for &i in &self.triangles {
            let [a, b, c] = geometry.world_triangle(i as usize);
            let emit = match materials[geometry.triangle_material[i as usize] as usize] {
                Material::Emissive { emit, .. } => emit.max_element(),
                _ => 0.0,
            };
            let power = 0.5 * triangle_normal(a, b, c).length() * emit;
            // Degenerate lights get no weight (and so are never picked).
            total += if power.is_finite() { power.max(0.0) } else { 0.0 };
            self.cdf.push(total);
        }
        if total <= 0.0 {
            self.cdf.clear();
        }
    }

    /// No light can be sampled.
    pub fn is_empty(&self) -> bool {
        self.cdf.is_empty()
    }

    pub fn len(&self) -> usize {
        self.triangles.len()
    }

    /// Whether primitive `prim` is a sampled light.
    #[inline]
    pub fn contains(&self, prim: u32) -> bool {
        self.is_light.get(prim as usize).copied().unwrap_or(false)
    }

    /// Picks a light by power and a uniform point on it.
    pub fn sample(&self, geometry: &Geometry, rng: &mut Pcg32) -> Option<LightSample> {
        let total = *self.cdf.last()?;
        let x = rng.next_f32() * total;
        let k = self.cdf.partition_point(|&c| c <= x).min(self.cdf.len() - 1);
        if self.cdf[k] <= if k > 0 { self.cdf[k - 1] } else { 0.0 } {
            return None;
        }
        let weight = self.cdf[k] - if k > 0 { self.cdf[k - 1] } else { 0.0 };
        let prim = self.triangles[k] as usize;
        let [a, b, c] = geometry.world_triangle(prim);
        let cross = triangle_normal(a, b, c);
        let area = 0.5 * cross.length();
        // Uniform on the triangle: the square-root warp of two uniforms.
        let (u1, u2) = (rng.next_f32(), rng.next_f32());
        let s = u1.sqrt();
        let point = a * (1.0 - s) + b * (s * (1.0 - u2)) + c * (s * u2);
        Some(LightSample {
            point,
            normal: cross / (2.0 * area),
            material: geometry.triangle_material[prim],
            pdf_area: weight / total / area,
        })
    }
}
