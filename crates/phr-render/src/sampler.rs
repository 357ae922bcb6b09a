//! Random numbers for the integrator: PCG32 (O'Neill 2014), seeded per pixel and per frame by
//! hashing, so every pixel's sample sequence is the same whatever the thread count or tile
//! order, and frame k of a progressive render is independent of frames 0..k.

use glam::Vec3;
use std::f32::consts::TAU;

/// PCG32 (XSH RR), the generator pbrt-v4 uses too.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

const MULTIPLIER: u64 = 6364136223846793005;

/// A 64-bit mixing function (SplitMix64's finaliser), used to derive stream seeds.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

impl Pcg32 {
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Self { state: 0, inc: (stream << 1) | 1 };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// Where in pixel `pixel` frame `frame` puts its camera ray, in [0, 1)²: point `frame` of
    /// the R2 sequence (Roberts 2018, the 2D golden-ratio sequence), shifted by a random
    /// offset of the pixel's own (Cranley–Patterson rotation), wrapped. Every frame's point
    /// is uniform in the pixel (the offset is), so the estimate stays unbiased; a pixel's
    /// successive frames cover it evenly, so an edge across it (a lamp's against a ceiling)
    /// converges much faster than with independent points.
    pub fn pixel_jitter(seed: u64, frame: u32, pixel: u32) -> (f32, f32) {
        jitter_at(frame, jitter_rotation(seed, pixel))
    }

    /// The generator of one pixel in one frame of a render with a user seed.
    pub fn for_pixel(seed: u64, frame: u32, pixel: u32) -> Self {
        let key = mix64(seed ^ mix64(((frame as u64) << 32) | pixel as u64));
        Self::new(key, mix64(key ^ 0x5851_f42d_4c95_7f2d))
    }

    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULTIPLIER).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }

    /// A uniformly distributed unit vector.
    #[inline]
    pub fn unit_vector(&mut self) -> Vec3 {
        let z = 1.0 - 2.0 * self.next_f32();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = TAU * self.next_f32();
        let (s, c) = phi.sin_cos();
        Vec3::new(r * c, r * s, z)
    }

    /// A point uniformly distributed in the unit ball.
    #[inline]
    pub fn in_unit_sphere(&mut self) -> Vec3 {
        self.unit_vector() * self.next_f32().cbrt()
    }
}

/// The random offset of pixel `pixel` that [`Pcg32::pixel_jitter`] shifts the R2 sequence by:
/// the same in every frame.
fn jitter_rotation(seed: u64, pixel: u32) -> [f32; 2] {
    let mut rotation = Pcg32::for_pixel(seed ^ 0x2545_f491_4f6c_dd1d, u32::MAX, pixel);
    [rotation.next_f32(), rotation.next_f32()]
}

/// Point `frame` of the R2 sequence shifted by `rotation`, wrapped into [0, 1)².
#[inline]
fn jitter_at(frame: u32, [ox, oy]: [f32; 2]) -> (f32, f32) {
    const A1: f64 = 0.754_877_666_246_692_8; // 1/φ₂, φ₂ the plastic number
    const A2: f64 = 0.569_840_290_998_053_3; // 1/φ₂²
    let n = f64::from(frame);
    (wrap_unit(0.5 + n * A1 + f64::from(ox)), wrap_unit(0.5 + n * A2 + f64::from(oy)))
}

/// Every pixel's jitter offset for one seed, made once for all the frames of a render: the
/// offset is a hash and a PCG32 stream's first two numbers per pixel, which cost about as
/// much as the camera ray itself (a tenth of the bunny's frame). [`JitterTable::jitter`]
/// equals [`Pcg32::pixel_jitter`] bit for bit.
#[derive(Debug)]
pub struct JitterTable {
    seed: u64,
    rotations: Vec<[f32; 2]>,
}

impl JitterTable {
    /// The offsets of pixels `0..pixels` under `seed`. On one thread: a renderer makes its
    /// table lazily, from inside its parallel tile loop, and a lazy initialiser that used
    /// rayon there could steal another tile that waits for the same table (rayon's
    /// documented deadlock). About 6 ms at 512², once per render.
    pub fn new(seed: u64, pixels: usize) -> Self {
        let pixels = u32::try_from(pixels).expect("pixel numbers are u32");
        Self { seed, rotations: (0..pixels).map(|p| jitter_rotation(seed, p)).collect() }
    }

    /// Whether it holds the offsets of `pixels` pixels under `seed`.
    pub fn fits(&self, seed: u64, pixels: usize) -> bool {
        self.seed == seed && self.rotations.len() == pixels
    }

    /// [`Pcg32::pixel_jitter`] of `pixel` (below the table's pixel count) in frame `frame`.
    #[inline]
    pub fn jitter(&self, frame: u32, pixel: u32) -> (f32, f32) {
        jitter_at(frame, self.rotations[pixel as usize])
    }
}

/// The fraction of `x` (non-negative, below 2^53) as an `f32` in `[0, 1)`: `fract`'s value,
/// but by a conversion instruction where `fract` calls the library's `trunc` (the x86-64
/// baseline has no rounding instruction; it was 1 % of a small scene's frame).
#[inline]
fn wrap_unit(x: f64) -> f32 {
    let x = (x - (x as u64) as f64) as f32;
    // Rounding to f32 may give 1.0.
    if x >= 1.0 {
        0.0
    } else {
        x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_jitter_table_gives_pixel_jitter() {
        let table = JitterTable::new(7, 5000);
        assert!(table.fits(7, 5000) && !table.fits(8, 5000) && !table.fits(7, 5001));
        for frame in [0, 1, 2, 1000, u32::MAX] {
            for pixel in (0..5000).step_by(7) {
                let (a, b) = (table.jitter(frame, pixel), Pcg32::pixel_jitter(7, frame, pixel));
                assert_eq!((a.0.to_bits(), a.1.to_bits()), (b.0.to_bits(), b.1.to_bits()));
            }
        }
    }

    /// The jitter's wrap is `fract`'s, bit for bit, over the range of its arguments (frames up
    /// to `u32::MAX` times a constant below 1, plus at most 1.5).
    #[test]
    fn the_jitter_wraps_as_fract() {
        let mut rng = Pcg32::new(3, 4);
        let samples = (0..100_000)
            .map(|_| f64::from(rng.next_u32()) * f64::from(rng.next_f32()) + 1.5 * f64::from(rng.next_f32()));
        for x in samples.chain([0.0, 0.5, 1.0, 0.999_999_999_9, 4_294_967_296.5]) {
            let expected = x.fract() as f32;
            let expected = if expected >= 1.0 { 0.0 } else { expected };
            assert_eq!(wrap_unit(x).to_bits(), expected.to_bits(), "{x}");
            assert!((0.0..1.0).contains(&wrap_unit(x)));
        }
    }

    #[test]
    fn uniform_and_unit() {
        let mut rng = Pcg32::for_pixel(1, 2, 3);
        let n = 100_000;
        let mut mean = 0.0f64;
        let mut vsum = Vec3::ZERO;
        for _ in 0..n {
            let x = rng.next_f32();
            assert!((0.0..1.0).contains(&x));
            mean += x as f64;
            let v = rng.unit_vector();
            assert!((v.length() - 1.0).abs() < 1e-5);
            vsum += v;
        }
        assert!((mean / n as f64 - 0.5).abs() < 0.01);
        assert!((vsum / n as f32).length() < 0.02);
    }

    #[test]
    fn streams_differ() {
        let a: Vec<u32> = (0..4).map(|_| Pcg32::for_pixel(0, 0, 0).next_u32()).collect();
        let mut b = Pcg32::for_pixel(0, 0, 1);
        let mut c = Pcg32::for_pixel(0, 1, 0);
        assert_ne!(a[0], b.next_u32());
        assert_ne!(a[0], c.next_u32());
        assert_eq!(a[0], a[1], "same inputs give the same sequence");
    }
}
