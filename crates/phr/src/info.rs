//! `phr info`: what is in a scene, and what the BVH over it looks like.

use crate::scene_arg::{open_scene, BUILTIN};
use anyhow::Result;
use clap::Args;
use phr_bvh::{sah_cost, tree_stats, Builder, SahConstants};
use phr_render::geometry::Geometry;
use std::time::Instant;

#[derive(Args)]
pub struct InfoArgs {
    /// A scene file (.json), a mesh (.obj, .ply, .gltf, .glb, optionally .gz), `builtin`, or a
    /// scene of scenes/suite by name (sponza, dragon, ...).
    #[arg(default_value = BUILTIN)]
    pub scene: String,
    /// BVH builder: lbvh, phr-fast, phr-hq, phr:ALPHA,DELTA, sweep-sah, binned-sah, sbvh.
    #[arg(long, default_value = "lbvh")]
    pub builder: Builder,
    /// Children per node (PHR builders: 2, 4, 8 or 16).
    #[arg(long, default_value_t = 2)]
    pub branching: u32,
}

pub fn run(args: &InfoArgs) -> Result<()> {
    let load_start = Instant::now();
    let scene = open_scene(&args.scene)?;
    let load_ms = load_start.elapsed().as_secs_f64() * 1e3;
    let builder = args.builder.with_branching(args.branching).map_err(anyhow::Error::msg)?;
    let mut geometry = Geometry::new(&scene);
    let report = geometry.build_report(&builder);
    let mut build = crate::render::describe_build(&builder, &report);
    geometry.set_bvh(report.bvh);
    build += &crate::render::describe_copies(&scene, geometry.build_copies(&builder));
    // As `phr render` does: the memory below is what a still render holds.
    geometry.release_triangles();
    let b = scene.bounds();
    println!("scene       {}", args.scene);
    println!("load        {load_ms:.1} ms");
    println!("triangles   {}", geometry.triangle_count());
    if !scene.instanced.is_empty() {
        let (placed, stored) = scene.instanced_triangle_count();
        println!(
            "copies      {} of {} meshes: {placed} triangles placed, {stored} stored",
            geometry.copy_count(),
            scene.instanced.len()
        );
    }
    println!("spheres     {}", geometry.spheres.len());
    println!("meshes      {}", scene.meshes.len());
    println!("materials   {}", scene.material_names.join(", "));
    println!("views       {}", scene.view_names().join(", "));
    println!(
        "bounds      ({:.4}, {:.4}, {:.4}) .. ({:.4}, {:.4}, {:.4})",
        b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z
    );
    let s = &scene.settings;
    println!("settings    {}x{}, {} spp, max depth {}", s.width, s.height, s.spp, s.max_depth);
    let t = tree_stats(geometry.bvh());
    println!("builder     {build}");
    println!("nodes       {} ({} leaves, up to {} children)", t.nodes, t.leaves, geometry.bvh().max_branching());
    println!("depth       max {}, mean leaf depth {:.1}", t.max_depth, t.mean_leaf_depth);
    println!("leaf size   max {}, mean {:.2}", t.max_leaf_size, t.mean_leaf_size);
    println!(
        "SAH cost    {:.3} (ct=1, ci=1)   {:.3} (ct=2, ci=1, thesis)",
        sah_cost(geometry.bvh(), SahConstants::UNIT),
        sah_cost(geometry.bvh(), SahConstants::THESIS)
    );
    let mem = geometry.memory();
    // Per stored primitive: a mesh placed many times counts once.
    let stored = geometry.prim_count() + scene.instanced_triangle_count().1;
    let per_triangle = |bytes: usize| bytes as f64 / stored.max(1) as f64;
    let mb = |bytes: usize| bytes as f64 / (1 << 20) as f64;
    println!(
        "memory      {:.1} MB: triangles {:.1}, boxes {:.1}, tree {:.1}, wide tree + packed triangles {:.1} \
         ({:.0} B/primitive; what rendering reads, triangles + wide tree + packed triangles, {:.0} B; \
         the packed triangles are a still render's only copy of the vertices)",
        mb(mem.total()),
        mb(mem.triangles),
        mb(mem.boxes),
        mb(mem.tree),
        mb(mem.wide),
        per_triangle(mem.total()),
        per_triangle(mem.wide + mem.triangles)
    );
    match builder.validate(geometry.bvh(), &geometry.boxes) {
        Ok(()) => println!("invariants  ok"),
        Err(e) => {
            println!("invariants  BROKEN: {e}");
            anyhow::bail!("the {} tree breaks its invariants: {e}", builder);
        }
    }
    Ok(())
}
