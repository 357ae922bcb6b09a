//! The ordered traversal of a [`WideBvh`], generic over the node kernel: one ray at a time
//! ([`run`]), or several interleaved ([`run_interleaved`]: each round visits one node or
//! leaf of every ray in flight, so that one ray's dependent node loads overlap the others'
//! work). Both repeat the same visit, `Walk::step`.
//!
//! One visit for closest and any hit: test all children of the current node at once, and
//! - no child hit: pop;
//! - one child hit: go there (no stack traffic, the common case deep in the tree);
//! - two (closest hit): push the farther, go to the nearer;
//! - more (closest hit): push all but the nearest, farthest first, and go to the nearest. The
//!   AVX2 kernel sorts them without a branch per child ([`super::child_order`]: +5–8 % on
//!   Sponza's and Conference's incoherent rays); the other kernels use an insertion sort on
//!   the keys `t_bits << 32 | slot` and push one child at a time.
//!
//! Any-hit queries push the hit children unsorted (the first hit ends the query wherever it
//! is found) and go to the last hit slot: the builders put a node's children in its slots
//! largest subtree first ([`super::pieces::slots_by_size`]), so a query visits the smallest
//! hit subtree first and pops the others smallest first, Embree's order for shadow rays.
//!
//! A leaf child is a stack entry like a node, with its primitive count, so leaves are tested
//! in entry-distance order too. Popped entries whose entry distance exceeds the closest hit
//! so far (times `ROBUST_SLAB`, as in the binary traversal) are skipped.
//!
//! The stack lives on the call stack when the tree's stack bound (computed by the collapse)
//! fits [`INLINE_STACK`] entries, on the heap otherwise; either way it is sized from the
//! bound, so pushes need no capacity check.

use super::simd::{node_scalar, RayPre};
use super::{Lanes, SimdLevel, WideBvh, WideNode, WideStats, Width};
use crate::aabb::ROBUST_SLAB;
use crate::ray::Ray;
use std::mem::MaybeUninit;

/// Stack entries kept on the call stack.
pub const INLINE_STACK: usize = 128;

#[derive(Clone, Copy)]
struct Entry {
    /// Node index, or first primitive of a leaf.
    child: u32,
    /// 0 for a node, else the leaf's primitive count.
    count: u32,
    t: f32,
}

/// The traversal stack, structure of arrays (one array per [`Entry`] field), so that a SIMD
/// kernel can push all hit children of a node with one vector store per field. Each array
/// has room for `stack_bound + N + 1` entries: the bound holds between node visits, and a
/// vector push writes `N` lanes (only the hit ones count) above it.
struct Stack {
    child: *mut u32,
    count: *mut u32,
    t: *mut f32,
    sp: usize,
}

impl Stack {
    /// # Safety
    /// Room for the entry (see the type's doc).
    #[inline(always)]
    unsafe fn push(&mut self, e: Entry) {
        // SAFETY: the caller guarantees room.
        unsafe {
            self.child.add(self.sp).write(e.child);
            self.count.add(self.sp).write(e.count);
            self.t.add(self.sp).write(e.t);
        }
        self.sp += 1;
    }

    /// # Safety
    /// `sp > 0`.
    #[inline(always)]
    unsafe fn pop(&mut self) -> Entry {
        self.sp -= 1;
        // SAFETY: entries below `sp` were written by pushes.
        unsafe {
            Entry {
                child: self.child.add(self.sp).read(),
                count: self.count.add(self.sp).read(),
                t: self.t.add(self.sp).read(),
            }
        }
    }
}

/// What the traversal does at leaves. Implement it on a type (with `#[inline(always)]` on
/// [`LeafVisitor::visit`]) to have the leaf test compiled into the traversal loop: a closure
/// passed to [`WideBvh::closest_hit_leaves`] is called through a function the compiler may
/// keep out of line (the loop is instantiated once per SIMD level), and every call then
/// spills and reloads the ray's SIMD registers.
pub trait LeafVisitor {
    /// Tests the primitives `prim_indices[first..first + count]`; on hits shrinks `ray.tmax`
    /// (closest hit). Returns whether anything was hit.
    fn visit(&mut self, first: u32, count: u32, ray: &mut Ray) -> bool;

    /// The leaf starting at `first` was pushed, to be visited later: a hint to ask for its
    /// primitive data now.
    #[inline(always)]
    fn prefetch(&self, first: u32) {
        let _ = first;
    }
}

/// Closures as [`LeafVisitor`]s: the leaf test and the prefetch hint.
pub(crate) struct FnLeaves<F, P>(pub F, pub P);

impl<F: FnMut(u32, u32, &mut Ray) -> bool, P: Fn(u32)> LeafVisitor for FnLeaves<F, P> {
    #[inline(always)]
    fn visit(&mut self, first: u32, count: u32, ray: &mut Ray) -> bool {
        (self.0)(first, count, ray)
    }

    #[inline(always)]
    fn prefetch(&self, first: u32) {
        (self.1)(first)
    }
}

/// A node kernel: the box test of [`super::simd`] for one width and level, and the push of
/// several hit children in entry-distance order.
trait Kernel<const N: usize> {
    /// # Safety
    /// The CPU must support the kernel's instructions.
    unsafe fn test(node: &WideNode<N>, r: &RayPre, tmax: f32, t: &mut [f32; N]) -> u32;

    /// Orders the children of `node` in `mask` (at least two) by their entry distances `t`:
    /// pushes all but the nearest, farthest first, and returns the nearest (to visit next).
    /// By default an insertion sort on the keys `t_bits << 32 | slot`, then one push per
    /// child, which also asks for the child's data to be loaded.
    ///
    /// # Safety
    /// The CPU must support the kernel's instructions; room on the stack as [`Stack`] says.
    #[inline(always)]
    unsafe fn push_sorted<V: LeafVisitor>(
        node: &WideNode<N>,
        t: &[f32; N],
        mask: u32,
        nodes: &[WideNode<N>],
        leaves: &V,
        stack: &mut Stack,
    ) -> Entry {
        // Entry distances are >= tmin; for tmin >= 0 their bit patterns order like the
        // floats (a negative tmin only changes the visit order, never the result).
        let mut keys = [0u64; N];
        let mut k = 0;
        let mut m = mask;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let key = (u64::from(t[i].to_bits()) << 32) | i as u64;
            let mut j = k;
            while j > 0 && keys[j - 1] > key {
                keys[j] = keys[j - 1];
                j -= 1;
            }
            keys[j] = key;
            k += 1;
        }
        for &key in keys[1..k].iter().rev() {
            let i = (key & 0xff) as usize;
            // SAFETY: the caller guarantees room.
            unsafe { push(node, i, t[i], nodes, leaves, stack) };
        }
        let i = (keys[0] & 0xff) as usize;
        Entry { child: node.child[i], count: node.count[i], t: t[i] }
    }
}

struct ScalarKernel;
#[cfg(target_arch = "x86_64")]
struct SseKernel;
#[cfg(target_arch = "x86_64")]
struct Avx2Kernel;

impl<const N: usize> Kernel<N> for ScalarKernel {
    #[inline(always)]
    unsafe fn test(node: &WideNode<N>, r: &RayPre, tmax: f32, t: &mut [f32; N]) -> u32 {
        node_scalar(node, r, tmax, t)
    }
}

#[cfg(target_arch = "x86_64")]
impl Kernel<4> for SseKernel {
    #[inline(always)]
    unsafe fn test(node: &WideNode<4>, r: &RayPre, tmax: f32, t: &mut [f32; 4]) -> u32 {
        // SAFETY: SSE is part of the x86_64 baseline.
        unsafe { super::simd::node_sse4(node, r, tmax, t) }
    }
}

#[cfg(target_arch = "x86_64")]
impl Kernel<8> for SseKernel {
    #[inline(always)]
    unsafe fn test(node: &WideNode<8>, r: &RayPre, tmax: f32, t: &mut [f32; 8]) -> u32 {
        // SAFETY: SSE is part of the x86_64 baseline.
        unsafe { super::simd::node_sse8(node, r, tmax, t) }
    }
}

#[cfg(target_arch = "x86_64")]
impl Kernel<8> for Avx2Kernel {
    #[inline(always)]
    unsafe fn test(node: &WideNode<8>, r: &RayPre, tmax: f32, t: &mut [f32; 8]) -> u32 {
        // SAFETY: the caller guarantees AVX2 (this kernel is only selected at SimdLevel::Avx2,
        // which `WideBvh::set_simd` only allows when the CPU has it).
        unsafe { super::simd::node_avx8(node, r, tmax, t) }
    }

    #[inline(always)]
    unsafe fn push_sorted<V: LeafVisitor>(
        node: &WideNode<8>,
        t: &[f32; 8],
        mask: u32,
        _nodes: &[WideNode<8>],
        _leaves: &V,
        stack: &mut Stack,
    ) -> Entry {
        // All hit children go on the stack in one store per array; the nearest is on top.
        // SAFETY: AVX2 as for `test`; the stack has room for 8 more entries, and at least
        // two were pushed.
        unsafe {
            super::child_order::push_sorted_avx8(node, t, mask, stack.child, stack.count, stack.t, stack.sp);
            stack.sp += mask.count_ones() as usize;
            stack.pop()
        }
    }
}

/// One ray's traversal in progress: its stack, its prepared ray, the entry it visits next
/// and whether a leaf has reported a hit. The single-ray loop ([`run`]) steps one walk to its
/// end; the interleaved loop ([`run_interleaved`]) steps several in turn.
struct Walk<const N: usize> {
    stack: Stack,
    pre: RayPre,
    cur: Entry,
    hit: bool,
}

/// Per-ray stack memory: room for `stack_bound + N + 1` entries per array (see [`Stack`]) on
/// the call stack when the tree's bound fits [`INLINE_STACK`] (nodes of up to 16 children),
/// else on the heap.
struct StackRoom {
    child: [MaybeUninit<u32>; ROOM],
    count: [MaybeUninit<u32>; ROOM],
    t: [MaybeUninit<f32>; ROOM],
    heap: (Vec<u32>, Vec<u32>, Vec<f32>),
}

/// Entries per array of an inline stack (array lengths cannot depend on `N`).
const ROOM: usize = INLINE_STACK + 16 + 1;

impl StackRoom {
    #[inline(always)]
    fn new() -> Self {
        Self {
            child: [MaybeUninit::uninit(); ROOM],
            count: [MaybeUninit::uninit(); ROOM],
            t: [MaybeUninit::uninit(); ROOM],
            heap: (Vec::new(), Vec::new(), Vec::new()),
        }
    }

    /// An empty stack in this room for traversing `bvh`.
    #[inline(always)]
    fn stack<const N: usize>(&mut self, bvh: &WideBvh<N>) -> Stack {
        if bvh.stack_bound < INLINE_STACK && N <= 16 {
            Stack {
                child: self.child.as_mut_ptr().cast(),
                count: self.count.as_mut_ptr().cast(),
                t: self.t.as_mut_ptr().cast(),
                sp: 0,
            }
        } else {
            let room = bvh.stack_bound + N + 1;
            let (child, count, t) = &mut self.heap;
            child.reserve_exact(room);
            count.reserve_exact(room);
            t.reserve_exact(room);
            Stack { child: child.as_mut_ptr(), count: count.as_mut_ptr(), t: t.as_mut_ptr(), sp: 0 }
        }
    }
}

/// Whether `ray` may be traversed. A ray with a non-finite origin or direction hits nothing,
/// and must not be traversed: through `inf - inf` or `inf * 0` its slab distances turn NaN,
/// which can make an empty slot (an inverted ±inf box whose child is 0) look hit, and the loop
/// would push the root again and again, past the end of the stack. A finite ray never hits an
/// empty slot, so every pushed entry is a real child and the stack bound holds. One test per
/// ray.
#[inline(always)]
pub(super) fn traversable(ray: &Ray) -> bool {
    ray.origin.is_finite() && ray.dir.is_finite() && ray.inv_dir.is_finite()
}

impl<const N: usize> Walk<N> {
    #[inline(always)]
    fn start(ray: &Ray, stack: Stack) -> Self {
        Self { stack, pre: RayPre::new(ray), cur: Entry { child: 0, count: 0, t: 0.0 }, hit: false }
    }

    /// Visits the current entry (one node's box test, or one leaf) and chooses the next.
    /// Returns false when the walk has ended (stack empty, or an any-hit query found a hit);
    /// `self.hit` then holds the answer. `ANY`: stop at the first leaf that reports a hit.
    /// `COUNT`: fill `stats`.
    ///
    /// # Safety
    /// The CPU must support `K`'s instructions; `nodes` must come from the collapse (child
    /// indices in range, stack bound correct) and the walk's ray must be [`traversable`].
    #[inline(always)]
    unsafe fn step<K: Kernel<N>, const ANY: bool, const COUNT: bool, V: LeafVisitor>(
        &mut self,
        nodes: &[WideNode<N>],
        stack_bound: usize,
        ray: &mut Ray,
        leaves: &mut V,
        stats: &mut WideStats,
    ) -> bool {
        let cur = self.cur;
        let stack = &mut self.stack;
        if cur.count == 0 {
            debug_assert!((cur.child as usize) < nodes.len(), "wide traversal: node index out of range");
            // SAFETY: child indices written by the collapse are in range (validated by
            // `WideBvh::validate` in the tests), and only used slots are visited (see
            // `traversable`).
            let node = unsafe { nodes.get_unchecked(cur.child as usize) };
            // The child references sit after the boxes, in a line the box test does not read:
            // ask for it now, so that its load overlaps the box test instead of following it.
            prefetch_line(node.child.as_ptr().cast());
            if COUNT {
                stats.nodes += 1;
            }
            let mut t = [0.0f32; N];
            // SAFETY: the caller guarantees the kernel's instructions.
            let mask = unsafe { K::test(node, &self.pre, ray.tmax, &mut t) };
            if mask != 0 {
                if mask & (mask - 1) == 0 {
                    let i = mask.trailing_zeros() as usize;
                    self.cur = Entry { child: node.child[i], count: node.count[i], t: t[i] };
                    return true;
                }
                debug_assert!(stack.sp <= stack_bound, "wide traversal: stack bound exceeded");
                if ANY {
                    // Any hit needs no distance order: push the children in slot order (no
                    // sort, no distance compare) and go to the last, the smallest subtree, as
                    // Embree's occlusion traversal does; the pushed ones pop smallest first.
                    let last = 31 - mask.leading_zeros() as usize;
                    let mut m = mask & !(1 << last);
                    while m != 0 {
                        let i = m.trailing_zeros() as usize;
                        m &= m - 1;
                        // SAFETY: see `Stack`.
                        unsafe { push(node, i, t[i], nodes, leaves, stack) };
                    }
                    self.cur = Entry { child: node.child[last], count: node.count[last], t: t[last] };
                    return true;
                }
                let rest = mask & (mask - 1);
                if rest & (rest - 1) == 0 {
                    // Two children (the common case): push the farther, visit the nearer.
                    let (a, b) = (mask.trailing_zeros() as usize, rest.trailing_zeros() as usize);
                    let (near, far) = if t[b] < t[a] { (b, a) } else { (a, b) };
                    // SAFETY: see `Stack`.
                    unsafe { push(node, far, t[far], nodes, leaves, stack) };
                    self.cur = Entry { child: node.child[near], count: node.count[near], t: t[near] };
                    return true;
                }
                // Several children: push all but the nearest, farthest first; go to the nearest.
                // SAFETY: see `Stack`; the caller guarantees the kernel's instructions.
                self.cur = unsafe { K::push_sorted(node, &t, mask, nodes, leaves, stack) };
                return true;
            }
        } else {
            if COUNT {
                stats.leaves += 1;
                stats.prims += cur.count;
            }
            if leaves.visit(cur.child, cur.count, ray) {
                self.hit = true;
                if ANY {
                    return false;
                }
            }
        }
        // Pop the next entry that still starts before the closest hit. (An any-hit query's
        // `tmax` never shrinks, so each entry still starts within it: no compare.)
        loop {
            if stack.sp == 0 {
                return false;
            }
            // SAFETY: `sp > 0`.
            let e = unsafe { stack.pop() };
            if ANY || e.t <= ray.tmax * ROBUST_SLAB {
                self.cur = e;
                return true;
            }
        }
    }
}

/// The traversal loop of one ray. `ANY`: stop at the first leaf that reports a hit. `COUNT`:
/// fill `stats`.
///
/// # Safety
/// The CPU must support `K`'s instructions; `bvh` must be a tree made by the collapse (child
/// indices in range, stack bound correct).
#[inline(always)]
unsafe fn run<const N: usize, K: Kernel<N>, const ANY: bool, const COUNT: bool, V: LeafVisitor>(
    bvh: &WideBvh<N>,
    ray: &mut Ray,
    leaves: &mut V,
    stats: &mut WideStats,
) -> bool {
    if bvh.nodes.is_empty() || !traversable(ray) {
        return false;
    }
    let mut room = StackRoom::new();
    let mut walk = Walk::<N>::start(ray, room.stack(bvh));
    // SAFETY: the caller guarantees the kernel and the tree; the ray is traversable.
    while unsafe { walk.step::<K, ANY, COUNT, V>(&bvh.nodes, bvh.stack_bound, ray, leaves, stats) } {}
    walk.hit
}

/// One slot of the interleaved loop: the ray it walks, that ray's leaf visitor and walk.
struct Slot<const N: usize, V> {
    index: usize,
    ray: Ray,
    visitor: V,
    walk: Walk<N>,
}

/// Closest hits (`ANY`: any hits) of `count` rays, `M` of them traversed at once: each round visits one node or
/// leaf of each busy walk in turn, so that the dependent loads of one ray overlap the work of
/// the others (the single-ray loop waits for each node before it can choose the next), and a
/// finished walk takes the next ray. `start(i)` gives ray `i` and its leaf visitor;
/// `finish(i, ray, visitor, hit)` takes them back when its walk ends (rays that are not
/// [`traversable`] finish at once, without a hit).
///
/// # Safety
/// As [`run`].
#[inline(always)]
unsafe fn run_interleaved<const N: usize, const M: usize, const ANY: bool, K: Kernel<N>, V: LeafVisitor>(
    bvh: &WideBvh<N>,
    count: usize,
    mut start: impl FnMut(usize) -> (Ray, V),
    mut finish: impl FnMut(usize, Ray, V, bool),
) {
    let mut rooms: [StackRoom; M] = std::array::from_fn(|_| StackRoom::new());
    let mut slots: [Option<Slot<N, V>>; M] = std::array::from_fn(|_| None);
    let mut next = 0;
    let mut busy = 0;
    for (slot, room) in slots.iter_mut().zip(rooms.iter_mut()) {
        busy += refill(bvh, count, &mut next, &mut start, &mut finish, slot, room) as usize;
    }
    // One copy of the step per slot (the `if` folds away for slots beyond `M`): each
    // slot's branches then have their own addresses in the branch predictor, instead of one
    // set of branches seeing the rays' outcomes mixed.
    const { assert!(M >= 1 && M <= 4, "1 to 4 rays at once") };
    // A room is borrowed again only to refill its slot, once the walk that pointed into it
    // has ended: a new `&mut` to a room while its walk's stack pointers are live would
    // invalidate them.
    macro_rules! turn {
        ($k:expr) => {
            // SAFETY: as this function's.
            if $k < M && unsafe { turn::<N, K, ANY, V>(bvh, &mut slots[$k]) } {
                let Slot { index, ray, visitor, walk } = slots[$k].take().expect("busy slot");
                finish(index, ray, visitor, walk.hit);
                if !refill(bvh, count, &mut next, &mut start, &mut finish, &mut slots[$k], &mut rooms[$k]) {
                    busy -= 1;
                }
            }
        };
    }
    while busy > 0 {
        turn!(0);
        turn!(1);
        turn!(2);
        turn!(3);
    }
}

/// One slot's turn in [`run_interleaved`]: a step of its walk, then a prefetch of what it
/// visits next. Returns whether the walk ended (the caller then finishes its ray and starts
/// the next); an idle slot does nothing.
///
/// # Safety
/// As [`run_interleaved`].
#[inline(always)]
unsafe fn turn<const N: usize, K: Kernel<N>, const ANY: bool, V: LeafVisitor>(
    bvh: &WideBvh<N>,
    slot: &mut Option<Slot<N, V>>,
) -> bool {
    let Some(s) = slot else { return false };
    let mut stats = WideStats::default();
    // SAFETY: the caller guarantees the kernel and the tree; the slot's ray is traversable.
    let going =
        unsafe { s.walk.step::<K, ANY, false, V>(&bvh.nodes, bvh.stack_bound, &mut s.ray, &mut s.visitor, &mut stats) };
    if going {
        // Ask for what the walk visits next: it comes up again only after the other slots'
        // steps, time enough for the load.
        let cur = s.walk.cur;
        if cur.count == 0 {
            prefetch_node(&bvh.nodes, cur.child);
        } else {
            s.visitor.prefetch(cur.child);
        }
    }
    !going
}

/// Fills `slot` with the next ray (from `*next` on) that needs a walk, finishing the others
/// at once; returns whether it found one.
#[inline(always)]
fn refill<const N: usize, V>(
    bvh: &WideBvh<N>,
    count: usize,
    next: &mut usize,
    start: &mut impl FnMut(usize) -> (Ray, V),
    finish: &mut impl FnMut(usize, Ray, V, bool),
    slot: &mut Option<Slot<N, V>>,
    room: &mut StackRoom,
) -> bool {
    while *next < count {
        let index = *next;
        *next += 1;
        let (ray, visitor) = start(index);
        if bvh.nodes.is_empty() || !traversable(&ray) {
            finish(index, ray, visitor, false);
            continue;
        }
        let walk = Walk::start(&ray, room.stack(bvh));
        *slot = Some(Slot { index, ray, visitor, walk });
        return true;
    }
    false
}

/// Pushes child `i` of `node` (entry distance `t`) and asks for its data to be loaded: the
/// node's box rows, or the leaf's primitives through the visitor.
///
/// # Safety
/// Room on the stack (see [`Stack`]).
#[inline(always)]
unsafe fn push<const N: usize, V: LeafVisitor>(
    node: &WideNode<N>,
    i: usize,
    t: f32,
    nodes: &[WideNode<N>],
    leaves: &V,
    stack: &mut Stack,
) {
    if node.count[i] == 0 {
        prefetch_node(nodes, node.child[i]);
    } else {
        leaves.prefetch(node.child[i]);
    }
    // SAFETY: the caller guarantees room for the entry.
    unsafe { stack.push(Entry { child: node.child[i], count: node.count[i], t }) };
}

/// Asks for the cache line at `p` (a hint; never faults).
#[inline(always)]
fn prefetch_line(p: *const i8) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: prefetching is a hint and never faults, whatever the address.
    unsafe {
        std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p)
    };
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Asks for the box rows of node `i` (popped later) to be loaded into the cache.
#[inline(always)]
pub(super) fn prefetch_node<const N: usize>(nodes: &[WideNode<N>], i: u32) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let p = nodes.as_ptr().wrapping_add(i as usize).cast::<i8>();
        for line in 0..std::mem::size_of::<WideNode<N>>() / 64 {
            // SAFETY: prefetching is a hint and never faults, whatever the address.
            unsafe { _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(64 * line)) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (nodes, i);
}

/// AVX2 entry points: the whole loop compiled with AVX2 enabled, so the kernel inlines.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn run_avx2_8<const ANY: bool, const COUNT: bool, V: LeafVisitor>(
    bvh: &WideBvh<8>,
    ray: &mut Ray,
    leaves: &mut V,
    stats: &mut WideStats,
) -> bool {
    // SAFETY: AVX2 is enabled here, which the caller guarantees the CPU has.
    unsafe { run::<8, Avx2Kernel, ANY, COUNT, V>(bvh, ray, leaves, stats) }
}

/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn run_avx2_4<const ANY: bool, const COUNT: bool, V: LeafVisitor>(
    bvh: &WideBvh<4>,
    ray: &mut Ray,
    leaves: &mut V,
    stats: &mut WideStats,
) -> bool {
    // SAFETY: SSE is baseline; AVX2 (VEX encoding) is what the caller guarantees.
    unsafe { run::<4, SseKernel, ANY, COUNT, V>(bvh, ray, leaves, stats) }
}

/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn run_interleaved_avx2_8<const M: usize, const ANY: bool, V: LeafVisitor>(
    bvh: &WideBvh<8>,
    count: usize,
    start: impl FnMut(usize) -> (Ray, V),
    finish: impl FnMut(usize, Ray, V, bool),
) {
    // SAFETY: AVX2 is enabled here, which the caller guarantees the CPU has.
    unsafe { run_interleaved::<8, M, ANY, Avx2Kernel, V>(bvh, count, start, finish) }
}

/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn run_interleaved_avx2_4<const M: usize, const ANY: bool, V: LeafVisitor>(
    bvh: &WideBvh<4>,
    count: usize,
    start: impl FnMut(usize) -> (Ray, V),
    finish: impl FnMut(usize, Ray, V, bool),
) {
    // SAFETY: SSE is baseline; AVX2 (VEX encoding) is what the caller guarantees.
    unsafe { run_interleaved::<4, M, ANY, SseKernel, V>(bvh, count, start, finish) }
}

pub mod sealed {
    use super::*;

    /// Dispatch from a [`SimdLevel`] to the kernels of one width.
    pub trait Sealed<const N: usize> {
        fn run<const ANY: bool, const COUNT: bool, V: LeafVisitor>(
            bvh: &WideBvh<N>,
            ray: &mut Ray,
            leaves: &mut V,
            stats: &mut WideStats,
        ) -> bool;

        fn run_interleaved<const M: usize, const ANY: bool, V: LeafVisitor>(
            bvh: &WideBvh<N>,
            count: usize,
            start: impl FnMut(usize) -> (Ray, V),
            finish: impl FnMut(usize, Ray, V, bool),
        );
    }
}

impl sealed::Sealed<4> for Lanes<4> {
    #[inline]
    fn run<const ANY: bool, const COUNT: bool, V: LeafVisitor>(
        bvh: &WideBvh<4>,
        ray: &mut Ray,
        leaves: &mut V,
        stats: &mut WideStats,
    ) -> bool {
        match bvh.simd() {
            // SAFETY (all arms): `WideBvh::set_simd` never selects a level the CPU lacks, and
            // the tree comes from the collapse.
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => unsafe { run_avx2_4::<ANY, COUNT, V>(bvh, ray, leaves, stats) },
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Sse => unsafe { run::<4, SseKernel, ANY, COUNT, V>(bvh, ray, leaves, stats) },
            _ => unsafe { run::<4, ScalarKernel, ANY, COUNT, V>(bvh, ray, leaves, stats) },
        }
    }

    #[inline]
    fn run_interleaved<const M: usize, const ANY: bool, V: LeafVisitor>(
        bvh: &WideBvh<4>,
        count: usize,
        start: impl FnMut(usize) -> (Ray, V),
        finish: impl FnMut(usize, Ray, V, bool),
    ) {
        match bvh.simd() {
            // SAFETY (all arms): as for `run`.
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => unsafe { run_interleaved_avx2_4::<M, ANY, V>(bvh, count, start, finish) },
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Sse => unsafe { run_interleaved::<4, M, ANY, SseKernel, V>(bvh, count, start, finish) },
            _ => unsafe { run_interleaved::<4, M, ANY, ScalarKernel, V>(bvh, count, start, finish) },
        }
    }
}

impl sealed::Sealed<8> for Lanes<8> {
    #[inline]
    fn run<const ANY: bool, const COUNT: bool, V: LeafVisitor>(
        bvh: &WideBvh<8>,
        ray: &mut Ray,
        leaves: &mut V,
        stats: &mut WideStats,
    ) -> bool {
        match bvh.simd() {
            // SAFETY (all arms): as for width 4.
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => unsafe { run_avx2_8::<ANY, COUNT, V>(bvh, ray, leaves, stats) },
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Sse => unsafe { run::<8, SseKernel, ANY, COUNT, V>(bvh, ray, leaves, stats) },
            _ => unsafe { run::<8, ScalarKernel, ANY, COUNT, V>(bvh, ray, leaves, stats) },
        }
    }

    #[inline]
    fn run_interleaved<const M: usize, const ANY: bool, V: LeafVisitor>(
        bvh: &WideBvh<8>,
        count: usize,
        start: impl FnMut(usize) -> (Ray, V),
        finish: impl FnMut(usize, Ray, V, bool),
    ) {
        match bvh.simd() {
            // SAFETY (all arms): as for `run`.
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Avx2 => unsafe { run_interleaved_avx2_8::<M, ANY, V>(bvh, count, start, finish) },
            #[cfg(target_arch = "x86_64")]
            SimdLevel::Sse => unsafe { run_interleaved::<8, M, ANY, SseKernel, V>(bvh, count, start, finish) },
            _ => unsafe { run_interleaved::<8, M, ANY, ScalarKernel, V>(bvh, count, start, finish) },
        }
    }
}

impl Width<4> for Lanes<4> {}
impl Width<8> for Lanes<8> {}
