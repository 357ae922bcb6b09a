#!/usr/bin/env python3
"""What the Python binding costs: trace the rays `phr bench-rays` traced, through `phr.Bvh`.

    phr --threads 2 bench-rays --scene scenes/suite/sponza.json --res 1024 --rays 1048576 \\
        --no-embree --export-rays --out /tmp/br
    python3 crates/phr-py/examples/binding_overhead.py /tmp/br/rays/sponza --builder phr-hq

`phr bench-rays` writes the scene's triangles, its ray sets (1M rays each at --res 1024) and
its closest hits. This script builds the same tree (same builder: bench-rays' default is
phr-hq) over the same triangles with `phr.Bvh`, traces each ray set in one call (best of
--repeats, all cores, as bench-rays' wide8 column with --threads equal to the core count),
checks the hits equal bench-rays' own, and prints Mrays/s to set beside bench-rays' table.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import phr


def read_counted(path, width, dtype):
    """A file of `phr bench-rays --export-rays`: a little-endian u32 count, then the rows."""
    data = path.read_bytes()
    count = int(np.frombuffer(data[:4], dtype="<u4")[0])
    return np.frombuffer(data[4 : 4 + count * width * 4], dtype=dtype).reshape(count, width)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", help="a rays/SCENE folder written by phr bench-rays --export-rays")
    ap.add_argument("--builder", default="phr-hq")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--threads", type=int, default=None, help="default: all cores")
    args = ap.parse_args()
    folder = Path(args.folder)
    tris = read_counted(folder / "triangles.bin", 9, "<f4")
    vertices = np.ascontiguousarray(tris.reshape(-1, 3))
    indices = np.arange(len(vertices), dtype=np.uint32).reshape(-1, 3)
    bvh = phr.Bvh(vertices, indices, builder=args.builder, threads=args.threads)
    print(f"{folder.name}: {len(indices)} triangles, {bvh.builder}, build {bvh.build_ms:.1f} ms")
    print(f"{'rays':<11} {'count':>8} {'Mrays/s':>8} {'hits equal':>10}")
    status = 0
    for kind in ["primary", "incoherent", "diffuse"]:
        path = folder / f"rays_{kind}.bin"
        if not path.exists():
            continue
        rays = read_counted(path, 6, "<f4")
        tmax = read_counted(folder / f"tfar_{kind}.bin", 1, "<f4")[:, 0]
        if not np.all(tmax == tmax[0]):
            print(f"{kind}: rays with different tmax, skipped (phr.Bvh.intersect takes one interval)")
            continue
        origins, directions = np.ascontiguousarray(rays[:, :3]), np.ascontiguousarray(rays[:, 3:])
        best = np.inf
        for _ in range(args.repeats):
            start = time.perf_counter()
            t, prim, _ = bvh.intersect(origins, directions, tmax=float(tmax[0]))
            best = min(best, time.perf_counter() - start)
        theirs = np.frombuffer((folder / f"hits_{kind}.bin").read_bytes(), dtype=[("prim", "<i4"), ("t", "<f4")])
        equal = bool(np.array_equal(prim, theirs["prim"].astype(np.int64)) and np.array_equal(t, theirs["t"]))
        status |= not equal
        print(f"{kind:<11} {len(rays):>8} {len(rays) / best / 1e6:8.2f} {str(equal):>10}")
    return status


if __name__ == "__main__":
    sys.exit(main())
