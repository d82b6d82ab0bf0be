"""benches/run.py works end to end on its cheap rows (``--quick``): the table and the
``--json`` file hold the same rows, each timed row is its number over the same run's
reference, each verdict agrees with its number and target, and ``--compare`` pairs the
rows of two runs. benches/online.py's ``--quick`` prints its rows, its feeds end where
``run_filter`` does, and run.py carries its headline rows. Nothing here judges the
machine's speed."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[1]
BENCHES = ROOT / "benches"
SCRIPT = BENCHES / "run.py"
#: Rows cheap enough for every CI run (seconds in all under --quick).
CHEAP = [
    "mechanization",
    "monte-carlo",
    "covariance-step",
    "hybrid",
    "dataset",
    "inference",
    "pyins",
    "real-memory",
    "bag-read",
]


def bench(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(SCRIPT), *args], capture_output=True, text=True, timeout=600
    )


@pytest.fixture(scope="module")
def quick(tmp_path_factory) -> tuple[str, dict, Path]:
    """``run.py --quick`` on the cheap rows: about a minute on two cores, so each test
    that reads it is marked slow (the online bench below stays in the fast tier)."""
    out = tmp_path_factory.mktemp("bench") / "quick.json"
    done = bench("--quick", "--only", *CHEAP, "--json", str(out))
    assert done.returncode == 0, done.stderr
    return done.stdout, json.loads(out.read_text()), out


def table(stdout: str) -> list[list[str]]:
    """The table's data rows, as cells."""
    lines = [line for line in stdout.splitlines() if line.startswith("| ")]
    cells = [[c.strip() for c in line.strip("|").split(" | ")] for line in lines]
    return [c for c in cells[1:] if c[0] != "---"]  # past the header and its rule


@pytest.mark.slow
def test_the_table_and_the_json_hold_the_same_rows(quick):
    stdout, record, _ = quick
    printed = table(stdout)
    rows = record["rows"]
    assert [c[0] for c in printed] == [r["what"] for r in rows]
    assert [c[3] for c in printed] == [r["measured"] for r in rows]
    assert record["runs"] == 10 and "--quick" in record["command"]
    assert all(len(c) == 7 for c in printed)
    whats = " / ".join(r["what"] for r in rows)
    for part in ("pronet.mechanize", "constant Q Monte Carlo", "1 → 2 threads", "ProNet detrend"):
        assert part in whats
    assert sum(r["what"].startswith("inference, ") for r in rows) >= 5
    before, after = record["reference_s"]
    assert before > 0 and after > 0
    assert f"every IMU step: {before:.3f} s before the rows" in stdout


@pytest.mark.slow
def test_each_timed_row_is_its_number_over_the_same_runs_reference(quick):
    stdout, record, _ = quick
    reference = record["reference_s"][0]
    per_step = reference / (100 * 33_000) * 1e9
    timed = 0
    for row, cells in zip(record["rows"], table(stdout), strict=True):
        if row["unit"] == "s":
            assert row["ratio"] == pytest.approx(row["value"] / reference), row
        elif row["unit"] == "ns per step":
            assert row["ratio"] == pytest.approx(row["value"] / per_step), row
        else:
            assert row["ratio"] is None, row
            continue
        assert cells[1].endswith("×") and float(cells[1][:-1]) == pytest.approx(
            row["ratio"], rel=0.01, abs=0.01
        )
        timed += 1
    assert timed >= 10
    # the constant-Q Monte Carlo at 10 runs: about a tenth of the 100-run reference
    (mc,) = [r for r in record["rows"] if r["what"].startswith("constant Q Monte Carlo")]
    assert 0.02 < mc["ratio"] < 0.5
    assert mc["ns_per_step"] == pytest.approx(mc["value"] / (10 * 33_000) * 1e9)


@pytest.mark.slow
def test_each_verdict_agrees_with_its_number_and_target(quick):
    _, record, _ = quick
    judged = 0
    for row in record["rows"]:
        assert row["value"] is None or row["value"] > 0, row
        target = re.fullmatch(r"([≤≥]) ([0-9.]+)×.*", row["target"])
        if target is not None:
            number = row["ratio"] if row["ratio"] is not None else row["value"]
            limit = float(target[2])
            assert row["met"] == (number <= limit if target[1] == "≤" else number >= limit), row
            judged += 1
        elif row["target"] in ("—", ""):
            assert row["met"] is None, row
    assert judged >= 5  # Mehra, threads, the covariance step, the two loops, the dataset


@pytest.mark.slow
def test_the_output_row_divides_the_every_epoch_pass_by_the_last_only_one(quick):
    _, record, _ = quick
    rows = {r["what"]: r for r in record["rows"]}
    step = "0.1 s covariance step: `run_filter`, 0.1 h at 100 Hz, 1 Hz DVL"
    last, every = rows[f"{step}, last epoch kept"], rows[f"{step}, every epoch kept"]
    ratio = rows["0.1 s covariance step: `run_filter` keeping every epoch against the last only"]
    assert ratio["value"] == pytest.approx(every["value"] / last["value"], rel=1e-9)
    assert ratio["target"] == "≤ 1.5×"


@pytest.mark.slow
def test_pyins_row_is_skipped_cleanly_without_pyins(quick):
    _, record, _ = quick
    (row,) = [r for r in record["rows"] if r["what"].startswith("pyins")]
    try:
        import pyins  # noqa: F401
    except ImportError:
        assert row["measured"].startswith("skipped: pyins") and row["met"] is None


@pytest.mark.slow
def test_compare_pairs_the_rows_of_two_files(quick, tmp_path):
    _, record, path = quick

    def doubled(r: dict) -> dict:
        twice = {k: 2 * r[k] for k in ("value", "ratio") if r[k]}
        return dict(r, **twice)

    other = dict(record, rows=[doubled(r) for r in record["rows"]])
    later = tmp_path / "doubled.json"
    later.write_text(json.dumps(other))
    done = bench("--compare", str(path), str(later))
    assert done.returncode == 0, done.stderr
    rows = table(done.stdout)
    assert [c[0] for c in rows] == [r["what"] for r in record["rows"]]
    for cells, r in zip(rows, record["rows"], strict=True):
        assert cells[3] == ("2.00×" if r["value"] else "")
        assert cells[4] == ("2.00×" if r["ratio"] else "")


def load(name: str, monkeypatch) -> ModuleType:
    """A module of benches/, imported as run.py imports it."""
    monkeypatch.syspath_prepend(str(BENCHES))
    return __import__(name)


def test_a_former_target_in_seconds_reads_over_the_target_machines_reference(monkeypatch):
    rows = load("rows", monkeypatch)
    ref = rows.Reference(0.5)
    at_most = rows.from_seconds_target(3.0)
    assert at_most == round(3.0 / rows.TARGET_MACHINE_REFERENCE, 2)
    fast = rows.timed_row("fast", 1.0, ref, "c", at_most=at_most, steps=1000)
    slow = rows.timed_row("slow", 1.5, ref, "c", at_most=at_most)
    assert fast.ratio == 2.0 and fast.met and fast.ns_per_step == pytest.approx(1e6)
    assert slow.ratio == 3.0 and slow.met is False and slow.ns_per_step is None
    assert fast.target == f"≤ {at_most:.2f}×"
    step = rows.per_step_row("step", ref.ns_per_step / 4, ref, "c")
    assert step.ratio == pytest.approx(0.25) and step.met is None


def test_the_formulation_row_divides_the_two_predict_steps_of_one_criterion_run(monkeypatch):
    filter_rows = load("filter_rows", monkeypatch)
    row = load("rows", monkeypatch).Row

    def rust(name: str, ns: float) -> object:
        return row(f"ekf predict {name} (covariance + strapdown) (Rust)", "", "—", None, "c", ns)

    for classic, invariant in [(400.0, 440.0), (400.0, 520.0)]:
        (ratio,) = filter_rows.formulation_ratio(
            [rust("classic", classic), rust("invariant", invariant)], "c"
        )
        assert ratio.value == pytest.approx(invariant / classic) and ratio.unit == "x"
        assert ratio.met == (invariant / classic <= filter_rows.FORMULATION_TARGET)
        assert ratio.target == f"≤ {filter_rows.FORMULATION_TARGET}×"
    assert filter_rows.formulation_ratio([rust("classic", 400.0)], "c") == []  # one side missing


#: benches/online.py's rows, in order (``--json``'s keys).
ONLINE_KEYS = [
    "run_filter",
    "run_filter_all",
    "imu_np",
    "wrapper_imu",
    "imu_float",
    "imu_list",
    "floor_np",
    "floor_float",
    "floor_list",
    "block_whole",
    "block_whole_checkpoint_every_epoch",
    "gil",
    "block_1000",
    "wrapper_block_1000",
    "feed_in_order",
    "late_reading",
    "late_feed",
    "memory_0.1h",
    "memory_0.5h",
    "memory_ratio",
]


@pytest.fixture(scope="module")
def online(tmp_path_factory) -> tuple[str, dict]:
    out = tmp_path_factory.mktemp("online") / "online.json"
    done = subprocess.run(
        [sys.executable, str(BENCHES / "online.py"), "--quick", "--json", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout, json.loads(out.read_text())


def test_the_online_bench_prints_its_rows_and_its_json_holds_them(online):
    stdout, record = online
    rows = record["rows"]
    assert [r["key"] for r in rows] == ONLINE_KEYS
    printed = table(stdout)
    assert [c[0] for c in printed] == [r["what"] for r in rows]
    assert [c[1] for c in printed] == [r["measured"] for r in rows]
    assert record["rounds"] == 3 and record["clock"] == "cpu"
    for clock in ("cpu", "wall"):
        times = record["times_s"][clock]
        assert all(len(v) == 3 and min(v) > 0 for v in times.values())
    for r in rows:
        if r["unit"] == "µs per sample":
            assert r["value"] > 0 and r["over_run_filter"] > 0, r
    assert "# where one sample per call goes" in stdout


def test_the_online_bench_feeds_end_on_run_filter_s_epoch_and_its_verdicts_agree(online):
    stdout, record = online
    checks = record["identical"]
    assert all(v for k, v in checks.items() if not k.endswith("_fates")), checks
    dvl = 120 * 5  # two minutes of a 5 Hz DVL
    # every DVL reading late (those fed after the last sample but stamped within its
    # half step: "current"), the depth, fixes and heading (1 Hz) on time
    for name in ("feed_late_05_fates", "feed_late_02_05_fates"):
        fates = dict(checks[name])
        assert fates.pop("late") + fates.pop("current", 0) == dvl, checks[name]
        assert fates == {"queued": 3 * 120}, checks[name]
    assert "bit for bit: yes" in stdout
    for r in record["rows"]:
        if r["target"].endswith("µs over run_filter"):
            assert isinstance(r["met"], bool), r
        elif r["target"].endswith("× run_filter"):
            assert r["met"] == (r["over_run_filter"] <= 1.1), r
        elif r["key"] == "memory_ratio":
            assert r["met"] == (r["value"] <= 1.05), r
        else:
            assert r["target"] == "—" and r["met"] is None, r
    short, long = record["memory"]
    for m, hours in ((short, 0.1), (long, 0.5)):
        samples = round(hours * 3600 * 100)
        assert m["imu_samples"] == m["epoch"] == samples
        assert m["applied"] == m["readings"] == samples // 100 * 8  # 5 Hz DVL + 3 at 1 Hz
        # every DVL reading late but those a chunk's end feeds within its last half step
        assert 0.99 * (samples // 20) <= m["late"] <= samples // 20 and m["peak_mib"] > 0


def test_the_online_rows_in_run_py_s_table(online, monkeypatch):
    _, record = online
    filter_rows = load("filter_rows", monkeypatch)
    ref = load("rows", monkeypatch).Reference(0.5)
    rows = filter_rows.online_rows(record, ref, "c")
    assert len(rows) == len(filter_rows.ONLINE_ROWS)
    for row in rows:
        assert row.what.startswith("online navigator: ")
        if row.unit == "ns per step":
            assert row.ratio == pytest.approx(row.value / ref.ns_per_step)
        else:
            assert row.ratio is None
    blocks = [r for r in rows if "blocks of 1000" in r.what]
    assert len(blocks) == 2 and all(r.unit == "x" and r.target == "≤ 1.1×" for r in blocks)
