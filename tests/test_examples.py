"""The scripts in examples/ run and print what their docstrings promise (few runs)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def run(name: str, *args: str) -> str:
    out = subprocess.run(
        [sys.executable, str(EXAMPLES / name), *args],
        check=True,
        capture_output=True,
        text=True,
        timeout=300,
    )
    return out.stdout


def test_every_example_is_tested() -> None:
    assert sorted(p.name for p in EXAMPLES.glob("*.py")) == [
        "custom_trajectory.py",
        "own_regressor.py",
        "sweep_tuning_period.py",
    ]


@pytest.mark.slow
def test_custom_trajectory() -> None:
    out = run("custom_trajectory.py", "--runs", "3").splitlines()
    assert out[0].startswith("survey: 404 s, 40400 IMU samples")
    constant = float(out[1].split("SRMSE ")[1].split()[0])
    assert 0 < constant < 0.2  # a matched filter with a good DVL
    assert "failed 0, diverged 0" in out[1]


@pytest.mark.slow
def test_own_regressor() -> None:
    out = run("own_regressor.py", "--runs", "2").splitlines()
    assert [line.split()[0] for line in out] == ["difference", "detrend"]
    assert all("328 tunings" in line for line in out)


@pytest.mark.slow
@pytest.mark.parametrize("periods", [["1", "5"]])
def test_sweep_tuning_period(periods) -> None:
    out = run("sweep_tuning_period.py", "--runs", "2", "--periods", *periods).splitlines()
    assert out[0] == "tuning_period_s,tunings,srmse,srmse_low,srmse_high,model_seconds"
    rows = [line.split(",") for line in out[1:]]
    assert [r[0] for r in rows] == periods
    assert [int(r[1]) for r in rows] == [328, 65]
    assert all(float(r[3]) <= float(r[2]) <= float(r[4]) for r in rows)
