"""The README's Python example runs as written."""

import re

from conftest import REPO


def test_the_readme_python_example_runs(monkeypatch):
    """The README's "From Python" block, run as it stands from the repository's root."""
    readme = (REPO / "README.md").read_text()
    block = re.search(r"## From Python.*?```python\n(.*?)```", readme, re.S).group(1)
    monkeypatch.chdir(REPO)
    names = {}
    exec(compile(block, "README.md", "exec"), names)
    assert names["image"].shape == (256, 256, 3) and 0.3 < (names["prim"] >= 0).mean() < 0.95
