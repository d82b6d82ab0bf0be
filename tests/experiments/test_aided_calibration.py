"""The DVL calibration states with position fixes and depth
(:mod:`pronet.experiments.aided_calibration`): the mechanism on a few runs, and, marked
slow, the issue's acceptance at 100 runs on every training trajectory. What holds is
asserted; where it does not (the horizontal error on the helix, a tie) it is measured and
reported in docs/results/calibration.md ("With position fixes and depth")."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pronet import _core
from pronet.experiments import aided_calibration
from pronet.montecarlo import monte_carlo
from pronet.recorded import dvlcalibration
from pronet.trajectory import builtin_trajectory


def test_the_aided_dvl_carries_the_scale_error_and_misalignment() -> None:
    """The experiment's sensors are dvlcalibration's DVL (0.5 %, 0.5° yaw) plus the
    fixes and depth, not an ideal DVL."""
    sensors = aided_calibration.aided_sensors()
    assert sensors.dvl_scale == dvlcalibration.TRUE_SCALE
    np.testing.assert_allclose(sensors.dvl_misalignment, dvlcalibration.TRUE_MISALIGNMENT)
    assert sensors.depth_sigma == aided_calibration.DEPTH_SIGMA
    assert [f["period"] for f in sensors.fixes] == [aided_calibration.FIX_PERIOD]


def test_fixes_and_depth_make_the_calibration_observable_on_a_straight_run() -> None:
    """On ``train-straight`` the DVL alone cannot see the scale or the yaw misalignment
    (they stay near their prior σ); with fixes every 60 s and depth the 19-state filter's
    σ of both falls below half of that, every error lies within 3σ, the fixes and depth
    readings arrive as scheduled, and the position error falls."""
    traj = builtin_trajectory("train-straight")
    results = [
        monte_carlo(
            traj,
            _core.Strategy.constant(dvlcalibration.IMU_Q),
            sensors=sensors,
            config=dvlcalibration.filter_config(True),
            n_runs=6,
            seed=1,
            record_every=aided_calibration.RECORD_EVERY,
        )
        for sensors in (dvlcalibration.sensors(), aided_calibration.aided_sensors())
    ]
    alone, aided = results
    assert alone.calibration_sigma is not None and aided.calibration_sigma is not None
    assert aided.calibration_error is not None
    sigma_alone, sigma_aided = alone.calibration_sigma.mean(0), aided.calibration_sigma.mean(0)
    for state in (0, 3):  # scale, yaw
        assert sigma_aided[state] < 0.5 * sigma_alone[state], (state, sigma_alone, sigma_aided)
    assert np.all(np.abs(aided.calibration_error) <= 3 * aided.calibration_sigma)
    assert aided.fix_updates.tolist() == [6] * 6  # 60 .. 360 s of a 400 s run
    assert aided.depth_updates.tolist() == [400] * 6
    assert np.all(alone.fix_updates == 0)
    rms = aided_calibration.horizontal_rms
    assert rms(aided).mean() < 0.5 * rms(alone).mean()


def test_horizontal_rms_is_over_the_recorded_epochs() -> None:
    error = np.zeros((2, 4, 15))
    error[0, :, 0] = [3.0, 3.0, 3.0, 3.0]
    error[1, :, :2] = [[0.0, 0.0], [3.0, 4.0], [0.0, 0.0], [3.0, 4.0]]
    result = monte_carlo(
        builtin_trajectory("paper"), _core.Strategy.constant((1e-4,) * 6), n_runs=2
    )
    got = aided_calibration.horizontal_rms(replace(result, error=error))
    np.testing.assert_allclose(got, [3.0, np.sqrt(12.5)])
    with pytest.raises(ValueError, match="^result: no error history"):
        aided_calibration.horizontal_rms(result)


@pytest.fixture(scope="module")
def rows() -> dict[str, aided_calibration.AidedRow]:
    return {r.trajectory: r for r in aided_calibration.aided_calibration_check(n_runs=100)}


@pytest.mark.slow
def test_the_scale_and_misalignment_lie_within_3_sigma_on_every_trajectory(rows) -> None:
    """The issue's first acceptance: in ≥ 95 % of 100 runs the estimated scale and
    misalignment (all four errors) lie within 3σ of the truth, on every training
    trajectory; the fixes and depth readings are consistent with their σ (NIS per dof
    within 10 % of 1)."""
    assert set(rows) == set(dvlcalibration.TRAJECTORIES)
    for name, r in rows.items():
        assert r.all_inside >= 0.95, (name, r)
        assert abs(r.fix_nis - 1.0) < 0.1, (name, r.fix_nis)


@pytest.mark.slow
def test_the_19_states_navigate_better_where_the_dvl_errors_show(rows) -> None:
    """The issue's second acceptance where it holds: on the straight, turns and zigzag
    trajectories the 19-state filter's horizontal error RMS is below the 15-state
    filter's, the whole 95 % CI of the paired difference below 0 (measured: -0.76,
    -0.40, -1.22 m). On the helix, whose circles average the DVL's errors out, the two
    tie (+0.01 [-0.01, +0.03] m): not asserted, reported in docs/results/calibration.md."""
    for name in ("train-straight", "train-turns", "train-zigzag"):
        r = rows[name]
        assert r.rms_19 < r.rms_15 and r.difference[2] < 0.0, (name, r)
