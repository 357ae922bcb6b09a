#!/usr/bin/env python3
"""Peers for `phr bench --peers`: Intel Embree (through the `embreex` package) on exactly the
triangles and rays phr traced, and Mitsuba 3 rendering the same frame, in the same run.

    python3 bench/peers.py DIR [--scene SCENE.json --res N --reference-tool PATH --scenes-dir DIR]

DIR holds what `phr bench --peers` exported for one scene:
  triangles.bin      u32 count N, then N x 9 float32 (v0, v1, v2)
  rays_KIND.bin      u32 count M, then M x 6 float32 (origin, direction), KIND = primary, diffuse
  hits_KIND.bin      M x (int32 primitive or -1, float32 t): phr's closest hits, to compare

Writes DIR/peers.json: Embree's build time (scene commit), closest-hit Mrays/s per ray kind
(embreex traces on one thread), and the agreement with phr's hits. With --scene, and when the
`mitsuba` package imports, also the time Mitsuba 3 takes for the same frame (first view, 1 spp,
through shared/reference/tools/render_reference.py, which reads the same JSON format). Exits 3
with a message if numpy or embreex is missing.
"""
import json
import sys
import time
from pathlib import Path


def read_counted(path, width, dtype):
    import numpy as np
    data = path.read_bytes()
    count = int(np.frombuffer(data[:4], dtype="<u4")[0])
    return np.frombuffer(data[4:4 + count * width * 4], dtype=dtype).reshape(count, width)


def mitsuba_frame(folder, scene_path, res, tool, scenes_dir):
    """Renders the scene's first view at 1 spp with Mitsuba 3; returns its timings or a reason."""
    try:
        import mitsuba  # noqa: F401
    except ImportError:
        return {"skipped": "mitsuba is not installed (python3 -m pip install mitsuba)"}
    import subprocess
    scene = json.loads(Path(scene_path).read_text())
    views = scene.get("views") or {}
    if "camera" not in scene and views:
        scene["camera"] = next(iter(views.values()))
    scene.update({"width": res, "height": res, "spp": 1, "background": [1, 1, 1]})
    for m in scene.get("materials", {}).values():
        m.clear()
        m.update({"type": "lambertian", "albedo": [0.7, 0.7, 0.7]})
    local = folder / "mitsuba_scene.json"
    local.write_text(json.dumps(scene))
    cmd = [sys.executable, str(tool), str(local), "-o", str(folder / "mitsuba"), "--spp", "1", "--passes", "1",
           "--res", f"{res}x{res}", "--max-depth", str(scene.get("max_depth", 6)), "--scenes-dir", str(scenes_dir), "--quiet"]
    run = subprocess.run(cmd, capture_output=True, text=True)
    if run.returncode != 0:
        return {"skipped": "render_reference.py failed: " + (run.stderr or run.stdout).strip()[-300:]}
    meta = json.loads((folder / "mitsuba.json").read_text())
    return {"variant": meta.get("variant"), "integrator": meta.get("integrator"), "timings": meta.get("timings")}


def main():
    import argparse
    ap = argparse.ArgumentParser(description="phr bench peers")
    ap.add_argument("folder")
    ap.add_argument("--scene")
    ap.add_argument("--res", type=int, default=256)
    ap.add_argument("--reference-tool")
    ap.add_argument("--scenes-dir")
    args = ap.parse_args()
    folder = Path(args.folder)
    try:
        import numpy as np
        from embreex import rtcore_scene as rtcs
        from embreex.mesh_construction import TriangleMesh
    except ImportError as e:
        print(f"peers: skipped, {e.name} is not installed (python3 -m pip install -r bench/requirements.txt)")
        return 3
    tris = read_counted(folder / "triangles.bin", 9, "<f4").reshape(-1, 3, 3).astype(np.float32)
    scene = rtcs.EmbreeScene()
    start = time.perf_counter()
    TriangleMesh(scene, tris)
    # embreex commits the scene on its first query: time one ray to include the BVH build.
    scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32), output=1)
    build_ms = (time.perf_counter() - start) * 1e3
    result = {"peer": "embree (embreex)", "triangles": int(len(tris)), "build_ms": build_ms, "threads": 1}
    for kind in ("primary", "diffuse"):
        path = folder / f"rays_{kind}.bin"
        if not path.exists():
            continue
        rays = read_counted(path, 6, "<f4")
        origins = np.ascontiguousarray(rays[:, :3])
        dirs = np.ascontiguousarray(rays[:, 3:])
        best = float("inf")
        for _ in range(3):
            start = time.perf_counter()
            out = scene.run(origins, dirs, output=1)
            best = min(best, time.perf_counter() - start)
        prim = np.asarray(out["primID"]).astype(np.int64)
        tfar = np.asarray(out["tfar"], dtype=np.float32)
        ours = np.frombuffer((folder / f"hits_{kind}.bin").read_bytes(), dtype=[("prim", "<i4"), ("t", "<f4")])
        hit_embree = prim >= 0
        hit_ours = ours["prim"] >= 0
        both = hit_embree & hit_ours
        same_t = np.abs(tfar[both] - ours["t"][both]) <= 1e-4 * np.maximum(1.0, np.abs(ours["t"][both]))
        result[kind] = {
            "rays": int(len(rays)),
            "mrays_per_s": len(rays) / best / 1e6,
            "hit_agreement": float(np.mean(hit_embree == hit_ours)),
            "t_agreement": float(np.mean(same_t)) if both.any() else 1.0,
        }
    if args.scene and args.reference_tool and Path(args.reference_tool).is_file():
        result["mitsuba"] = mitsuba_frame(folder, args.scene, args.res, args.reference_tool, args.scenes_dir)
    (folder / "peers.json").write_text(json.dumps(result, indent=1))
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
