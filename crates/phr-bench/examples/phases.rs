use phr_bvh::binned_sah::build_binned_sah;
use phr_bvh::phr::{build_phr, AuxTree, PhrOptions};
use phr_bvh::*;
use std::time::Instant;
fn med(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}
fn main() {
    let dir = phr_bench::suite::shared_scenes_dir(None).unwrap();
    let name = std::env::args().nth(1).unwrap_or("dragon/dragon_vrip.ply".into());
    let (g, _) = phr_bench::suite::open_mesh(&dir, &name).unwrap();
    let boxes = g.boxes.clone();
    let tris = g.triangles.clone();
    let t = |f: &mut dyn FnMut()| {
        med((0..7)
            .map(|_| {
                let s = Instant::now();
                f();
                s.elapsed().as_secs_f64() * 1e3
            })
            .collect())
    };
    let mut aux = AuxTree::build(&boxes);
    println!(
        "aux lbvh      {:8.2}",
        t(&mut || {
            aux = AuxTree::build(&boxes);
        })
    );
    println!("refit         {:8.2}", t(&mut || aux.refit(&boxes)));
    if std::env::var("ONLY_BINNED").is_ok() {
        for _ in 0..5 {
            std::hint::black_box(build_binned_sah(&boxes, &Default::default()));
        }
        return;
    }
    if std::env::var("ONLY_COLLAPSE").is_ok() {
        let bvh = build_phr(&aux, &PhrOptions::FAST).0;
        let mut w = WideBvh::<8>::from_bvh(&bvh);
        for _ in 0..30 {
            w.rebuild(&bvh);
        }
        return;
    }
    if let Ok(k) = std::env::var("ONLY_PHR") {
        let o =
            if k == "hq" { PhrOptions::HQ } else { PhrOptions { branching: k.parse().unwrap(), ..PhrOptions::FAST } };
        for _ in 0..6 {
            std::hint::black_box(build_phr(&aux, &o));
        }
        return;
    }
    for (k, base) in [(2u32, PhrOptions::FAST), (3, PhrOptions::HQ), (8, PhrOptions::FAST)] {
        let o = PhrOptions { branching: k.min(2).max(if k == 8 { 8 } else { 2 }), ..base };
        let k = if k == 3 { "2 hq".to_string() } else { k.to_string() };
        let mut bvh = Bvh::default();
        println!(
            "phr-fast k={k}  {:8.2}",
            t(&mut || {
                bvh = build_phr(&aux, &o).0;
            })
        );
        let mut w = WideBvh::<8>::from_bvh(&bvh);
        println!("  collapse    {:8.2}", t(&mut || w.rebuild(&bvh)));
        let mut p = PackedTriangles::new(&w.prim_indices, &tris);
        println!("  repack      {:8.2}", t(&mut || p.repack(&w.prim_indices, &tris)));
        println!("  sah {:.3} nodes {}", sah_cost(&bvh, SahConstants::UNIT), w.nodes.len());
    }
}
#[allow(dead_code)]
fn only_phr() {}
