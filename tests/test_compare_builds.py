"""benches/compare_builds.py loads several builds of the core into one process and
times them interleaved, after checking that they answer alike bit for bit; bad
arguments and unloadable builds are named."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from pronet import _core

from module_file import load

SCRIPT = Path(__file__).resolve().parents[1] / "benches" / "compare_builds.py"


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(SCRIPT), *args], capture_output=True, text=True, timeout=300
    )


def rows(stdout: str) -> dict[str, dict[str, list[str]]]:
    """Each title's rows, by build name."""
    out: dict[str, dict[str, list[str]]] = {}
    title = ""
    for line in stdout.splitlines():
        if line.startswith("  "):
            out[title][line.split()[0]] = line.split()
        else:
            title = line
            out[title] = {}
    return out


@pytest.fixture(scope="module")
def script() -> ModuleType:
    return load(SCRIPT, "compare_builds")


@pytest.mark.slow
def test_two_copies_of_the_installed_build_are_timed_side_by_side(tmp_path: Path) -> None:
    copy = tmp_path / "_core.abi3.so"
    shutil.copyfile(_core.__file__, copy)
    out = run(
        f"installed={_core.__file__}",
        f"copy={copy}",
        "--rounds",
        "2",
        "--calls",
        "1",
        "--monte-carlo",
    )
    assert out.returncode == 0, out.stderr
    tables = rows(out.stdout)
    assert list(tables) == [
        "detrend net, 600 windows, 2 threads",
        "constant-Q Monte Carlo, 100 runs, 2 threads",
    ]
    for table in tables.values():
        assert set(table) == {"installed", "copy"}
        assert table["installed"][-1] == "×1.000"  # the first build is the reference
        medians = [float(table[name][2]) for name in ("installed", "copy")]
        assert all(np.isfinite(medians)) and min(medians) > 0


def test_builds_that_answer_differently_are_refused_with_where(script: ModuleType) -> None:
    a = np.array([[1.0, np.nan], [0.0, 2.0]])
    assert script.first_difference({"a": a, "b": a.copy()}) is None  # NaN is NaN
    signed = np.array([[1.0, np.nan], [-0.0, 2.0]])  # equal as numbers, not bit for bit
    assert script.first_difference({"a": a, "b": signed}) == (
        "b: 1 of 4 values differ from a's, the first at (1, 0): -0.0 against 0.0"
    )
    runs = {"error": a, "steps": 7}  # a Monte Carlo's answer: its arrays are compared
    assert script.first_difference({"a": runs, "b": {"error": a.copy()}}) is None
    assert script.first_difference({"a": runs, "b": {"error": a[:1]}}) == (
        "b: error not shaped or typed as a's"
    )
    assert script.first_difference({"a": runs, "b": {}}) == "b: error not shaped or typed as a's"
    # Nothing to compare in two empty arrays (an older build's with fewer columns).
    assert script.first_difference({"a": np.empty((0, 4)), "b": np.empty((0, 7))}) is None
    for other in (np.zeros((1, 4)), np.empty((0, 4), dtype=np.int64), np.empty((0, 4, 1))):
        assert script.first_difference({"a": np.empty((0, 4)), "b": other}) == (
            "b: not shaped or typed as a's"
        )


def test_a_tolerance_admits_rounding_and_nothing_more(script: ModuleType) -> None:
    a = np.array([1.0, 2.0, np.nan, 4.0])
    near = a * (1 + np.array([1e-13, -1e-13, 0.0, 0.0]))
    assert script.first_difference({"a": a, "b": near}) is not None  # not bit for bit
    assert script.first_difference({"a": a, "b": near}, rtol=1e-12) is None
    far = a + np.array([0.0, 0.0, 0.0, 1e-11])  # beyond 1e-12 of the largest, 4
    assert script.first_difference({"a": a, "b": far}, rtol=1e-12) == (
        "b: 1 of 4 values differ from a's, the first at (3,): 4.00000000001 against 4.0"
    )


@pytest.mark.slow
def test_the_filter_is_timed_per_imu_step(tmp_path: Path) -> None:
    copy = tmp_path / "_core.abi3.so"
    shutil.copyfile(_core.__file__, copy)
    out = run(
        f"installed={_core.__file__}",
        f"copy={copy}",
        *("--rounds", "2", "--calls", "1", "--filter", "--rtol", "1e-12", "--hours", "0.02"),
        "--no-net",
    )
    assert out.returncode == 0, out.stderr
    title = "run_filter, 0.02 h at 100 Hz, 5 Hz DVL, default covariance step, epochs kept:"
    assert list(rows(out.stdout)) == [f"{title} last"]  # --no-net: the filter alone
    table = rows(out.stdout)[f"{title} last"]
    assert set(table) == {"installed", "copy"} and table["installed"][3] == "ns/step"
    # Both ways: each build keeping the last epoch and every epoch, compared alike.
    out = run(
        f"installed={_core.__file__}",
        f"copy={copy}",
        *("--rounds", "2", "--filter", "--hours", "0.02", "--epochs", "both", "--no-net"),
    )
    assert out.returncode == 0, out.stderr
    table = rows(out.stdout)[f"{title} both"]
    names = {f"{build}/{kept}" for build in ("installed", "copy") for kept in ("last", "all")}
    assert set(table) == names


def test_bad_arguments_and_unloadable_builds_are_named(tmp_path: Path) -> None:
    out = run("no-equals-sign")
    assert out.returncode == 2 and "expected NAME=PATH.so, got 'no-equals-sign'" in out.stderr
    out = run(f"a={_core.__file__}", f"a={_core.__file__}")
    assert out.returncode == 2 and "the name 'a' is given twice" in out.stderr
    out = run(f"a={_core.__file__}", "--calls", "0")
    assert out.returncode == 2 and "--calls: must be >= 1, got 0" in out.stderr
    out = run(f"a={_core.__file__}", "--no-net")
    assert out.returncode == 2 and "--no-net leaves nothing to time" in out.stderr
    bad = tmp_path / "_core.abi3.so"
    bad.write_bytes(b"not a shared object")
    out = run(f"bad={bad}")
    (line,) = out.stderr.strip().splitlines()  # one line, no traceback
    assert out.returncode == 1 and line.startswith(f"{bad}: not a loadable build of pronet")
