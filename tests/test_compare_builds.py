"""benches/compare_builds.py loads several builds of the core into one process and
times them interleaved; a build that predicts differently is refused, not timed."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

from pronet import _core

SCRIPT = Path(__file__).resolve().parents[1] / "benches" / "compare_builds.py"


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(SCRIPT), *args], capture_output=True, text=True, timeout=300
    )


def test_two_copies_of_the_installed_build_are_timed_side_by_side(tmp_path: Path) -> None:
    copy = tmp_path / "_core.abi3.so"
    shutil.copyfile(_core.__file__, copy)
    out = run(f"installed={_core.__file__}", f"copy={copy}", "--rounds", "2", "--calls", "1")
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == "detrend net, 600 windows, 2 threads"
    rows = {line.split()[0]: line.split() for line in lines[1:]}
    assert set(rows) == {"installed", "copy"}
    assert rows["installed"][-1] == "×1.000"  # the first build is the reference
    medians = [float(rows[name][2]) for name in ("installed", "copy")]
    assert all(np.isfinite(medians)) and min(medians) > 0


def test_a_build_is_named_when_it_cannot_be_loaded_or_is_malformed(tmp_path: Path) -> None:
    out = run("no-equals-sign")
    assert out.returncode == 2 and "expected NAME=PATH.so, got 'no-equals-sign'" in out.stderr
    bad = tmp_path / "_core.abi3.so"
    bad.write_bytes(b"not a shared object")
    out = run(f"bad={bad}")
    assert out.returncode != 0 and str(bad) in out.stderr
