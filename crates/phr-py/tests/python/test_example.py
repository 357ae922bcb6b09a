"""examples/compare_builders.py runs: every builder, the plot, the check against Embree."""

import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("trimesh", reason="trimesh is not installed (python3 -m pip install trimesh)")
pytest.importorskip("matplotlib", reason="matplotlib is not installed (python3 -m pip install matplotlib)")
pytest.importorskip("embreex", reason="embreex is not installed (python3 -m pip install embreex)")

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "compare_builders.py"


def test_compare_builders_plots_every_builder_and_agrees_with_embree(tmp_path, shared):
    out = tmp_path / "builders.png"
    mesh = shared / "scenes" / "bunny" / "bun_zipper.ply"
    run = subprocess.run(
        [sys.executable, str(EXAMPLE), str(mesh), "--out", str(out), "--rays", "20000", "--repeats", "1"],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert out.stat().st_size > 10_000
    for name in ["lbvh", "phr-fast", "phr-hq", "sbvh", "phr:0.45,7", "embree"]:
        assert f"\n{name} " in run.stdout, run.stdout
