#!/usr/bin/env python3
"""Compare phr's BVH builders on a mesh: SAH cost against build time, next to Embree's build.

    python3 -m pip install ./crates/phr-py trimesh matplotlib embreex
    python3 crates/phr-py/examples/compare_builders.py ../shared/scenes/bunny/bun_zipper.ply --out builders.png

Loads the mesh with trimesh, builds a BVH with every phr builder (and PHR over a few alpha,
delta pairs), plots each build's SAH cost (traversal 1, intersection 1) against its build
time, draws Embree's build time (through embreex, which includes its Python-side conversion;
embreex does not expose Embree's tree, so it has no SAH cost), and checks that the closest
hits of every tree equal Embree's on random rays. Exits 1 if they disagree.
"""

import argparse
import sys
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import phr  # noqa: E402
import trimesh  # noqa: E402


def random_rays(vertices, count, seed=0):
    """Rays from a sphere around the mesh towards random points in its central half."""
    rng = np.random.default_rng(seed)
    lo, hi = vertices.min(0), vertices.max(0)
    centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
    u = rng.normal(size=(count, 3))
    origins = centre + radius * u / np.linalg.norm(u, axis=1, keepdims=True)
    targets = centre + 0.5 * (hi - lo) * (rng.random((count, 3)) - 0.5)
    return origins.astype(np.float32), (targets - origins).astype(np.float32)


def embree_build(vertices, faces, origins, directions):
    """Embree's build time (ms, through embreex) and its closest hits on the rays, or None."""
    try:
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh
    except ImportError:
        print("embreex is not installed (python3 -m pip install embreex): Embree skipped")
        return None
    scene = rtcs.EmbreeScene()
    start = time.perf_counter()
    TriangleMesh(scene, vertices[faces])
    # embreex builds the tree on the first query: time one ray with it.
    scene.run(origins[:1], directions[:1], output=1)
    build_ms = (time.perf_counter() - start) * 1e3
    start = time.perf_counter()
    hits = scene.run(origins, directions, output=1)
    trace_s = time.perf_counter() - start
    return build_ms, np.asarray(hits["primID"]).astype(np.int64), len(origins) / trace_s / 1e6


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mesh", help="a mesh file trimesh reads (.ply, .obj, .glb, ...)")
    ap.add_argument("--out", default="compare_builders.png", help="the plot (.png, .svg, .pdf)")
    ap.add_argument("--rays", type=int, default=200_000, help="random rays for the hit check")
    ap.add_argument("--repeats", type=int, default=3, help="builds per builder (the median is plotted) and traces (the best is printed)")
    args = ap.parse_args()

    mesh = trimesh.load(args.mesh, force="mesh", process=False)
    vertices = np.ascontiguousarray(mesh.vertices, dtype=np.float32)
    faces = np.ascontiguousarray(mesh.faces, dtype=np.uint32)
    print(f"{args.mesh}: {len(faces)} triangles")
    origins, directions = random_rays(vertices, args.rays)

    builds = [(name, {}) for name in phr.BUILDERS]
    # PHR between and beyond its two presets (phr-fast: 0.5, 6; phr-hq: 0.55, 9).
    builds += [(f"phr:{a},{d}", {}) for a, d in [(0.4, 6), (0.45, 7), (0.5, 8), (0.6, 10)]]
    results = []
    print(f"{'builder':<14} {'build ms':>9} {'SAH':>8} {'Mrays/s':>8} {'agree':>7}")
    embree = embree_build(vertices, faces, origins, directions)
    failed = False
    for name, options in builds:
        times = []
        for _ in range(args.repeats):
            bvh = phr.Bvh(vertices, faces, builder=name, **options)
            times.append(bvh.build_ms)
        build_ms = float(np.median(times))
        sah = bvh.stats()["sah_cost"]
        best = float("inf")
        for _ in range(args.repeats):
            start = time.perf_counter()
            _, prim, _ = bvh.intersect(origins, directions)
            best = min(best, time.perf_counter() - start)
        mrays = len(origins) / best / 1e6
        agree = float("nan")
        if embree is not None:
            agree = float(np.mean(prim == embree[1]))
            failed |= agree < 0.999
        results.append((name, build_ms, sah))
        print(f"{name:<14} {build_ms:9.1f} {sah:8.2f} {mrays:8.2f} {agree:7.4f}")
    if embree is not None:
        print(f"{'embree':<14} {embree[0]:9.1f} {'-':>8} {embree[2]:8.2f} (embreex: one thread, build includes conversion)")

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for name, build_ms, sah in results:
        phr_like = name.startswith("phr")
        ax.scatter(build_ms, sah, marker="o" if phr_like else "s", color="C0" if phr_like else "C1")
        ax.annotate(name, (build_ms, sah), textcoords="offset points", xytext=(5, 3), fontsize=8)
    if embree is not None:
        ax.axvline(embree[0], color="C3", linestyle="--", label="Embree build (embreex, incl. conversion)")
        ax.legend(loc="upper right", fontsize=8)
    ax.set_xscale("log")
    ax.set_xlabel("build time, ms (median, log scale)")
    ax.set_ylabel("SAH cost (traversal 1, intersection 1)")
    ax.set_title(f"{args.mesh.split('/')[-1]}: {len(faces)} triangles")
    fig.tight_layout()
    fig.savefig(args.out, dpi=120)
    print(f"wrote {args.out}")
    if failed:
        print("error: some builder's hits disagree with Embree's on more than 0.1 % of the rays")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
