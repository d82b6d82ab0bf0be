"""The documentation site (``mkdocs.yml``): the API reference that
``scripts/api_pages.py`` writes at build time has a page for every public module of
``pronet`` and ``pronet._core``, and each name it promises is one that griffe, reading
the sources and the stub the way mkdocstrings does, can document; the hook of
``scripts/mkdocs_hooks.py`` turns links out of ``docs/`` into repository paths and
reports the broken ones. ``scripts/test.sh`` builds the site itself
(``mkdocs build --strict``)."""

from __future__ import annotations

import functools
import inspect
import re
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

import pronet
from pronet import _core

from module_file import load

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "python" / "pronet"
DOCS = ROOT / "docs"


def _script(name: str) -> ModuleType:
    return load(ROOT / "scripts" / f"{name}.py")


@functools.cache
def api_pages() -> ModuleType:
    return _script("api_pages")


@functools.cache
def griffe_tree() -> Any:
    """``pronet`` as griffe loads it for mkdocstrings (``mkdocs.yml``): statically, with
    the ``#:`` comments read as attribute docstrings."""
    griffe = pytest.importorskip("griffe", reason="the docs extra is not installed")
    return griffe.load(
        "pronet",
        search_paths=[str(PACKAGE.parent)],
        extensions=griffe.load_extensions("griffe_sphinx"),
        docstring_parser="google",
        allow_inspection=False,
    )


def walked_modules() -> set[str]:
    """The package's public modules found by walking the tree: every ``.py`` file and
    the stub, by dotted name, none with a part starting with ``_`` but ``_core``."""
    names = set()
    for path in [*PACKAGE.rglob("*.py"), PACKAGE / "_core.pyi"]:
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        if all(not p.startswith("_") or p == "_core" for p in parts):
            names.add(".".join(parts))
    return names


def test_there_is_a_page_per_public_module() -> None:
    pages = api_pages().pages()
    modules = api_pages().public_modules()
    assert set(modules) == walked_modules()
    assert {"pronet", "pronet._core", "pronet.recorded.aiding", "pronet.cli"} <= set(modules)
    assert not [m for m in modules if m.startswith(("pronet._util", "pronet.cli.__main__"))]
    for module in modules:
        page = api_pages().page_path(module)
        assert page.startswith("reference/api/pronet"), page
        assert pages[page].startswith(f"::: {module}\n"), f"{page} does not document {module}"
    assert api_pages().page_path("pronet.recorded.aiding") == (
        "reference/api/pronet/recorded/aiding.md"
    )
    assert api_pages().page_path("pronet.recorded") == "reference/api/pronet/recorded/index.md"
    # One page each, every page in the section's navigation, nothing under docs/.
    assert len({api_pages().page_path(m) for m in modules}) == len(modules)
    summary = pages["reference/api/SUMMARY.md"]
    linked = set(re.findall(r"\]\(([^)]+)\)", summary))
    assert {p.removeprefix("reference/api/") for p in pages if p.endswith(".md")} - linked == {
        "SUMMARY.md"
    }
    assert not (DOCS / "reference" / "api").exists(), "the reference is generated, not kept"
    gitignore = (ROOT / ".gitignore").read_text(encoding="utf-8").split()
    assert "/site/" in gitignore


def test_every_public_native_name_is_documented() -> None:
    """Every public name of the built module (and each public member of its classes)
    is in the stub as griffe reads it for the ``pronet._core`` page."""
    stub = griffe_tree()["_core"]
    assert stub.filepath == PACKAGE / "_core.pyi"
    runtime = {n for n in dir(_core) if not n.startswith("_")} | {"__version__"}
    assert set(_core.__all__) == runtime, "_core.__all__ differs from the module's names"
    missing = sorted(runtime - set(stub.members))
    for name in sorted(runtime & set(stub.members)):
        obj = getattr(_core, name)
        if inspect.isclass(obj):
            members = {m for m in vars(obj) if not m.startswith("_")}
            missing += [f"{name}.{m}" for m in sorted(members - set(stub[name].members))]
    assert not missing, f"native names the reference does not document: {missing}"
    # Each module-level name has its text (a docstring, or a ``#:`` comment for data),
    # but the raw constructors that pronet.trajectory wraps under the same name: the
    # wrapper, which pronet exports, carries the text.
    undocumented = [n for n in sorted(runtime) if stub[n].docstring is None]
    wrapped = griffe_tree()["trajectory"].members
    bare = [n for n in undocumented if n not in wrapped or wrapped[n].docstring is None]
    assert not bare, f"native names without a docstring: {bare}"


@pytest.mark.parametrize("name", pronet.__all__)
def test_every_exported_name_has_its_place_in_the_reference(name: str) -> None:
    """The index links ``pronet.<name>`` to the identifier it is documented under: a
    public member of a module that has a page, or one the ``pronet`` page lists."""
    target = api_pages().target(name)
    assert f"[`pronet.{name}`][{target}]" in api_pages().pages()["reference/api/index.md"]
    tree = griffe_tree()
    obj = tree[target.removeprefix("pronet.")]
    if target == f"pronet.{name}":
        assert name in api_pages().pages()["reference/api/pronet/index.md"]
    else:
        module, _, member = target.rpartition(".")
        assert module in api_pages().public_modules() and not member.startswith("_")
    documented = obj.final_target if obj.is_alias else obj
    assert documented.docstring is not None, f"{target} has no docstring"


def test_the_reference_lists_the_state_blocks() -> None:
    """``STATE_BLOCKS`` is rendered with its value and its ``#:`` comment."""
    attribute = griffe_tree()["montecarlo.STATE_BLOCKS"]
    assert str(attribute.value) == repr(pronet.STATE_BLOCKS)
    assert attribute.docstring.value.startswith("Names of the five 3-blocks")


def test_links_out_of_the_docs_become_repository_paths(tmp_path: Path) -> None:
    hooks = _script("mkdocs_hooks")
    page = DOCS / "accuracy.md"
    text = (
        "[`benches/run.py`](../benches/run.py) and [the README](../README.md#x), "
        "[a page](filter.md), `[code](../nowhere.py)`, [gone](../nowhere.py), "
        "| [v̂×][ω_ie×] | [a name][pronet.run.run]\n```\n[fenced](../nowhere.md)\n```\n"
    )
    out, missing = hooks.rewrite(text, page, DOCS, ROOT)
    assert out.startswith("`benches/run.py` and the README (`README.md`), [a page](filter.md)")
    assert "`[code](../nowhere.py)`" in out and "[fenced](../nowhere.md)" in out
    assert "[gone](../nowhere.py)" in out and missing == ["../nowhere.py"]
    assert r"[v̂×]\[ω_ie×]" in out and "[a name][pronet.run.run]" in out
    # A folder of docs/ without an index.md is no page either.
    folder = next(p for p in DOCS.iterdir() if p.is_dir() and not (p / "index.md").exists())
    out, _ = hooks.rewrite(f"[data]({folder.name}/)", page, DOCS, ROOT)
    assert out == f"data (`docs/{folder.name}/`)"


def test_sphinx_roles_become_cross_references() -> None:
    """A role naming an object the reference documents links to it (by its canonical
    path, found from the docstring's own scope outward); any other is plain code."""
    roles = _script("griffe_roles")
    tree = griffe_tree()
    run = tree["run.run"]
    text = (
        ":func:`pronet.monte_carlo` :class:`Recorded` :data:`~pronet.STATE_BLOCKS` "
        ":mod:`pronet._util.outputs` :func:`numpy.linalg.solve` :meth:`FilterResult.\n"
        "    to_dataframe` :func:`run()`"
    )
    assert roles.rewrite(text, run, tree) == (
        "[`pronet.monte_carlo`][pronet.montecarlo.monte_carlo] "
        "[`Recorded`][pronet.run.Recorded] [`STATE_BLOCKS`][pronet.montecarlo.STATE_BLOCKS] "
        "`pronet._util.outputs` `numpy.linalg.solve` "
        "[`FilterResult.to_dataframe`][pronet.filter.FilterResult.to_dataframe] "
        "[`run()`][pronet.run.run]"
    )
