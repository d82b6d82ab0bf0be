"""The code says what it does, not how it came to be: no internal issue number
("issue 42") and no dated note ("before 2026-12") in the package, the Rust crate, the
scripts, the benchmarks, the examples or the tests. The history lives in CHANGELOG.md
and the commit log."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Where the code lives; the docs pages are checked with the pages.
CODE = ("python", "rust/src", "rust/tests", "scripts", "benches", "examples", "tests")
SUFFIXES = {".py", ".pyi", ".rs", ".sh", ".toml"}
#: "issue 42", "Issue 58 §1", "issues 37 and 42", "issue #42".
ISSUE = re.compile(r"\bissues?\s+#?\d+", flags=re.I)
#: A date: "2026-12" or "2026-12-04".
DATE = re.compile(r"\b20\d\d-(0[1-9]|1[0-2])(-\d\d)?\b")


def history(text: str) -> list[str]:
    """The issue numbers and dates of a text, as written."""
    return [m.group(0) for m in (*ISSUE.finditer(text), *DATE.finditer(text))]


#: The checkers themselves, whose fixtures are history on purpose (this file, and the
#: docs pages' twin of it).
CHECKERS = {Path(__file__).resolve(), ROOT / "tests" / "test_docs_shape.py"}


def code_files() -> list[Path]:
    return sorted(
        p
        for folder in CODE
        for p in (ROOT / folder).rglob("*")
        if p.suffix in SUFFIXES and p.is_file() and p.resolve() not in CHECKERS
    )


def test_the_code_cites_no_issue_and_no_date() -> None:
    files = code_files()
    assert len(files) > 300 and ROOT / "rust" / "src" / "ekf" / "config.rs" in files
    found = {
        f"{p.relative_to(ROOT)}:{n}": hits
        for p in files
        for n, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
        if (hits := history(line))
    }
    assert not found, f"history in the code (say the thing itself): {found}"


def test_the_patterns_find_what_they_look_for() -> None:
    assert history("(issue 37, point 5; Issue 58 §1) issues 41 and issue #43") == [
        "issue 37",
        "Issue 58",
        "issues 41",
        "issue #43",
    ]
    assert history("pronet's filter before 2026-12, moved 2026-12-04") == [
        "2026-12",
        "2026-12-04",
    ]
    assert history("an issue with 3 parts, 20260 samples, seed 2024, 1e-12") == []
