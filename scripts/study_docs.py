"""Regenerate ``docs/results/study.md``'s tables and figure from a study's result folder.

    pronet study --out results/study            # 100 runs, about a minute
    python scripts/study_docs.py results/study  # copies study.csv and study.png into
                                                # docs/results/study/ and rewrites
                                                # the tables

The tables between the ``study`` markers of ``docs/results/study.md`` are rendered
from ``docs/results/study/study.csv`` by
:func:`pronet.experiments.study.study_markdown`, never typed;
``tests/test_docs.py`` checks that they match.
"""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "results" / "study.md"
DATA = ROOT / "docs" / "results" / "study"


def render(page: str, tables: str) -> str:
    """``page`` with the text between the study markers replaced by ``tables``."""
    from pronet.results import between_markers

    return between_markers(page, "study-tables", tables, str(PAGE))


def tables() -> str:
    """The tables of ``docs/results/study/study.csv``."""
    import pandas as pd

    from pronet.experiments.study import study_markdown

    return study_markdown(pd.read_csv(DATA / "study.csv"))


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: python scripts/study_docs.py RESULT_FOLDER", file=sys.stderr)
        return 2
    folder = Path(argv[0])
    for name in ("study.csv", "study.png", "config.json"):
        if not (folder / name).is_file():
            print(f"{folder}: no {name}; is it a pronet study folder?", file=sys.stderr)
            return 2
    DATA.mkdir(exist_ok=True)
    for name in ("study.csv", "study.png", "config.json"):
        shutil.copyfile(folder / name, DATA / name)
    PAGE.write_text(render(PAGE.read_text(), tables()))
    print(f"{PAGE} and {DATA} updated from {folder}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
