//! The leaf policy every top-down builder shares (PHR, full-sweep SAH, binned SAH), so that
//! their SAH costs compare: a node becomes a leaf when it holds few enough primitives and the
//! surface area heuristic says intersecting them all is no dearer than splitting.

use crate::metrics::SahConstants;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LeafPolicy {
    /// No leaf holds more primitives than this.
    pub max_leaf_size: u32,
    /// The constants of the termination test.
    pub sah: SahConstants,
}

impl Default for LeafPolicy {
    fn default() -> Self {
        Self { max_leaf_size: 8, sah: SahConstants::UNIT }
    }
}

impl LeafPolicy {
    /// Whether `n` primitives in a box of surface area `area` should form a leaf rather than
    /// be split into children with `Σ A_child · N_child = split_area_count`.
    ///
    /// Leaf: `c_i · n · A`; split: `c_t · A + c_i · Σ A_child · N_child` (MacDonald & Booth).
    #[inline]
    pub fn prefers_leaf(&self, n: u32, area: f32, split_area_count: f32) -> bool {
        n <= 1
            || (n <= self.max_leaf_size
                && self.sah.intersection * n as f32 * area
                    <= self.sah.traversal * area + self.sah.intersection * split_area_count)
    }

    /// Whether `n` primitives must be split whatever the SAH says.
    #[inline]
    pub fn must_split(&self, n: u32) -> bool {
        n > self.max_leaf_size
    }
}

/// The depth from which the top-down builders stop asking the SAH and split by count (an
/// object median), as Embree's builders fall back past their maximum depth.
///
/// On nested or coincident geometry (10⁶ copies of one triangle, the duplicates of scanned
/// and CAD data) the SAH legitimately peels one primitive a level off a cluster, which makes
/// a tree as deep as the input is large: recursion overflows the stack, the traversal's stack
/// grows with the depth, and a full sweep turns quadratic. Past this depth every split halves
/// the primitives, so no tree is deeper than this plus `log2(n)`. Real scenes' SAH trees never
/// reach it (the deepest leaf of PHR-HQ and the full sweep: Sponza 22, the dragon 26), so
/// their trees do not change.
pub const MEDIAN_SPLIT_DEPTH: u32 = 48;
