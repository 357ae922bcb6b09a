//! The box of PHR parameters a search covers, and the thesis's box, defined once.

use crate::grid::linspace;

/// A box of PHR parameters: α from `lower[0]` to `upper[0]`, δ from `lower[1]` to `upper[1]`.
/// Grid search evaluates points of it; Bayesian optimisation searches it, and its two corners
/// are the thesis's normalisation runs (the lowest parameters give the worst tree, the
/// highest the most build work).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SearchBox {
    pub lower: [f64; 2],
    pub upper: [f64; 2],
}

impl SearchBox {
    /// The thesis's box (section 6.2): α ∈ [0.4, 0.55], δ ∈ [6, 9], the span of its 4 × 4
    /// grid ([`crate::grid::THESIS_ALPHAS`] × [`crate::grid::THESIS_DELTAS`]). Every search
    /// of the project covers it unless told otherwise (`phr tune`'s default grid, `phr
    /// bench`'s PHR-grid and PHR-BO, `phr bench-tune`, the viewer's "tune" button), so their
    /// optima compare.
    pub const THESIS: Self = Self { lower: [0.4, 6.0], upper: [0.55, 9.0] };

    /// The smallest box holding every `(α, δ)` of `alphas × deltas` (both non-empty).
    pub fn spanning(alphas: &[f64], deltas: &[f64]) -> Self {
        let lo = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = |v: &[f64]| v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        Self { lower: [lo(alphas), lo(deltas)], upper: [hi(alphas), hi(deltas)] }
    }

    /// `n` evenly spaced α and `n` evenly spaced δ from corner to corner.
    pub fn grid(&self, n: usize) -> (Vec<f64>, Vec<f64>) {
        (linspace(self.lower[0], self.upper[0], n), linspace(self.lower[1], self.upper[1], n))
    }

    /// Maps a point of the box to the unit square (a flat axis maps to 0).
    pub fn to_unit(&self, x: [f64; 2]) -> [f64; 2] {
        [0, 1].map(|i| {
            let span = self.upper[i] - self.lower[i];
            if span > 0.0 {
                (x[i] - self.lower[i]) / span
            } else {
                0.0
            }
        })
    }

    /// Maps a point of the unit square into the box.
    pub fn from_unit(&self, u: [f64; 2]) -> [f64; 2] {
        [0, 1].map(|i| self.lower[i] + u[i] * (self.upper[i] - self.lower[i]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{THESIS_ALPHAS, THESIS_DELTAS};

    #[test]
    fn the_thesis_box_spans_the_thesis_grid() {
        assert_eq!(SearchBox::spanning(&THESIS_ALPHAS, &THESIS_DELTAS), SearchBox::THESIS);
        let (alphas, deltas) = SearchBox::THESIS.grid(4);
        for (a, b) in alphas.iter().zip(THESIS_ALPHAS).chain(deltas.iter().zip(THESIS_DELTAS)) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
    }

    #[test]
    fn unit_square_round_trip_and_flat_axes() {
        let b = SearchBox { lower: [0.2, 3.0], upper: [0.6, 3.0] };
        let u = b.to_unit([0.4, 3.0]);
        assert!((u[0] - 0.5).abs() < 1e-12 && u[1] == 0.0, "{u:?}");
        let x = b.from_unit([0.25, 0.7]);
        assert!((x[0] - 0.3).abs() < 1e-12 && x[1] == 3.0);
    }
}
