"""What the make_*.py scripts next to this file share: their command line, Mitsuba 3's setup
through render_reference.py (the team's reference renderer in ../shared/reference/tools),
and writing a reference as render_reference.py writes them (NAME_ref.exr, NAME_ref_var.exr,
NAME_ref.png and NAME_ref.json)."""

import argparse
import atexit
import json
import os
import shutil
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
TOOLS = os.path.join(HERE, "..", "..", "..", "..", "..", "shared", "reference", "tools")
sys.path.insert(0, TOOLS)
import render_reference as rr  # noqa: E402


def options(doc, spp):
    """The scripts' command line: --spp, --passes, --variant."""
    ap = argparse.ArgumentParser(description=doc.split("\n\n")[0])
    ap.add_argument("--spp", type=int, default=spp)
    ap.add_argument("--passes", type=int, default=16)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    return ap.parse_args()


def mitsuba_dict(opts, scene, integrator):
    """Sets Mitsuba's variant up and returns (the variant, the mitsuba module, `scene` as
    render_reference.py makes it a Mitsuba scene dictionary with `integrator`)."""
    variant = rr.setup_variant(opts.variant)
    rr.register_rtiow_plugins()
    build = argparse.Namespace(max_depth=None, integrator=integrator, bsdfs="builtin", rr=False,
                               scenes_dir=None, ray_offset=-1.0)
    # The meshes render_reference.py writes for inline objects go to a scratch folder,
    # removed when the script ends.
    scratch = tempfile.mkdtemp(prefix="phr-reference-")
    atexit.register(shutil.rmtree, scratch, ignore_errors=True)
    return variant, rr.mi, rr.build_mitsuba_dict(scene, build, scratch)


def render_and_write(d, opts, name, variant, integrator, made_by):
    """Renders `d` and writes the reference `name` next to this file."""
    mean, var, timings = rr.render(d, opts.spp, opts.passes)
    prefix = os.path.join(HERE, f"{name}_ref")
    rr.write_exr(prefix + ".exr", mean)
    rr.write_exr(prefix + "_var.exr", var)
    rr.write_png(prefix + ".png", mean)
    side = {"scene": f"{name}.json", "spp": opts.spp, "passes": opts.passes, "variant": variant,
            "integrator": integrator, "timings": timings, "made_by": made_by}
    with open(prefix + ".json", "w") as f:
        json.dump(side, f, indent=2)
        f.write("\n")
    print(f"wrote {prefix}.exr ({opts.spp} spp, {variant})")
