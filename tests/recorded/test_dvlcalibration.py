"""The DVL calibration states in simulation (:mod:`pronet.recorded.dvlcalibration`): a DVL with
a 0.5 % scale error and a 0.5° yaw misalignment on the training trajectories. What is
asserted is what the states are for and what holds; the full table, with the numbers
that miss the issue's targets, is in docs/results/calibration.md."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import pronet
from pronet import _core
from pronet.montecarlo import monte_carlo
from pronet.recorded import dvlcalibration

from module_file import load

RUNS = 50


@pytest.fixture(scope="module")
def rows() -> dict[str, dvlcalibration.CalibrationRow]:
    return {r.trajectory: r for r in dvlcalibration.calibration_check(n_runs=RUNS)}


@pytest.mark.slow
def test_the_calibration_states_are_consistent_on_every_training_trajectory(rows) -> None:
    """In ≥ 95 % of the runs all four calibration errors lie within 3σ, and the mean
    NIS over the runs is inside its 95 % band at ≥ 90 % of the DVL epochs."""
    for name, r in rows.items():
        assert r.inside_3sigma >= 0.95, (name, r)
        assert r.nis_in_band >= 0.90, (name, r)


@pytest.mark.slow
def test_turns_make_the_calibration_observable_and_pay(rows) -> None:
    """Where the vehicle turns (``train-zigzag``, ``train-turns``) the states find the
    scale and the yaw misalignment: the mean estimate over the runs lies closer to the
    truth than to the prior's 0 (within three standard errors of it on the zigzag,
    where the posterior σ is a quarter of the prior's; on ``train-turns`` the scale
    keeps about half its prior σ and its estimate is pulled towards 0, as a Bayesian
    estimate of a fixed truth is), the spread is under half the prior σ, and the final
    horizontal error falls well below the 15-state filter's, towards the ideal DVL's."""
    for name in ("train-zigzag", "train-turns"):
        r = rows[name]
        for (mean, spread), truth, prior in (
            (r.scale, dvlcalibration.TRUE_SCALE, 0.01),
            (r.yaw, dvlcalibration.TRUE_MISALIGNMENT[2], math.radians(1.0)),
        ):
            assert abs(mean - truth) < 0.5 * truth, (name, mean, truth)
            if name == "train-zigzag":
                assert abs(mean - truth) < 3 * spread / math.sqrt(RUNS), (name, mean, truth)
            assert spread < 0.5 * prior, (name, spread)
        assert r.ratio < 0.7, (name, r.final_19, r.final_15)
        assert r.final_ideal < r.final_19, name


def test_a_dvl_without_errors_and_states_without_a_prior_change_nothing() -> None:
    """The 15-state filter on an ideal simulated DVL is bit-identical whether or not
    the scenario spells out a zero scale and misalignment; the 19-state filter whose
    calibration prior is zero follows the 15-state one to rounding."""
    traj = pronet.builtin_trajectory("train-turns")
    q = dvlcalibration.IMU_Q
    plain = _core.SensorConfig(imu_variance=q)
    spelt = _core.SensorConfig(imu_variance=q, dvl_scale=0.0, dvl_misalignment=(0.0, 0.0, 0.0))
    strategy = _core.Strategy.constant(q)
    a = monte_carlo(traj, strategy, sensors=plain, n_runs=3)
    b = monte_carlo(traj, strategy, sensors=spelt, n_runs=3)
    np.testing.assert_array_equal(a.srmse, b.srmse)
    assert a.calibration_error is None
    frozen = _core.FilterConfig(
        dvl_calibration=True, dvl_scale_sigma=0.0, dvl_misalignment_sigma=(0.0, 0.0, 0.0)
    )
    c = monte_carlo(traj, strategy, sensors=plain, config=frozen, n_runs=3)
    np.testing.assert_allclose(c.srmse, a.srmse, rtol=1e-9)
    assert c.calibration_error is not None and np.all(c.calibration_error == 0.0)


def test_calibration_arguments_are_checked() -> None:
    with pytest.raises(ValueError, match="dvl_misalignment_sigma: describes the DVL"):
        _core.FilterConfig(dvl_misalignment_sigma=(0.01, 0.01, 0.01))
    with pytest.raises(ValueError, match="dvl_calibration: the DVL calibration states need"):
        _core.FilterConfig(dvl_calibration=True, aiding="nav")
    with pytest.raises(ValueError, match="dvl_scale_sigma"):
        _core.FilterConfig(dvl_calibration=True, dvl_scale_sigma=-0.01)
    with pytest.raises(ValueError, match="dvl_scale: must be finite and > -1"):
        _core.SensorConfig(dvl_scale=-1.0)
    with pytest.raises(ValueError, match="dvl_misalignment"):
        _core.SensorConfig(dvl_misalignment=(0.0, float("nan"), 0.0))
    cfg = _core.FilterConfig(dvl_calibration=True)
    assert cfg.dvl_calibration and cfg.dvl_scale_sigma == 0.01
    assert cfg.dvl_misalignment_sigma == pytest.approx([math.radians(1.0)] * 3)
    assert _core.FilterConfig().dvl_scale_sigma is None
    s = _core.SensorConfig(dvl_scale=0.005, dvl_misalignment=(0.001, -0.002, 0.0087))
    assert s.dvl_scale == 0.005
    assert s.dvl_misalignment == pytest.approx([0.001, -0.002, 0.0087], abs=1e-15)


@pytest.mark.slow
def test_with_the_dvl_drawn_from_the_prior_the_calibration_nees_is_consistent() -> None:
    """The NEES test proper: each of 100 runs gets its own DVL scale and mounting drawn
    from the filter's prior. Where the vehicle turns, the mean calibration NEES is
    inside its 95 % band at ≥ 90 % of the epochs and ≥ 95 % of the runs end within 3σ
    (the straight trajectory's 67 % is in docs/results/calibration.md)."""
    for name in ("train-zigzag", "train-turns"):
        got = dvlcalibration.drawn_consistency(name, n_runs=100)
        assert got.nees_in_band >= 0.90, got
        assert got.inside_3sigma >= 0.95, got
        assert got.nis_in_band >= 0.90, got


def _scale_drift():
    """``scripts/scale_drift.py``, imported (a script, not part of the package)."""
    return load(Path(__file__).resolve().parents[2] / "scripts" / "scale_drift.py")


def test_on_a_steady_leg_the_scale_drifts_low_and_the_exact_posterior_agrees() -> None:
    """docs/results/calibration.md#the-scale-drifts-low-on-steady-legs: on the one-axis model (truth
    k = 0) the EKF's final scale and the exact posterior mean under the same
    error-state model drift alike, and both drift below 0 when the INS velocity
    wanders; with the 19-state filter on a steady straight run with an ideal DVL the
    scale ends below 0 as well."""
    drift = _scale_drift()
    runs = 40
    ekf = drift.one_axis(3.2e-4, False, runs, np.random.default_rng(1))
    exact = drift.one_axis(3.2e-4, True, runs, np.random.default_rng(1))
    # the same drift (means within a tenth of it), run by run closely alike
    assert abs(np.mean(ekf) - np.mean(exact)) < 0.1 * abs(np.mean(exact))
    assert np.corrcoef(ekf, exact)[0, 1] > 0.8
    for k in (ekf, exact):
        assert np.mean(k) < -5 * np.std(k) / math.sqrt(runs)  # well below the truth, 0
    table = drift.filter_table(12)
    rows = [line.split(" | ") for line in table.splitlines()[2:]]
    assert len(rows) == 5 and rows[0][1] == ""  # the 15-state row has no scale
    scale = float(rows[1][1].split(" ± ")[0])
    assert scale < -0.2  # % : below the truth's 0, as the doc's -0.65 % at 60 runs


def test_the_calibration_prior_can_be_chosen() -> None:
    """``calibration_check(prior=)`` reaches the filter: the states start from it, and
    on a straight run (scale barely observable) they end near its σ, not the default's."""
    straight = ("train-straight",)
    tight = dvlcalibration.calibration_check(8, trajectories=straight, prior=(0.003, 0.005))
    default_scale = dvlcalibration.filter_config(True).dvl_scale_sigma
    assert default_scale is not None and tight[0].sigma_scale < 0.003 < 0.5 * default_scale
    assert tight[0].sigma_yaw < 0.005


def test_both_calibration_tables_report_the_estimates_alike() -> None:
    """:func:`dvlcalibration.estimate_spread` is the truth plus the errors, averaged
    (and the σ), and the simulated table and the aided experiment's print it with the
    same cells and the same DVL in the title."""
    from pronet.experiments import aided_calibration

    error = np.array([[0.001, 0, 0, -0.002], [-0.001, 0, 0, 0.004]])
    sigma = np.full((2, 4), 0.003)
    spread = dvlcalibration.estimate_spread(error, sigma)
    assert spread.scale == pytest.approx((dvlcalibration.TRUE_SCALE, 0.001))
    assert spread.yaw == pytest.approx((dvlcalibration.TRUE_MISALIGNMENT[2] + 0.001, 0.003))
    assert spread.sigma_scale == spread.sigma_yaw == 0.003
    common = {"trajectory": "t", "runs": 2, **spread._asdict()}
    plain = dvlcalibration.CalibrationRow(
        final_15=1.0, final_19=0.5, final_ideal=0.4, srmse_15=0.01, srmse_19=0.01,
        inside_3sigma=1.0, nis_in_band=1.0, nees_in_band=1.0, **common,
    )  # fmt: skip
    aided = aided_calibration.AidedRow(
        scale_inside=1.0, yaw_inside=1.0, all_inside=1.0, rms_15=2.0, rms_19=1.0,
        difference=(-1.0, -1.5, -0.5), fix_nis=1.0, **common,
    )  # fmt: skip
    cells = dvlcalibration.spread_cells(plain)
    assert cells == ["0.50 ± 0.10 (0.30)", "0.56 ± 0.17 (0.17)"]
    tables = (dvlcalibration.calibration_table([plain]), aided_calibration.aided_table([aided]))
    for table in tables:
        assert f"| {cells[0]} | {cells[1]} |" in table
        assert table.startswith(f"### {dvlcalibration.miscalibration()}, ")
