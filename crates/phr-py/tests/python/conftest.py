"""Shared fixtures: the repository, the shared scenes, the `phr` binary, a brute-force tracer."""

import os
from pathlib import Path

import numpy as np
import phr
import pytest

REPO = Path(__file__).resolve().parents[4]


@pytest.fixture(scope="session")
def shared() -> Path:
    path = Path(os.environ.get("PHR_SHARED", REPO.parent / "shared"))
    if not (path / "scenes").is_dir():
        pytest.fail(f"the shared scenes are not at {path}; set PHR_SHARED")
    return path


@pytest.fixture(scope="session")
def phr_bin() -> Path:
    """The command line the module must agree with (`cargo build --release -p phr`)."""
    path = Path(os.environ.get("PHR_BIN", REPO / "target" / "release" / "phr"))
    if not path.is_file():
        pytest.fail(f"no phr binary at {path}: build it (cargo build --release -p phr) or set PHR_BIN")
    return path


@pytest.fixture(scope="session")
def bunny(shared):
    """The Stanford bunny (69,451 triangles) as (vertices, indices), loaded by phr's PLY reader."""
    return phr.Scene(str(shared / "scenes" / "bunny" / "bun_zipper.ply")).triangles()


def brute_force(vertices, indices, origins, directions, tmin=0.0, tmax=np.inf, chunk=64):
    """Closest hits by testing every triangle (Möller–Trumbore in float64): (t, prim, second),
    with t = inf and prim = -1 on a miss, and `second` the distance of the next-closest
    triangle hit (to tell ties apart)."""
    tri = vertices.astype(np.float64)[indices]
    v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    n = len(origins)
    t_best = np.full(n, np.inf)
    t_second = np.full(n, np.inf)
    prim = np.full(n, -1, np.int64)
    for s in range(0, n, chunk):
        o = origins[s : s + chunk, None, :].astype(np.float64)
        d = directions[s : s + chunk, None, :].astype(np.float64)
        p = np.cross(d, e2[None])
        det = np.einsum("rtk,tk->rt", p, e1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            sv = o - v0[None]
            u = np.einsum("rtk,rtk->rt", sv, p) * inv
            q = np.cross(sv, e1[None])
            v = np.einsum("rtk,rtk->rt", d, q) * inv
            t = np.einsum("tk,rtk->rt", e2, q) * inv
        hit = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > tmin) & (t <= tmax)
        t = np.where(hit, t, np.inf)
        order = np.argsort(t, axis=1, kind="stable")
        rows = np.arange(len(t))
        t_best[s : s + chunk] = t[rows, order[:, 0]]
        if t.shape[1] > 1:
            t_second[s : s + chunk] = t[rows, order[:, 1]]
        prim[s : s + chunk] = np.where(np.isfinite(t_best[s : s + chunk]), order[:, 0], -1)
    return t_best, prim, t_second


def rays_towards(vertices, count, seed, spread=0.6):
    """`count` rays from a sphere around the mesh towards random points near its centre."""
    rng = np.random.default_rng(seed)
    lo, hi = vertices.min(0), vertices.max(0)
    centre, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo))
    u = rng.normal(size=(count, 3))
    origins = centre + radius * u / np.linalg.norm(u, axis=1, keepdims=True)
    targets = centre + spread * (hi - lo) * (rng.random((count, 3)) - 0.5)
    return origins.astype(np.float32), (targets - origins).astype(np.float32)
