"""``benches/run.py --compare OLD.json NEW.json``: two ``--json`` files of the same
command (the previous build and this one, or two machines) side by side, row by row.

Each row's ``new / old`` is given twice: of its number as measured, and of its ratio
to the reference of its own run, from which much of the drift between the two runs
cancels. Files written before rows carried a ratio show the first only.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any


def _over(new: Any, old: Any) -> str:
    """``new / old`` as printed ("" unless both are positive numbers)."""
    if isinstance(new, int | float) and isinstance(old, int | float) and new > 0 and old > 0:
        return f"{new / old:.2f}×"
    return ""


def compare_lines(old: dict[str, Any], new: dict[str, Any], names: tuple[str, str]) -> list[str]:
    """The table of two ``--json`` records (``names``: their files), matched on
    ``what`` in the new record's order."""
    before = {r["what"]: r for r in old["rows"]}
    lines = [
        f"| what | {names[0]} | {names[1]} | new / old | new / old, × reference |",
        "|---|---|---|---|---|",
    ]
    for row in new["rows"]:
        was = before.get(row["what"], {})
        lines.append(
            f"| {row['what']} | {was.get('measured', '—')} | {row['measured']} "
            f"| {_over(row.get('value'), was.get('value'))} "
            f"| {_over(row.get('ratio'), was.get('ratio'))} |"
        )
    for name, record in zip(names, (old, new), strict=True):
        if "reference_s" in record:
            readings = ", ".join(f"{s:.3f} s" for s in record["reference_s"] if s is not None)
            lines.append(f"# {name}: reference {readings}")
    return lines


def compare(old_path: str, new_path: str) -> int:
    """Print two ``--json`` files side by side."""
    old, new = (json.loads(Path(p).read_text()) for p in (old_path, new_path))
    print("\n".join(compare_lines(old, new, (old_path, new_path))))
    return 0
