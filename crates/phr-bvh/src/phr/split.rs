//! The split of a cut: a full-sweep SAH over the cut's nodes (thesis 5.2; Hendrich et al.
//! 2017, section 4.2), as the full-sweep SAH builder does over primitives, but with each
//! auxiliary node standing for its whole subtree.
//!
//! On each axis the nodes are sorted by the centre of their box; one sweep from the right
//! stores the area of every suffix's union, one from the left evaluates
//! `A_L · n_L + A_R · n_R` at every position. `n` is the node's weight: the number of auxiliary
//! nodes under it (the thesis's choice) or of primitives (see [`super::CutWeight`]). A cut of
//! [`BINNED_AXIS_FROM`] nodes or more is sorted and swept along one axis only, the one where a
//! binned estimate over 16 bins finds the cheapest split ([`binned_axis`]). Whether to
//! split at all is decided by the shared [`crate::sah::LeafPolicy`] on primitive counts, as for
//! every other builder. The cut is reordered and split in place: no allocation.

use super::cut::{node_key, CutNode};
use super::key_sort::{sort_keys, sort_three};
use super::CutWeight;
use crate::aabb::Aabb;
use glam::Vec3A;

/// The chosen split of a cut slice: after [`best_split`] the slice is sorted along the split
/// axis and `left_len` nodes go left.
pub struct CutSplit {
    pub left_len: usize,
    /// `Σ A_child · N_child` over both halves, with N in primitives.
    pub area_count: f32,
}

/// Scratch space of [`best_split`], reused across calls.
#[derive(Default)]
pub struct SplitScratch {
    /// Per position, the area of the union of the nodes from there on, on each axis.
    right_area: Vec<[f32; 3]>,
    /// The nodes' keys sorted along each axis swept.
    orders: [Vec<u64>; 3],
    reordered: Vec<CutNode>,
    boxes: Vec<(Vec3A, Vec3A)>,
    weights: Vec<f32>,
}

/// Finds the best full-sweep split of `cut` (at least two nodes) over the three axes (over
/// the axis [`binned_axis`] picks from [`BINNED_AXIS_FROM`] nodes on) and leaves `cut`
/// ordered along the best axis.
///
/// Sorting moves 8-byte integer keys (the centroid coordinate's order-preserving bits above
/// the node's position, so ties go by position), not the nodes; the nodes are permuted once,
/// at the end. A cut of two nodes has only one split and skips all of it.
pub fn best_split(cut: &mut [CutNode], weight: CutWeight, scratch: &mut SplitScratch) -> CutSplit {
    let m = cut.len();
    debug_assert!(m >= 2);
    if m == 2 {
        return CutSplit { left_len: 1, area_count: side_cost(&cut[..1]) + side_cost(&cut[1..]) };
    }
    if centres_coincide(cut) {
        return median_split(cut);
    }
    // The boxes as SIMD vectors and the weights, read once for the three axes.
    scratch.boxes.clear();
    scratch.boxes.extend(cut.iter().map(|n| (Vec3A::from(n.bounds.min), Vec3A::from(n.bounds.max))));
    scratch.weights.clear();
    scratch.weights.extend(cut.iter().map(|n| weight.of(n.prims)));
    let total_weight: f32 = scratch.weights.iter().sum();
    let best = if m >= BINNED_AXIS_FROM {
        // A large cut: the axis from a binned estimate, then the full sweep along it alone.
        let axis = binned_axis(&scratch.boxes, &scratch.weights);
        let best = sweep_one_axis(axis, scratch, total_weight);
        // (The three-axis sweep's rule: any cost below infinity.)
        (best.0 < f32::INFINITY).then_some((axis, best))
    } else {
        sweep_three_axes(scratch, total_weight)
    };
    let Some((axis, (_, left_len, left_area))) = best else {
        // No finite cost: the cut as it came, halved.
        let left_len = m / 2;
        return CutSplit { left_len, area_count: side_cost(&cut[..left_len]) + side_cost(&cut[left_len..]) };
    };
    scratch.reordered.clear();
    scratch.reordered.extend(scratch.orders[axis].iter().map(|&key| cut[(key & 0xffff_ffff) as usize]));
    cut.copy_from_slice(&scratch.reordered);
    // Both sides' areas from the sweeps: the unions `side_cost` would form again, so the
    // same bits (for finite, non-empty boxes: with a NaN, a union depends on its order, and
    // the right side's sweep runs backwards; an inverted box has no area in `side_cost`).
    // `A · n` counts primitives whatever the sweep's weight.
    let left_prims: u32 = cut[..left_len].iter().map(|n| n.prims).sum();
    let right_prims: u32 = cut[left_len..].iter().map(|n| n.prims).sum();
    let area_count = left_area * left_prims as f32 + scratch.right_area[left_len][axis] * right_prims as f32;
    debug_assert!(
        cut.iter().any(|n| !(n.bounds.min.is_finite() && n.bounds.max.is_finite()) || n.bounds.is_empty())
            || area_count.to_bits() == (side_cost(&cut[..left_len]) + side_cost(&cut[left_len..])).to_bits()
    );
    CutSplit { left_len, area_count }
}

/// From this many nodes on, a cut is swept along one axis only, the one [`binned_axis`] picks:
/// the sorts and sweeps of large cuts were most of PHR-HQ's split time, and the binned
/// estimate picks the full sweep's axis nearly always (`docs/bench-build/history.md`).
pub const BINNED_AXIS_FROM: usize = 32;

/// Sorts the keys of `scratch.boxes` along each axis into `scratch.orders` and sweeps the
/// three axes side by side (each sweep is a chain of dependent min/max steps, and three
/// independent chains keep the core busy where one waits on the last step's latency).
/// Returns the cheapest axis with its first cheapest position as `(cost, left length, left
/// area)` (`None`: no finite cost); `scratch.right_area[k][axis]` holds the area right of
/// position `k`.
fn sweep_three_axes(scratch: &mut SplitScratch, total_weight: f32) -> Option<(usize, (f32, usize, f32))> {
    let m = scratch.boxes.len();
    for (axis, order) in scratch.orders.iter_mut().enumerate() {
        fill_keys(&scratch.boxes, axis, order);
    }
    sort_three(&mut scratch.orders);
    scratch.right_area.resize(m, [0.0; 3]);
    let (orders, boxes, weights) = (&scratch.orders, &scratch.boxes, &scratch.weights);
    let index = |order: &[u64], k: usize| (order[k] & 0xffff_ffff) as usize;
    let mut lo = [Vec3A::INFINITY; 3];
    let mut hi = [Vec3A::NEG_INFINITY; 3];
    for k in (1..m).rev() {
        let mut right = [0.0; 3];
        for (axis, order) in orders.iter().enumerate() {
            let b = &boxes[index(order, k)];
            (lo[axis], hi[axis]) = (lo[axis].min(b.0), hi[axis].max(b.1));
            right[axis] = area(lo[axis], hi[axis]);
        }
        scratch.right_area[k] = right;
    }
    // Each axis's first cheapest position, then the axes in order, each kept only if
    // strictly cheaper: the choice of sweeping the axes one after the other.
    let mut best_of = [(f32::INFINITY, m / 2, 0.0f32); 3];
    let mut lo = [Vec3A::INFINITY; 3];
    let mut hi = [Vec3A::NEG_INFINITY; 3];
    let mut left_weight = [0.0f32; 3];
    for k in 1..m {
        for (axis, order) in orders.iter().enumerate() {
            let i = index(order, k - 1);
            (lo[axis], hi[axis]) = (lo[axis].min(boxes[i].0), hi[axis].max(boxes[i].1));
            left_weight[axis] += weights[i];
            let left_area = area(lo[axis], hi[axis]);
            let cost = left_area * left_weight[axis] + scratch.right_area[k][axis] * (total_weight - left_weight[axis]);
            if cost < best_of[axis].0 {
                best_of[axis] = (cost, k, left_area);
            }
        }
    }
    let mut best_axis = None;
    let mut best_cost = f32::INFINITY;
    for (axis, &(cost, _, _)) in best_of.iter().enumerate() {
        if cost < best_cost {
            (best_cost, best_axis) = (cost, Some(axis));
        }
    }
    best_axis.map(|axis| (axis, best_of[axis]))
}

/// [`sweep_three_axes`] along `axis` alone: its first cheapest position.
fn sweep_one_axis(axis: usize, scratch: &mut SplitScratch, total_weight: f32) -> (f32, usize, f32) {
    let m = scratch.boxes.len();
    fill_keys(&scratch.boxes, axis, &mut scratch.orders[axis]);
    sort_keys(&mut scratch.orders[axis]);
    scratch.right_area.resize(m, [0.0; 3]);
    let (order, boxes, weights) = (&scratch.orders[axis], &scratch.boxes, &scratch.weights);
    let index = |k: usize| (order[k] & 0xffff_ffff) as usize;
    let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    for k in (1..m).rev() {
        let b = &boxes[index(k)];
        (lo, hi) = (lo.min(b.0), hi.max(b.1));
        scratch.right_area[k][axis] = area(lo, hi);
    }
    let mut best = (f32::INFINITY, m / 2, 0.0f32);
    let (mut lo, mut hi, mut left_weight) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY, 0.0f32);
    for k in 1..m {
        let i = index(k - 1);
        (lo, hi) = (lo.min(boxes[i].0), hi.max(boxes[i].1));
        left_weight += weights[i];
        let left_area = area(lo, hi);
        let cost = left_area * left_weight + scratch.right_area[k][axis] * (total_weight - left_weight);
        if cost < best.0 {
            best = (cost, k, left_area);
        }
    }
    best
}

/// The keys of `boxes` along `axis` into `order`: the centre coordinate's order-preserving
/// bits above the node's position (so that ties go by position).
fn fill_keys(boxes: &[(Vec3A, Vec3A)], axis: usize, order: &mut Vec<u64>) {
    order.clear();
    order.extend(boxes.iter().enumerate().map(|(i, (lo, hi))| (ordered_bits(lo[axis] + hi[axis]) << 32) | i as u64));
}

/// The bins of [`binned_axis`].
const AXIS_BINS: usize = 16;

/// The axis along which a binned SAH sweep (the nodes' centres in [`AXIS_BINS`] equal bins,
/// as the binned SAH builder bins primitives) finds the cheapest split; ties go to the
/// lower axis, and an axis along which the centres do not spread is not considered.
fn binned_axis(boxes: &[(Vec3A, Vec3A)], weights: &[f32]) -> usize {
    let (low, high) = boxes
        .iter()
        .fold((Vec3A::INFINITY, Vec3A::NEG_INFINITY), |(a, b), (lo, hi)| (a.min(*lo + *hi), b.max(*lo + *hi)));
    let extent = high - low;
    // Just under `AXIS_BINS` per extent, so that the highest centre falls in the last bin.
    let scale = Vec3A::select(
        extent.cmpgt(Vec3A::ZERO),
        Vec3A::splat(AXIS_BINS as f32 * (1.0 - f32::EPSILON)) / extent,
        Vec3A::ZERO,
    );
    let mut bin_lo = [[Vec3A::INFINITY; AXIS_BINS]; 3];
    let mut bin_hi = [[Vec3A::NEG_INFINITY; AXIS_BINS]; 3];
    let mut bin_weight = [[0.0f32; AXIS_BINS]; 3];
    let mut bin_nodes = [[0u32; AXIS_BINS]; 3];
    let last = Vec3A::splat((AXIS_BINS - 1) as f32);
    for ((lo, hi), &weight) in boxes.iter().zip(weights) {
        let bin = ((*lo + *hi - low) * scale).min(last);
        for axis in 0..3 {
            let k = bin[axis] as usize;
            bin_lo[axis][k] = bin_lo[axis][k].min(*lo);
            bin_hi[axis][k] = bin_hi[axis][k].max(*hi);
            bin_weight[axis][k] += weight;
            bin_nodes[axis][k] += 1;
        }
    }
    // (No position with nodes on both sides, as when the boxes are not finite: the axis of
    // widest spread.)
    let mut best = (f32::INFINITY, Aabb::new(low.into(), high.into()).longest_axis());
    for axis in (0..3).filter(|&a| extent[a] > 0.0) {
        // Per position, the right side's `A · n` and node count.
        let mut right = [(0.0f32, 0u32); AXIS_BINS];
        let (mut lo, mut hi, mut weight, mut nodes) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY, 0.0f32, 0);
        for k in (1..AXIS_BINS).rev() {
            (lo, hi) = (lo.min(bin_lo[axis][k]), hi.max(bin_hi[axis][k]));
            (weight, nodes) = (weight + bin_weight[axis][k], nodes + bin_nodes[axis][k]);
            right[k] = (area(lo, hi) * weight, nodes);
        }
        let (mut lo, mut hi, mut weight, mut nodes) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY, 0.0f32, 0);
        // Boundary k lies between bins k − 1 (the last on the left) and k.
        for (b, &(right_cost, right_nodes)) in right.iter().enumerate().skip(1).map(|(k, r)| (k - 1, r)) {
            (lo, hi) = (lo.min(bin_lo[axis][b]), hi.max(bin_hi[axis][b]));
            (weight, nodes) = (weight + bin_weight[axis][b], nodes + bin_nodes[axis][b]);
            if nodes > 0 && right_nodes > 0 {
                let cost = area(lo, hi) * weight + right_cost;
                if cost < best.0 {
                    best = (cost, axis);
                }
            }
        }
    }
    best.1
}

/// Splits `cut` (at least two nodes) at its primitive median along the axis where the nodes'
/// centres spread most: each side gets at least one node and as close to half of the
/// primitives as the nodes allow. What a cut gets when its centres coincide (no sweep position
/// separates them) or its node lies past [`crate::sah::MEDIAN_SPLIT_DEPTH`].
pub fn median_split(cut: &mut [CutNode]) -> CutSplit {
    let m = cut.len();
    debug_assert!(m >= 2);
    let centres = cut.iter().fold(Aabb::EMPTY, |b, n| b.grown(n.bounds.min + n.bounds.max));
    let axis = centres.longest_axis();
    cut.sort_unstable_by(|a, b| {
        (a.bounds.min[axis] + a.bounds.max[axis])
            .total_cmp(&(b.bounds.min[axis] + b.bounds.max[axis]))
            .then(node_key(a).cmp(&node_key(b)))
    });
    let total: u64 = cut.iter().map(|n| u64::from(n.prims)).sum();
    let mut left = 0u64;
    let mut left_len = 0;
    while left_len < m - 1 && (left_len == 0 || 2 * left < total) {
        left += u64::from(cut[left_len].prims);
        left_len += 1;
    }
    CutSplit { left_len, area_count: side_cost(&cut[..left_len]) + side_cost(&cut[left_len..]) }
}

/// The surface area of the non-empty box `lo..hi`, in SIMD registers (the sweeps' boxes: the
/// scalar `Aabb` form was most of their time).
#[inline(always)]
fn area(lo: Vec3A, hi: Vec3A) -> f32 {
    let e = hi - lo;
    2.0 * e.dot(Vec3A::new(e.y, e.z, e.x))
}

/// `A · n` of one side: its box's area times its primitives.
fn side_cost(half: &[CutNode]) -> f32 {
    let b = half.iter().fold(Aabb::EMPTY, |b, n| b.union(n.bounds));
    b.surface_area() * half.iter().map(|n| n.prims).sum::<u32>() as f32
}

/// Whether every node of the cut has the same centre.
fn centres_coincide(cut: &[CutNode]) -> bool {
    let c = cut[0].bounds.min + cut[0].bounds.max;
    cut[1..].iter().all(|n| n.bounds.min + n.bounds.max == c)
}

/// The bits of a float, mapped so that integer order is float order (negative floats have
/// their bits flipped, positive ones their sign bit set).
#[inline(always)]
fn ordered_bits(x: f32) -> u64 {
    let b = x.to_bits();
    (if b & 0x8000_0000 != 0 { !b } else { b | 0x8000_0000 }) as u64
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

    /// The plain full sweep: each of `axes` in turn, the nodes sorted by centre (ties by
    /// position), every position's cost computed from scratch; the first strictly cheapest
    /// (axis, position) wins. `best_split` must choose as it does and order the cut the same.
    fn reference_split(cut: &[CutNode], weight: CutWeight, axes: &[usize]) -> (Vec<CutNode>, usize) {
        let union = |nodes: &[CutNode]| nodes.iter().fold(Aabb::EMPTY, |b, n| b.union(n.bounds));
        let sides = |nodes: &[CutNode]| {
            let b = union(nodes);
            area(Vec3A::from(b.min), Vec3A::from(b.max)) * nodes.iter().map(|n| weight.of(n.prims)).sum::<f32>()
        };
        let mut best: Option<(f32, Vec<CutNode>, usize)> = None;
        for &axis in axes {
            let mut sorted: Vec<(usize, CutNode)> = cut.iter().copied().enumerate().collect();
            let centre = |n: &CutNode| n.bounds.min[axis] + n.bounds.max[axis];
            sorted.sort_by(|(i, a), (j, b)| centre(a).total_cmp(&centre(b)).then(i.cmp(j)));
            let sorted: Vec<CutNode> = sorted.into_iter().map(|(_, n)| n).collect();
            for k in 1..sorted.len() {
                let cost = sides(&sorted[..k]) + sides(&sorted[k..]);
                if best.as_ref().is_none_or(|b| cost < b.0) {
                    best = Some((cost, sorted.clone(), k));
                }
            }
        }
        let (_, sorted, k) = best.expect("at least two nodes");
        (sorted, k)
    }

    /// The binned estimate's axis is the one whose cheapest bin boundary, costed from
    /// scratch (the union and weight of the nodes on each side), is cheapest, axes and
    /// boundaries in order; on a cut stretched along one axis, that axis.
    #[test]
    fn the_binned_axis_has_the_cheapest_bin_boundary() {
        let mut state = 0x1234_5678_9abc_def1u64;
        let mut next = || (xorshift(&mut state) >> 40) as f32 / (1u64 << 24) as f32;
        for m in [BINNED_AXIS_FROM, 57, 300] {
            for stretched in 0..4 {
                for _ in 0..20 {
                    let boxes: Vec<(Vec3A, Vec3A)> = (0..m)
                        .map(|_| {
                            let mut lo = Vec3A::new(next(), next(), next());
                            if stretched < 3 {
                                lo[stretched] *= 50.0;
                            }
                            (lo, lo + Vec3A::new(next(), next(), next()) * 0.3)
                        })
                        .collect();
                    let weights: Vec<f32> = (0..m).map(|i| (1 + i % 5) as f32).collect();
                    let (low, high) = boxes.iter().fold((Vec3A::INFINITY, Vec3A::NEG_INFINITY), |(a, b), (lo, hi)| {
                        (a.min(*lo + *hi), b.max(*lo + *hi))
                    });
                    let mut want = (f32::INFINITY, usize::MAX);
                    for axis in 0..3 {
                        let extent = high[axis] - low[axis];
                        let scale = AXIS_BINS as f32 * (1.0 - f32::EPSILON) / extent;
                        let bin = |(lo, hi): &(Vec3A, Vec3A)| {
                            ((lo[axis] + hi[axis] - low[axis]) * scale).min((AXIS_BINS - 1) as f32) as usize
                        };
                        for k in 1..AXIS_BINS {
                            let side = |left: bool| {
                                let nodes: Vec<usize> = (0..m).filter(|&i| (bin(&boxes[i]) < k) == left).collect();
                                let (lo, hi) =
                                    nodes.iter().fold((Vec3A::INFINITY, Vec3A::NEG_INFINITY), |(a, b), &i| {
                                        (a.min(boxes[i].0), b.max(boxes[i].1))
                                    });
                                (area(lo, hi) * nodes.iter().map(|&i| weights[i]).sum::<f32>(), nodes.len())
                            };
                            let ((left, left_nodes), (right, right_nodes)) = (side(true), side(false));
                            if left_nodes > 0 && right_nodes > 0 && left + right < want.0 {
                                want = (left + right, axis);
                            }
                        }
                    }
                    assert_eq!(binned_axis(&boxes, &weights), want.1, "{m} nodes, stretched along {stretched}");
                    if stretched < 3 {
                        assert_eq!(want.1, stretched, "{m} nodes");
                    }
                }
            }
        }
    }

    /// A large cut with boxes that are NaN, infinite or flat is still split, into two
    /// non-empty sides holding its nodes.
    #[test]
    fn a_large_cut_of_broken_boxes_is_split() {
        let mut scratch = SplitScratch::default();
        for broken in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 0.0] {
            let cut: Vec<CutNode> = (0..BINNED_AXIS_FROM as u32 + 9)
                .map(|i| {
                    let lo = glam::Vec3::new(i as f32, (i % 3) as f32, 0.0);
                    let hi = if i % 4 == 1 { glam::Vec3::new(broken, 1.0, broken) } else { lo + glam::Vec3::ONE };
                    CutNode { bounds: Aabb::new(lo, hi), first: i, prims: 1 }
                })
                .collect();
            let mut got = cut.clone();
            let split = best_split(&mut got, CutWeight::Primitives, &mut scratch);
            assert!((1..cut.len()).contains(&split.left_len), "{broken}: {} of {}", split.left_len, cut.len());
            let mut firsts: Vec<u32> = got.iter().map(|n| n.first).collect();
            firsts.sort_unstable();
            assert_eq!(firsts, (0..cut.len() as u32).collect::<Vec<_>>(), "{broken}");
        }
    }

    #[test]
    fn the_sweep_chooses_as_the_plain_sweep_does() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || (xorshift(&mut state) >> 40) as f32 / (1u64 << 24) as f32;
        let mut scratch = SplitScratch::default();
        for m in 3..70 {
            for weight in [CutWeight::Primitives, CutWeight::AuxNodes] {
                // Boxes on a coarse grid, so that centres and costs tie now and then.
                let cut: Vec<CutNode> = (0..m)
                    .map(|i| {
                        let lo = glam::Vec3::new(next(), next(), next()) * 8.0;
                        let lo = lo.floor() / 2.0;
                        let size = glam::Vec3::new(next(), next(), next()) * 3.0 + glam::Vec3::splat(0.1);
                        CutNode { bounds: Aabb::new(lo, lo + size.floor() / 2.0), first: i, prims: 1 + i % 5 }
                    })
                    .collect();
                if centres_coincide(&cut) {
                    continue;
                }
                // A large cut is swept along the binned estimate's axis alone.
                let axes = if (m as usize) < BINNED_AXIS_FROM {
                    vec![0, 1, 2]
                } else {
                    let boxes: Vec<_> =
                        cut.iter().map(|n| (Vec3A::from(n.bounds.min), Vec3A::from(n.bounds.max))).collect();
                    let weights: Vec<f32> = cut.iter().map(|n| weight.of(n.prims)).collect();
                    vec![binned_axis(&boxes, &weights)]
                };
                let (want, want_len) = reference_split(&cut, weight, &axes);
                let mut got = cut.clone();
                let split = best_split(&mut got, weight, &mut scratch);
                assert_eq!(split.left_len, want_len, "{m} nodes");
                let keys = |nodes: &[CutNode]| nodes.iter().map(node_key).collect::<Vec<_>>();
                assert_eq!(keys(&got), keys(&want), "{m} nodes");
            }
        }
    }
}
