//! `f32` lanes for the à-trous tap loop ([`super::atrous`]): one type per instruction set
//! (plain `f32`, AVX2's 8 lanes, AVX-512's 16), so that one generic loop keeps a chunk of
//! centre pixels and their sums in registers across all 25 taps.
//!
//! Every operation is the same IEEE operation in every type (nothing fused; `max`/`min` as
//! `maxps`/`minps`: the second operand when either is NaN), so the three give the same bits.

/// Lanes of `f32`, and masks over them.
///
/// # Safety
/// The methods of [`Avx2`] and [`Avx512`] execute AVX2 and AVX-512 F instructions: call them
/// only where the CPU has those (inside functions compiled with the features, checked at run
/// time), where they are inlined.
pub(crate) trait Lanes: Copy {
    /// Lanes per value.
    const N: usize;
    type Mask: Copy;
    /// Loads `N` floats from `p`.
    unsafe fn load(p: *const f32) -> Self;
    /// Stores the lanes at `p` (`N` floats).
    unsafe fn store(self, p: *mut f32);
    unsafe fn splat(x: f32) -> Self;
    unsafe fn add(self, o: Self) -> Self;
    unsafe fn sub(self, o: Self) -> Self;
    unsafe fn mul(self, o: Self) -> Self;
    unsafe fn div(self, o: Self) -> Self;
    unsafe fn sqrt(self) -> Self;
    /// `self > o ? self : o` per lane.
    unsafe fn max(self, o: Self) -> Self;
    /// `self < o ? self : o` per lane.
    unsafe fn min(self, o: Self) -> Self;
    unsafe fn abs(self) -> Self;
    /// `self < o` (false for NaN).
    unsafe fn lt(self, o: Self) -> Self::Mask;
    /// `self > o` (false for NaN).
    unsafe fn gt(self, o: Self) -> Self::Mask;
    unsafe fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// Whether `m` holds in any lane.
    unsafe fn any(m: Self::Mask) -> bool;
    /// The lanes of `self` where `m` holds, 0 elsewhere.
    unsafe fn keep(self, m: Self::Mask) -> Self;
    /// The lanes of `self` where `m` holds, those of `other` elsewhere.
    unsafe fn or_else(self, m: Self::Mask, other: Self) -> Self;
    /// `2^k · self` for the integers `k` held in the low mantissa bits of `rounded`, which is
    /// `y + ROUND` ([`exp_neg`]).
    unsafe fn scale_by_exponent(self, rounded: Self) -> Self;
}

/// Adding and taking away 1.5·2^23 rounds to the nearest integer (no `floor`, which is a
/// library call below SSE4.1), and leaves that integer in the sum's low mantissa bits.
const ROUND: f32 = 12_582_912.0;

/// `e^-x` for `x` in `[0, 20]` within 10⁻⁵ relative: `2^y` with `y = −x·log2(e)`, from the
/// exponent bits of `y`'s nearest integer and a degree-5 Taylor polynomial for the rest (in
/// [−½, ½)). Plain arithmetic, so it runs on whole lanes (the library `exp` is a call per
/// lane).
#[inline(always)]
pub(crate) unsafe fn exp_neg<V: Lanes>(x: V) -> V {
    // SAFETY: the caller's (see `Lanes`).
    unsafe {
        let y = x.mul(V::splat(-std::f32::consts::LOG2_E)).max(V::splat(-126.0));
        let rounded = y.add(V::splat(ROUND));
        let whole = rounded.sub(V::splat(ROUND));
        let f = y.sub(whole).mul(V::splat(std::f32::consts::LN_2));
        let c = |k: f32| V::splat(k);
        let p = c(1.0 / 120.0).mul(f).add(c(1.0 / 24.0)).mul(f).add(c(1.0 / 6.0)).mul(f).add(c(0.5));
        let p = p.mul(f).add(c(1.0)).mul(f).add(c(1.0));
        p.scale_by_exponent(rounded)
    }
}

/// One `f32` at a time: the portable loop, and the reference the others are tested against.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Scalar(f32);

impl Lanes for Scalar {
    const N: usize = 1;
    type Mask = bool;
    #[inline(always)]
    unsafe fn load(p: *const f32) -> Self {
        // SAFETY: the caller's.
        Self(unsafe { *p })
    }
    #[inline(always)]
    unsafe fn store(self, p: *mut f32) {
        // SAFETY: the caller's.
        unsafe { *p = self.0 }
    }
    #[inline(always)]
    unsafe fn splat(x: f32) -> Self {
        Self(x)
    }
    #[inline(always)]
    unsafe fn add(self, o: Self) -> Self {
        Self(self.0 + o.0)
    }
    #[inline(always)]
    unsafe fn sub(self, o: Self) -> Self {
        Self(self.0 - o.0)
    }
    #[inline(always)]
    unsafe fn mul(self, o: Self) -> Self {
        Self(self.0 * o.0)
    }
    #[inline(always)]
    unsafe fn div(self, o: Self) -> Self {
        Self(self.0 / o.0)
    }
    #[inline(always)]
    unsafe fn sqrt(self) -> Self {
        Self(self.0.sqrt())
    }
    #[inline(always)]
    unsafe fn max(self, o: Self) -> Self {
        if self.0 > o.0 {
            self
        } else {
            o
        }
    }
    #[inline(always)]
    unsafe fn min(self, o: Self) -> Self {
        if self.0 < o.0 {
            self
        } else {
            o
        }
    }
    #[inline(always)]
    unsafe fn abs(self) -> Self {
        Self(f32::from_bits(self.0.to_bits() & 0x7fff_ffff))
    }
    #[inline(always)]
    unsafe fn lt(self, o: Self) -> bool {
        self.0 < o.0
    }
    #[inline(always)]
    unsafe fn gt(self, o: Self) -> bool {
        self.0 > o.0
    }
    #[inline(always)]
    unsafe fn and(a: bool, b: bool) -> bool {
        a & b
    }
    #[inline(always)]
    unsafe fn any(m: bool) -> bool {
        m
    }
    #[inline(always)]
    unsafe fn keep(self, m: bool) -> Self {
        if m {
            self
        } else {
            Self(0.0)
        }
    }
    #[inline(always)]
    unsafe fn or_else(self, m: bool, other: Self) -> Self {
        if m {
            self
        } else {
            other
        }
    }
    #[inline(always)]
    unsafe fn scale_by_exponent(self, rounded: Self) -> Self {
        let k = rounded.0.to_bits().wrapping_sub(ROUND.to_bits());
        Self(f32::from_bits(k.wrapping_add(127) << 23) * self.0)
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use x86::{Avx2, Avx512};

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::{Lanes, ROUND};
    use std::arch::x86_64::*;

    /// 8 lanes (AVX2).
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Avx2(__m256);

    /// 16 lanes (AVX-512 F).
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Avx512(__m512);

    // SAFETY (all methods below): the caller's, see `Lanes`.
    impl Lanes for Avx2 {
        const N: usize = 8;
        type Mask = __m256;
        #[inline(always)]
        unsafe fn load(p: *const f32) -> Self {
            Self(unsafe { _mm256_loadu_ps(p) })
        }
        #[inline(always)]
        unsafe fn store(self, p: *mut f32) {
            unsafe { _mm256_storeu_ps(p, self.0) }
        }
        #[inline(always)]
        unsafe fn splat(x: f32) -> Self {
            Self(unsafe { _mm256_set1_ps(x) })
        }
        #[inline(always)]
        unsafe fn add(self, o: Self) -> Self {
            Self(unsafe { _mm256_add_ps(self.0, o.0) })
        }
        #[inline(always)]
        unsafe fn sub(self, o: Self) -> Self {
            Self(unsafe { _mm256_sub_ps(self.0, o.0) })
        }
        #[inline(always)]
        unsafe fn mul(self, o: Self) -> Self {
            Self(unsafe { _mm256_mul_ps(self.0, o.0) })
        }
        #[inline(always)]
        unsafe fn div(self, o: Self) -> Self {
            Self(unsafe { _mm256_div_ps(self.0, o.0) })
        }
        #[inline(always)]
        unsafe fn sqrt(self) -> Self {
            Self(unsafe { _mm256_sqrt_ps(self.0) })
        }
        #[inline(always)]
        unsafe fn max(self, o: Self) -> Self {
            Self(unsafe { _mm256_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        unsafe fn min(self, o: Self) -> Self {
            Self(unsafe { _mm256_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        unsafe fn abs(self) -> Self {
            Self(unsafe { _mm256_and_ps(self.0, _mm256_castsi256_ps(_mm256_set1_epi32(0x7fff_ffff))) })
        }
        #[inline(always)]
        unsafe fn lt(self, o: Self) -> __m256 {
            unsafe { _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        unsafe fn gt(self, o: Self) -> __m256 {
            unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        unsafe fn and(a: __m256, b: __m256) -> __m256 {
            unsafe { _mm256_and_ps(a, b) }
        }
        #[inline(always)]
        unsafe fn any(m: __m256) -> bool {
            unsafe { _mm256_movemask_ps(m) != 0 }
        }
        #[inline(always)]
        unsafe fn keep(self, m: __m256) -> Self {
            Self(unsafe { _mm256_and_ps(self.0, m) })
        }
        #[inline(always)]
        unsafe fn or_else(self, m: __m256, other: Self) -> Self {
            Self(unsafe { _mm256_blendv_ps(other.0, self.0, m) })
        }
        #[inline(always)]
        unsafe fn scale_by_exponent(self, rounded: Self) -> Self {
            unsafe {
                let k = _mm256_sub_epi32(_mm256_castps_si256(rounded.0), _mm256_set1_epi32(ROUND.to_bits() as i32));
                let two_k = _mm256_slli_epi32::<23>(_mm256_add_epi32(k, _mm256_set1_epi32(127)));
                Self(_mm256_mul_ps(_mm256_castsi256_ps(two_k), self.0))
            }
        }
    }

    impl Lanes for Avx512 {
        const N: usize = 16;
        type Mask = __mmask16;
        #[inline(always)]
        unsafe fn load(p: *const f32) -> Self {
            Self(unsafe { _mm512_loadu_ps(p) })
        }
        #[inline(always)]
        unsafe fn store(self, p: *mut f32) {
            unsafe { _mm512_storeu_ps(p, self.0) }
        }
        #[inline(always)]
        unsafe fn splat(x: f32) -> Self {
            Self(unsafe { _mm512_set1_ps(x) })
        }
        #[inline(always)]
        unsafe fn add(self, o: Self) -> Self {
            Self(unsafe { _mm512_add_ps(self.0, o.0) })
        }
        #[inline(always)]
        unsafe fn sub(self, o: Self) -> Self {
            Self(unsafe { _mm512_sub_ps(self.0, o.0) })
        }
        #[inline(always)]
        unsafe fn mul(self, o: Self) -> Self {
            Self(unsafe { _mm512_mul_ps(self.0, o.0) })
        }
        #[inline(always)]
        unsafe fn div(self, o: Self) -> Self {
            Self(unsafe { _mm512_div_ps(self.0, o.0) })
        }
        #[inline(always)]
        unsafe fn sqrt(self) -> Self {
            Self(unsafe { _mm512_sqrt_ps(self.0) })
        }
        #[inline(always)]
        unsafe fn max(self, o: Self) -> Self {
            Self(unsafe { _mm512_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        unsafe fn min(self, o: Self) -> Self {
            Self(unsafe { _mm512_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        unsafe fn abs(self) -> Self {
            unsafe {
                Self(_mm512_castsi512_ps(_mm512_and_si512(_mm512_castps_si512(self.0), _mm512_set1_epi32(0x7fff_ffff))))
            }
        }
        #[inline(always)]
        unsafe fn lt(self, o: Self) -> __mmask16 {
            unsafe { _mm512_cmp_ps_mask::<_CMP_LT_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        unsafe fn gt(self, o: Self) -> __mmask16 {
            unsafe { _mm512_cmp_ps_mask::<_CMP_GT_OQ>(self.0, o.0) }
        }
        #[inline(always)]
        unsafe fn and(a: __mmask16, b: __mmask16) -> __mmask16 {
            a & b
        }
        #[inline(always)]
        unsafe fn any(m: __mmask16) -> bool {
            m != 0
        }
        #[inline(always)]
        unsafe fn keep(self, m: __mmask16) -> Self {
            Self(unsafe { _mm512_maskz_mov_ps(m, self.0) })
        }
        #[inline(always)]
        unsafe fn or_else(self, m: __mmask16, other: Self) -> Self {
            Self(unsafe { _mm512_mask_blend_ps(m, other.0, self.0) })
        }
        #[inline(always)]
        unsafe fn scale_by_exponent(self, rounded: Self) -> Self {
            unsafe {
                let k = _mm512_sub_epi32(_mm512_castps_si512(rounded.0), _mm512_set1_epi32(ROUND.to_bits() as i32));
                let two_k = _mm512_slli_epi32::<23>(_mm512_add_epi32(k, _mm512_set1_epi32(127)));
                Self(_mm512_mul_ps(_mm512_castsi512_ps(two_k), self.0))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scalar_exp(x: f32) -> f32 {
        // SAFETY: `Scalar` needs no CPU feature.
        unsafe { exp_neg(Scalar(x)).0 }
    }

    #[test]
    fn exp_neg_is_exp() {
        for i in 0..=20_000 {
            let x = i as f32 * 1e-3;
            let (ours, exact) = (scalar_exp(x), (-x).exp());
            assert!((ours - exact).abs() <= 1e-5 * exact, "e^-{x}: {ours} vs {exact}");
        }
    }

    /// The wide types' `exp_neg` gives the scalar one's bits, lane by lane.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn wide_exp_neg_is_the_scalar_one() {
        #[target_feature(enable = "avx2")]
        fn avx2(x: &[f32; 8]) -> [f32; 8] {
            let mut out = [0.0; 8];
            // SAFETY: compiled for AVX2; 8 floats each way.
            unsafe { exp_neg(Avx2::load(x.as_ptr())).store(out.as_mut_ptr()) };
            out
        }
        #[target_feature(enable = "avx512f")]
        fn avx512(x: &[f32; 16]) -> [f32; 16] {
            let mut out = [0.0; 16];
            // SAFETY: compiled for AVX-512 F; 16 floats each way.
            unsafe { exp_neg(Avx512::load(x.as_ptr())).store(out.as_mut_ptr()) };
            out
        }
        let xs: Vec<f32> = (0..=20_000 - 16).map(|i| i as f32 * 1e-3 + 1e-7 * (i % 7) as f32).collect();
        let mut compared = 0;
        for x in xs.chunks_exact(16) {
            let scalar: Vec<u32> = x.iter().map(|&x| scalar_exp(x).to_bits()).collect();
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2.
                let wide = unsafe { avx2(x[..8].try_into().unwrap()) };
                assert_eq!(wide.map(f32::to_bits)[..], scalar[..8], "AVX2 at {}", x[0]);
                compared += 1;
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512 F.
                let wide = unsafe { avx512(x.try_into().unwrap()) };
                assert_eq!(wide.map(f32::to_bits)[..], scalar[..], "AVX-512 at {}", x[0]);
                compared += 1;
            }
        }
        assert!(compared > 0 || !std::arch::is_x86_feature_detected!("avx2"));
    }
}
