//! Morton codes (Z-order) of quantised centroids, the sort key of the LBVH
//! (Lauterbach et al. 2009, "Fast BVH Construction on GPUs"; thesis section 4.1).
//!
//! We use 63-bit codes (21 bits per axis): with 30-bit codes, a million triangles in a
//! scene with a large empty box (Sponza, San Miguel) collide heavily and the duplicates are
//! split by count instead of space, which costs tree quality.

use crate::aabb::Aabb;
use glam::Vec3;

/// Bits per axis.
pub const BITS_PER_AXIS: u32 = 21;

/// Spreads the low 21 bits of `v` so that there are two zero bits between each pair.
#[inline]
pub fn spread_bits_3(v: u32) -> u64 {
    let mut x = (v as u64) & 0x1f_ffff;
    x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
    x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
    x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
    x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
    x = (x | (x << 2)) & 0x1249_2492_4924_9249;
    x
}

/// Interleaves three 21-bit coordinates into a 63-bit code, x in the highest position.
#[inline]
pub fn encode(x: u32, y: u32, z: u32) -> u64 {
    (spread_bits_3(x) << 2) | (spread_bits_3(y) << 1) | spread_bits_3(z)
}

/// Maps points of `bounds` to Morton codes. Flat axes (zero extent) map to 0.
#[derive(Clone, Copy, Debug)]
pub struct MortonQuantizer {
    origin: Vec3,
    scale: Vec3,
}

impl MortonQuantizer {
    pub fn new(bounds: &Aabb) -> Self {
        let cells = ((1u32 << BITS_PER_AXIS) - 1) as f32;
        let extent = bounds.extent();
        let scale = Vec3::select(extent.cmpgt(Vec3::ZERO), Vec3::splat(cells) / extent, Vec3::ZERO);
        Self { origin: bounds.min, scale }
    }

    #[inline]
    pub fn code(&self, p: Vec3) -> u64 {
        let max = ((1u32 << BITS_PER_AXIS) - 1) as f32;
        // `clamp` also maps NaN to 0 via `max(0)` ordering below; casts saturate.
        let q = ((p - self.origin) * self.scale).clamp(Vec3::ZERO, Vec3::splat(max));
        encode(q.x as u32, q.y as u32, q.z as u32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interleaving_matches_naive() {
        let naive = |x: u32, y: u32, z: u32| {
            let mut c = 0u64;
            for b in 0..21 {
                c |= (((x >> b) & 1) as u64) << (3 * b + 2);
                c |= (((y >> b) & 1) as u64) << (3 * b + 1);
                c |= (((z >> b) & 1) as u64) << (3 * b);
            }
            c
        };
        for &(x, y, z) in &[(0, 0, 0), (1, 2, 3), (0x1f_ffff, 0, 0x12345), (0x0a_aaaa, 0x15_5555, 0x1f_ffff)] {
            assert_eq!(encode(x, y, z), naive(x, y, z));
        }
        assert_eq!(encode(0x1f_ffff, 0x1f_ffff, 0x1f_ffff), (1u64 << 63) - 1);
    }

    #[test]
    fn quantizer_corners_and_flat_axes() {
        let q = MortonQuantizer::new(&Aabb::new(Vec3::ZERO, Vec3::new(1.0, 0.0, 1.0)));
        assert_eq!(q.code(Vec3::ZERO), 0);
        let top = q.code(Vec3::new(1.0, 0.0, 1.0));
        assert_eq!(top, encode(0x1f_ffff, 0, 0x1f_ffff));
    }
}
