"""The package's layout (docs/how-to/development.md, "The house"): a few modules at the top,
subpackages by concept, no import circle, no file over 600 lines, and each subpackage's
``__init__`` naming what it holds.

The imports are read from the source with ``ast``, every one of them: at module level,
inside functions and under ``TYPE_CHECKING`` alike, since a circle through a type-only
import is still a circle a reader has to untangle.
"""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest
from import_graph import import_circles

PACKAGE = Path(__file__).resolve().parents[1] / "python" / "pronet"
#: The subpackages, each one concept, in the order their imports may run: a package
#: imports only packages before it (the top-level modules form the layer "" between
#: ``_util`` and the rest, except the run path's ``run``, ``results``, ``shards`` and
#: ``config``, which sit above ``sim`` and ``learn``).
LAYERS = (
    "_util",
    "core",
    "plots",
    "learn",
    "strategies",
    "sim",
    "path",
    "recorded",
    "experiments",
    "cli",
)
#: The top-level modules and the layer each belongs to.
TOP = {
    "__init__": "core",
    "filter": "core",
    "montecarlo": "core",
    "navigation": "core",
    "trajectory": "core",
    "stats": "core",
    "strategies": "strategies",
    "run": "path",
    "results": "path",
    "shards": "path",
    "config": "path",
}
MAX_TOP_MODULES = 12
MAX_LINES = 600


def _modules() -> dict[str, Path]:
    """Every Python module of the package by dotted name (``pronet.recorded.real``);
    a package by its own name (its ``__init__``)."""
    found = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


MODULES = {**_modules(), "pronet._core": PACKAGE / "_core.pyi"}


def _imports(path: Path) -> set[str]:
    """The pronet modules ``path`` imports (a name imported from a package resolves to
    its submodule when there is one, else to the package)."""
    targets = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets |= {a.name for a in node.names if a.name.split(".")[0] == "pronet"}
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            if node.module.split(".")[0] != "pronet":
                continue
            for alias in node.names:
                sub = f"{node.module}.{alias.name}"
                targets.add(sub if sub in MODULES or alias.name == "_core" else node.module)
    return {t for t in targets if t in MODULES}


GRAPH = {name: _imports(path) - {name} for name, path in MODULES.items()}


def _layer(module: str) -> str:
    parts = module.split(".")
    if len(parts) == 1:
        return "core"  # pronet itself
    if parts[1] in TOP:
        return TOP[parts[1]]
    return parts[1]


def test_at_most_twelve_modules_at_the_top() -> None:
    top = sorted(p.name for p in PACKAGE.iterdir() if p.suffix == ".py" or ".so" in p.suffixes)
    native = [p for p in top if p.startswith("_core.")]
    count = len([p for p in top if p.endswith(".py")]) + bool(native)
    assert count <= MAX_TOP_MODULES, top
    assert {p.removesuffix(".py") for p in top if p.endswith(".py")} == set(TOP), (
        "a new top-level module: put it in the subpackage of its concept, or add it to TOP "
        "with its layer"
    )


def test_no_import_circle() -> None:
    """Tarjan's strongly connected components over every import: each is one module."""
    circles = import_circles(GRAPH)
    assert circles == []


def test_the_circle_walk_finds_every_circle_and_only_circles() -> None:
    graph = {"a": ["b"], "b": ["c"], "c": ["a"], "d": ["a", "e"], "e": ["d"], "f": []}
    assert sorted(import_circles(graph)) == [["a", "b", "c"], ["d", "e"]]
    assert import_circles({"a": ["b"], "b": []}) == []


def test_packages_import_only_the_layers_below() -> None:
    order = {layer: i for i, layer in enumerate(LAYERS)}
    upward = []
    for module, targets in GRAPH.items():
        for target in targets:
            if target == "pronet._core":
                continue  # the native core: below everything
            if order[_layer(target)] > order[_layer(module)]:
                upward.append(f"{module} -> {target}")
    assert upward == []


def test_the_walk_sees_real_imports() -> None:
    """The graph is not empty by accident: known edges are in it."""
    assert "pronet.recorded.runs" in GRAPH["pronet.recorded.tables"]
    assert "pronet.learn.hybrid" in GRAPH["pronet.strategies"]
    assert "pronet._core" in GRAPH["pronet.filter"]


#: The native core's stub mirrors the bound API one class and function at a time, the
#: source of their runtime docstrings: it grows with the binding, which is cut one file
#: per exposed type already (``rust/src/python``).
STUB_MAX_LINES = 700


def test_no_file_over_600_lines() -> None:
    lines = {name: len(path.read_text().splitlines()) for name, path in MODULES.items()}
    bound = {name: STUB_MAX_LINES if name == "pronet._core" else MAX_LINES for name in lines}
    long = {name: n for name, n in lines.items() if n > bound[name]}
    assert long == {}


SUBPACKAGES = sorted(
    name
    for name, path in MODULES.items()
    if path.name == "__init__.py" and name not in ("pronet", "pronet.cli")
)


@pytest.mark.parametrize("package", SUBPACKAGES)
def test_each_subpackage_says_what_it_holds(package: str) -> None:
    """Its docstring names every module in it, private ones too, and everything in its
    ``__all__`` exists: its public modules (``pronet.plots``: the figure functions it
    re-exports)."""
    mod = importlib.import_module(package)
    inside = sorted(
        name.rpartition(".")[2] for name in MODULES if name.rpartition(".")[0] == package
    )
    assert inside, package
    missing = [leaf for leaf in inside if f"{package}.{leaf}`" not in (mod.__doc__ or "")]
    assert missing == [], f"{package}'s docstring does not name {missing}"
    if package == "pronet.plots":
        assert all(callable(getattr(mod, name)) for name in mod.__all__)
    else:
        assert sorted(mod.__all__) == [leaf for leaf in inside if not leaf.startswith("_")]
