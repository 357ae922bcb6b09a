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

import json
import os

import numpy as np

from reference_run import HERE, mitsuba_dict, options, render_and_write, rr

# Three quads: (name, corners counter-clockwise seen from the inside, uv scale).
SURFACES = [
    ("floor", [[-1, 0, 1], [1, 0, 1], [1, 0, -1], [-1, 0, -1]], 3.0),
    ("back", [[-1, 0, -1], [1, 0, -1], [1, 2, -1], [-1, 2, -1]], 1.0),
    ("left", [[-1, 0, 1], [-1, 0, -1], [-1, 2, -1], [-1, 2, 1]], 1.0),
]
CORNER_UV = [[0, 0], [1, 0], [1, 1], [0, 1]]

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
    lines = ["mtllib textured.mtl"]
    mtl = []
    for k, (name, corners, scale) in enumerate(SURFACES):
        lines += [f"v {x} {y} {z}" for x, y, z in corners]
        lines += [f"vt {u * scale} {v * scale}" for u, v in CORNER_UV]
        i = 4 * k
        lines += [f"usemtl {name}", f"f {i + 1}/{i + 1} {i + 2}/{i + 2} {i + 3}/{i + 3} {i + 4}/{i + 4}"]
        mtl += [f"newmtl {name}", "Kd 0.5 0.5 0.5", "map_Kd textured.png", ""]
    with open(os.path.join(HERE, "textured.obj"), "w") as f:
        f.write("\n".join(lines) + "\n")
    with open(os.path.join(HERE, "textured.mtl"), "w") as f:
        f.write("\n".join(mtl))
    with open(os.path.join(HERE, "textured.json"), "w") as f:
        json.dump(SCENE, f, indent=2)
        f.write("\n")


def textured_meshes(mi):
    """The three quads as Mitsuba meshes with the OBJ's texture coordinates; Mitsuba's bitmap
    has v = 0 at the image's top, OBJ at its bottom: v is flipped, as Mitsuba's OBJ reader
    does."""
    shapes = {}
    for name, corners, scale in SURFACES:
        mesh = mi.Mesh(name, 4, 2, has_vertex_texcoords=True)
        params = mi.traverse(mesh)
        params["vertex_positions"] = np.array(corners, dtype=np.float32).ravel()
        params["faces"] = np.array([0, 1, 2, 0, 2, 3], dtype=np.uint32)
        uv = np.array([[u * scale, 1.0 - v * scale] for u, v in CORNER_UV], dtype=np.float32)
        params["vertex_texcoords"] = uv.ravel()
        params.update()
        bitmap = {"type": "bitmap", "filename": os.path.join(HERE, "textured.png"),
                  "filter_type": "bilinear", "wrap_mode": "repeat", "raw": False}
        mesh.set_bsdf(mi.load_dict({"type": "diffuse", "reflectance": bitmap}))
        shapes[name] = mesh
    return shapes


def main():
    opts = options(__doc__, SCENE["spp"])
    write_files()
    variant, mi, d = mitsuba_dict(opts, dict(SCENE, objects=[]), "path")
    d.update(textured_meshes(mi))
    render_and_write(d, opts, "textured", variant, "path", "make_textured.py")


if __name__ == "__main__":
    main()
