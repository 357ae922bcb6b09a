"""Type stubs of the phr extension module (see the docstrings of the Rust side for details)."""

from typing import Any, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

__version__: str
BUILDERS: Sequence[str]
"""The builders with fixed parameters; ``phr:ALPHA,DELTA`` names PHR with others."""

class Bvh:
    """A BVH over a triangle mesh, traced as phr's renderer traces it (8-wide, SIMD)."""

    def __init__(
        self,
        vertices: npt.NDArray[Any],
        indices: npt.NDArray[Any],
        builder: str = "phr-fast",
        alpha: Optional[float] = None,
        delta: Optional[float] = None,
        branching: int = 2,
        threads: Optional[int] = None,
    ) -> None:
        """Builds over float vertices of shape (n, 3) and integer indices of shape (m, 3)
        (float32 and uint32, C-contiguous, are read without a copy). ``builder``: one of
        ``BUILDERS`` or ``phr:ALPHA,DELTA``; ``alpha``/``delta`` override a PHR builder's;
        ``branching`` 2 to 16 (PHR only); ``threads``: None for all cores, 1 to trace on the
        calling thread (several Python threads then trace at once), n for a pool of n threads.
        Inputs are read in place with the GIL released: do not write to them during a call."""
    @property
    def build_ms(self) -> float:
        """The last build's time in ms (PHR: its auxiliary tree included)."""
    @property
    def aux_ms(self) -> float:
        """The auxiliary tree's part of ``build_ms`` (PHR only)."""
    @property
    def wide_ms(self) -> float:
        """Time to make the traced 8-wide tree and pack its triangles, ms."""
    @property
    def builder(self) -> str:
        """The builder's name, as ``Bvh(builder=...)`` takes it."""
    @property
    def branching(self) -> int: ...
    def __len__(self) -> int: ...
    def refit(self, vertices: npt.NDArray[Any]) -> float:
        """Moves the vertices (same count) and refits the tree; returns ms."""
    def rebuild(self) -> float:
        """Builds again over the current vertices (PHR: from its refitted auxiliary tree);
        returns the build's ms."""
    def stats(self, traversal: float = 1.0, intersection: float = 1.0) -> dict[str, Any]:
        """``sah_cost``, ``build_cost`` (Σ|cut|, PHR only), ``nodes``, ``leaves``, ``depth``,
        ``mean_leaf_depth``, ``max_leaf_size``, ``mean_leaf_size``, ``wide_nodes``, timings."""
    def intersect(
        self, origins: npt.NDArray[Any], directions: npt.NDArray[Any], tmin: float = 0.0, tmax: float = ...
    ) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.int64], npt.NDArray[np.float32]]:
        """Closest hits: ``(t, prim, uv)``; t = inf and prim = -1 on a miss; uv of shape (n, 2)."""
    def occluded(
        self, origins: npt.NDArray[Any], directions: npt.NDArray[Any], tmin: float = 0.0, tmax: float = ...
    ) -> npt.NDArray[np.bool_]:
        """Whether anything is hit within (tmin, tmax] along each ray."""

class Scene:
    """A scene file, mesh, ``"builtin"`` or suite scene name, loaded once."""

    def __init__(self, scene: str) -> None: ...
    @property
    def views(self) -> list[str]: ...
    @property
    def triangle_count(self) -> int: ...
    @property
    def sphere_count(self) -> int: ...
    @property
    def settings(self) -> dict[str, int]: ...
    def triangles(self) -> Tuple[npt.NDArray[np.float32], npt.NDArray[np.uint32]]:
        """Every triangle of the scene's meshes: vertices (n, 3) and indices (m, 3)."""
    def render(
        self,
        width: Optional[int] = None,
        height: Optional[int] = None,
        spp: Optional[int] = None,
        view: Optional[str] = None,
        seed: int = 0,
        max_depth: Optional[int] = None,
        builder: str = "sbvh",
        integrator: str = "path",
        denoiser: str = "none",
        threads: Optional[int] = None,
    ) -> npt.NDArray[np.float32]:
        """Path traces as ``phr render`` does; the linear mean, shape (height, width, 3).

        ``integrator``: ``"path"`` samples the lights with MIS (the default),
        ``"implicit"`` is the thesis's estimator. The raw mean (``phr render --linear``)
        unless ``denoiser="atrous"`` (``phr render --out``)."""

def render(scene: str, **options: Any) -> npt.NDArray[np.float32]:
    """``Scene(scene).render(**options)``."""

def tune(
    vertices: npt.NDArray[Any],
    indices: npt.NDArray[Any],
    width: int = 256,
    height: int = 256,
    method: str = "bo",
    objective: str = "thesis",
    budget: int = 20,
    seed: int = 0,
    alphas: Optional[Sequence[float]] = None,
    deltas: Optional[Sequence[float]] = None,
    omega_p: float = ...,
    omega_r: float = ...,
    time_budget_ms: Optional[int] = None,
    threads: Optional[int] = None,
) -> dict[str, Any]:
    """Chooses PHR's alpha and delta (``"bo"`` or ``"grid"``; ``"thesis"`` or ``"frame-time"``)."""
