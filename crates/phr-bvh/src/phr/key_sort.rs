//! Sorting the keys of a cut's split ([`super::split`]): distinct 64-bit keys (a centre
//! coordinate's order-preserving bits above the node's position in the cut), one set per
//! axis, the three of the same length.
//!
//! Sets of up to 16 keys go through Batcher's odd-even merge sort network, whose
//! compare-exchanges are branch-free where insertion sort's comparisons mispredicted. Where
//! the CPU has AVX-512, the three axes' sets go through it together, a layer of disjoint
//! compare-exchanges at a time, each set in one or two 512-bit registers: a permutation brings
//! every key's partner beside it, and one `min`, one `max` and a blend finish the layer (the
//! scalar network spends a compare and two selects on each of its 63 compare-exchanges of
//! 16 keys). Larger sets go to `sort_unstable`.

/// Sorts each of three sets of distinct keys of the same length.
pub(super) fn sort_three(orders: &mut [Vec<u64>; 3]) {
    debug_assert!(orders.iter().all(|o| o.len() == orders[0].len()));
    #[cfg(target_arch = "x86_64")]
    if orders[0].len() <= 16 && std::arch::is_x86_feature_detected!("avx512f") {
        // SAFETY: the CPU has AVX-512 F (checked).
        unsafe { avx512::sort_three(orders) };
        return;
    }
    for order in orders {
        sort_keys(order);
    }
}

/// Sorts distinct keys: small sets through a sorting network (Batcher's odd-even merge sort,
/// padded to 8 or 16 keys with `u64::MAX`), whose compare-exchanges are branch-free, where
/// insertion sort's comparisons mispredicted; larger ones with `sort_unstable`.
pub(super) fn sort_keys(keys: &mut Vec<u64>) {
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

/// One layer of a network of at most 16 wires: disjoint compare-exchanges, as each wire's
/// partner (itself where it has none) and the wires that take the larger key of their pair
/// (the higher wire of each).
#[derive(Clone, Copy)]
struct Layer {
    partner: [u64; 16],
    takes_max: u16,
}

/// The layers of [`batcher`]`(n)`, and their number: each compare-exchange goes to the first
/// layer after the last one on either of its wires, which keeps the order of the
/// compare-exchanges that share a wire (and so the network's result).
const fn batcher_layers(n: usize) -> ([Layer; BATCHER_MAX], usize) {
    let (pairs, count) = batcher(n);
    let mut identity = [0u64; 16];
    let mut w = 0;
    while w < 16 {
        identity[w] = w as u64;
        w += 1;
    }
    let mut layers = [Layer { partner: identity, takes_max: 0 }; BATCHER_MAX];
    let mut depth = [0usize; 16];
    let mut used = 0;
    let mut c = 0;
    while c < count {
        let (i, j) = (pairs[c].0 as usize, pairs[c].1 as usize);
        let d = if depth[i] > depth[j] { depth[i] } else { depth[j] };
        layers[d].partner[i] = j as u64;
        layers[d].partner[j] = i as u64;
        layers[d].takes_max |= 1 << j;
        (depth[i], depth[j]) = (d + 1, d + 1);
        if d + 1 > used {
            used = d + 1;
        }
        c += 1;
    }
    (layers, used)
}

/// The `L` ([`batcher_depth`]) layers of [`batcher_layers`]`(n)`.
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
const fn layers_of<const L: usize>(n: usize) -> [Layer; L] {
    let (all, used) = batcher_layers(n);
    assert!(used == L, "L must be batcher_depth(n)");
    let mut layers = [all[0]; L];
    let mut i = 0;
    while i < L {
        layers[i] = all[i];
        i += 1;
    }
    layers
}

#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
const fn batcher_depth(n: usize) -> usize {
    batcher_layers(n).1
}

/// The networks through AVX-512 F registers.
#[cfg(target_arch = "x86_64")]
mod avx512 {
    use super::{batcher_depth, layers_of, Layer};
    use std::arch::x86_64::*;

    const LAYERS_8: [Layer; batcher_depth(8)] = layers_of::<{ batcher_depth(8) }>(8);
    const LAYERS_16: [Layer; batcher_depth(16)] = layers_of::<{ batcher_depth(16) }>(16);

    /// [`super::sort_three`] for sets of at most 16 keys: each set in one register (up to
    /// 8 keys) or two, padded with `u64::MAX`, the three through each layer side by side.
    ///
    /// Call it only where the CPU has AVX-512 F.
    #[target_feature(enable = "avx512f")]
    pub(super) fn sort_three(orders: &mut [Vec<u64>; 3]) {
        let m = orders[0].len();
        assert!(m <= 16 && orders.iter().all(|o| o.len() == m));
        let padding = _mm512_set1_epi64(-1);
        // SAFETY (the loads and stores): each touches only the lanes its mask selects, which
        // lie within the set's `m` keys.
        if m <= 8 {
            let k = ((1u32 << m) - 1) as __mmask8;
            let mut v = [padding; 3];
            for (x, o) in v.iter_mut().zip(orders.iter()) {
                *x = unsafe { _mm512_mask_loadu_epi64(padding, k, o.as_ptr().cast()) };
            }
            for layer in &LAYERS_8 {
                // SAFETY: 16 values, of which the first 8 are read.
                let partner = unsafe { _mm512_loadu_si512(layer.partner.as_ptr().cast()) };
                let takes_max = layer.takes_max as __mmask8;
                for x in &mut v {
                    let other = _mm512_permutexvar_epi64(partner, *x);
                    *x = _mm512_mask_blend_epi64(takes_max, _mm512_min_epu64(*x, other), _mm512_max_epu64(*x, other));
                }
            }
            for (o, x) in orders.iter_mut().zip(v) {
                unsafe { _mm512_mask_storeu_epi64(o.as_mut_ptr().cast(), k, x) };
            }
        } else {
            let k = ((1u32 << (m - 8)) - 1) as __mmask8;
            let mut v = [(padding, padding); 3];
            for ((a, b), o) in v.iter_mut().zip(orders.iter()) {
                *a = unsafe { _mm512_loadu_si512(o.as_ptr().cast()) };
                *b = unsafe { _mm512_mask_loadu_epi64(padding, k, o.as_ptr().add(8).cast()) };
            }
            for layer in &LAYERS_16 {
                // SAFETY: 16 values, read as two vectors of 8.
                let (partner_a, partner_b) = unsafe {
                    (
                        _mm512_loadu_si512(layer.partner.as_ptr().cast()),
                        _mm512_loadu_si512(layer.partner.as_ptr().add(8).cast()),
                    )
                };
                let (max_a, max_b) = (layer.takes_max as __mmask8, (layer.takes_max >> 8) as __mmask8);
                for (a, b) in &mut v {
                    let other_a = _mm512_permutex2var_epi64(*a, partner_a, *b);
                    let other_b = _mm512_permutex2var_epi64(*a, partner_b, *b);
                    *a = _mm512_mask_blend_epi64(max_a, _mm512_min_epu64(*a, other_a), _mm512_max_epu64(*a, other_a));
                    *b = _mm512_mask_blend_epi64(max_b, _mm512_min_epu64(*b, other_b), _mm512_max_epu64(*b, other_b));
                }
            }
            for (o, (a, b)) in orders.iter_mut().zip(v) {
                unsafe {
                    _mm512_storeu_si512(o.as_mut_ptr().cast(), a);
                    _mm512_mask_storeu_epi64(o.as_mut_ptr().add(8).cast(), k, b);
                }
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
        for m in 0..40 {
            for _ in 0..200 {
                let mut keys = keys(m, &mut state);
                let mut expected = keys.clone();
                expected.sort_unstable();
                sort_keys(&mut keys);
                assert_eq!(keys, expected, "{m} keys");
            }
        }
    }

    /// The layers hold the network's compare-exchanges, each once, none two on one wire.
    #[test]
    fn the_layers_hold_the_network() {
        for (n, depth) in [(8, 6), (16, 10)] {
            assert_eq!(batcher_depth(n), depth);
            let (layers, used) = batcher_layers(n);
            let mut pairs: Vec<(u64, u64)> = layers[..used]
                .iter()
                .flat_map(|l| {
                    (0..16u64).filter(move |&w| l.partner[w as usize] > w).map(move |w| (w, l.partner[w as usize]))
                })
                .collect();
            for l in &layers[..used] {
                for w in 0..16 {
                    assert_eq!(l.partner[l.partner[w] as usize], w as u64, "{n} wires");
                    let higher = l.partner[w] < w as u64;
                    assert_eq!(l.takes_max >> w & 1 == 1, higher, "{n} wires, wire {w}");
                }
            }
            let (all, count) = batcher(n);
            let mut want: Vec<(u64, u64)> = all[..count].iter().map(|&(i, j)| (i as u64, j as u64)).collect();
            pairs.sort_unstable();
            want.sort_unstable();
            assert_eq!(pairs, want, "{n} wires");
        }
    }

    /// The three sets come out as `sort_unstable` sorts them, through AVX-512 where the CPU
    /// has it (up to 16 keys) and the portable networks and sort otherwise.
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
