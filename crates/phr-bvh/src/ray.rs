//! Rays with a precomputed inverse direction (for the slab test) and a `[tmin, tmax]` interval.

use glam::Vec3;

#[derive(Clone, Copy, Debug)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
    /// `1 / dir` per component (±inf for a zero component), computed once per ray.
    pub inv_dir: Vec3,
    pub tmin: f32,
    /// The far end of the interval; closest-hit traversal shrinks it as hits are found.
    pub tmax: f32,
}

impl Ray {
    /// (Inlined across crates: the renderer makes one per path segment.)
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self::with_interval(origin, dir, 0.0, f32::INFINITY)
    }

    #[inline]
    pub fn with_interval(origin: Vec3, dir: Vec3, tmin: f32, tmax: f32) -> Self {
        Self { origin, dir, inv_dir: safe_recip(dir), tmin, tmax }
    }

    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.dir
    }
}

/// `1 / d` per component, with zero components replaced by a tiny number of the same sign
/// first: the slab test then never computes `0 * inf = NaN` for a ray that lies in a slab's
/// plane, and such a ray counts as inside that slab.
#[inline]
pub fn safe_recip(d: Vec3) -> Vec3 {
    const TINY: f32 = 1.0e-30;
    // In `Vec3A` (SIMD lanes where the target has them): one division instruction instead
    // of three, the same quotients.
    let d = glam::Vec3A::from(d);
    let tiny = glam::Vec3A::splat(TINY).copysign(d);
    Vec3::from(glam::Vec3A::select(d.abs().cmplt(glam::Vec3A::splat(TINY)), tiny, d).recip())
}
