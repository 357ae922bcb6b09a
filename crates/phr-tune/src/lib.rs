//! # phr-tune: choosing PHR's α and δ (thesis chapter 6)
//!
//! PHR trades build time (more refinement, larger α and δ) against trace time (better trees).
//! Which (α, δ) gives the fastest frame depends on the scene, the view and the image size.
//! This crate evaluates PHR builds ([`evaluator`]), scores them ([`objective`]: the thesis's
//! normalised objective `e(α, δ)`, and a predicted frame time in milliseconds), and searches
//! the parameter box ([`SearchBox`]) by [`grid`] search or by [`bayes`]ian optimisation (a Gaussian process
//! with expected improvement). [`tune()`] runs a whole optimisation as the thesis did, with the
//! two normalisation runs and a [`cache`] of their maxima.

pub mod bayes;
pub mod cache;
pub mod evaluator;
pub mod grid;
pub mod objective;
pub mod search_box;
pub mod tune;

pub use evaluator::{Evaluation, PhrEvaluator};
pub use objective::{FrameTimeModel, Objective, ThesisObjective};
pub use search_box::SearchBox;
pub use tune::{tune, Method, TuneOptions, TuneResult};
