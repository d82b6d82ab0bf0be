"""The core's second-order heading term (``FilterConfig.heading_second_order``) equals
the NumPy reference's (``numpy_reference_second_order.py``) to 1e-8, through the DVL,
depth and fix updates, at every sample and under a covariance step."""

from __future__ import annotations

import numpy as np
import pytest

import pronet

from numpy_reference_ekf import run_reference_filter
from test_numpy_reference_ekf import P0, Q, _inputs

#: The heading 0.5 rad uncertain at the start and the gyro biases 1e-3 rad/s, walking
#: at 1e-6 (rad/s)²/s, so that the term grows to a few per cent of the position σ.
P0_HEADING = np.concatenate([P0[:8], [0.5], P0[9:12], [1e-3] * 3])


def _aiding(seconds: float) -> dict:
    """Depth every second and a fix every 10 s (every other one without its height) at
    the paper trajectory's truth, noise-free."""
    traj = pronet.builtin_trajectory("paper")
    depth_time = np.arange(0.503, seconds, 1.0)
    depth = -np.interp(depth_time, traj.time, traj.lla[:, 2])
    fix_time = np.arange(9.996, seconds, 10.0)
    fix = np.stack([np.interp(fix_time, traj.time, traj.lla[:, i]) for i in range(3)], axis=1)
    fix[1::2, 2] = np.nan
    return dict(depth=depth, depth_time=depth_time, depth_sigma=0.1, fix=fix,
                fix_time=fix_time, fix_sigma=np.full((len(fix_time), 3), 2.0))  # fmt: skip


@pytest.mark.parametrize("covariance_step", [0.0, 0.1])
@pytest.mark.parametrize("formulation", ["classic", "invariant"])
def test_the_second_order_heading_term_matches_the_reference(formulation, covariance_step) -> None:
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = _inputs(60.0, np.zeros(3), "body")
    a = _aiding(60.0)
    tuning = dict(accel_bias_psd=1e-6, gyro_bias_psd=1e-6, dvl_variance=(0.01,) * 3,
                  p0_sigma=P0_HEADING, formulation=formulation,
                  covariance_step=covariance_step)  # fmt: skip

    def rust(second_order: bool) -> pronet.FilterResult:
        cfg = pronet.FilterConfig(heading_second_order=second_order, **tuning)
        streams = [
            pronet.Dvl(dvl_time, dvl),
            pronet.Depth(a["depth_time"], a["depth"], sigma=a["depth_sigma"]),
            pronet.Fix(a["fix_time"], a["fix"], sigma=a["fix_sigma"]),
        ]
        return pronet.run_filter(
            imu, imu_time, streams, t0=0.0, lla0=lla0, vel0=vel0, rpy0=rpy0, config=cfg,
            strategy=pronet.Strategy.constant(Q), warn=False,
        )  # fmt: skip

    out = rust(True)
    ref = run_reference_filter(
        imu, imu_time, dvl, dvl_time, 0.0, lla0, vel0, rpy0, q=Q, imu_dt=0.01,
        heading_second_order=True, **tuning, **a,
    )  # fmt: skip
    assert len(ref["fix_nis"]) == 6 and len(ref["depth_nis"]) == 60
    np.testing.assert_allclose(out.sigma, ref["sigma"], rtol=1e-8, atol=0.0)
    np.testing.assert_allclose(out.vel, ref["vel"], rtol=1e-8, atol=1e-8)
    np.testing.assert_allclose(out.lla[:, :2], ref["lla"][:, :2], rtol=0, atol=1e-8 * 60 / 6.4e6)
    np.testing.assert_allclose(out.nis, ref["nis"], rtol=1e-8)
    np.testing.assert_allclose(out.fix_nis, ref["fix_nis"], rtol=1e-8)
    # The term is there: the north σ (the track's first leg) wider before the first fix
    # (about 5 %) and after the last.
    linear = rust(False)
    before = int(np.searchsorted(out.time, 9.9))
    assert out.sigma[before, 0] > 1.03 * linear.sigma[before, 0]
    assert out.sigma[-1, 0] > 1.02 * linear.sigma[-1, 0]
