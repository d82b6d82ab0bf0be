"""The σ that ``run_filter`` reports at the epochs inside a covariance step."""

from __future__ import annotations

import numpy as np
import pytest
from test_position_aiding import P0, Q, _inputs

import pronet


def _run(step: float, calibrated: bool) -> pronet.FilterResult:
    arm = (0.5, -0.2, 1.0)
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = _inputs(60.0, np.array(arm), "body")
    cfg = pronet.FilterConfig(p0_sigma=P0, lever_arm=arm, accel_bias_psd=1e-6,
                              gyro_bias_psd=1e-8, covariance_step=step,
                              dvl_calibration=calibrated)  # fmt: skip
    q = pronet.Strategy.constant(Q)
    return pronet.run_filter(imu, imu_time, [pronet.Dvl(dvl_time, dvl)], t0=0.0, lla0=lla0,
                             vel0=vel0, rpy0=rpy0, config=cfg, strategy=q)  # fmt: skip


@pytest.mark.parametrize("calibrated", [False, True])
def test_sigma_inside_a_step_follows_the_per_sample_filter(calibrated) -> None:
    """Inside a 0.1 s step P stands at the step's start; the σ reported there is
    interpolated in variance up to the step's close, so it grows between the DVL
    updates as the per-sample filter's does (a stale σ would stay flat for ten samples
    and read up to a step's growth too small)."""
    every, stepped = _run(0.0, calibrated), _run(0.1, calibrated)
    assert every.sigma.shape == stepped.sigma.shape
    np.testing.assert_allclose(stepped.sigma, every.sigma, rtol=2e-3)
    # Between two DVL updates (1 Hz) the velocity σ grows at every sample.
    vel_n = stepped.sigma[:, 3]
    between = np.ones(vel_n.size - 1, bool)
    between[np.asarray(stepped.dvl_epoch) - 1] = False  # the step into an update
    assert (np.diff(vel_n)[between] > 0).all()
    if calibrated:
        np.testing.assert_allclose(stepped.calibration_sigma, every.calibration_sigma, rtol=2e-3)
