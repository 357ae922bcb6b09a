//! One name for every builder, so front ends can offer a choice (`--builder lbvh`) and
//! benchmarks can loop over them.

use crate::aabb::Aabb;
use crate::lbvh::{build_lbvh, LbvhOptions};
use crate::node::Bvh;
use std::fmt;
use std::str::FromStr;

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Builder {
    /// [`crate::lbvh`] with leaves of at most `max_leaf_size` primitives.
    Lbvh(LbvhOptions),
}

impl Default for Builder {
    fn default() -> Self {
        Builder::Lbvh(LbvhOptions::default())
    }
}

impl Builder {
    pub fn build(&self, boxes: &[Aabb]) -> Bvh {
        match self {
            Builder::Lbvh(o) => build_lbvh(boxes, *o),
        }
    }

    /// The largest leaf this builder makes (for [`crate::validate`]).
    pub fn max_leaf_size(&self) -> u32 {
        match self {
            Builder::Lbvh(o) => o.max_leaf_size,
        }
    }
}

impl fmt::Display for Builder {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Builder::Lbvh(_) => write!(f, "lbvh"),
        }
    }
}

impl FromStr for Builder {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.to_ascii_lowercase().as_str() {
            "lbvh" => Ok(Builder::Lbvh(LbvhOptions::default())),
            other => Err(format!("unknown builder \"{other}\" (available: lbvh)")),
        }
    }
}
