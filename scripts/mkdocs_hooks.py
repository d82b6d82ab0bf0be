"""mkdocs hooks (``mkdocs.yml``, ``hooks:``): links that leave ``docs/``.

A page may link to a file of the repository outside ``docs/`` (``../README.md``,
``../python/pronet/run.py``, ``../benches/``): GitHub follows it, the site cannot (the
file is not one of its pages). Before a page is rendered, each such link becomes the
file's repository path in code marks (``[the runner](../benches/run.py)`` reads
"the runner (`benches/run.py`)"); a link to a file that does not exist is logged as a
warning, which ``mkdocs build --strict`` turns into a failure. Links inside code are
left alone. Links between pages are mkdocs' own to check (``validation:``).
"""

from __future__ import annotations

import logging
import re
from pathlib import Path
from typing import Any

log = logging.getLogger("mkdocs.hooks.outside_links")

#: A fenced block or an inline code span: never rewritten.
CODE = re.compile(r"^(```|~~~).*?^\1[^\n]*$|(`+)(?:(?!\2).)+?\2", flags=re.S | re.M)
#: ``[text](target)`` or ``![alt](target)``, an optional ``"title"`` after the target.
LINK = re.compile(r"(!?)\[([^\]]*)\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
#: ``[a][b]`` where ``b`` is no Python name (a formula: ``[v̂×][ω_ie×]``): GitHub shows
#: it as text, but mkdocs-autorefs would read it as a cross-reference to ``b``.
NOT_A_REFERENCE = re.compile(r"(\[[^\]]*\])(\[[^\]]*[^\w.\]][^\]]*\])")
SCHEME = re.compile(r"[a-zA-Z][a-zA-Z0-9+.-]*:")


def outside_path(target: str, page_file: Path, docs_dir: Path, root: Path) -> Path | None:
    """The repository file a link target names when it is not a page of the site: a
    file out of ``docs/``, or a folder of ``docs/`` without an ``index.md``; else None."""
    if SCHEME.match(target) or target.startswith(("#", "/")):
        return None
    path = re.split(r"[#?]", target, maxsplit=1)[0]
    if not path:
        return None
    resolved = (page_file.parent / path).resolve()
    if not resolved.is_relative_to(root):
        return None
    if resolved.is_relative_to(docs_dir):
        folder = resolved.is_dir() and not (resolved / "index.md").exists()
        return resolved if folder else None
    return resolved


def rewrite(markdown: str, page_file: Path, docs_dir: Path, root: Path) -> tuple[str, list[str]]:
    """The page with its links out of ``docs/`` turned into repository paths, and the
    targets of those that name no existing file."""
    missing: list[str] = []

    def one(match: re.Match[str]) -> str:
        image, text, target = match.groups()
        resolved = outside_path(target, page_file, docs_dir, root)
        if resolved is None:
            return match.group(0)
        if not resolved.exists():
            missing.append(target)
            return match.group(0)
        repo_path = resolved.relative_to(root).as_posix() + ("/" if resolved.is_dir() else "")
        shown = text.strip().strip("`")
        if image or not shown or shown in {repo_path, repo_path.rstrip("/"), resolved.name}:
            return f"`{repo_path}`"
        return f"{text} (`{repo_path}`)"

    def prose(text: str) -> str:
        return NOT_A_REFERENCE.sub(r"\1\\\2", LINK.sub(one, text))

    # A link's text may hold code (``[`run.py`](../run.py)``): code spans that lie
    # inside a link are prose here, the link is rewritten whole.
    codes = [m.span() for m in CODE.finditer(markdown)]
    links = [m.span() for m in LINK.finditer(markdown)]
    codes = [(a, b) for a, b in codes if not any(s < a and b <= e for s, e in links)]
    out, last = [], 0
    for start, end in codes:
        if start < last:
            continue
        out.append(prose(markdown[last:start]))
        out.append(markdown[start:end])
        last = end
    out.append(prose(markdown[last:]))
    return "".join(out), missing


def on_page_markdown(markdown: str, page: Any, config: Any, files: Any) -> str:
    if page.file.abs_src_path is None:  # a generated page (the API reference)
        return markdown
    docs_dir = Path(config["docs_dir"]).resolve()
    root = Path(config["config_file_path"]).resolve().parent
    text, missing = rewrite(markdown, Path(page.file.abs_src_path).resolve(), docs_dir, root)
    for target in missing:
        log.warning("%s: a link to %r, which does not exist", page.file.src_uri, target)
    return text


def on_nav(nav: Any, config: Any, files: Any) -> Any:
    """The generated reference's section is named after its folder, ``api``: show it as
    ``API``."""
    todo = list(nav.items)
    while todo:
        item = todo.pop()
        if getattr(item, "is_section", False):
            if item.title == "Api":
                item.title = "API"
            todo.extend(item.children)
    return nav
