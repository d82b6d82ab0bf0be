"""benches/run.py works end to end on its cheap rows (``--quick``): the table and the
``--json`` file hold the same rows, each row's verdict agrees with its number and
target, ``--compare`` pairs the rows, and the yardstick reading divides as documented.
Nothing here judges the machine's speed."""

from __future__ import annotations

import importlib.util
import json
import re
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benches" / "run.py"
#: Rows cheap enough for every CI run (seconds in all under --quick).
CHEAP = ["mechanization", "monte-carlo", "covariance-step", "hybrid", "dataset", "inference"]


def bench(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(SCRIPT), *args], capture_output=True, text=True, timeout=600
    )


@pytest.fixture(scope="module")
def quick(tmp_path_factory) -> tuple[str, dict, Path]:
    out = tmp_path_factory.mktemp("bench") / "quick.json"
    done = bench("--quick", "--only", *CHEAP, "--json", str(out))
    assert done.returncode == 0, done.stderr
    return done.stdout, json.loads(out.read_text()), out


def table(stdout: str) -> list[list[str]]:
    """The table's data rows, as cells."""
    lines = [line for line in stdout.splitlines() if line.startswith("| ")]
    cells = [[c.strip() for c in line.strip("|").split(" | ")] for line in lines]
    return [c for c in cells[1:] if c[0] != "---"]  # past the header and its rule


def test_the_table_and_the_json_hold_the_same_rows(quick):
    stdout, record, _ = quick
    printed = table(stdout)
    rows = record["rows"]
    assert [c[0] for c in printed] == [r["what"] for r in rows]
    assert [c[1] for c in printed] == [r["measured"] for r in rows]
    assert record["runs"] == 10 and "--quick" in record["command"]
    assert all(len(c) == 5 for c in printed)
    whats = " / ".join(r["what"] for r in rows)
    for part in ("pronet.mechanize", "constant Q Monte Carlo", "1 → 2 threads", "ProNet detrend"):
        assert part in whats
    assert sum(r["what"].startswith("inference, ") for r in rows) >= 5


def test_each_verdict_agrees_with_its_number_and_target(quick):
    _, record, _ = quick
    judged = 0
    for row in record["rows"]:
        assert row["value"] is None or row["value"] > 0, row
        limit = re.fullmatch(r"≤ ([0-9.]+) s", row["target"])
        if limit is not None:
            assert row["unit"] == "s" and row["met"] == (row["value"] <= float(limit[1])), row
            judged += 1
        elif row["target"] in ("—", ""):
            assert row["met"] is None, row
    assert judged >= 4  # the two Monte Carlos, the two loops with targets, the dataset


def test_compare_pairs_the_rows_of_two_files(quick, tmp_path):
    _, record, path = quick
    other = dict(
        record, rows=[dict(r, value=2 * r["value"]) if r["value"] else r for r in record["rows"]]
    )
    doubled = tmp_path / "doubled.json"
    doubled.write_text(json.dumps(other))
    done = bench("--compare", str(path), str(doubled))
    assert done.returncode == 0, done.stderr
    rows = table(done.stdout)
    assert [c[0] for c in rows] == [r["what"] for r in record["rows"]]
    assert all(
        c[3] == ("2.00×" if r["value"] else "") for c, r in zip(rows, record["rows"], strict=True)
    )
    assert "yardsticks" not in done.stdout  # at 10 runs the reading is not defined


def load_script(monkeypatch) -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_run", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "bench_run", module)  # for its dataclasses
    spec.loader.exec_module(module)
    return module


def test_yardsticks_divide_by_the_same_runs_constant_q_monte_carlo(monkeypatch):
    run = load_script(monkeypatch)
    stick = f"{run.YARDSTICK_ROW}, 100 runs × 330 s, 2 threads"
    rows = [
        {"what": stick, "target": "≤ 0.8 s", "value": 0.5},
        {"what": "fast", "target": "≤ 3 s", "value": 1.0},
        {"what": "slow", "target": "≤ 1.5 s", "value": 1.0},
        {"what": "no target", "target": "—", "value": 9.0},
        {"what": "a ratio", "target": "≥ 1.8×", "value": 1.9},
    ]
    lines = run.in_yardsticks(rows, 100)
    limit_fast, limit_slow = 3 / run.TARGET_MACHINE_YARDSTICK, 1.5 / run.TARGET_MACHINE_YARDSTICK
    assert lines[1:] == [
        f"#   fast: 2.00 (target {limit_fast:.2f}, met)",
        f"#   slow: 2.00 (target {limit_slow:.2f}, **not met**)",
    ]
    assert run.in_yardsticks(rows, 10) == []  # not at the targets' 100 runs
    assert run.in_yardsticks(rows[1:], 100) == []  # no yardstick row


def test_the_formulation_row_divides_the_two_predict_steps_of_one_criterion_run(monkeypatch):
    run = load_script(monkeypatch)
    row = run.Row

    def rust(name: str, ns: float) -> object:
        return row(f"ekf predict {name} (covariance + strapdown) (Rust)", "", "—", None, "c", ns)

    for classic, invariant in [(400.0, 440.0), (400.0, 520.0)]:
        (ratio,) = run.formulation_ratio(
            [rust("classic", classic), rust("invariant", invariant)], "c"
        )
        assert ratio.value == pytest.approx(invariant / classic) and ratio.unit == "x"
        assert ratio.met == (invariant / classic <= run.FORMULATION_TARGET)
        assert ratio.target == f"≤ {run.FORMULATION_TARGET}×"
    assert run.formulation_ratio([rust("classic", 400.0)], "c") == []  # one side missing
