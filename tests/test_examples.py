"""The scripts in examples/ run and print what their docstrings promise (few runs), and
the docs pages show the ones they walk through as they are."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

import pronet

from module_file import load

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
NUMBER = r"[-+]?\d+\.\d+"


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
        "mems_survey.py",
        "online_ros2.py",  # tests/recorded/test_online_example.py (a ROS 2 bag)
        "own_arrays.py",
        "own_estimator.py",
        "own_regressor.py",
        "sweep_tuning_period.py",
    ]


def _example_docs():
    return load(ROOT / "scripts" / "example_docs.py")


def test_python_md_shows_the_walked_examples_as_they_are(capsys) -> None:
    docs = _example_docs()
    assert docs.main(["--check"]) == 0, capsys.readouterr().out
    for name, path in docs.WALKED.items():
        page = path.read_text(encoding="utf-8")
        assert (EXAMPLES / name).read_text(encoding="utf-8") in page, name
    # A page whose copy differs from its script is rewritten to the script.
    path = docs.WALKED["mems_survey.py"]
    page = path.read_text(encoding="utf-8")
    stale = page.replace("lawnmower()", "survey()", 1)
    assert stale != page and docs.render(stale, path) == page


@pytest.mark.slow
def test_mems_survey_reports_a_consistent_filter_in_every_block() -> None:
    out = run("mems_survey.py", "--runs", "8").splitlines()
    assert out[0] == "lawnmower: 384 s, 38400 IMU samples, 5 Hz DVL"
    srmse = float(re.search(f"SRMSE ({NUMBER})", out[1]).group(1))  # type: ignore[union-attr]
    assert 0 < srmse < 0.2  # a MEMS IMU held by a 5 Hz DVL
    blocks = [line.split() for line in out[3:]]
    assert [b[0] for b in blocks] == list(pronet.STATE_BLOCKS)
    # The filter is told the simulated model: every block's run-mean NEES near 3.
    assert all(1.5 < float(b[1].rstrip(",")) < 6.0 for b in blocks), out


@pytest.mark.slow
def test_own_estimator_runs_in_lockstep_and_reports_a_paired_difference() -> None:
    out = run("own_estimator.py", "--runs", "4").splitlines()
    assert out[0].startswith("difference variance: SRMSE ") and out[0].endswith("328 tunings")
    low_high = re.search(f"paired difference: +({NUMBER}) \\[({NUMBER}), ({NUMBER})\\]", out[2])
    assert low_high is not None, out[2]
    mean, low, high = (float(x) for x in low_high.groups())
    assert low <= mean <= high


def test_own_arrays_filters_the_arrays_and_keeps_the_covariance_asked_for() -> None:
    out = run("own_arrays.py").splitlines()
    assert out[0].startswith("33001 epochs, 1650 DVL updates, mean NIS ")
    assert 2.0 < float(out[0].rsplit(" ", 1)[1]) < 4.0  # R told the truth: NIS ≈ 3
    kept = out[2:]
    assert [line.split(" s:")[0] for line in kept] == ["t =  60.0", "t = 180.0", "t = 300.0"]
    for line in kept:
        north, east, major, minor = (float(x) for x in re.findall(NUMBER, line.split(":", 1)[1]))
        assert 0 < minor <= major
        assert max(abs(north), abs(east)) < 4 * major, line  # inside the ellipse's box


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
