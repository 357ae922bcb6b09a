"""The type stub parses and names what the module has, with the same parameters."""

import ast
import inspect
from pathlib import Path

import phr

STUB = Path(phr.__file__).with_name("__init__.pyi")


def stub_parameters(node):
    return [a.arg for a in node.args.args + node.args.kwonlyargs]


def runtime_parameters(obj):
    return [p for p in inspect.signature(obj).parameters if p not in ("self", "options")]


def test_the_stub_matches_the_module():
    tree = ast.parse(STUB.read_text())
    top = {n.name: n for n in tree.body if isinstance(n, (ast.FunctionDef, ast.ClassDef))}
    assert set(phr.__all__) - {"BUILDERS", "__version__"} <= set(top)
    assert runtime_parameters(phr.tune) == stub_parameters(top["tune"])
    for cls in ["Bvh", "Scene"]:
        methods = {n.name: n for n in top[cls].body if isinstance(n, ast.FunctionDef)}
        assert runtime_parameters(getattr(phr, cls)) == stub_parameters(methods["__init__"])[1:]
        public = {m for m in dir(getattr(phr, cls)) if not m.startswith("_")}
        assert public <= set(methods), f"{cls}: not in the stub: {public - set(methods)}"
        for name in public:
            member = getattr(getattr(phr, cls), name)
            if callable(member):
                assert runtime_parameters(member) == stub_parameters(methods[name])[1:], f"{cls}.{name}"
