#!/usr/bin/env python3
"""Makes the `environment` reference: a diffuse ball and a mirror ball on a grey ground under
an HDR environment map (a sky with a small bright sun and a red patch near the horizon, so
that a wrong orientation, a flip or a mis-sampled sun shows), turned 30 degrees about +y,
rendered by Mitsuba 3 with its own `envmap` emitter on the same image.

Writes, next to this script: environment.exr (the map, 64 x 32, linear RGB), the scene file
environment.json, and environment_ref.exr / environment_ref_var.exr / environment_ref.png /
environment_ref.json (the reference, as render_reference.py writes them).

Run from anywhere, with Mitsuba 3 installed (python3 -m pip install mitsuba numpy; the llvm
variant needs libLLVM >= 17, found at DRJIT_LIBLLVM_PATH):

    python3 crates/phr-render/tests/references/make_environment.py [--spp 4096]

The camera, the objects and the film come from render_reference.py (the team's reference
renderer in ../shared/reference/tools), which knows no environment maps; only the `envmap`
emitter is added here. The integrator is Mitsuba's `prb_basic`, BSDF sampling only: the
thesis's estimator, whose noise per sample the tests compare ours with (with a small sun it
is far noisier than a light-sampling estimator, hence the many samples).
"""

import json
import math
import os

import numpy as np

from reference_run import HERE, mitsuba_dict, options, render_and_write, rr

ROTATE = 30.0

SCENE = {
    "description": "An HDR environment map (environment.exr, a sky with a sun and a red patch, turned "
                   "30 degrees about +y) against Mitsuba 3's envmap emitter: a diffuse ball and a mirror "
                   "ball on a grey ground; made by make_environment.py",
    "width": 96,
    "height": 96,
    "spp": 16384,
    "max_depth": 8,
    "background": {"type": "environment", "file": "environment.exr", "rotate": ROTATE},
    "camera": {"position": [0, 1.2, 3.2], "look_at": [0, 0.4, 0], "up": [0, 1, 0], "vfov": 40},
    "materials": {
        "ground": {"type": "lambertian", "albedo": [0.6, 0.6, 0.6]},
        "clay": {"type": "lambertian", "albedo": [0.8, 0.4, 0.25]},
        "mirror": {"type": "metal", "albedo": [0.9, 0.9, 0.9], "fuzz": 0.0},
    },
    "objects": [
        {"type": "quad", "Q": [-3, 0, 3], "u": [6, 0, 0], "v": [0, 0, -6], "material": "ground"},
        {"type": "sphere", "center": [-0.6, 0.5, 0], "radius": 0.5, "material": "clay"},
        {"type": "sphere", "center": [0.6, 0.5, 0], "radius": 0.5, "material": "mirror"},
    ],
}


def environment():
    """64 x 32 texels, row 0 straight up: blue at the zenith fading to a pale horizon, brown
    ground below it, a 3 x 2 sun of radiance ~60 at u = 0.3, 50 degrees from the zenith, and a
    red patch just above the horizon at u = 0.8."""
    w, h = 64, 32
    img = np.zeros((h, w, 3), dtype=np.float32)
    for y in range(h):
        theta = math.pi * y / (h - 1)  # where the lookup puts row y
        if theta < math.pi / 2:
            a = theta / (math.pi / 2)
            img[y, :] = (1 - a) * np.array([0.25, 0.45, 1.0]) + a * np.array([0.9, 0.9, 1.0])
        else:
            img[y, :] = [0.3, 0.25, 0.2]
    sun_row = int(50.0 / 180.0 * h)
    img[sun_row:sun_row + 2, 19:22] = [60.0, 55.0, 45.0]
    img[13:15, 50:54] = [3.0, 0.2, 0.1]
    return img


def write_files():
    rr.write_exr(os.path.join(HERE, "environment.exr"), environment())
    with open(os.path.join(HERE, "environment.json"), "w") as f:
        json.dump(SCENE, f, indent=2)
        f.write("\n")


def main():
    opts = options(__doc__, SCENE["spp"])
    write_files()
    # render_reference.py knows constant and gradient skies only: a black one, then the map.
    variant, mi, d = mitsuba_dict(opts, dict(SCENE, background=[0.0, 0.0, 0.0]), "prb_basic")
    d["environment"] = {"type": "envmap", "filename": os.path.join(HERE, "environment.exr"),
                        "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], ROTATE)}
    render_and_write(d, opts, "environment", variant, "prb_basic", "make_environment.py")


if __name__ == "__main__":
    main()
