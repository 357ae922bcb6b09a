#!/usr/bin/env python3
"""Makes the converged references of `phr bench-quality`'s own scenes, next to this script:
images/NAME.exr (the mean), images/NAME_var.exr (the variance of that mean), images/NAME.png
and images/NAME.json (how it was made), as render_reference.py writes them, for

- sponza_textured (scenes/sponza_textured.json): Sponza with its 18 textures under a sky,
  rendered through tools/render_textured.py (render_reference.py with MTL `map_Kd` textures);
- builtin: phr's built-in scene (the Cornell box with the torus knot), written by
  `phr export-reference builtin` into scenes/ (JSON and PLY; not kept in git: `phr
  bench-quality` writes it again) and rendered by render_reference.py.

Mitsuba 3's `path` integrator (light sampling with MIS), llvm_ad_rgb, 256 x 256, 4096 samples
per pixel from seed 0 (the benchmark's Mitsuba runs start at seed 1000000). Needs Mitsuba 3
(python3 -m pip install mitsuba numpy; the llvm variant needs libLLVM >= 17, found at
DRJIT_LIBLLVM_PATH) and a release build of phr:

    cargo build --release && python3 crates/phr-bench/references/make_references.py [--spp 4096] [NAME ...]
"""

import argparse
import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", "..", ".."))
RENDER = os.path.join(ROOT, "tools", "render_textured.py")
SIZE = 256


def export_builtin(phr, spp):
    """phr's built-in scene in the reference renderer's format, in scenes/."""
    subprocess.run([phr, "export-reference", "builtin", "--out", os.path.join(HERE, "scenes"), "--name", "builtin",
                    "--width", str(SIZE), "--height", str(SIZE), "--spp", str(spp)], check=True)


def render(name, opts):
    scene = os.path.join(HERE, "scenes", f"{name}.json")
    out = os.path.join(HERE, "images", name)
    command = [sys.executable, RENDER, scene, "-o", out, "--variant", "llvm_ad_rgb", "--integrator", "path",
               "--spp", str(opts.spp), "--passes", str(opts.passes), "--seed", "0", "--threads", str(opts.threads)]
    print(" ".join(command), flush=True)
    subprocess.run(command, check=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("names", nargs="*", default=["sponza_textured", "builtin"])
    ap.add_argument("--spp", type=int, default=4096)
    ap.add_argument("--passes", type=int, default=64)
    ap.add_argument("--threads", type=int, default=0, help="Mitsuba's threads (default: all cores)")
    ap.add_argument("--phr", default=os.path.join(ROOT, "target", "release", "phr"))
    opts = ap.parse_args()
    for name in opts.names:
        if name == "builtin":
            export_builtin(opts.phr, opts.spp)
        render(name, opts)


if __name__ == "__main__":
    main()
