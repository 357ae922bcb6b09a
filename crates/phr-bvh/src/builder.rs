//! One name for every builder, so front ends can offer a choice (`--builder phr-hq`) and
//! benchmarks can loop over them.
//!
//! Names: `lbvh`, `phr-fast` (α = 0.5, δ = 6), `phr-hq` (α = 0.55, δ = 9), `phr:α,δ`,
//! `phr-thesis:α,δ` (PHR with the thesis's auxiliary-node weights and initial-cut cap),
//! `sweep-sah`, `binned-sah`, `sbvh`.

use crate::aabb::Aabb;
use crate::binned_sah::{build_binned_sah, BinnedSahOptions};
use crate::lbvh::{build_lbvh, LbvhOptions};
use crate::node::Bvh;
use crate::phr::{build_phr, AuxTree, PhrOptions, PhrStats};
use crate::sbvh::{build_sbvh, SbvhOptions};
use crate::sweep_sah::{build_sweep_sah, SweepSahOptions};
use glam::Vec3;
use std::fmt;
use std::str::FromStr;
use std::time::{Duration, Instant};

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Builder {
    /// [`crate::lbvh`] with leaves of at most `max_leaf_size` primitives.
    Lbvh(LbvhOptions),
    /// [`crate::phr`] over its auxiliary tree ([`AuxTree`]: the LBVH with one primitive per leaf).
    Phr(PhrOptions),
    SweepSah(SweepSahOptions),
    BinnedSah(BinnedSahOptions),
    /// [`crate::sbvh`]: binned SAH with spatial splits (a primitive may be in several leaves).
    Sbvh(SbvhOptions),
}

impl Default for Builder {
    fn default() -> Self {
        Builder::Lbvh(LbvhOptions::default())
    }
}

/// A build with its timings.
#[derive(Clone, Debug)]
pub struct BuildReport {
    pub bvh: Bvh,
    /// Time of the auxiliary LBVH (PHR only).
    pub aux_time: Duration,
    /// Time of the builder proper (for PHR: without the auxiliary LBVH).
    pub build_time: Duration,
    /// PHR's statistics (Σ|cut|).
    pub phr: Option<PhrStats>,
}

impl BuildReport {
    pub fn total_time(&self) -> Duration {
        self.aux_time + self.build_time
    }
}

impl Builder {
    /// The names of the builders with fixed parameters, in the order front ends list them
    /// (`phr:ALPHA,DELTA` and `phr-thesis:ALPHA,DELTA` name PHR with others).
    pub const NAMES: &'static [&'static str] = &["lbvh", "phr-fast", "phr-hq", "sweep-sah", "binned-sah", "sbvh"];

    pub const PHR_FAST: Builder = Builder::Phr(PhrOptions::FAST);
    pub const PHR_HQ: Builder = Builder::Phr(PhrOptions::HQ);

    pub fn build(&self, boxes: &[Aabb]) -> Bvh {
        self.build_timed(boxes).bvh
    }

    pub fn build_timed(&self, boxes: &[Aabb]) -> BuildReport {
        self.build_timed_with_triangles(boxes, &[])
    }

    /// [`Builder::build`] for primitives of which the first `triangles.len()` are these
    /// triangles (with `boxes[..triangles.len()]` their boxes): the SBVH may cut them (never
    /// the others); the other builders need the boxes only.
    pub fn build_with_triangles(&self, boxes: &[Aabb], triangles: &[[Vec3; 3]]) -> Bvh {
        self.build_timed_with_triangles(boxes, triangles).bvh
    }

    pub fn build_timed_with_triangles(&self, boxes: &[Aabb], triangles: &[[Vec3; 3]]) -> BuildReport {
        let start = Instant::now();
        match self {
            Builder::Phr(o) => {
                let aux = AuxTree::build(boxes);
                let aux_time = start.elapsed();
                let (bvh, stats) = build_phr(&aux, o);
                BuildReport { bvh, aux_time, build_time: start.elapsed() - aux_time, phr: Some(stats) }
            }
            _ => {
                let bvh = match self {
                    Builder::Lbvh(o) => build_lbvh(boxes, *o),
                    Builder::SweepSah(o) => build_sweep_sah(boxes, o),
                    Builder::BinnedSah(o) => build_binned_sah(boxes, o),
                    Builder::Sbvh(o) => build_sbvh(boxes, triangles, o),
                    Builder::Phr(_) => unreachable!(),
                };
                BuildReport { bvh, aux_time: Duration::ZERO, build_time: start.elapsed(), phr: None }
            }
        }
    }

    /// The largest leaf this builder makes (for [`crate::validate()`]).
    pub fn max_leaf_size(&self) -> u32 {
        match self {
            Builder::Lbvh(o) => o.max_leaf_size,
            Builder::Phr(o) => o.leaf.max_leaf_size,
            Builder::SweepSah(o) => o.leaf.max_leaf_size,
            Builder::BinnedSah(o) => o.leaf.max_leaf_size,
            Builder::Sbvh(o) => o.leaf.max_leaf_size,
        }
    }

    /// Whether this builder may put a primitive in several leaves, each enclosing a part of it
    /// (check its trees with [`crate::validate::validate_split`]).
    pub fn splits_primitives(&self) -> bool {
        matches!(self, Builder::Sbvh(o) if o.max_references > 1.0)
    }

    /// Checks a tree this builder made over `boxes` ([`crate::validate()`], or
    /// [`crate::validate::validate_split`] for the SBVH).
    pub fn validate(&self, bvh: &Bvh, boxes: &[Aabb]) -> Result<(), String> {
        if self.splits_primitives() {
            crate::validate::validate_split(bvh, boxes, self.max_leaf_size())
        } else {
            crate::validate(bvh, boxes, self.max_leaf_size())
        }
    }

    /// Sets the branching factor (2 to 16). Only PHR builds wide trees natively.
    pub fn with_branching(self, k: u32) -> Result<Self, String> {
        match self {
            Builder::Phr(o) if (2..=16).contains(&k) => Ok(Builder::Phr(PhrOptions { branching: k, ..o })),
            Builder::Phr(_) => Err(format!("branching factor {k} is outside 2..=16")),
            _ if k == 2 => Ok(self),
            _ => Err(format!("{self} builds binary trees only; branching {k} needs a PHR builder")),
        }
    }
}

impl fmt::Display for Builder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Builder::Lbvh(_) => write!(f, "lbvh"),
            Builder::Phr(o) => {
                let name = if *o == (PhrOptions { branching: o.branching, ..PhrOptions::thesis(o.alpha, o.delta) }) {
                    format!("phr-thesis:{},{}", o.alpha, o.delta)
                } else if (o.alpha, o.delta) == (PhrOptions::FAST.alpha, PhrOptions::FAST.delta) {
                    "phr-fast".to_string()
                } else if (o.alpha, o.delta) == (PhrOptions::HQ.alpha, PhrOptions::HQ.delta) {
                    "phr-hq".to_string()
                } else {
                    format!("phr:{},{}", o.alpha, o.delta)
                };
                if o.branching == 2 {
                    write!(f, "{name}")
                } else {
                    write!(f, "{name} (k={})", o.branching)
                }
            }
            Builder::SweepSah(_) => write!(f, "sweep-sah"),
            Builder::BinnedSah(_) => write!(f, "binned-sah"),
            Builder::Sbvh(_) => write!(f, "sbvh"),
        }
    }
}

impl FromStr for Builder {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let s = s.trim().to_ascii_lowercase();
        for (prefix, make) in
            [("phr:", PhrOptions::with as fn(f32, f32) -> PhrOptions), ("phr-thesis:", PhrOptions::thesis)]
        {
            if let Some(params) = s.strip_prefix(prefix) {
                let parse = |v: &str| v.trim().parse::<f32>().ok().filter(|x| x.is_finite() && *x >= 0.0);
                return match params.split_once(',').map(|(a, d)| (parse(a), parse(d))) {
                    Some((Some(alpha), Some(delta))) => Ok(Builder::Phr(make(alpha, delta))),
                    _ => Err(format!(
                        "\"{s}\": expected {prefix}ALPHA,DELTA with two non-negative numbers, e.g. {prefix}0.5,6"
                    )),
                };
            }
        }
        match s.as_str() {
            "lbvh" => Ok(Builder::Lbvh(LbvhOptions::default())),
            "phr-fast" | "phr" => Ok(Builder::PHR_FAST),
            "phr-hq" => Ok(Builder::PHR_HQ),
            "sweep-sah" => Ok(Builder::SweepSah(SweepSahOptions::default())),
            "binned-sah" => Ok(Builder::BinnedSah(BinnedSahOptions::default())),
            "sbvh" => Ok(Builder::Sbvh(SbvhOptions::default())),
            other => Err(format!(
                "unknown builder \"{other}\" (available: lbvh, phr-fast, phr-hq, phr:ALPHA,DELTA, phr-thesis:ALPHA,DELTA, sweep-sah, binned-sah, sbvh)"
            )),
        }
    }
}
