"""The documentation: docs/api.md matches the docstrings, and every relative link in
the Markdown pages points to a file that exists."""

from __future__ import annotations

import functools
import importlib.util
import re
import sys
from pathlib import Path
from types import ModuleType

import pytest

import pronet

ROOT = Path(__file__).resolve().parents[1]
API = ROOT / "docs" / "api.md"
PAGES = sorted((ROOT / "docs").glob("*.md")) + [ROOT / "README.md"]
#: ``[text](target)`` or ``[text](target "title")``; images (``![alt](…)``) included.
LINK = re.compile(r"\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
FENCE = re.compile(r"^(```|~~~).*?^\1", flags=re.S | re.M)
INLINE_CODE = re.compile(r"(`+)(?:(?!\1).)+?\1", flags=re.S)


@functools.cache
def _api_docs() -> ModuleType:
    """``scripts/api_docs.py``, imported (it is a script, not part of the package)."""
    spec = importlib.util.spec_from_file_location("api_docs", ROOT / "scripts" / "api_docs.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def _headings(text: str) -> set[str]:
    body = FENCE.sub("", text)
    return {
        m.group(1).strip().strip("`")
        for m in re.finditer(r"^#{1,6}\s+(.+?)\s*#*\s*$", body, flags=re.M)
    }


def relative_links(text: str) -> list[str]:
    """The link targets of a Markdown text that name a file: not web or mail addresses,
    not in-page anchors, not inside code; ``#anchor`` and ``?query`` parts removed."""
    prose = INLINE_CODE.sub("", FENCE.sub("", text))
    targets = []
    for target in LINK.findall(prose):
        if re.match(r"[a-zA-Z][a-zA-Z0-9+.-]*:", target) or target.startswith("#"):
            continue  # http:, https:, mailto:, … or an anchor on the same page
        path = re.split(r"[#?]", target, maxsplit=1)[0]
        if path:
            targets.append(path)
    return targets


def test_api_reference_is_up_to_date() -> None:
    expected = _api_docs().generate()
    assert API.exists(), "docs/api.md is missing; run python scripts/api_docs.py"
    assert API.read_text(encoding="utf-8") == expected, (
        "docs/api.md is out of date; run python scripts/api_docs.py"
    )


def test_api_reference_has_no_memory_addresses() -> None:
    assert not re.search(r" at 0x[0-9a-fA-F]+", API.read_text(encoding="utf-8"))


@pytest.mark.parametrize("name", pronet.__all__)
def test_every_exported_name_has_a_heading(name: str) -> None:
    headings = _headings(API.read_text(encoding="utf-8"))
    assert f"pronet.{name}" in headings, f"docs/api.md has no heading for pronet.{name}"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_point_to_existing_files(page: Path) -> None:
    broken = [
        target
        for target in relative_links(page.read_text(encoding="utf-8"))
        if not (page.parent / target).exists()
    ]
    assert not broken, f"{page.relative_to(ROOT)}: broken links {broken}"


def test_the_pages_have_relative_links_to_check() -> None:
    # The link check must see real links, or it passes vacuously.
    assert "docs/filter.md" in relative_links((ROOT / "README.md").read_text(encoding="utf-8"))
    concepts = relative_links((ROOT / "docs" / "concepts.md").read_text(encoding="utf-8"))
    assert {"filter.md", "api.md", "../README.md"} <= set(concepts)


def test_link_parser() -> None:
    text = (
        "[a](docs/x.md) [b](https://e.org/y) [c](#here) [d](../z.md#part) "
        '![img](fig.png "Title") `[code](not/a/link.md)`\n'
        "```\n[fenced](not/either.md)\n```\n[e](mailto:a@b.c)"
    )
    assert relative_links(text) == ["docs/x.md", "../z.md", "fig.png"]


def test_check_mode_reports_a_stale_page(tmp_path: Path, capsys, monkeypatch) -> None:
    api_docs = _api_docs()
    stale = tmp_path / "api.md"
    stale.write_text("# stale\n", encoding="utf-8")
    monkeypatch.setattr(api_docs, "OUTPUT", stale)
    assert api_docs.main(["--check"]) == 1
    assert "docs/api.md is out of date; run python scripts/api_docs.py" in capsys.readouterr().err
    assert stale.read_text(encoding="utf-8") == "# stale\n"  # --check never writes
