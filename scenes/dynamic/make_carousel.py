#!/usr/bin/env python3
"""Writes carousel.gltf and floor.gltf, the self-contained dynamic example scene's meshes.

carousel.gltf: a pole and four subdivided octahedra ("riders") on a turning platform. The
platform node spins (rotation keyframes, linear slerp) and each rider bobs (translation
keyframes, one cubic-spline track and three linear ones), so the file exercises glTF node
animation through a hierarchy. floor.gltf: a 64x64 grid, static; the scene file makes it wave.

Run: python3 make_carousel.py  (no dependencies; the outputs are committed).
"""
import base64
import json
import math
import struct


def octasphere(level):
    """An octahedron subdivided `level` times and pushed onto the unit sphere."""
    v = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    f = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    for _ in range(level):
        mid = {}

        def m(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = [(x + y) / 2 for x, y in zip(v[a], v[b])]
                n = math.sqrt(sum(c * c for c in p))
                v.append(tuple(c / n for c in p))
                mid[key] = len(v) - 1
            return mid[key]

        f = [t for a, b, c in f for t in ((a, m(a, b), m(c, a)), (b, m(b, c), m(a, b)), (c, m(c, a), m(b, c)), (m(a, b), m(b, c), m(c, a)))]
    return v, f


def cylinder(radius, height, segments):
    v, f = [], []
    for i in range(segments):
        a = 2 * math.pi * i / segments
        v += [(radius * math.cos(a), 0, radius * math.sin(a)), (radius * math.cos(a), height, radius * math.sin(a))]
    for i in range(segments):
        j = (i + 1) % segments
        f += [(2 * i, 2 * i + 1, 2 * j), (2 * j, 2 * i + 1, 2 * j + 1)]
    return v, f


def disc(radius, y, segments):
    v = [(0, y, 0)] + [(radius * math.cos(2 * math.pi * i / segments), y, radius * math.sin(2 * math.pi * i / segments)) for i in range(segments)]
    f = [(0, 1 + (i + 1) % segments, 1 + i) for i in range(segments)]
    return v, f


def grid(n, size):
    v = [(size * (i / n - 0.5), 0, size * (j / n - 0.5)) for j in range(n + 1) for i in range(n + 1)]
    f = []
    for j in range(n):
        for i in range(n):
            a = j * (n + 1) + i
            f += [(a, a + n + 1, a + 1), (a + 1, a + n + 1, a + n + 2)]
    return v, f


class Writer:
    def __init__(self):
        self.data = bytearray()
        self.gltf = {"asset": {"version": "2.0", "generator": "phr make_carousel.py"}, "buffers": [], "bufferViews": [], "accessors": [], "meshes": [], "materials": [], "nodes": []}

    def accessor(self, fmt, items, kind, component, minmax=False):
        while len(self.data) % 4:
            self.data.append(0)
        offset = len(self.data)
        for item in items:
            self.data += struct.pack("<" + fmt, *(item if isinstance(item, (tuple, list)) else (item,)))
        self.gltf["bufferViews"].append({"buffer": 0, "byteOffset": offset, "byteLength": len(self.data) - offset})
        acc = {"bufferView": len(self.gltf["bufferViews"]) - 1, "componentType": component, "count": len(items), "type": kind}
        if minmax:
            acc["min"] = [min(p[k] for p in items) for k in range(len(items[0]))]
            acc["max"] = [max(p[k] for p in items) for k in range(len(items[0]))]
        self.gltf["accessors"].append(acc)
        return len(self.gltf["accessors"]) - 1

    def mesh(self, name, v, f, material):
        pos = self.accessor("fff", v, "VEC3", 5126, minmax=True)
        idx = self.accessor("I", [i for t in f for i in t], "SCALAR", 5125)
        self.gltf["meshes"].append({"name": name, "primitives": [{"attributes": {"POSITION": pos}, "indices": idx, "material": material}]})
        return len(self.gltf["meshes"]) - 1

    def material(self, name, rgb, metallic=0.0, roughness=1.0):
        self.gltf["materials"].append({"name": name, "pbrMetallicRoughness": {"baseColorFactor": list(rgb) + [1.0], "metallicFactor": metallic, "roughnessFactor": roughness}})
        return len(self.gltf["materials"]) - 1

    def node(self, **kw):
        self.gltf["nodes"].append(kw)
        return len(self.gltf["nodes"]) - 1

    def save(self, path, roots):
        self.gltf["scenes"] = [{"nodes": roots}]
        self.gltf["scene"] = 0
        self.gltf["buffers"] = [{"byteLength": len(self.data), "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(self.data)).decode()}]
        with open(path, "w") as out:
            json.dump(self.gltf, out, indent=1)
            out.write("\n")


def carousel():
    w = Writer()
    colours = [("red", (0.8, 0.15, 0.1), 0.0, 1.0), ("green", (0.15, 0.7, 0.2), 0.0, 1.0), ("blue", (0.15, 0.3, 0.85), 0.0, 1.0), ("gold", (0.95, 0.75, 0.35), 1.0, 0.3)]
    mats = [w.material(*c) for c in colours]
    wood = w.material("wood", (0.55, 0.4, 0.25))
    sphere = octasphere(4)
    riders = [w.mesh(f"rider_{name}", *sphere, m) for (name, *_), m in zip(colours, mats)]
    pole = w.mesh("pole", *cylinder(0.08, 2.2, 24), wood)
    platform = w.mesh("platform", *disc(2.0, 0.05, 48), wood)
    children = [w.node(name="pole", mesh=pole)]
    for k, mesh in enumerate(riders):
        a = 2 * math.pi * k / 4
        children.append(w.node(name=f"rider{k}", mesh=mesh, translation=[1.5 * math.cos(a), 0.8, 1.5 * math.sin(a)], scale=[0.35, 0.35, 0.35]))
    spin = w.node(name="platform", mesh=platform, children=children)
    animation = {"name": "ride", "samplers": [], "channels": []}

    def channel(node, path, times, values, fmt, kind, interpolation="LINEAR"):
        t = w.accessor("f", times, "SCALAR", 5126)
        acc = w.gltf["accessors"][t]
        acc["min"], acc["max"] = [min(times)], [max(times)]
        o = w.accessor(fmt, values, kind, 5126)
        animation["samplers"].append({"input": t, "output": o, "interpolation": interpolation})
        animation["channels"].append({"sampler": len(animation["samplers"]) - 1, "target": {"node": node, "path": path}})

    times = [0.0, 2.0, 4.0, 6.0, 8.0]
    quats = [(0.0, math.sin(-math.pi * i / 4), 0.0, math.cos(-math.pi * i / 4)) for i in range(5)]
    channel(spin, "rotation", times, quats, "ffff", "VEC4")
    for k in range(4):
        a = 2 * math.pi * k / 4
        base = (1.5 * math.cos(a), 0.8, 1.5 * math.sin(a))
        heights = [0.0, 0.5, 0.0, 0.5, 0.0]
        shift = k % 2
        ys = [heights[(i + shift) % 4] for i in range(5)]
        values = [(base[0], base[1] + y, base[2]) for y in ys]
        if k == 0:
            # Cubic spline: (in-tangent, value, out-tangent) per key, zero tangents.
            values = [v for p in values for v in ((0.0, 0.0, 0.0), p, (0.0, 0.0, 0.0))]
            channel(children[1 + k], "translation", times, values, "fff", "VEC3", "CUBICSPLINE")
        else:
            channel(children[1 + k], "translation", times, values, "fff", "VEC3")
    w.gltf["animations"] = [animation]
    w.save("carousel.gltf", [spin])


def floor():
    w = Writer()
    m = w.material("floor", (0.75, 0.75, 0.72))
    mesh = w.mesh("floor", *grid(64, 8.0), m)
    w.save("floor.gltf", [w.node(name="floor", mesh=mesh)])


carousel()
floor()
