"""Copy the walk-through examples into ``docs/python.md``.

    python scripts/example_docs.py          # rewrite the page's example blocks
    python scripts/example_docs.py --check  # exit 1 if a block differs from its script

The scripts in ``examples/`` are the one source: each of :data:`WALKED` stands in
``docs/python.md`` whole, as a Python block between the markers
``<!-- example-NAME:begin -->`` and ``<!-- example-NAME:end -->`` (NAME the script's
stem). ``tests/test_examples.py`` runs the scripts and checks that the page is current.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "python.md"
EXAMPLES = ROOT / "examples"
#: The scripts the page walks through, in its order.
WALKED = ("mems_survey.py", "own_estimator.py", "own_arrays.py")


def render(page: str) -> str:
    """``page`` with each walked script's block replaced by the script as it is."""
    from pronet.results import between_markers

    for name in WALKED:
        code = (EXAMPLES / name).read_text(encoding="utf-8")
        block = f"```python\n{code}```\n"
        page = between_markers(page, f"example-{Path(name).stem}", block, str(PAGE))
    return page


def main(argv: list[str]) -> int:
    page = PAGE.read_text(encoding="utf-8")
    current = render(page)
    if argv == ["--check"]:
        if current != page:
            print(f"{PAGE} differs from examples/; run python scripts/example_docs.py")
            return 1
        return 0
    if argv:
        print("usage: python scripts/example_docs.py [--check]", file=sys.stderr)
        return 2
    PAGE.write_text(current, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
