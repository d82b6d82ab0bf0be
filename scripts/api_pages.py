"""Write the API reference's pages while ``mkdocs build`` runs (mkdocs-gen-files).

``mkdocs.yml`` runs this script through the ``gen-files`` plugin: it writes one page per
public module of ``pronet`` (a module none of whose dotted parts starts with ``_``) and
one for the native core ``pronet._core``, each holding a mkdocstrings directive
(``::: pronet.run``) that griffe fills from the source and from the stub ``_core.pyi``
without importing the package. The pages live under ``reference/api/`` in the built
site only; nothing is written into ``docs/``. ``reference/api/SUMMARY.md`` gives their
order to the ``literate-nav`` plugin, and ``reference/api/index.md`` lists them with the
top-level namespace (``pronet.__all__``), each name linked to the module that defines it.

Run by hand (``python scripts/api_pages.py``) it prints the pages it would write.
"""

from __future__ import annotations

import ast
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "python" / "pronet"
#: Where the pages go, relative to the site's root.
PREFIX = "reference/api"
NATIVE = "pronet._core"


def public_modules() -> list[str]:
    """Every public module of the package by dotted name, ``pronet`` first, then
    ``pronet._core`` (the stub), then the rest in sorted order. A module is public when
    no part of its dotted name starts with ``_`` (``pronet._util.files`` and
    ``pronet.cli.__main__`` are not)."""
    names = []
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        if not any(part.startswith("_") for part in parts):
            names.append(".".join(parts))
    rest = sorted(n for n in names if n != "pronet")
    return ["pronet", NATIVE, *rest]


def is_package(module: str) -> bool:
    return (PACKAGE.parent.joinpath(*module.split(".")) / "__init__.py").exists()


def page_path(module: str) -> str:
    """The page of a module, relative to the site's root: a package's is its folder's
    ``index.md`` (``reference/api/pronet/recorded/index.md``), a module's its own file
    (``reference/api/pronet/recorded/aiding.md``)."""
    parts = module.split(".")
    if is_package(module):
        return "/".join([PREFIX, *parts, "index.md"])
    return "/".join([PREFIX, *parts]) + ".md"


def exported() -> dict[str, str]:
    """``pronet.__all__``'s names and the module each is imported from, read from
    ``pronet/__init__.py`` without importing it."""
    tree = ast.parse((PACKAGE / "__init__.py").read_text(encoding="utf-8"))
    sources: dict[str, str] = {}
    names: list[str] = []
    for node in tree.body:
        if isinstance(node, ast.ImportFrom) and node.module:
            for alias in node.names:
                sources[alias.asname or alias.name] = node.module
        if isinstance(node, ast.Assign) and any(
            isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets
        ):
            names = list(ast.literal_eval(node.value))
    return {name: sources[name] for name in names}


def documented_here() -> list[str]:
    """The names of ``pronet.__all__`` whose defining module has no page of its own (a
    private one, ``pronet._util.plausibility``) or that the module pages leave out (a
    dunder, ``__version__``): the ``pronet`` page documents them itself."""
    return [
        name
        for name, source in exported().items()
        if name.startswith("__")
        or any(part.startswith("_") for part in source.split(".") if part != "_core")
    ]


def target(name: str) -> str:
    """The identifier a name of ``pronet.__all__`` is documented under."""
    return f"pronet.{name}" if name in documented_here() else f"{exported()[name]}.{name}"


def module_page(module: str) -> str:
    """The Markdown of a module's page: the mkdocstrings directive, whose root heading
    (the module's name, at level 1 in ``mkdocs.yml``) is the page's title."""
    if module == "pronet":
        # The namespace re-exports names documented on their own modules' pages (the
        # index links each); this page holds the package's docstring and the names
        # documented nowhere else.
        members = "".join(f"\n        - {name}" for name in documented_here())
        return f"::: {module}\n    options:\n      filters: []\n      members:{members}\n"
    return f"::: {module}\n"


def index_page(modules: list[str]) -> str:
    """The reference's front page: the top-level namespace, each name linked to where
    it is defined (mkdocstrings resolves ``[text][identifier]``), and every module."""
    lines = [
        "# API reference",
        "",
        "Generated from the docstrings and the native core's stub (`_core.pyi`) each",
        "time the site is built; one page per public module.",
        "",
        "## The top-level namespace",
        "",
        "`import pronet` gives these names; each links to the module that defines it.",
        "",
        "| name | defined in |",
        "|---|---|",
    ]
    for name, source in sorted(exported().items(), key=lambda item: item[0].lower()):
        lines.append(f"| [`pronet.{name}`][{target(name)}] | `{source}` |")
    lines += ["", "## Modules", "", *module_list(modules)]
    return "\n".join(lines) + "\n"


def summary(modules: list[str]) -> str:
    """The literate-nav order of the section: the index, then the modules, each
    subpackage's modules nested under it."""
    return "\n".join(["- [Overview](index.md)", *module_list(modules)]) + "\n"


def module_list(modules: list[str]) -> list[str]:
    """A Markdown list linking each module's page from the reference's folder, a
    subpackage's modules nested under it."""
    lines = []
    for module in modules:
        depth = max(module.count(".") - 1, 0)
        link = page_path(module).removeprefix(PREFIX + "/")
        lines.append(f"{'    ' * depth}- [`{module}`]({link})")
    return lines


def pages() -> dict[str, str]:
    """Every page this script writes, by its path from the site's root."""
    modules = public_modules()
    out = {page_path(m): module_page(m) for m in modules}
    out[f"{PREFIX}/index.md"] = index_page(modules)
    out[f"{PREFIX}/SUMMARY.md"] = summary(modules)
    return out


def write() -> None:
    """Write the pages into mkdocs' virtual file tree (only while ``mkdocs build`` runs)."""
    import mkdocs_gen_files

    for path, text in pages().items():
        with mkdocs_gen_files.open(path, "w") as handle:
            handle.write(text)


if __name__ == "__main__":
    print("\n".join(pages()))
    sys.exit(0)
elif __name__ == "<run_path>":  # mkdocs-gen-files runs the script with runpy.run_path
    write()
