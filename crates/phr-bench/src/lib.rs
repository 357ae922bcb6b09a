//! The evaluation as a library: what the `phr bench*` commands measure, written once.
//!
//! - [`suite`]: the scene suite of `scenes/suite` and the thesis's benchmark setting;
//! - [`stats`]: medians and spreads of repeated measurements;
//! - [`frame`]: timed 1-spp frames of our renderer;
//! - [`mitsuba`]: the same frame rendered by Mitsuba 3 (the peer of the frame benchmark).
//!
//! The command-line front end parses arguments, calls these, and prints.

pub mod frame;
pub mod frame_report;
pub mod mitsuba;
pub mod stats;
pub mod suite;

pub use stats::Stat;
