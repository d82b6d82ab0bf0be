"""The Rust RTS smoother agrees with the independent NumPy one (per-step recursion,
dense matrices), in both formulations and both aidings, to 1e-8."""

from __future__ import annotations

import numpy as np
import pytest

import pronet

from numpy_reference_ekf import dcm_from_euler, run_reference_filter
from numpy_reference_smoother import rts_smooth
from test_numpy_reference_ekf import P0, Q, _inputs


def _both(aiding: str, lever_arm, formulation: str, strategy=None, covariance_step=0.0):
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = _inputs(60.0, np.array(lever_arm), aiding)
    tuning = dict(accel_bias_psd=1e-6, gyro_bias_psd=1e-8, dvl_variance=(0.01,) * 3)
    cfg = pronet.FilterConfig(
        p0_sigma=P0, lever_arm=lever_arm, aiding=aiding, formulation=formulation,
        covariance_step=covariance_step, **tuning,
    )  # fmt: skip
    rust = pronet.run_filter(
        imu, imu_time, dvl, dvl_time, t0=0.0, lla0=lla0, vel0=vel0, rpy0=rpy0, config=cfg,
        strategy=strategy or pronet.Strategy.constant(Q), smooth=True,
    )  # fmt: skip
    log: list = []
    forward = run_reference_filter(
        imu, imu_time, dvl, dvl_time, 0.0, lla0, vel0, rpy0, q=Q, p0_sigma=P0, imu_dt=0.01,
        lever_arm=lever_arm, aiding=aiding, formulation=formulation, log=log,
        covariance_step=covariance_step, **tuning,
    )  # fmt: skip
    return rust, forward, rts_smooth(forward, log, formulation)


@pytest.mark.parametrize(
    ("aiding", "lever_arm"), [("body", (0.5, -0.2, 1.0)), ("nav", (0.0, 0.0, 0.0))]
)
@pytest.mark.parametrize("formulation", ["classic", "invariant"])
@pytest.mark.parametrize("covariance_step", [0.0, 0.1, 0.07])
def test_rust_smoother_matches_reference(aiding, lever_arm, formulation, covariance_step) -> None:
    """0.1 s: ten steps between DVL rows; 0.07 s: a short step closed by each row."""
    rust, forward, ref = _both(aiding, lever_arm, formulation, covariance_step=covariance_step)
    s = rust.smoothed
    assert s is not None
    np.testing.assert_array_equal(s.time, rust.time)
    # The forward pass is the same with and without the smoother.
    np.testing.assert_allclose(rust.vel, forward["vel"], rtol=1e-8, atol=1e-8)
    # The smoother moved the solution, by far more than the tolerance.
    assert np.abs(ref["vel"] - forward["vel"]).max() > 1e-3
    rtol = 1e-8
    np.testing.assert_allclose(s.vel, ref["vel"], rtol=rtol, atol=1e-8 * 1.0)  # ~1 m/s
    np.testing.assert_allclose(s.rpy, ref["rpy"], rtol=rtol, atol=1e-8 * 1e-2)  # ~0.01 rad
    np.testing.assert_allclose(s.bias, ref["bias"], rtol=rtol, atol=1e-8 * 1e-3)
    np.testing.assert_allclose(s.sigma, ref["sigma"], rtol=rtol, atol=0.0)
    np.testing.assert_allclose(s.lla[:, :2], ref["lla"][:, :2], rtol=0, atol=1e-8 * 60 / 6.4e6)
    np.testing.assert_allclose(s.lla[:, 2], ref["lla"][:, 2], rtol=rtol, atol=1e-8)
    # Every epoch's smoothed σ is at most the forward one, and equal at the end (to rounding).
    assert (s.sigma <= rust.sigma * (1 + 1e-12)).all()
    np.testing.assert_allclose(s.sigma[-1], rust.sigma[-1], rtol=1e-14, atol=0)


@pytest.mark.parametrize("formulation", ["classic", "invariant"])
@pytest.mark.parametrize("covariance_step", [0.0, 0.07])
def test_rust_smoother_with_dvl_calibration_states_matches_reference(
    formulation, covariance_step
) -> None:
    """All 19 states smoothed (a DVL with a 0.5 % scale error and a (0.1°, −0.2°,
    0.5°) mounting, walks included): the navigation solution and the calibration
    states with their σ equal the dense reference to 1e-8, every sample and over
    0.07 s steps; the smoothed calibration σ never above the forward one."""
    arm = np.array([0.5, -0.2, 1.0])
    imu, imu_time, dvl_body, dvl_time, lla0, vel0, rpy0 = _inputs(60.0, arm, "body")
    m_true = dcm_from_euler(*np.radians([0.1, -0.2, 0.5])).T  # body -> DVL
    dvl = (1.005 * (m_true @ dvl_body.T)).T
    calibration = (0.01, (0.02, 0.02, 0.03), 1e-8, 1e-9)
    tuning = dict(accel_bias_psd=1e-6, gyro_bias_psd=1e-8, dvl_variance=(0.01,) * 3)
    cfg = pronet.FilterConfig(
        p0_sigma=P0, lever_arm=arm, formulation=formulation, covariance_step=covariance_step,
        dvl_calibration=True, dvl_scale_sigma=calibration[0],
        dvl_misalignment_sigma=calibration[1], dvl_scale_psd=calibration[2],
        dvl_misalignment_psd=calibration[3], **tuning,
    )  # fmt: skip
    rust = pronet.run_filter(
        imu, imu_time, dvl, dvl_time, t0=0.0, lla0=lla0, vel0=vel0, rpy0=rpy0, config=cfg,
        strategy=pronet.Strategy.constant(Q), smooth=True,
    )  # fmt: skip
    log: list = []
    forward = run_reference_filter(
        imu, imu_time, dvl, dvl_time, 0.0, lla0, vel0, rpy0, q=Q, p0_sigma=P0, imu_dt=0.01,
        lever_arm=arm, formulation=formulation, calibration=calibration, log=log,
        covariance_step=covariance_step, **tuning,
    )  # fmt: skip
    ref = rts_smooth(forward, log, formulation)
    s = rust.smoothed
    assert s is not None and s.calibration.shape == rust.calibration.shape
    # The smoother moved the calibration states, by far more than the tolerance.
    assert np.abs(ref["calibration"] - forward["calibration"]).max() > 1e-5
    rtol = 1e-8
    np.testing.assert_allclose(s.vel, ref["vel"], rtol=rtol, atol=1e-8)
    np.testing.assert_allclose(s.rpy, ref["rpy"], rtol=rtol, atol=1e-10)
    np.testing.assert_allclose(s.bias, ref["bias"], rtol=rtol, atol=1e-11)
    np.testing.assert_allclose(s.sigma, ref["sigma"], rtol=rtol, atol=0.0)
    np.testing.assert_allclose(s.lla[:, :2], ref["lla"][:, :2], rtol=0, atol=1e-8 * 60 / 6.4e6)
    np.testing.assert_allclose(s.calibration, ref["calibration"], rtol=rtol, atol=1e-10)
    np.testing.assert_allclose(s.calibration_sigma, ref["calibration_sigma"], rtol=rtol, atol=0)
    assert (s.calibration_sigma <= rust.calibration_sigma * (1 + 1e-12)).all()
    np.testing.assert_allclose(s.calibration_sigma[-1], rust.calibration_sigma[-1], rtol=1e-14)
