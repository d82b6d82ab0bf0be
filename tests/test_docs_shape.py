"""The shape of the documentation: every page under docs/ says on its first line which
kind it is (a tutorial, a how-to guide, reference or results; the landing page an
overview), has at most 450 lines and cites no issue number and no dated note, and
every ``docs/...md`` path that the code, the scripts and the README cite names a page
that exists."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: The four kinds of page and the first line that says which one a page is.
KINDS = {
    "tutorials": "*Tutorial.*",
    "how-to": "*How-to guide.*",
    "reference": "*Reference.*",
    "results": "*Results.*",
}
#: The landing page's first line.
OVERVIEW = "*Overview.*"
#: Generated pages that are not written by hand (the API reference), exempt from the shape.
GENERATED = {DOCS / "api.md", *DOCS.glob("reference/api/**/*.md")}
MAX_LINES = 450
#: Where the code cites pages: the package, the core, the scripts, the README.
CITING = [ROOT / "python", ROOT / "rust" / "src", ROOT / "scripts", ROOT / "README.md"]
#: ``docs/x.md`` or ``docs/kind/x.md`` as a page is cited in code and prose.
CITED = re.compile(r"\bdocs/((?:[a-z0-9_-]+/)*[a-z0-9_-]+\.md)")
ISSUE = re.compile(r"\bissues? #?\d+", flags=re.I)
#: A dated note (``2026-12-05``, ``2026-12``); a results page's "generated on" line may
#: carry its date.
DATE = re.compile(r"\b20\d{2}-[01]\d(?:-[0-3]\d)?\b")


def pages() -> list[Path]:
    """The hand-written pages under docs/."""
    return sorted(p for p in DOCS.rglob("*.md") if p not in GENERATED)


def _id(page: Path) -> str:
    return page.relative_to(DOCS).as_posix()


def expected_kind(page: Path) -> str | None:
    """The first line ``page`` must start with: its folder's kind, the overview for
    docs/index.md, None for a page outside the four folders (which it must not be)."""
    if page == DOCS / "index.md":
        return OVERVIEW
    folder = page.relative_to(DOCS).parts[0]
    return KINDS.get(folder)


def kind_problems(page: Path, text: str) -> list[str]:
    """What is wrong with ``text`` as ``page``: its first line, its title, its length,
    issue numbers it cites."""
    problems = []
    lines = text.splitlines()
    want = expected_kind(page)
    if want is None:
        problems.append(f"not in one of {sorted(KINDS)}")
    elif not lines or lines[0] != want:
        problems.append(f"first line {lines[0] if lines else ''!r}, not {want!r}")
    titles = [line for line in lines[1:4] if line.startswith("# ")]
    if not titles:
        problems.append("no '# Title' right after the first line")
    if len(lines) > MAX_LINES:
        problems.append(f"{len(lines)} lines, more than {MAX_LINES}")
    problems += [f"cites {m.group(0)!r}" for m in ISSUE.finditer(text)]
    dated = "\n".join(line for line in lines if "generated on" not in line.lower())
    problems += [f"dated {m.group(0)!r}" for m in DATE.finditer(dated)]
    return problems


def cited_paths(text: str) -> list[str]:
    """The ``docs/...md`` paths ``text`` cites, relative to docs/."""
    return CITED.findall(text)


def citing_files() -> list[Path]:
    files: list[Path] = []
    for place in CITING:
        if place.is_file():
            files.append(place)
        else:
            files += [p for p in place.rglob("*") if p.suffix in {".py", ".pyi", ".rs", ".sh"}]
    return sorted(files)


@pytest.mark.parametrize("page", pages(), ids=_id)
def test_every_page_says_its_kind_and_stays_short(page: Path) -> None:
    problems = kind_problems(page, page.read_text(encoding="utf-8"))
    assert not problems, f"docs/{_id(page)}: {problems}"


def test_every_cited_page_exists() -> None:
    missing = [
        f"{path.relative_to(ROOT)}: docs/{cited}"
        for path in citing_files()
        for cited in cited_paths(path.read_text(encoding="utf-8"))
        if not (DOCS / cited).is_file()
    ]
    assert not missing, f"paths to pages that do not exist: {missing}"


def test_the_shape_checks_see_what_is_wrong() -> None:
    # The checks must see real pages and real citations, or they pass vacuously.
    found = {_id(p) for p in pages()}
    assert {"index.md", "reference/filter.md", "results/smoother.md"} <= found
    assert {p.relative_to(DOCS).parts[0] for p in pages() if p.parent != DOCS} == set(KINDS)
    assert any(cited_paths(p.read_text(encoding="utf-8")) for p in citing_files())
    good = "*Reference.*\n\n# The filter\n\ntext\n"
    page = DOCS / "reference" / "x.md"
    assert kind_problems(page, good) == []
    assert kind_problems(DOCS / "results" / "x.md", good) == [
        "first line '*Reference.*', not '*Results.*'"
    ]
    assert kind_problems(DOCS / "x.md", good) == ["not in one of " + str(sorted(KINDS))]
    assert kind_problems(page, "# The filter\n") == [
        "first line '# The filter', not '*Reference.*'",
        "no '# Title' right after the first line",
    ]
    assert kind_problems(page, good + "line\n" * MAX_LINES) == [
        f"{MAX_LINES + 5} lines, more than {MAX_LINES}"
    ]
    assert kind_problems(page, good + "as issue 43 measured; Issue #7\n") == [
        "cites 'issue 43'",
        "cites 'Issue #7'",
    ]
    assert kind_problems(page, good + "the issue's target; tissue 4\n") == []
    assert kind_problems(page, good + "measured 2026-12-05, before 2026-12\n") == [
        "dated '2026-12-05'",
        "dated '2026-12'",
    ]
    assert kind_problems(page, good + "Generated on 2026-12-05 by the script\n") == []
    text = "see ``docs/reference/filter.md`` and docs/api.md, not docs/x.py or mydocs/y.md"
    assert cited_paths(text) == ["reference/filter.md", "api.md"]
