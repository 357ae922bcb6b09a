#!/usr/bin/env python3
"""render_reference.py with textures: the team's Mitsuba 3 reference renderer
(shared/reference/tools/render_reference.py) reads an `obj_mtl` object's MTL for its flat
`Kd` and `Ke` only. Here every material of such an object that names a `map_Kd` image is
given to Mitsuba as a mesh with the OBJ's texture coordinates (Mitsuba's own OBJ reader) and
a two-sided diffuse BSDF whose reflectance is that image (a `bitmap`: sRGB decoded,
bilinear, repeating): what phr does with `map_Kd`, the image taking the place of `Kd`. The
other materials, objects and settings go through render_reference.py unchanged.

The command line is render_reference.py's, plus where to find it:

    python3 tools/render_textured.py SCENE.json -o PREFIX [render_reference.py's options]
        [--reference-tool PATH/render_reference.py]

(default: ../shared/reference/tools/render_reference.py next to this repository). `phr
bench-quality` runs it for Mitsuba's column; `crates/phr-bench/references/make_references.py`
renders the converged references of the textured scenes with it.
"""

import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_TOOL = os.path.join(HERE, "..", "..", "shared", "reference", "tools", "render_reference.py")


def reference_tool(argv):
    """The path given by --reference-tool (removed from argv), else the default."""
    if "--reference-tool" in argv:
        k = argv.index("--reference-tool")
        if k + 1 >= len(argv):
            sys.exit("--reference-tool needs a path")
        path = argv[k + 1]
        del argv[k : k + 2]
        return path
    return DEFAULT_TOOL


def lines_of(path):
    """The words of each non-empty line of an OBJ or MTL file, comments removed."""
    with open(path, "r", errors="replace") as fh:
        for line in fh:
            words = line.split("#", 1)[0].split()
            if words:
                yield words


def read_mtl(path):
    """{material: {"Kd": [..], "Ke": [..], "map_Kd": absolute image path}} of an MTL file
    (`map_Kd` options skipped: the last word is the image, relative to the MTL's folder)."""
    out, name = {}, None
    for t in lines_of(path):
        if t[0] == "newmtl":
            name = " ".join(t[1:])
            out[name] = {}
        elif name is not None and t[0] in ("Kd", "Ke"):
            out[name][t[0]] = [float(x) for x in t[1:4]]
        elif name is not None and t[0] == "map_Kd" and len(t) > 1:
            out[name]["map_Kd"] = os.path.normpath(os.path.join(os.path.dirname(path), t[-1]))
    return out


def split_obj(path):
    """The OBJ's faces by material: {material: [face, ...]}, each face a list of (v, vt)
    0-based indices (vt None without one), and the file's positions, texture coordinates and
    MTL files."""
    positions, uvs, groups, current, mtllibs = [], [], {}, "default", []
    for t in lines_of(path):
        if t[0] == "v":
            positions.append(t[1:4])
        elif t[0] == "vt":
            uvs.append(t[1:3])
        elif t[0] == "f":
            face = []
            for token in t[1:]:
                parts = token.split("/")
                v = int(parts[0])
                v = v - 1 if v > 0 else len(positions) + v
                vt = None
                if len(parts) > 1 and parts[1]:
                    vt = int(parts[1])
                    vt = vt - 1 if vt > 0 else len(uvs) + vt
                face.append((v, vt))
            groups.setdefault(current, []).append(face)
        elif t[0] == "usemtl":
            current = " ".join(t[1:])
        elif t[0] == "mtllib":
            mtllibs.append(os.path.join(os.path.dirname(path), " ".join(t[1:])))
    return positions, uvs, groups, mtllibs


def write_group(path, positions, uvs, faces):
    """One material's faces as an OBJ of their own (positions and texture coordinates
    renumbered; Mitsuba's reader flips v, as phr's OBJ reader does)."""
    v_index, vt_index, lines_v, lines_vt, lines_f = {}, {}, [], [], []
    for face in faces:
        corners = []
        for v, vt in face:
            if v not in v_index:
                v_index[v] = len(v_index) + 1
                lines_v.append("v " + " ".join(positions[v]))
            if vt is None:
                corners.append(f"{v_index[v]}")
                continue
            if vt not in vt_index:
                vt_index[vt] = len(vt_index) + 1
                lines_vt.append("vt " + " ".join(uvs[vt]))
            corners.append(f"{v_index[v]}/{vt_index[vt]}")
        lines_f.append("f " + " ".join(corners))
    with open(path, "w") as f:
        f.write("\n".join(lines_v + lines_vt + lines_f) + "\n")


def with_textures(rr):
    """Wraps rr.build_mitsuba_dict: textured materials of `obj_mtl` objects become meshes of
    their own with a bitmap reflectance; the rest of each object stays an `obj_mtl` object
    whose textured materials are left out."""
    build = rr.build_mitsuba_dict

    def build_with_textures(scene, opts, tmpdir):
        textured = []
        objects = []
        for obj in scene["objects"]:
            if obj["type"].lower() != "obj_mtl":
                objects.append(obj)
                continue
            path = rr.resolve_path(obj["file"], scene, opts)
            positions, uvs, groups, mtllibs = split_obj(path)
            mtl = {}
            for lib in mtllibs:
                if os.path.exists(lib):
                    mtl.update(read_mtl(lib))
            # Materials the scene file names for this object replace the MTL's, textures and all.
            overrides, fallback = obj.get("materials", {}), obj.get("material")
            kept = {}
            for name, faces in groups.items():
                image = mtl.get(name, {}).get("map_Kd")
                if image is None or name in overrides or fallback is not None:
                    kept[name] = faces
                    continue
                if not os.path.exists(image):
                    raise FileNotFoundError(f"material {name}: texture {image} not found")
                file = os.path.join(tmpdir, f"textured{len(textured):04d}.obj")
                write_group(file, positions, uvs, faces)
                textured.append((file, image, obj.get("transform")))
            if kept:
                file = os.path.join(tmpdir, f"untextured{len(objects):04d}.obj")
                with open(file, "w") as f:
                    f.writelines("v " + " ".join(p) + "\n" for p in positions)
                    f.writelines(f"mtllib {os.path.abspath(lib)}\n" for lib in mtllibs)
                    for name, faces in kept.items():
                        f.write(f"usemtl {name}\n")
                        f.writelines("f " + " ".join(str(v + 1) for v, _ in face) + "\n" for face in faces)
                objects.append(dict(obj, file=file))
        d = build(dict(scene, objects=objects), opts, tmpdir)
        for k, (file, image, transform) in enumerate(textured):
            reflectance = {"type": "bitmap", "filename": image, "filter_type": "bilinear",
                           "wrap_mode": "repeat", "raw": False}
            d[f"textured{k:04d}"] = {
                "type": "obj", "filename": file, "face_normals": True,
                "to_world": rr.mesh_transform(transform),
                "bsdf": {"type": "twosided", "bsdf": {"type": "diffuse", "reflectance": reflectance}},
            }
        return d

    rr.build_mitsuba_dict = build_with_textures


def main():
    argv = sys.argv[1:]
    tool = reference_tool(argv)
    if not os.path.isfile(tool):
        sys.exit(f"render_reference.py not found at {tool} (give --reference-tool)")
    sys.path.insert(0, os.path.dirname(os.path.abspath(tool)))
    import render_reference as rr

    with_textures(rr)
    return rr.main(argv)


if __name__ == "__main__":
    sys.exit(main())
