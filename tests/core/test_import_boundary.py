"""The core and io never pull in Blender, and no module imports another that imports
it back: checked on every module, found by walking the folders."""

import ast
import subprocess
import sys
from pathlib import Path

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

from tests.conftest import ROOT

BLENDER_FREE = ("autoscoop_blender/core", "autoscoop_blender/io")


def _modules(*folders: str) -> dict[str, Path]:
    """Dotted module name -> file, for every .py file under the folders."""
    out = {}
    for folder in folders:
        for path in sorted((ROOT / folder).rglob("*.py")):
            name = ".".join(path.relative_to(ROOT).with_suffix("").parts)
            out[name.removesuffix(".__init__")] = path
    return out


def test_core_and_io_import_no_blender():
    modules = _modules(*BLENDER_FREE)
    assert len(modules) >= 30 and "autoscoop_blender.core.run" in modules
    imports = "; ".join(f"import {m}" for m in modules)
    code = (
        f"import sys; {imports}; sys.exit(bool({{'bpy', 'mathutils', 'bmesh'}} & set(sys.modules)))"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


def _imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The project modules ``name`` imports, anywhere in its file (functions too)."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")
            if node.level:
                base = base[: len(base) - node.level + 1]
            stem = ".".join(base + ([node.module] if node.module else []))
            if not node.level:
                stem = node.module or ""
            found |= {f"{stem}.{a.name}" for a in node.names} | {stem}
    # A module importing its own parent package (re-exports) is not a dependency.
    return {m for m in found & known if m != name and not name.startswith(m + ".")}


def test_no_import_cycles():
    modules = _modules("autoscoop_blender", "headless", "tools")
    names = sorted(modules)
    index = {m: k for k, m in enumerate(names)}
    edges = [(index[m], index[t]) for m in names for t in _imports(m, modules[m], set(names))]
    rows, cols = zip(*edges)
    graph = csr_matrix((np.ones(len(edges)), (rows, cols)), shape=(len(names), len(names)))
    _, labels = connected_components(graph, directed=True, connection="strong")
    cycles = [
        sorted(m for m, label in zip(names, labels) if label == k)
        for k in np.flatnonzero(np.bincount(labels) > 1)
    ]
    assert cycles == []


def test_developer_tools_stay_out_of_the_users_commands():
    """The developer tools (``tools``) are apart: neither the extension nor the users'
    commands import any of them, and ``tools`` is where they all are."""
    users = _modules("autoscoop_blender", "headless")
    everything = set(users) | set(_modules("tools"))
    assert {"tools.bench", "tools.build_extension", "tools.samples", "tools.mutants"} <= everything
    for m, path in users.items():
        assert [t for t in _imports(m, path, everything) if t.split(".")[0] == "tools"] == [], m
    assert not (ROOT / "headless" / "devtools").exists()
