"""Copy the walk-through examples into the docs pages that walk through them.

    python scripts/example_docs.py          # rewrite the pages' example blocks
    python scripts/example_docs.py --check  # exit 1 if a block differs from its script

The scripts in ``examples/`` are the one source: each of :data:`WALKED` stands in its
page (``docs/tutorials/first-monte-carlo.md``, ``docs/how-to/own-estimator.md``) whole,
as a Python block between the markers ``<!-- example-NAME:begin -->`` and
``<!-- example-NAME:end -->`` (NAME the script's stem). ``tests/test_examples.py`` runs
the scripts and checks that the pages are current.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
#: The scripts the pages walk through, in their order, each with its page.
WALKED = {
    "mems_survey.py": ROOT / "docs" / "tutorials" / "first-monte-carlo.md",
    "own_estimator.py": ROOT / "docs" / "how-to" / "own-estimator.md",
    "own_arrays.py": ROOT / "docs" / "how-to" / "own-estimator.md",
}
#: The pages, each once.
PAGES = tuple(dict.fromkeys(WALKED.values()))


def render(page: str, path: Path) -> str:
    """``page`` (the text of ``path``) with each of its walked scripts' blocks replaced by
    the script as it is."""
    from pronet.results import between_markers

    for name, where in WALKED.items():
        if where != path:
            continue
        code = (EXAMPLES / name).read_text(encoding="utf-8")
        block = f"```python\n{code}```\n"
        page = between_markers(page, f"example-{Path(name).stem}", block, str(path))
    return page


def main(argv: list[str]) -> int:
    if argv not in ([], ["--check"]):
        print("usage: python scripts/example_docs.py [--check]", file=sys.stderr)
        return 2
    stale = 0
    for path in PAGES:
        page = path.read_text(encoding="utf-8")
        current = render(page, path)
        if current == page:
            continue
        if argv == ["--check"]:
            print(f"{path} differs from examples/; run python scripts/example_docs.py")
            stale = 1
        else:
            path.write_text(current, encoding="utf-8")
    return stale


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
