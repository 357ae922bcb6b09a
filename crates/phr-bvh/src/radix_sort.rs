//! Parallel least-significant-digit radix sort of (64-bit key, 32-bit value) pairs: the sort
//! step of the LBVH. Linear in n, unlike a comparison sort, and stable, so equal Morton codes
//! keep primitive order and the build is deterministic.
//!
//! Large arrays are first split by their most significant digit (one parallel histogram and
//! one parallel scatter over the whole array); every bucket, small enough to stay in cache, is
//! then sorted on the remaining bits by LSD passes, buckets in parallel. Two passes over the
//! big array instead of eight: the sort is bound by memory traffic, not by arithmetic.
//!
//! Each pass splits its array into chunks, histograms the chunks in parallel, turns the
//! histograms into per-chunk write offsets, and scatters in parallel. Digits of 8 bits;
//! passes whose digit is the same for every key are skipped.

use rayon::prelude::*;

const RADIX_BITS: u32 = 8;
const BUCKETS: usize = 1 << RADIX_BITS;

/// Below this many pairs a single chunk is used (threads cost more than they save).
const MIN_CHUNK: usize = 1 << 15;

/// Above this many pairs the sort starts with a most-significant-digit split.
const MSD_THRESHOLD: usize = 1 << 16;

/// Sorts `pairs` by `.0` (the key), looking only at the lowest `key_bits` bits.
pub fn radix_sort_pairs(pairs: &mut Vec<(u64, u32)>, key_bits: u32) {
    let n = pairs.len();
    if n < MSD_THRESHOLD || key_bits <= RADIX_BITS {
        lsd_sort(pairs, key_bits);
        return;
    }
    let shift = key_bits - RADIX_BITS;
    let chunks = (n / MIN_CHUNK).clamp(1, 4 * rayon::current_num_threads().max(1));
    let chunk_len = n.div_ceil(chunks);
    let histograms = chunk_histograms(pairs, chunk_len, shift);
    let mut scratch: Vec<(u64, u32)> = vec![(0, 0); n];
    scatter(pairs, &mut scratch, &chunk_offsets(&histograms), chunk_len, shift);
    // Bucket b now holds every key whose top digit is b; sort each on the lower bits.
    let mut buckets = Vec::with_capacity(BUCKETS);
    let mut rest = &mut scratch[..];
    for b in 0..BUCKETS {
        let len: usize = histograms.iter().map(|h| h[b]).sum();
        let (bucket, tail) = std::mem::take(&mut rest).split_at_mut(len);
        buckets.push(bucket);
        rest = tail;
    }
    buckets.into_par_iter().for_each(|bucket| {
        let mut v = bucket.to_vec();
        lsd_sort(&mut v, shift);
        bucket.copy_from_slice(&v);
    });
    std::mem::swap(pairs, &mut scratch);
}

fn chunk_histograms(pairs: &[(u64, u32)], chunk_len: usize, shift: u32) -> Vec<[usize; BUCKETS]> {
    pairs
        .par_chunks(chunk_len)
        .map(|chunk| {
            let mut h = [0usize; BUCKETS];
            for &(k, _) in chunk {
                h[((k >> shift) as usize) & (BUCKETS - 1)] += 1;
            }
            h
        })
        .collect()
}

/// LSD passes over the lowest `key_bits` bits.
fn lsd_sort(pairs: &mut Vec<(u64, u32)>, key_bits: u32) {
    let n = pairs.len();
    if n < 2 {
        return;
    }
    let chunks = (n / MIN_CHUNK).clamp(1, 4 * rayon::current_num_threads().max(1));
    let chunk_len = n.div_ceil(chunks);
    let mut scratch: Vec<(u64, u32)> = vec![(0, 0); n];
    let mut shift = 0;
    while shift < key_bits {
        let histograms = chunk_histograms(pairs, chunk_len, shift);
        if histograms_single_bucket(&histograms, n) {
            shift += RADIX_BITS;
            continue;
        }
        let offsets = chunk_offsets(&histograms);
        scatter(pairs, &mut scratch, &offsets, chunk_len, shift);
        std::mem::swap(pairs, &mut scratch);
        shift += RADIX_BITS;
    }
}

fn histograms_single_bucket(histograms: &[[usize; BUCKETS]], n: usize) -> bool {
    (0..BUCKETS).any(|b| histograms.iter().map(|h| h[b]).sum::<usize>() == n)
}

/// Exclusive prefix sums in (bucket, chunk) order: where chunk c writes its first key of
/// bucket b.
fn chunk_offsets(histograms: &[[usize; BUCKETS]]) -> Vec<[usize; BUCKETS]> {
    let mut offsets = vec![[0usize; BUCKETS]; histograms.len()];
    let mut sum = 0;
    for b in 0..BUCKETS {
        for (c, h) in histograms.iter().enumerate() {
            offsets[c][b] = sum;
            sum += h[b];
        }
    }
    offsets
}

fn scatter(src: &[(u64, u32)], dst: &mut [(u64, u32)], offsets: &[[usize; BUCKETS]], chunk_len: usize, shift: u32) {
    let out = crate::parallel::UnsafeSlice::new(dst);
    src.par_chunks(chunk_len).zip(offsets.par_iter()).for_each(|(chunk, start)| {
        let mut cursor = *start;
        for &pair in chunk {
            let b = ((pair.0 >> shift) as usize) & (BUCKETS - 1);
            // SAFETY: the offsets partition `dst` into disjoint ranges, one per (chunk,
            // bucket), each exactly as long as that chunk's count of that bucket, so every
            // index is written by exactly one thread, once.
            unsafe { out.write(cursor[b], pair) };
            cursor[b] += 1;
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sorts_like_std_and_is_stable() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for &n in &[0usize, 1, 2, 1000, 100_000, 300_001, 1_000_003] {
            let mut pairs: Vec<(u64, u32)> = (0..n).map(|i| (next() >> 1 & 0xffff_ffff_0000_00ff, i as u32)).collect();
            let mut expected = pairs.clone();
            expected.sort_by_key(|p| p.0); // stable
            radix_sort_pairs(&mut pairs, 63);
            assert_eq!(pairs, expected, "n = {n}");
        }
    }
}
