#!/usr/bin/env python3
"""Embree's side of `phr bench-rays`: closest-hit throughput of Intel Embree (through the
`embreex` package) on exactly the triangles and ray batches phr traced, in the same run; the
`shadow` batch as any-hit queries (`rtcOccluded1`, with each ray's own tfar).

    python3 bench/embree_rays.py DIR --kinds primary,incoherent,diffuse --threads 1,2 --repeats 3

DIR holds what `phr bench-rays` exported for one scene (the format of bench/peers.py):
  triangles.bin      u32 count N, then N x 9 float32 (v0, v1, v2)
  rays_KIND.bin      u32 count M, then M x 6 float32 (origin, direction); tnear = 0
  tfar_KIND.bin      u32 count M, then M float32: each ray's tfar (inf, or the shadow interval)
  hits_KIND.bin      M x (int32 primitive or -1, float32 t): phr's closest hits, to compare

Threads: embreex's `EmbreeScene.run` is a serial loop of `rtcIntersect1` that holds the GIL
(two Python threads on one scene take as long as one), so one process traces on one thread.
For T > 1 threads this script starts T processes (fork), each builds its own copy of the scene,
and after a barrier each traces 1/T of the rays; the time is the slowest process's. That is
Embree's single-ray kernel on T cores, with T copies of the BVH instead of one shared copy.

Writes DIR/embree.json: build time (first commit), per kind the rays, Mrays/s per thread count
(best of --repeats) with embreex's default scene (`mrays_per_s`) and with `robust=True`
(`robust_mrays_per_s`, RTC_SCENE_FLAG_ROBUST: conservative traversal like phr's), and the
agreement of hits with phr's. Exits 3 if numpy or embreex is missing.
"""
import json
import multiprocessing as mp
import sys
import time
from pathlib import Path


def read_counted(path, width, dtype):
    import numpy as np
    data = path.read_bytes()
    count = int(np.frombuffer(data[:4], dtype="<u4")[0])
    return np.frombuffer(data[4:4 + count * width * 4], dtype=dtype).reshape(count, width)


def make_scene(tris, robust=False):
    import numpy as np
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh
    scene = rtcs.EmbreeScene(robust=robust)
    TriangleMesh(scene, tris)
    # embreex commits (builds the BVH) on the first query.
    scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), output=1)
    return scene


def trace(scene, origins, dirs, dists, occluded):
    """One pass: closest hits (rtcIntersect1), or occlusion (rtcOccluded1) within `dists`."""
    if occluded:
        return scene.run(origins, dirs, dists=dists, query="OCCLUDED")
    return scene.run(origins, dirs, output=1)


def worker(tris, origins, dirs, dists, occluded, repeats, robust, barrier, queue, index):
    scene = make_scene(tris, robust)
    times = []
    for _ in range(repeats):
        barrier.wait()
        start = time.perf_counter()
        trace(scene, origins, dirs, dists, occluded)
        times.append(time.perf_counter() - start)
    queue.put((index, times))


def parallel_mrays(tris, origins, dirs, dists, occluded, threads, repeats, robust):
    """Mrays/s of `threads` processes tracing equal shares, best of `repeats`."""
    import numpy as np
    ctx = mp.get_context("fork")
    barrier = ctx.Barrier(threads)
    queue = ctx.Queue()
    parts = np.array_split(np.arange(len(origins)), threads)
    procs = [
        ctx.Process(target=worker, args=(tris, np.ascontiguousarray(origins[p]), np.ascontiguousarray(dirs[p]),
                                         np.ascontiguousarray(dists[p]), occluded, repeats, robust, barrier,
                                         queue, i))
        for i, p in enumerate(parts)
    ]
    for p in procs:
        p.start()
    results = dict(queue.get() for _ in procs)
    for p in procs:
        p.join()
    walls = [max(results[i][r] for i in range(threads)) for r in range(repeats)]
    return len(origins) / min(walls) / 1e6


def main():
    import argparse
    ap = argparse.ArgumentParser(description="phr bench-rays: Embree side")
    ap.add_argument("folder")
    ap.add_argument("--kinds", default="primary,incoherent,diffuse,shadow")
    ap.add_argument("--threads", default="1,2")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    folder = Path(args.folder)
    try:
        import numpy as np
        import embreex  # noqa: F401
    except ImportError as e:
        print(f"embree: skipped, {e.name} is not installed (python3 -m pip install -r bench/requirements.txt)")
        return 3
    tris = read_counted(folder / "triangles.bin", 9, "<f4").reshape(-1, 3, 3).astype(np.float32)
    start = time.perf_counter()
    scene = make_scene(tris)
    build_ms = (time.perf_counter() - start) * 1e3
    robust_scene = make_scene(tris, robust=True)
    threads = [int(t) for t in args.threads.split(",") if t]
    result = {"peer": "embree (embreex)", "triangles": int(len(tris)), "build_ms": build_ms, "kinds": {},
              "threading": "T processes x 1 thread (embreex run() is serial and holds the GIL)"}
    for kind in [k for k in args.kinds.split(",") if k]:
        rays = read_counted(folder / f"rays_{kind}.bin", 6, "<f4")
        origins = np.ascontiguousarray(rays[:, :3])
        dirs = np.ascontiguousarray(rays[:, 3:])
        tfar_file = folder / f"tfar_{kind}.bin"
        dists = (read_counted(tfar_file, 1, "<f4")[:, 0].copy() if tfar_file.exists()
                 else np.full(len(rays), np.inf, np.float32))
        occluded = kind == "shadow"
        entry = {"rays": int(len(rays)), "query": "occluded" if occluded else "intersect",
                 "mrays_per_s": {}, "robust_mrays_per_s": {}}
        for key, robust, sc in (("mrays_per_s", False, scene), ("robust_mrays_per_s", True, robust_scene)):
            for t in threads:
                if t == 1:
                    best = float("inf")
                    for _ in range(args.repeats):
                        start = time.perf_counter()
                        trace(sc, origins, dirs, dists, occluded)
                        best = min(best, time.perf_counter() - start)
                    entry[key]["1"] = len(rays) / best / 1e6
                else:
                    entry[key][str(t)] = parallel_mrays(tris, origins, dirs, dists, occluded, t, args.repeats,
                                                        robust)
        ours = np.frombuffer((folder / f"hits_{kind}.bin").read_bytes(), dtype=[("prim", "<i4"), ("t", "<f4")])
        hit_ours = ours["prim"] >= 0
        if occluded:
            # rtcOccluded1 through embreex: 0 where occluded, -1 where not.
            hit_embree = np.asarray(trace(scene, origins, dirs, dists, True)) >= 0
            entry["hit_agreement"] = float(np.mean(hit_embree == hit_ours))
        else:
            out = trace(scene, origins, dirs, dists, False)
            prim = np.asarray(out["primID"]).astype(np.int64)
            tfar = np.asarray(out["tfar"], dtype=np.float32)
            hit_embree = (prim >= 0) & (prim < len(tris))
            both = hit_embree & hit_ours
            same_t = np.abs(tfar[both] - ours["t"][both]) <= 1e-4 * np.maximum(1.0, np.abs(ours["t"][both]))
            entry["hit_agreement"] = float(np.mean(hit_embree == hit_ours))
            entry["t_agreement"] = float(np.mean(same_t)) if both.any() else 1.0
        result["kinds"][kind] = entry
    (folder / "embree.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
