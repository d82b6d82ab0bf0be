"""A griffe extension (``mkdocs.yml``): the Sphinx roles of pronet's docstrings
(``:func:`pronet.monte_carlo```, ``:class:`Recorded```, ``:data:`STATE_BLOCKS```) as the
site's cross-references.

The docstrings are written for ``help()`` and editors, where a role reads as plain
text; mkdocstrings reads Markdown, where it would show as ``:func:`` before the name.
Once the package is loaded, each role becomes a link to the object it names
(``[`pronet.monte_carlo`][pronet.montecarlo.monte_carlo]``, resolved from the
docstring's own class and module outward, then from the package) when the reference
documents that object, and plain code when it does not (a private module's, numpy's).
"""

from __future__ import annotations

import re
from typing import Any

import griffe

#: A role; its name may break across a line (``:func:`pronet.recorded.export.\nwrite_all```).
ROLE = re.compile(
    r":(?:func|class|meth|data|mod|attr|exc|obj):`([~!.]*)([\w.]+(?:\s+[\w.]+)?)(\(\))?`"
)


def _documented(path: str) -> bool:
    """Whether the reference renders the object at ``path``: one of a public module of
    pronet (or of the stub ``pronet._core``) and public itself."""
    parts = path.split(".")
    return parts[0] == "pronet" and all(p == "_core" or not p.startswith("_") for p in parts)


def _find(name: str, scope: griffe.Object, pkg: griffe.Module) -> str | None:
    """The path of the object ``name`` stands for, seen from ``scope``, else None."""
    places: list[griffe.Object] = []
    obj: griffe.Object | None = scope
    while obj is not None:
        places.append(obj)
        obj = obj.parent
    candidates = [name.removeprefix("pronet.")] if name.startswith("pronet.") else []
    for place in [*places, pkg] if not candidates else [pkg]:
        try:
            found = place[candidates[0] if candidates else name]
            target = found.final_target if found.is_alias else found
        except (KeyError, ValueError, griffe.AliasResolutionError, griffe.CyclicAliasError):
            continue
        return str(target.path)
    return None


def rewrite(text: str, scope: griffe.Object, pkg: griffe.Module) -> str:
    """``text`` with each role a cross-reference or plain code."""

    def one(match: re.Match[str]) -> str:
        marks, broken, call = match.groups()
        name = re.sub(r"\s+", "", broken)
        shown = (name.rsplit(".", 1)[-1] if "~" in marks else name) + (call or "")
        path = _find(name.lstrip("."), scope, pkg)
        if path is not None and _documented(path):
            return f"[`{shown}`][{path}]"
        return f"`{shown}`"

    return ROLE.sub(one, text)


class SphinxRoles(griffe.Extension):
    """Rewrite the roles of every docstring of the package once it is loaded."""

    def on_package(self, *, pkg: griffe.Module, **kwargs: Any) -> None:
        todo: list[griffe.Object] = [pkg]
        while todo:
            obj = todo.pop()
            if obj.docstring is not None:
                obj.docstring.value = rewrite(obj.docstring.value, obj, pkg)
            todo.extend(m for m in obj.members.values() if isinstance(m, griffe.Object))
