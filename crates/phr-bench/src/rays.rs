//! The ray sets every ray benchmark traces, made one way: primary rays of a view, one diffuse
//! bounce from each primary hit, incoherent rays through the scene box, and shadow rays.

use glam::Vec3;
use phr_bvh::{Aabb, Ray};
use phr_render::camera::Camera;
use phr_render::geometry::Geometry;
use phr_render::sampler::Pcg32;
use rayon::prelude::*;

/// Primary rays and one diffuse bounce from each primary hit.
pub struct RaySet {
    /// One ray through the centre of each pixel of a `res`² image, row-major.
    pub primary: Vec<Ray>,
    /// From each primary hit (in pixel order), a cosine-distributed direction about the
    /// normal facing the ray.
    pub diffuse: Vec<Ray>,
}

impl RaySet {
    /// The rays of `camera` at `res`² over `geometry` (its tree built).
    pub fn new(geometry: &Geometry, camera: &Camera, res: u32) -> Self {
        let primary: Vec<Ray> =
            (0..res * res).map(|i| camera.ray((i % res) as f32 + 0.5, (i / res) as f32 + 0.5)).collect();
        let diffuse = primary
            .par_iter()
            .enumerate()
            .filter_map(|(i, ray)| {
                let hit = geometry.intersect(ray)?;
                let s = geometry.surface_point(ray, &hit);
                let facing = if s.front { s.normal } else { -s.normal };
                let dir = (facing + Pcg32::for_pixel(1, 0, i as u32).unit_vector()).normalize_or(facing);
                Some(Ray::new(s.spawn_origin(dir), dir))
            })
            .collect();
        Self { primary, diffuse }
    }
}

/// Incoherent rays: uniform origins in `bounds`, uniform directions.
pub fn incoherent_rays(bounds: Aabb, count: usize) -> Vec<Ray> {
    (0..count)
        .into_par_iter()
        .map(|i| {
            let mut rng = Pcg32::new(0x5eed, i as u64);
            let u = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32());
            Ray::new(bounds.min + u * bounds.extent(), rng.unit_vector())
        })
        .collect()
}

/// Shadow rays: from each of `from`'s origins to a uniform point of `bounds`, over the interval
/// (0, 1 − 10⁻⁴) of the unnormalised direction (the renderer's light-sample rays).
pub fn shadow_rays(from: &[Ray], bounds: Aabb) -> Vec<Ray> {
    from.par_iter()
        .enumerate()
        .map(|(i, r)| {
            let mut rng = Pcg32::new(0x5ad0, i as u64);
            let target = bounds.min + Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * bounds.extent();
            Ray::with_interval(r.origin, target - r.origin, 0.0, 1.0 - 1e-4)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn incoherent_rays_start_in_the_box_and_shadow_rays_end_in_it() {
        let b = Aabb { min: Vec3::new(-1.0, 0.0, 2.0), max: Vec3::new(3.0, 1.0, 5.0) };
        let rays = incoherent_rays(b, 500);
        let inside = |p: Vec3| p.cmpge(b.min - 1e-5).all() && p.cmple(b.max + 1e-5).all();
        assert!(rays.iter().all(|r| inside(r.origin) && (r.dir.length() - 1.0).abs() < 1e-4));
        let shadow = shadow_rays(&rays, b);
        for (s, r) in shadow.iter().zip(&rays) {
            assert_eq!(s.origin, r.origin);
            let end = s.origin + s.dir;
            assert!(inside(end) && s.tmin == 0.0 && s.tmax == 1.0 - 1e-4);
        }
    }
}
