"""The DVL calibration a section's ground truth implies (pronet.recorded.dvltruth): recovered on
simulated sections with a known scale error and mounting, refused where it cannot be
made."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import pronet
from pronet.recorded import real
from pronet.recorded.alignment import Alignment, Section, align
from pronet.recorded.dvltruth import MIN_ROWS, truth_calibration

from synthetic_recording import (
    DVL_CLOCK,
    DVL_LEVER_ARM,
    GT_CLOCK,
    IMU_LEVER_ARM,
    synthetic_recording,
)


def section(seed: int, mounting=(0.0, (0.0, 0.0, 0.0)), duration: float = 400.0) -> Section:
    """A simulated section aligned with its true clocks and lever arms."""
    rec = synthetic_recording(seed, duration, dvl_mounting=mounting).recording
    given = Alignment(GT_CLOCK, DVL_CLOCK, IMU_LEVER_ARM, DVL_LEVER_ARM, how="given")
    return align(rec, given)


@pytest.mark.parametrize(
    "mounting",
    [
        (0.0, (0.0, 0.0, 0.0)),
        (0.004, (math.radians(0.3), math.radians(-0.4), math.radians(0.5))),
        (-0.006, (0.0, math.radians(0.6), math.radians(-0.8))),
    ],
)
def test_the_truth_gives_back_the_dvls_scale_and_mounting(mounting) -> None:
    truth = np.array([mounting[0], *mounting[1]])
    fit = truth_calibration(section(3, mounting))
    assert fit.rows > 350
    # within 3 sigma, and the sigmas small enough to mean something: 0.1 % and 0.1 deg
    # for scale, pitch and yaw. The roll is seen only through motion along the body's
    # y and z axes, which this vehicle hardly has: its sigma is large, and says so.
    assert np.all(np.abs(fit.estimate - truth) <= 3 * fit.sigma), (fit.estimate, fit.sigma)
    assert fit.sigma[0] < 1e-3 and np.all(fit.sigma[2:] < math.radians(0.1)), fit.sigma
    assert fit.rms_residual == pytest.approx(0.01, rel=0.2)  # the DVL's own noise


def test_a_wrong_mounting_is_seen_beyond_its_sigma() -> None:
    """The fit is not just near zero: 0.5 % and 0.5 deg stand out by many sigma."""
    fit = truth_calibration(section(4, (0.005, (0.0, 0.0, math.radians(0.5)))))
    assert abs(fit.estimate[0]) > 5 * fit.sigma[0] and abs(fit.estimate[3]) > 5 * fit.sigma[3]


def test_too_few_rows_or_no_motion_is_refused_naming_the_section() -> None:
    short = section(5, duration=8.0)
    assert len(short.dvl_time) < MIN_ROWS
    with pytest.raises(ValueError, match=r"^synthetic: \d+ DVL rows inside the ground truth"):
        truth_calibration(short)
    still = section(5, duration=40.0)
    at_rest = dataclasses.replace(still, truth_vel=np.zeros_like(still.truth_vel))
    at_rest = dataclasses.replace(at_rest, imu=np.zeros_like(still.imu))
    with pytest.raises(ValueError, match="^synthetic: the truth's median speed is 0 m/s"):
        truth_calibration(at_rest)


@pytest.mark.parametrize(
    "mounting",
    [
        (0.005, (0.0, math.radians(-0.4), math.radians(1.0))),
        (-0.006, (0.0, math.radians(0.5), math.radians(-0.8))),
    ],
)
def test_the_fit_and_the_filters_calibration_states_speak_the_same_convention(mounting):
    """Scale, pitch and yaw from the truth fit and from the 19-state filter's final
    estimate on the same section (with turns and dives) both land within 3σ of the
    simulated DVL's: the table sets them side by side, so their signs must mean the
    same."""
    sec = section(3, mounting)
    truth = np.array([mounting[0], *mounting[1]])
    config = real.real_filter_config(
        sec.alignment.filter_lever_arm, (0.01**2,) * 3, calibration=True
    )
    strategy = pronet.Strategy.constant(real.white_noise_q(sec.imu))
    result = real.run_section(sec, strategy, config).result
    fit = truth_calibration(sec)
    for estimate, sigma in (
        (result.calibration[-1], result.calibration_sigma[-1]),
        (fit.estimate, fit.sigma),
    ):
        seen = [0, 2, 3]  # the roll is barely seen by either
        assert np.all(np.abs(estimate[seen] - truth[seen]) <= 3 * sigma[seen]), (estimate, sigma)


def test_a_vehicle_moving_only_forward_leaves_the_roll_unfitted() -> None:
    """No lateral or vertical motion: the roll cannot be told and is not fitted (NaN,
    infinite σ); scale, pitch and yaw are."""
    sec = section(6, duration=120.0)
    n = len(sec.truth_time)
    forward = dataclasses.replace(
        sec,
        truth_rpy=np.zeros((n, 3)),
        truth_vel=np.tile([1.5, 0.0, 0.0], (n, 1)),
        imu=np.zeros_like(sec.imu),
        dvl=np.tile([1.5 * 1.003, 0.0, 0.0], (len(sec.dvl_time), 1))
        + np.random.default_rng(0).normal(scale=0.01, size=(len(sec.dvl_time), 3)),
    )
    fit = truth_calibration(forward)
    assert np.isnan(fit.estimate[1]) and fit.sigma[1] == np.inf
    assert np.all(np.isfinite(fit.estimate[[0, 2, 3]])) and np.all(fit.sigma[[0, 2, 3]] < 0.01)
    assert abs(fit.estimate[0] - 0.003) <= 3 * fit.sigma[0]
