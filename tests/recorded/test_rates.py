"""Any rates: IMUs at 50 and 200 Hz and one with a 10 % jitter, a DVL
and a ground truth at other rates than 1 Hz; the IMU's real step recorded in
``config.json`` and used by the filter's white-noise term."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from pronet.cli import main
from pronet.recorded.recordings import write_recording
from pronet.recorded.tuning import imu_step

from synthetic_recording import DVL_LEVER_ARM, IMU_LEVER_ARM, synthetic_recording

ARMS = [
    "--imu-lever-arm=" + ",".join(map(str, IMU_LEVER_ARM)),
    "--dvl-lever-arm=" + ",".join(map(str, DVL_LEVER_ARM)),
]


def test_the_nominal_step_is_the_whole_rate_near_the_median_step():
    snapir = np.arange(40_000) * (400 / 39_999)  # the Snapir IMU's stamps: 99.9975 Hz
    assert imu_step(snapir) == 0.01
    assert imu_step(np.arange(100) * 0.005) == 0.005 and imu_step(np.arange(9) / 50) == 0.02
    odd = np.arange(100) * 0.0123  # 81.3 Hz: no whole rate near it, the median step
    assert imu_step(odd) == pytest.approx(0.0123, rel=1e-12)
    jittered = np.arange(1000) * 0.01 + np.random.default_rng(0).uniform(-5e-4, 5e-4, 1000)
    assert imu_step(jittered) == 0.01


def _run(tmp_path, name, duration=100.0, **rates):
    rec = synthetic_recording(seed=5, duration=duration, name=name, **rates).recording
    write_recording(tmp_path / "data" / name, rec)
    out = tmp_path / f"out-{name}"
    argv = ["real", "--data", str(tmp_path / "data" / name), "--format", "generic"]
    assert main([*argv, "--out", str(out), "--quiet", "--no-plots", "--no-models", *ARMS]) == 0
    config = json.loads((out / "config.json").read_text())
    metrics = pd.read_csv(out / "metrics.csv")
    return config, metrics[metrics.scenario == name].iloc[0]


@pytest.mark.parametrize(
    ("rates", "step"),
    [
        ({"imu_rate": 50.0}, 0.02),
        ({"imu_rate": 200.0, "dvl_rate": 5.0, "gt_rate": 20.0}, 0.005),
        ({"imu_rate": 100.0, "jitter": 0.1}, 0.01),
        pytest.param(
            {"imu_rate": 400.0, "dvl_rate": 0.2, "gt_rate": 100.0}, 0.0025, marks=pytest.mark.slow
        ),
        ({"imu_rate": 1000.0, "dvl_rate": 20.0}, 0.001),
        ({"imu_rate": 50.0, "dvl_rate": 0.1, "duration": 300.0}, 0.02),
    ],
)
def test_any_rate_runs_with_its_own_step_in_config_json(tmp_path, capsys, rates, step):
    name = "r" + "-".join(f"{v:g}" for k, v in rates.items() if k != "duration")
    config, first = _run(tmp_path, name, **rates)
    assert config["imu_dt_s"] == {name: step}
    assert f"imu_dt={step}" in config["filter"]
    # the filter does its job at every rate: the error of the 100 Hz section's order
    assert np.isfinite(first.srmse) and first.srmse < 0.1, first.srmse
    assert config["clocks"][name]["gt"][1] == pytest.approx(0.9975, abs=2e-4)
    # 20 DVL rows at 0.2 Hz, 30 at 0.1 Hz: the windowed rows cannot act; left out, said so
    left_out = config["rows_not_run"].get(name, {})
    assert bool(left_out) == (rates.get("dvl_rate", 1.0) < 0.5), left_out
    assert all("never fills" in why for why in left_out.values())
    capsys.readouterr()


def test_a_jittered_imu_is_integrated_over_its_own_steps(tmp_path, capsys):
    """A 10 % jitter, each sample the mean over its own interval: integrated over each
    step as stamped, the filter does as well as on the uniform IMU."""
    _, uniform = _run(tmp_path, "uniform", jitter=0.0)
    _, jittered = _run(tmp_path, "jittered", jitter=0.1)
    assert jittered.srmse == pytest.approx(uniform.srmse, rel=0.25)
    assert jittered.final_horizontal_error < 2 * uniform.final_horizontal_error + 0.5
    capsys.readouterr()
