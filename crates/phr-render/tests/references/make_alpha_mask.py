#!/usr/bin/env python3
"""Makes the `alpha_mask` reference: a leaf-like quad cut out by an MTL `map_d` checker mask
(tiled twice), standing tilted in front of a wall on a floor under a white sky, so that the
camera sees the wall through its holes and the floor shows its patterned shadow; rendered by
Mitsuba 3 with its own `mask` BSDF, whose opacity is the same image.

Writes, next to this script: alpha_mask.png (the mask: 4 x 4 texels, black and white),
alpha_mask.obj and alpha_mask.mtl (the geometry with `vt`; the leaf's material names the
mask with `map_d`), the scene file alpha_mask.json, and alpha_mask_ref.exr /
alpha_mask_ref_var.exr / alpha_mask_ref.png / alpha_mask_ref.json (the reference, as
render_reference.py writes them).

Run from anywhere, with Mitsuba 3 installed (python3 -m pip install mitsuba numpy; the llvm
variant needs libLLVM >= 17, found at DRJIT_LIBLLVM_PATH):

    python3 crates/phr-render/tests/references/make_alpha_mask.py [--spp 4096]

Our mask is an alpha test: the bilinearly filtered coverage against one half. On a black and
white checker that is exactly nearest-texel lookup (the filtered value is
0.5 + 2 (fx - 1/2)(fy - 1/2) between four texels of a checker), which is what the reference's
opacity texture uses, so Mitsuba's stochastic `mask` (opacity 0 or 1 everywhere) cuts the same
holes. The camera, the sky, the integrator and the film come from render_reference.py (the
team's reference renderer in ../shared/reference/tools), which knows no textures; only the
meshes and their BSDFs are made here.
"""

import os

import numpy as np

from reference_run import HERE, quad_mesh, render_meshes, rr, write_quads

# Quads: (name, corners counter-clockwise, uv scale, Kd, masked).
SURFACES = [
    ("floor", [[-1.5, 0, 1.5], [1.5, 0, 1.5], [1.5, 0, -1.5], [-1.5, 0, -1.5]], 1.0, [0.6, 0.6, 0.6], False),
    ("wall", [[-1.5, 0, -1.5], [1.5, 0, -1.5], [1.5, 2, -1.5], [-1.5, 2, -1.5]], 1.0, [0.8, 0.5, 0.3], False),
    ("leaf", [[-0.8, 0.3, 0.4], [0.8, 0.3, 0.4], [0.8, 1.5, -0.1], [-0.8, 1.5, -0.1]], 2.0, [0.2, 0.7, 0.2], True),
]
SCENE = {
    "description": "An alpha mask (MTL map_d, a 4 x 4 checker tiled twice) against Mitsuba 3's mask BSDF: "
                   "a tilted green quad with holes in front of a wall, on a floor, under a white sky; "
                   "made by make_alpha_mask.py",
    "width": 128,
    "height": 128,
    "spp": 4096,
    "max_depth": 8,
    "background": [1.0, 1.0, 1.0],
    "camera": {"position": [0.7, 1.3, 2.8], "look_at": [0.0, 0.7, -0.4], "up": [0, 1, 0], "vfov": 45},
    "objects": [{"type": "obj_mtl", "file": "alpha_mask.obj"}],
}


def mask():
    """4 x 4 texels, row 0 at the top: white (there) where x + y is even, black (a hole)
    elsewhere. A flip of either axis turns the checker over (an even number of rows), so it
    shows."""
    m = np.zeros((4, 4, 3), dtype=np.float32)
    for y in range(4):
        for x in range(4):
            m[y, x] = 1.0 if (x + y) % 2 == 0 else 0.0
    return m


def write_files():
    rr.write_png(os.path.join(HERE, "alpha_mask.png"), mask(), gamma="linear")
    quads = [(name, corners, scale, ["Kd {} {} {}".format(*kd)] + (["map_d alpha_mask.png"] if masked else []))
             for name, corners, scale, kd, masked in SURFACES]
    write_quads("alpha_mask", quads, SCENE)


def meshes(mi):
    """The quads as Mitsuba meshes with the OBJ's texture coordinates, two-sided diffuse as
    render_reference.py makes Lambertian surfaces; the leaf's inside a `mask` BSDF."""
    shapes = {}
    for name, corners, scale, kd, masked in SURFACES:
        bsdf = {"type": "twosided", "material": {"type": "diffuse", "reflectance": {"type": "rgb", "value": kd}}}
        if masked:
            opacity = {"type": "bitmap", "filename": os.path.join(HERE, "alpha_mask.png"),
                       "filter_type": "nearest", "wrap_mode": "repeat", "raw": True}
            bsdf = {"type": "mask", "opacity": opacity, "material": bsdf}
        shapes[name] = quad_mesh(mi, name, corners, scale, bsdf)
    return shapes


if __name__ == "__main__":
    render_meshes(__doc__, SCENE, "alpha_mask", write_files, meshes)
