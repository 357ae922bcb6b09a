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


CORNER_UV = [[0, 0], [1, 0], [1, 1], [0, 1]]


def write_quads(name, quads, scene):
    """Writes NAME.obj (one quad per `(material, corners counter-clockwise, uv scale)` of
    `quads`, each with its `vt` corners (0, 0) to (scale, scale) and its own `usemtl`),
    NAME.mtl from `quads`' MTL lines (`(material, lines)`) and the scene file NAME.json."""
    lines = [f"mtllib {name}.mtl"]
    mtl = []
    for k, (material, corners, scale, entry) in enumerate(quads):
        lines += [f"v {x} {y} {z}" for x, y, z in corners]
        lines += [f"vt {u * scale} {v * scale}" for u, v in CORNER_UV]
        i = 4 * k
        lines += [f"usemtl {material}", f"f {i + 1}/{i + 1} {i + 2}/{i + 2} {i + 3}/{i + 3} {i + 4}/{i + 4}"]
        mtl += [f"newmtl {material}"] + entry + [""]
    with open(os.path.join(HERE, f"{name}.obj"), "w") as f:
        f.write("\n".join(lines) + "\n")
    with open(os.path.join(HERE, f"{name}.mtl"), "w") as f:
        f.write("\n".join(mtl))
    with open(os.path.join(HERE, f"{name}.json"), "w") as f:
        json.dump(scene, f, indent=2)
        f.write("\n")


def quad_mesh(mi, name, corners, scale, bsdf):
    """A quad of `write_quads` as a Mitsuba mesh with the OBJ's texture coordinates (v
    flipped: Mitsuba's bitmap has v = 0 at the image's top, OBJ at its bottom, as Mitsuba's
    OBJ reader flips it) and the BSDF made from the dictionary `bsdf`."""
    import numpy as np
    mesh = mi.Mesh(name, 4, 2, has_vertex_texcoords=True)
    params = mi.traverse(mesh)
    params["vertex_positions"] = np.array(corners, dtype=np.float32).ravel()
    params["faces"] = np.array([0, 1, 2, 0, 2, 3], dtype=np.uint32)
    uv = np.array([[u * scale, 1.0 - v * scale] for u, v in CORNER_UV], dtype=np.float32)
    params["vertex_texcoords"] = uv.ravel()
    params.update()
    mesh.set_bsdf(mi.load_dict(bsdf))
    return mesh


def render_meshes(doc, scene, name, write_files, meshes):
    """The whole of a script whose objects are its own Mitsuba meshes: reads the command line,
    writes its files, renders `scene` (objects left out) plus `meshes(mi)` with Mitsuba's
    `path` integrator and writes the reference `name`."""
    opts = options(doc, scene["spp"])
    write_files()
    variant, mi, d = mitsuba_dict(opts, dict(scene, objects=[]), "path")
    d.update(meshes(mi))
    render_and_write(d, opts, name, variant, "path", f"make_{name}.py")
