"""Hits against Intel Embree's (through the embreex package) on the bunny, when embreex is
installed (the test runner installs it; a skip says why it could not)."""

import numpy as np
import phr
import pytest
from conftest import rays_towards

embreex = pytest.importorskip("embreex", reason="embreex is not installed (python3 -m pip install embreex)")


def test_bunny_hits_equal_embrees(bunny):
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    vertices, indices = bunny
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, vertices[indices])
    origins, directions = rays_towards(vertices, 100_000, seed=11)
    embree = scene.run(origins, directions, output=1)
    embree_prim = np.asarray(embree["primID"]).astype(np.int64)
    embree_t = np.asarray(embree["tfar"], np.float32)
    for builder in ["phr-hq", "sbvh"]:
        t, prim, _ = phr.Bvh(vertices, indices, builder=builder).intersect(origins, directions)
        hit = prim >= 0
        assert 0.3 < hit.mean() < 0.95
        # Embree's default (non-robust) test may differ on rays that graze an edge.
        assert np.mean(hit == (embree_prim >= 0)) > 0.999
        both = hit & (embree_prim >= 0)
        assert np.mean(prim[both] == embree_prim[both]) > 0.999
        np.testing.assert_allclose(t[both], embree_t[both], rtol=1e-4)
