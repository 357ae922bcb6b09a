//! Fuzzing the builders with arbitrary triangle soups: bytes become triangles (floats up to
//! ±1e18, the renderer's range: huge, tiny, subnormal, zero, repeated; runs of identical and
//! degenerate triangles), boxed as the renderer boxes them (`triangle_bounds`, which holds the
//! triangle test's edge slack), and every builder, branching factor and the wide collapse must
//! give a valid tree whose closest hits equal brute force. Any other float (up to ±3e38,
//! infinities, NaN), which loaders refuse, must still not make a builder panic.
//!
//! CI runs a short smoke with a fixed seed; `PHR_FUZZ_SECONDS=600` runs longer (see
//! `common/mutate.rs`).

mod common;
#[path = "common/mutate.rs"]
mod mutate;

use common::*;
use glam::Vec3;
use phr_bvh::triangle::triangle_bounds;
use phr_bvh::{Builder, Ray, WideBvh};
use std::time::Duration;

/// Triangles from bytes: 4 bytes a coordinate, with a palette of special values so that
/// duplicates and extremes are common.
fn soup(bytes: &[u8], finite: bool) -> Vec<[Vec3; 3]> {
    const SPECIAL: [f32; 10] = [0.0, -0.0, 1.0, -1.0, 1e-40, 3e38, -3e38, 1e18, 0.5, 1e-20];
    const RANGE: f32 = 1e18;
    let coords: Vec<f32> = bytes
        .chunks_exact(4)
        .map(|c| {
            let bits = u32::from_le_bytes([c[0], c[1], c[2], c[3]]);
            let x = if bits >> 28 == 0xf { SPECIAL[(bits % 10) as usize] } else { f32::from_bits(bits) };
            let in_range = x.abs() <= RANGE;
            if finite && !in_range {
                (bits % 1000) as f32
            } else {
                x
            }
        })
        .collect();
    coords
        .chunks_exact(9)
        .map(|c| [Vec3::new(c[0], c[1], c[2]), Vec3::new(c[3], c[4], c[5]), Vec3::new(c[6], c[7], c[8])])
        .collect()
}

fn builders() -> Vec<Builder> {
    let mut b: Vec<Builder> =
        ["lbvh", "phr-fast", "phr-hq", "sweep-sah", "binned-sah", "sbvh"].iter().map(|s| s.parse().unwrap()).collect();
    b.push(Builder::PHR_HQ.with_branching(8).unwrap());
    b
}

fn check_finite_soup(bytes: &[u8]) {
    let tris = soup(bytes, true);
    let boxes: Vec<phr_bvh::Aabb> = tris.iter().map(|&[a, b, c]| triangle_bounds(a, b, c)).collect();
    let mut rng = Rng::new(bytes.len() as u64);
    for builder in builders() {
        let bvh = builder.build_with_triangles(&boxes, &tris);
        if tris.is_empty() {
            continue;
        }
        builder.validate(&bvh, &boxes).unwrap_or_else(|e| panic!("{builder}: {e}"));
        let wide = WideBvh::<8>::from_bvh(&bvh);
        let valid = if builder.splits_primitives() { wide.validate_split(&boxes) } else { wide.validate(&boxes) };
        valid.unwrap_or_else(|e| panic!("{builder}, wide: {e}"));
        let packed = phr_bvh::PackedTriangles::new(&wide.prim_indices, &tris);
        let bounds = bvh.root_bounds();
        let rays: Vec<Ray> = if bounds.extent().is_finite() { random_rays(bounds, 8, &mut rng) } else { Vec::new() };
        for ray in rays {
            let expected = brute_force(&tris, &ray);
            assert_eq!(bvh_hit(&bvh, &tris, &ray), expected, "{builder}: binary");
            assert_eq!(wide.closest_triangle(&packed, &ray).map(|(p, h)| (h.t, p)), expected, "{builder}: wide");
        }
    }
}

fn check_any_soup(bytes: &[u8]) {
    let tris = soup(bytes, false);
    let boxes: Vec<phr_bvh::Aabb> = tris.iter().map(|&[a, b, c]| triangle_bounds(a, b, c)).collect();
    for builder in builders() {
        let bvh = builder.build_with_triangles(&boxes, &tris);
        let _ = WideBvh::<8>::from_bvh(&bvh);
    }
}

#[test]
fn builders_survive_arbitrary_soups() {
    let budget = mutate::budget(Duration::from_secs(4));
    let crash_dir = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("fuzz-crashes");
    let mut rng = Rng::new(11);
    // Seeds: a random soup, a grid with shared vertices, and identical triangles, as bytes.
    let as_bytes = |tris: &[[Vec3; 3]]| -> Vec<u8> {
        tris.iter().flat_map(|t| t.iter().flat_map(|v| v.to_array())).flat_map(f32::to_le_bytes).collect()
    };
    let seeds = vec![
        as_bytes(&random_soup(60, 1.0, &mut rng)),
        as_bytes(&vec![[Vec3::ZERO, Vec3::X, Vec3::Y]; 40]),
        as_bytes(&random_soup(30, 1e6, &mut rng)),
    ];
    let (runs, crashes) = mutate::fuzz("builders", &seeds, &[], budget, &crash_dir, check_finite_soup);
    assert!(crashes.is_empty(), "soups that break a builder: {crashes:#?}");
    let (_, crashes) = mutate::fuzz("builders-non-finite", &seeds, &[], budget / 2, &crash_dir, check_any_soup);
    assert!(crashes.is_empty(), "non-finite soups that panic a builder: {crashes:#?}");
    assert!(runs > 10, "only {runs} runs");
}

/// Replays one saved input with the panic message shown:
/// `PHR_FUZZ_REPLAY=target/tmp/fuzz-crashes/builders-0.bin cargo test --release -p phr-bvh --test fuzz_builders replay -- --ignored`.
#[test]
#[ignore = "replays the input named by PHR_FUZZ_REPLAY"]
fn replay() {
    let path = std::env::var("PHR_FUZZ_REPLAY").expect("set PHR_FUZZ_REPLAY to a saved input");
    let bytes = std::fs::read(&path).unwrap();
    check_finite_soup(&bytes);
    check_any_soup(&bytes);
}
