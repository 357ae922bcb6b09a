"""phr.Scene and phr.render: the same image as `phr render`, and their errors."""

import subprocess

import numpy as np
import phr
import pytest


def read_pfm(path):
    """A colour PFM as float32 (height, width, 3), top row first."""
    data = path.read_bytes()
    header = data.split(b"\n", 3)
    assert header[0] == b"PF", header[0]
    width, height = map(int, header[1].split())
    scale = float(header[2])
    pixels = np.frombuffer(header[3], dtype="<f4" if scale < 0 else ">f4", count=width * height * 3)
    return pixels.reshape(height, width, 3)[::-1]


@pytest.mark.parametrize(
    "scene,options",
    [
        ("builtin", dict(width=48, height=32, spp=3, seed=7)),
        ("builtin", dict(width=40, height=40, spp=2, view="close", builder="phr-fast", max_depth=3)),
        ("builtin", dict(width=24, height=24, spp=2, integrator="implicit")),
        ("builtin", dict(width=24, height=24, spp=3, denoiser="atrous")),
        ("SHARED/reference/scenes/cornell_obj.json", dict(width=32, height=32, spp=2)),
    ],
)
def test_render_equals_the_command_line(tmp_path, phr_bin, shared, scene, options):
    """The array is `phr render --linear`'s raw mean, or `--out`'s denoised image with
    denoiser="atrous"."""
    scene = scene.replace("SHARED", str(shared))
    out, raw = tmp_path / "cli.pfm", tmp_path / "raw.pfm"
    args = [str(phr_bin), "render", scene, "--quiet", "--out", str(out), "--linear", str(raw)]
    for key, value in options.items():
        flag = "--" + key.replace("_", "-")
        args += [flag] if value is True else [flag, str(value)]
    subprocess.run(args, check=True, capture_output=True)
    image = phr.render(scene, **options)
    assert image.dtype == np.float32 and image.shape == (options["height"], options["width"], 3)
    assert image.mean() > 0.01
    expected = read_pfm(out if options.get("denoiser") == "atrous" else raw)
    np.testing.assert_array_equal(image, expected)


def test_a_scene_renders_several_views_the_same_for_any_thread_count():
    scene = phr.Scene("builtin")
    assert scene.views == ["front", "close", "corner"]
    assert scene.triangle_count > 100_000 and scene.sphere_count == 2
    assert set(scene.settings) == {"width", "height", "spp", "max_depth"}
    front = scene.render(width=32, height=24, spp=2)
    np.testing.assert_array_equal(front, scene.render(width=32, height=24, spp=2, threads=1))
    np.testing.assert_array_equal(front, scene.render(width=32, height=24, spp=2, threads=3))
    assert not np.array_equal(front, scene.render(width=32, height=24, spp=2, view="corner"))
    assert not np.array_equal(front, scene.render(width=32, height=24, spp=2, seed=1))
    vertices, indices = scene.triangles()
    assert vertices.shape[1] == 3 and len(indices) == scene.triangle_count
    assert indices.max() < len(vertices)


def test_bad_scenes_and_settings_raise_with_the_message(tmp_path):
    with pytest.raises(FileNotFoundError, match="no_such.obj"):
        phr.Scene(str(tmp_path / "no_such.obj"))
    broken = tmp_path / "broken.obj"
    broken.write_text("v 0 0 0\nv 1 0 0\nf 1 2 7\n")
    with pytest.raises(ValueError, match="broken.obj"):
        phr.Scene(str(broken))
    scene = phr.Scene("builtin")
    with pytest.raises(ValueError, match='no view "side"'):
        scene.render(width=8, height=8, spp=1, view="side")
    with pytest.raises(ValueError, match="empty"):
        scene.render(width=0, height=8, spp=1)
    with pytest.raises(ValueError, match="spp"):
        scene.render(width=8, height=8, spp=0)
    with pytest.raises(ValueError, match="denoiser"):
        scene.render(width=8, height=8, spp=1, denoiser="bm3d")
    # The module is built without Open Image Denoise: the error says how to get it.
    with pytest.raises(ValueError, match="setup-oidn.sh"):
        scene.render(width=8, height=8, spp=1, denoiser="oidn")
    with pytest.raises(ValueError, match="integrator"):
        scene.render(width=8, height=8, spp=1, integrator="bdpt")
    with pytest.raises(ValueError, match="unknown builder"):
        phr.render("builtin", width=8, height=8, spp=1, builder="kd-tree")
