//! Sorting the keys of a cut's split ([`super::split`]): distinct 64-bit keys (a centre
//! coordinate's order-preserving bits above the node's position in the cut), one set per
//! axis, the three of the same length.
//!
//! Small sets go through sorting networks, whose compare-exchanges are branch-free where
//! insertion sort's and quicksort's comparisons mispredicted. Where the CPU has AVX-512, a set
//! of up to 64 keys goes through the bitonic network in 512-bit registers (8 keys each), a
//! layer of disjoint compare-exchanges at a time: a permutation brings every key's partner
//! beside it (from its own register or from one other), and one `min`, one `max` and a blend
//! finish the layer (a scalar network spends a compare and two selects on each
//! compare-exchange: 63 of them for 16 keys). The three axes' sets of up to 32 keys go through
//! each layer side by side. Elsewhere sets of up to 16 keys take Batcher's odd-even merge
//! sort network and larger ones `sort_unstable`.

/// Sorts each of three sets of distinct keys of the same length.
pub(super) fn sort_three(orders: &mut [Vec<u64>; 3]) {
    debug_assert!(orders.iter().all(|o| o.len() == orders[0].len()));
    #[cfg(target_arch = "x86_64")]
    if orders[0].len() <= 32 && std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU has AVX-512 F (checked).
        unsafe { avx512::sort(orders) };
        return;
    }
    for order in orders {
        sort_keys(order);
    }
}

/// Sorts distinct keys: up to 64 through the AVX-512 network where the CPU has it, else up to
/// 16 through the scalar network (padded to 8 or 16 keys with `u64::MAX`); larger sets with
/// `sort_unstable`.
pub(super) fn sort_keys(keys: &mut Vec<u64>) {
    #[cfg(target_arch = "x86_64")]
    if keys.len() <= 64 && std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU has AVX-512 F (checked).
        unsafe { avx512::sort(std::array::from_mut(keys)) };
        return;
    }
    sort_keys_portable(keys);
}

/// [`sort_keys`] without AVX-512.
fn sort_keys_portable(keys: &mut Vec<u64>) {
    fn network<const N: usize, const K: usize>(keys: &mut Vec<u64>, pairs: &[(u8, u8); K]) {
        let m = keys.len();
        keys.resize(N, u64::MAX);
        let a: &mut [u64; N] = (&mut keys[..]).try_into().expect("resized to N");
        for &(i, j) in pairs {
            let (x, y) = (a[i as usize], a[j as usize]);
            (a[i as usize], a[j as usize]) = (x.min(y), x.max(y));
        }
        keys.truncate(m);
    }
    match keys.len() {
        0..=8 => network::<8, { batcher_len(8) }>(keys, &const { batcher_pairs::<{ batcher_len(8) }>(8) }),
        9..=16 => network::<16, { batcher_len(16) }>(keys, &const { batcher_pairs::<{ batcher_len(16) }>(16) }),
        _ => keys.sort_unstable(),
    }
}

/// Most compare-exchanges [`batcher`] makes (those of 16 inputs).
const BATCHER_MAX: usize = 63;

/// The compare-exchange pairs of Batcher's odd-even merge sort of `n` inputs (a power of two,
/// at most 16), in order, and their number.
const fn batcher(n: usize) -> ([(u8, u8); BATCHER_MAX], usize) {
    assert!(n <= 16);
    let mut pairs = [(0u8, 0u8); BATCHER_MAX];
    let mut count = 0;
    let mut p = 1;
    while p < n {
        let mut k = p;
        while k >= 1 {
            let mut j = k % p;
            while j + k < n {
                let mut i = 0;
                while i < k && i + j + k < n {
                    if (i + j) / (2 * p) == (i + j + k) / (2 * p) {
                        pairs[count] = ((i + j) as u8, (i + j + k) as u8);
                        count += 1;
                    }
                    i += 1;
                }
                j += 2 * k;
            }
            k /= 2;
        }
        p *= 2;
    }
    (pairs, count)
}

/// The `K` ([`batcher_len`]) compare-exchange pairs of [`batcher`]`(n)`.
const fn batcher_pairs<const K: usize>(n: usize) -> [(u8, u8); K] {
    let (all, count) = batcher(n);
    assert!(count == K, "K must be batcher_len(n)");
    let mut pairs = [(0u8, 0u8); K];
    let mut i = 0;
    while i < K {
        pairs[i] = all[i];
        i += 1;
    }
    pairs
}

const fn batcher_len(n: usize) -> usize {
    batcher(n).1
}

/// The number of layers of the bitonic network of `n` wires (a power of two): `t (t + 1) / 2`
/// for `n = 2^t`.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
const fn bitonic_depth(n: usize) -> usize {
    let t = n.trailing_zeros() as usize;
    t * (t + 1) / 2
}

/// One register's share of a layer of the bitonic network over registers of 8 wires: each
/// lane's partner as an index into the register itself (0–7) or into register `other` (8–15,
/// lane + 8), and the lanes that take the larger key (the higher wire of each pair).
#[derive(Clone, Copy)]
struct RegisterLayer {
    index: [u64; 8],
    other: usize,
    takes_max: u8,
}

/// The `L` ([`bitonic_depth`]) layers of the bitonic sorting network of `8 R` wires, register
/// by register. The network is the one without direction changes: each merge of two sorted
/// blocks into one of `b` wires first pairs every wire with its mirror in the block
/// (`w ^ (b − 1)`), then at distances `b / 4, …, 1` (`w ^ k`); the smaller key always goes to
/// the lower wire. Every layer pairs `w` with `w ^ x` for one `x`, so a register's partners
/// lie in itself (`x < 8`) or in one other register, lane for lane or mirrored: one
/// permutation of two registers per register and layer. (Batcher's odd-even merge sort, which
/// the scalar network uses for its fewer compare-exchanges, pairs some registers' lanes with
/// two others.)
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
const fn register_layers<const R: usize, const L: usize>() -> [[RegisterLayer; R]; L] {
    assert!(L == bitonic_depth(8 * R), "L must be bitonic_depth(8 R)");
    let mut out = [[RegisterLayer { index: [0; 8], other: 0, takes_max: 0 }; R]; L];
    let mut l = 0;
    let mut block = 2;
    while block <= 8 * R {
        // The mirror, then the half-cleaners.
        let mut x = block - 1;
        while x >= 1 {
            let mut r = 0;
            while r < R {
                out[l][r].other = r ^ (x / 8);
                let mut lane = 0;
                while lane < 8 {
                    let w = 8 * r + lane;
                    let partner = w ^ x;
                    out[l][r].index[lane] = (partner % 8 + if partner / 8 == r { 0 } else { 8 }) as u64;
                    if partner < w {
                        out[l][r].takes_max |= 1 << lane;
                    }
                    lane += 1;
                }
                r += 1;
            }
            l += 1;
            x = if x == block - 1 { block / 4 } else { x / 2 };
        }
        block *= 2;
    }
    assert!(l == L);
    out
}

/// The networks through AVX-512 F registers.
#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::{bitonic_depth, register_layers, RegisterLayer};
    use std::arch::x86_64::*;

    /// Sorts each of the sets (up to 64 keys, all of the same length; at most 32 when more
    /// than one) through the bitonic network of 8, 16, 32 or 64 wires, the sets through each
    /// layer side by side.
    ///
    /// Call it only where the CPU has AVX-512 F.
    #[target_feature(enable = "avx512f")]
    pub(super) fn sort<const S: usize>(sets: &mut [Vec<u64>; S]) {
        match sets[0].len() {
            0..=8 => {
                sort_in::<S, 1, { bitonic_depth(8) }>(sets, &const { register_layers::<1, { bitonic_depth(8) }>() })
            }
            9..=16 => {
                sort_in::<S, 2, { bitonic_depth(16) }>(sets, &const { register_layers::<2, { bitonic_depth(16) }>() })
            }
            17..=32 => {
                sort_in::<S, 4, { bitonic_depth(32) }>(sets, &const { register_layers::<4, { bitonic_depth(32) }>() })
            }
            _ => {
                assert!(S == 1, "more than one set of over 32 keys");
                sort_in::<S, 8, { bitonic_depth(64) }>(sets, &const { register_layers::<8, { bitonic_depth(64) }>() })
            }
        }
    }

    /// [`sort`] in `R` registers per set.
    #[target_feature(enable = "avx512f")]
    #[inline]
    fn sort_in<const S: usize, const R: usize, const L: usize>(
        sets: &mut [Vec<u64>; S],
        layers: &[[RegisterLayer; R]; L],
    ) {
        let m = sets[0].len();
        assert!(m <= 8 * R && sets.iter().all(|s| s.len() == m));
        // Register r holds keys 8 r .. 8 r + 8, those past `m` padded with `u64::MAX`.
        let mask = |r: usize| ((1u32 << m.saturating_sub(8 * r).min(8)) - 1) as __mmask8;
        let padding = _mm512_set1_epi64(-1);
        let mut v = [[padding; R]; S];
        for (regs, set) in v.iter_mut().zip(sets.iter()) {
            for (r, x) in regs.iter_mut().enumerate() {
                // SAFETY: the load touches only the lanes the mask selects, which lie within
                // the set's `m` keys (a register of none touches nothing).
                *x = unsafe { _mm512_mask_loadu_epi64(padding, mask(r), set.as_ptr().wrapping_add(8 * r).cast()) };
            }
        }
        for layer in layers {
            let index = layer.map(|l| {
                // SAFETY: 8 values.
                unsafe { _mm512_loadu_si512(l.index.as_ptr().cast()) }
            });
            for regs in &mut v {
                let old = *regs;
                for (r, (x, l)) in regs.iter_mut().zip(layer).enumerate() {
                    let other = _mm512_permutex2var_epi64(old[r], index[r], old[l.other]);
                    *x = _mm512_mask_blend_epi64(
                        l.takes_max,
                        _mm512_min_epu64(old[r], other),
                        _mm512_max_epu64(old[r], other),
                    );
                }
            }
        }
        for (set, regs) in sets.iter_mut().zip(v) {
            for (r, x) in regs.into_iter().enumerate() {
                // SAFETY: as the load.
                unsafe { _mm512_mask_storeu_epi64(set.as_mut_ptr().wrapping_add(8 * r).cast(), mask(r), x) };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Marsaglia's xorshift64: the tests' random numbers, reproducible.
    fn xorshift(state: &mut u64) -> u64 {
        *state ^= *state << 13;
        *state ^= *state >> 7;
        *state ^= *state << 17;
        *state
    }

    /// Distinct keys, as the split's (its position in the low bits), with some high bits
    /// equal, the largest ones among them.
    fn keys(m: usize, state: &mut u64) -> Vec<u64> {
        (0..m).map(|i| ((xorshift(state) % 5) << 32) | if i % 7 == 3 { u64::MAX << 8 } else { 0 } | i as u64).collect()
    }

    #[test]
    fn the_networks_sort_like_sort_unstable() {
        assert_eq!(batcher_len(8), 19);
        assert_eq!(batcher_len(16), 63);
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for m in 0..80 {
            for _ in 0..200 {
                let mut keys = keys(m, &mut state);
                let mut expected = keys.clone();
                expected.sort_unstable();
                let mut portable = keys.clone();
                sort_keys_portable(&mut portable);
                assert_eq!(portable, expected, "{m} keys, portable");
                sort_keys(&mut keys);
                assert_eq!(keys, expected, "{m} keys");
            }
        }
    }

    /// The layers register by register, run lane by lane as the AVX-512 code runs them
    /// (the permutation's index, the min, max and blend), sort like `sort_unstable`: checked
    /// on any CPU.
    #[test]
    fn the_register_layers_sort() {
        fn run<const R: usize, const L: usize>(state: &mut u64) {
            let layers = register_layers::<R, L>();
            for m in 0..=8 * R {
                for _ in 0..50 {
                    let mut wires = keys(m, state);
                    let mut expected = wires.clone();
                    expected.sort_unstable();
                    wires.resize(8 * R, u64::MAX);
                    for layer in &layers {
                        let old = wires.clone();
                        for (r, l) in layer.iter().enumerate() {
                            for lane in 0..8 {
                                let i = l.index[lane] as usize;
                                let other = old[8 * if i < 8 { r } else { l.other } + i % 8];
                                let x = old[8 * r + lane];
                                wires[8 * r + lane] =
                                    if l.takes_max >> lane & 1 == 1 { x.max(other) } else { x.min(other) };
                            }
                        }
                    }
                    wires.truncate(m);
                    assert_eq!(wires, expected, "{m} keys in {R} registers");
                }
            }
        }
        let mut state = 0x6a09_e667_f3bc_c908u64;
        run::<1, { bitonic_depth(8) }>(&mut state);
        run::<2, { bitonic_depth(16) }>(&mut state);
        run::<4, { bitonic_depth(32) }>(&mut state);
        run::<8, { bitonic_depth(64) }>(&mut state);
    }

    /// The three sets come out as `sort_unstable` sorts them, through AVX-512 where the CPU
    /// has it (up to 32 keys) and the portable networks and sort otherwise.
    #[test]
    fn three_sets_sort_like_sort_unstable() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for m in 0..40 {
            for _ in 0..200 {
                let mut orders = [keys(m, &mut state), keys(m, &mut state), keys(m, &mut state)];
                let expected = orders.clone().map(|mut o| {
                    o.sort_unstable();
                    o
                });
                sort_three(&mut orders);
                assert_eq!(orders, expected, "{m} keys");
            }
        }
    }
}
