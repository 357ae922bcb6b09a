//! The order in which the traversal visits the hit children of a node: nearest first,
//! the others pushed farthest first. With three or more hits a scalar insertion sort costs
//! data-dependent branches per child;
//! here the 8 entry distances are sorted in one AVX2 register by a bitonic sorting network
//! (Batcher 1968) of 6 compare-exchange layers, and the children are pushed with one vector
//! store per stack array. Measured in `docs/bench-frame/history.md`.
//!
//! x86_64 only: other targets use the insertion sort of the traversal loop.

use super::WideNode;

/// The lanes of a compare-exchange layer of the bitonic sorting network that keep the
/// larger key, for a descending sort of 8 lanes: layer `(k, j)` compares lane `i` with lane
/// `i ^ j`, in blocks of `k` lanes that alternate direction until the last merge (`k = 8`).
const fn keeps_max(k: usize, j: usize) -> i32 {
    let mut mask = 0;
    let mut i = 0;
    while i < 8 {
        let lower = i & j == 0;
        let descending = i & k == 0;
        if lower == descending {
            mask |= 1 << i;
        }
        i += 1;
    }
    mask
}

mod network {
    use super::keeps_max;
    use std::arch::x86_64::*;

    /// One compare-exchange layer: `partner` is the vector with each lane's partner.
    #[inline(always)]
    unsafe fn layer<const MAX_LANES: i32>(v: __m256i, partner: __m256i) -> __m256i {
        _mm256_blend_epi32::<MAX_LANES>(_mm256_min_epi32(v, partner), _mm256_max_epi32(v, partner))
    }

    /// Sorts 8 signed 32-bit keys, largest first (a bitonic network of 6 layers).
    ///
    /// # Safety
    /// Needs AVX2 (inlined: call it from AVX2-enabled code).
    #[inline(always)]
    pub unsafe fn sort8_descending(v: __m256i) -> __m256i {
        // Partners: lane i ^ 1 and i ^ 2 within each 128-bit half, i ^ 4 across the halves.
        let x1 = |v| _mm256_shuffle_epi32::<0b10_11_00_01>(v);
        let x2 = |v| _mm256_shuffle_epi32::<0b01_00_11_10>(v);
        let x4 = |v| _mm256_permute2x128_si256::<0x01>(v, v);
        let v = layer::<{ keeps_max(2, 1) }>(v, x1(v));
        let v = layer::<{ keeps_max(4, 2) }>(v, x2(v));
        let v = layer::<{ keeps_max(4, 1) }>(v, x1(v));
        let v = layer::<{ keeps_max(8, 4) }>(v, x4(v));
        let v = layer::<{ keeps_max(8, 2) }>(v, x2(v));
        layer::<{ keeps_max(8, 1) }>(v, x1(v))
    }
}

/// Pushes the hit children of an 8-wide node (lanes of `mask`, entry distances `t`) onto a
/// structure-of-arrays stack at `sp`, farthest first, without a branch per child: keys
/// `t_bits & !7 | lane` (hit lanes; missed lanes get negative keys) are sorted by a bitonic
/// network, the lane indices in their low bits permute the children, counts and distances,
/// and one vector store per array writes all 8 lanes, of which the first `mask.count_ones()`
/// are the hit children. Distances that differ only in the 3 dropped bits may be visited in
/// either order, which changes no result.
///
/// Inlined into the traversal loop (a call would spill the ray's registers): call it only
/// from a function compiled with AVX2 enabled.
///
/// # Safety
/// Needs AVX2; each array has room for 8 entries at `sp`.
#[inline(always)]
pub unsafe fn push_sorted_avx8(
    node: &WideNode<8>,
    t: &[f32; 8],
    mask: u32,
    child: *mut u32,
    count: *mut u32,
    dist: *mut f32,
    sp: usize,
) {
    use std::arch::x86_64::*;
    // SAFETY: loads from arrays of 8 elements; stores to the room the caller guarantees.
    unsafe {
        let lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        let tv = _mm256_loadu_ps(t.as_ptr());
        // Entry distances are >= tmin; clamped at 0 their bits order like the floats.
        let bits = _mm256_castps_si256(_mm256_max_ps(tv, _mm256_setzero_ps()));
        let key = _mm256_or_si256(_mm256_and_si256(bits, _mm256_set1_epi32(!7)), lane);
        let hit = _mm256_cmpgt_epi32(
            _mm256_and_si256(_mm256_set1_epi32(mask as i32), _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128)),
            _mm256_setzero_si256(),
        );
        let key = _mm256_blendv_epi8(_mm256_or_si256(lane, _mm256_set1_epi32(i32::MIN)), key, hit);
        let order = _mm256_and_si256(network::sort8_descending(key), _mm256_set1_epi32(7));
        let children = _mm256_loadu_si256(node.child.as_ptr().cast());
        let counts = _mm256_loadu_si256(node.count.as_ptr().cast());
        _mm256_storeu_si256(child.add(sp).cast(), _mm256_permutevar8x32_epi32(children, order));
        _mm256_storeu_si256(count.add(sp).cast(), _mm256_permutevar8x32_epi32(counts, order));
        _mm256_storeu_ps(dist.add(sp), _mm256_permutevar8x32_ps(tv, order));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The AVX2 push writes exactly the hit children, each once, farthest first (distances
    /// compared without their 3 lowest bits), with their counts and distances.
    #[test]
    fn avx2_push_sorts_the_hit_children() {
        if super::super::SimdLevel::detect() < super::super::SimdLevel::Avx2 {
            eprintln!("no AVX2 on this CPU: the AVX2 push is not used, nothing to test");
            return;
        }
        let mut node = WideNode::<8>::EMPTY;
        for i in 0..8 {
            node.child[i] = 100 + i as u32;
            node.count[i] = i as u32 % 3;
        }
        let mut s = 7u32;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 17;
            s ^= s << 5;
            s
        };
        for round in 0..20_000 {
            let mask = rnd() & 0xff;
            let t: [f32; 8] = std::array::from_fn(|_| match rnd() % 8 {
                0 => 0.0,
                1 => f32::INFINITY,
                // Equal distances and distances a few ulps apart.
                2 => 1.0,
                3 => f32::from_bits(1.0f32.to_bits() + 3),
                4 => -0.5,
                _ => (rnd() >> 8) as f32 / 1000.0,
            });
            let (mut child, mut count, mut dist) = ([0u32; 10], [0u32; 10], [0f32; 10]);
            // SAFETY: AVX2 was detected (the test function inlines the intrinsics' calls
            // into plain calls, which is allowed); room for 8 entries at index 2.
            unsafe { push_sorted_avx8(&node, &t, mask, child.as_mut_ptr(), count.as_mut_ptr(), dist.as_mut_ptr(), 2) };
            let k = mask.count_ones() as usize;
            let mut lanes: Vec<usize> = child[2..2 + k].iter().map(|&c| (c - 100) as usize).collect();
            for (j, &lane) in lanes.iter().enumerate() {
                assert_eq!(count[2 + j], node.count[lane], "round {round}");
                assert_eq!(dist[2 + j].to_bits(), t[lane].to_bits(), "round {round}");
            }
            let key = |x: f32| x.max(0.0).to_bits() & !7;
            assert!(lanes.windows(2).all(|w| key(t[w[0]]) >= key(t[w[1]])), "round {round}: {lanes:?} {t:?}");
            lanes.sort_unstable();
            let expected: Vec<usize> = (0..8).filter(|i| mask >> i & 1 == 1).collect();
            assert_eq!(lanes, expected, "round {round}");
        }
    }
}
