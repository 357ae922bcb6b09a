#!/usr/bin/env python3
"""Writes bunnies_1000.json (and bunnies_1.json, bunnies_1000_moving.json): a field of
Stanford bunnies, each a copy (an instance) of one mesh, on a floor under a sky. The scene for
the instancing goal of the dynamic-scenes issue: 1,000 copies of the 69,451-triangle bunny
place 69.5M triangles, stored once. bunnies_1.json is the same scene with the first copy only,
to compare memory and load time. In bunnies_1000_moving.json every bunny turns about its own
centre and sways: only the copies' transforms change, so a frame rebuilds only their top level.

Run: python3 make_bunnies.py  (no dependencies; the outputs are committed).
"""
import json
import random

COLUMNS, ROWS, SPACING = 40, 25, 2.2


def placements(count):
    """A 40 x 25 grid, each bunny turned about y and scaled a little, jittered in its cell."""
    rng = random.Random(1000)
    out = []
    for k in range(COLUMNS * ROWS):
        i, j = k % COLUMNS, k // COLUMNS
        x = (i - (COLUMNS - 1) / 2) * SPACING + rng.uniform(-0.3, 0.3)
        z = -j * SPACING + rng.uniform(-0.3, 0.3)
        scale = round(rng.uniform(8.0, 12.0), 3)
        # The bunny's feet are at y = 0.033 in the file.
        out.append({
            "scale": scale,
            "rotate": [0, 1, 0, round(rng.uniform(0, 360), 2)],
            "translate": [round(x, 3), round(-0.033 * scale, 4), round(z, 3)],
        })
    return out[:count]


def scene(count, moving=False):
    width = COLUMNS * SPACING + 4
    depth = ROWS * SPACING + 4
    return {
        "description": f"{count} copies of the Stanford bunny (69,451 triangles each, one tree) on a floor under a sky"
        + (", each turning and swaying" if moving else "")
        + ". Written by make_bunnies.py.",
        "width": 512,
        "height": 288,
        "spp": 64,
        "max_depth": 6,
        "background": {"type": "gradient", "bottom": [1, 1, 1], "top": [0.5, 0.7, 1.0]},
        "materials": {
            "clay": {"type": "lambertian", "albedo": [0.8, 0.45, 0.3]},
            "floor": {"type": "lambertian", "albedo": [0.6, 0.6, 0.6]},
        },
        "views": {
            "overview": {"position": [0.0, 14.0, 14.0], "look_at": [0.0, 0.0, -18.0], "vfov": 50},
            "ground": {"position": [-3.0, 1.2, 4.0], "look_at": [2.0, 0.8, -10.0], "vfov": 55},
        },
        "objects": [
            {
                "type": "quad",
                "Q": [-width / 2, 0, 8],
                "u": [width, 0, 0],
                "v": [0, 0, -(depth + 6)],
                "material": "floor",
            },
            {
                "type": "mesh",
                "file": "{scenes}/bunny/bun_zipper.ply",
                "material": "clay",
                "instances": placements(count),
            }
            | ({"animate": [
                {"type": "rotate", "axis": [0, 1, 0], "degrees_per_second": 60},
                {"type": "oscillate", "amplitude": [0.25, 0, 0.15], "period": 1.5},
            ]} if moving else {}),
        ],
    }


if __name__ == "__main__":
    for name, count, moving in (("bunnies_1000", 1000, False), ("bunnies_1", 1, False),
                                ("bunnies_1000_moving", 1000, True)):
        with open(f"{name}.json", "w") as f:
            json.dump(scene(count, moving), f, indent=1)
            f.write("\n")
