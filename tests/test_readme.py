"""The Python blocks of the README and the docs pages run as written: the README's
quick start as one session, and each page's blocks as one session of their own."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: docs/api.md is generated from the docstrings; its blocks are signatures, not sessions.
GENERATED = {ROOT / "docs" / "api.md"}
PYTHON_BLOCK = re.compile(r"```python\n(.*?)```", flags=re.S)


def run_blocks(page: Path) -> dict[str, object]:
    """Run every ```python block of ``page`` in order, in one namespace, and return it."""
    blocks = PYTHON_BLOCK.findall(page.read_text(encoding="utf-8"))
    assert blocks, f"{page.relative_to(ROOT)} has no Python block"
    namespace: dict[str, object] = {"__name__": "__docs__"}
    for code in blocks:
        exec(compile(code, str(page), "exec"), namespace)  # noqa: S102 - our own pages
    return namespace


def pages_with_python() -> list[Path]:
    pages = sorted((ROOT / "docs").glob("*.md"))
    return [
        p
        for p in pages
        if p not in GENERATED and PYTHON_BLOCK.search(p.read_text(encoding="utf-8"))
    ]


@pytest.mark.slow
def test_readme_quick_start_runs() -> None:
    namespace = run_blocks(README)
    assert namespace["res"].summary()["srmse"].mean < 0.1


def test_the_docs_pages_have_python_to_run() -> None:
    # The page check below must see real pages, or it passes vacuously.
    names = {p.name for p in pages_with_python()}
    assert {"python.md", "learning.md", "cli.md"} <= names


def _python_md(ns: dict) -> None:
    assert ns["mine"].time[-1] == 75.0  # 30 s + 45 s of segments
    assert ns["res"].error.shape == ns["res"].sigma.shape == (10, 76, 15)  # every 1 s
    assert ns["out"].nis.shape == (10,)  # one NIS per DVL reading
    assert len(ns["table"]) == len(ns["out"].time)
    np.testing.assert_allclose(ns["back"], ns["out"].lla, rtol=0, atol=1e-8)  # ECEF rounding
    assert ns["mine_result"].n_runs == 4 and ns["mine_result"].q is None
    assert ns["mine_result"].summary()["position_nees"].n == 4


def _learning_md(ns: dict) -> None:
    assert ns["hyb"].result.summary()["srmse"].mean < 5.0


def _cli_md(ns: dict) -> None:
    assert len(ns["df"]) == 4  # 2 strategies x 2 noise levels
    assert len(ns["runs"]) == 16  # x 4 runs


#: What each page's session must have produced, beyond running without an error.
CHECKS = {"python.md": _python_md, "learning.md": _learning_md, "cli.md": _cli_md}


@pytest.mark.parametrize("page", pages_with_python(), ids=lambda p: p.name)
def test_docs_python_blocks_run(page: Path) -> None:
    namespace = run_blocks(page)
    CHECKS.get(page.name, lambda ns: None)(namespace)
