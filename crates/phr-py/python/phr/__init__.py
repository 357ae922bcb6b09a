"""phr: progressive BVH refinement, from numpy.

Build any of phr's BVHs over a triangle mesh and trace rays through it (``Bvh``), choose
PHR's alpha and delta for a mesh (``tune``), and path trace scene files (``Scene``,
``render``). Every long call releases the GIL and runs on all cores (or on ``threads``).

>>> import numpy as np, phr
>>> v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
>>> bvh = phr.Bvh(v, np.array([[0, 1, 2]], np.uint32), builder="phr-hq")
>>> t, prim, uv = bvh.intersect(np.array([[0.2, 0.2, 1]], np.float32), np.array([[0, 0, -1]], np.float32))
>>> float(t[0]), int(prim[0])
(1.0, 0)
"""

from ._phr import BUILDERS, Bvh, Scene, __version__, tune

__all__ = ["BUILDERS", "Bvh", "Scene", "__version__", "render", "tune"]


def render(scene, **options):
    """Opens ``scene`` and renders it once: ``Scene(scene).render(**options)`` (width, height,
    spp, view, seed, max_depth, builder, integrator, denoiser, threads), the linear mean as float32 of shape
    (height, width, 3)."""
    return Scene(scene).render(**options)
