#!/usr/bin/env python3
"""Makes the `textured` reference: a corner (floor and two walls) with a colour texture, lit
by a white sky, rendered by Mitsuba 3 with its own `bitmap` texture (sRGB, bilinear,
repeating) on meshes carrying the same texture coordinates as textured.obj.

Writes, next to this script: textured.png (the texture: four coloured quadrants with a
gradient, so that a flip or a wrong decoding shows), textured.obj and textured.mtl (the
geometry with `vt`, one `usemtl` per surface: the floor tiles the texture 3 times), the scene
file textured.json, and textured_ref.exr / textured_ref_var.exr / textured_ref.png (the
reference, as render_reference.py writes them).

Run from anywhere, with Mitsuba 3 installed (python3 -m pip install mitsuba numpy; the llvm
variant needs libLLVM >= 17, found at DRJIT_LIBLLVM_PATH):

    python3 crates/phr-render/tests/references/make_textured.py [--spp 4096]

The camera, the sky, the integrator and the film come from render_reference.py (the team's
reference renderer in ../shared/reference/tools), which knows no textures; only the meshes
and their textured BSDFs are made here.
"""

import os

import numpy as np

from reference_run import HERE, quad_mesh, render_meshes, rr, write_quads

# Three quads: (name, corners counter-clockwise seen from the inside, uv scale).
SURFACES = [
    ("floor", [[-1, 0, 1], [1, 0, 1], [1, 0, -1], [-1, 0, -1]], 3.0),
    ("back", [[-1, 0, -1], [1, 0, -1], [1, 2, -1], [-1, 2, -1]], 1.0),
    ("left", [[-1, 0, 1], [-1, 0, -1], [-1, 2, -1], [-1, 2, 1]], 1.0),
]

SCENE = {
    "description": "Textures against Mitsuba 3's bitmap texture: a floor (the texture tiled 3 times, "
                   "wrapping) and two walls with textured.png through OBJ vt coordinates and MTL "
                   "map_Kd, under a white sky; made by make_textured.py",
    "width": 128,
    "height": 128,
    "spp": 4096,
    "max_depth": 8,
    "background": [1.0, 1.0, 1.0],
    "camera": {"position": [1.2, 1.4, 2.6], "look_at": [-0.3, 0.5, -0.4], "up": [0, 1, 0], "vfov": 50},
    "objects": [{"type": "obj_mtl", "file": "textured.obj"}],
}


def texture():
    """16 x 16 sRGB texels, row 0 at the top: red / green over blue / yellow quadrants,
    darkened towards the right."""
    t = np.zeros((16, 16, 3), dtype=np.uint8)
    colours = {(0, 0): (230, 40, 30), (0, 1): (40, 200, 60), (1, 0): (40, 70, 220), (1, 1): (240, 220, 40)}
    for y in range(16):
        for x in range(16):
            c = np.array(colours[(y // 8, x // 8)], dtype=np.float64)
            t[y, x] = np.round(c * (1.0 - 0.6 * x / 15.0))
    return t


def write_files():
    rr.write_png(os.path.join(HERE, "textured.png"), texture().astype(np.float32) / 255.0, gamma="linear")
    entry = ["Kd 0.5 0.5 0.5", "map_Kd textured.png"]
    write_quads("textured", [(name, corners, scale, entry) for name, corners, scale in SURFACES], SCENE)


def textured_meshes(mi):
    """The three quads as Mitsuba meshes with the OBJ's texture coordinates."""
    bitmap = {"type": "bitmap", "filename": os.path.join(HERE, "textured.png"),
              "filter_type": "bilinear", "wrap_mode": "repeat", "raw": False}
    bsdf = {"type": "diffuse", "reflectance": bitmap}
    return {name: quad_mesh(mi, name, corners, scale, bsdf) for name, corners, scale in SURFACES}


if __name__ == "__main__":
    render_meshes(__doc__, SCENE, "textured", write_files, textured_meshes)
