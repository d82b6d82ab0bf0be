"""The RTS smoother on simulated passes: consistent, and better than the filter.

Forty passes over the first 120 s of the ``paper`` trajectory, each with its own IMU
noise, turn-on biases, DVL noise and initial error drawn from what the filter is told
(so a consistent filter's velocity NEES is 3, with 3 degrees of freedom). The NumPy
reference check of the same smoother is ``tests/test_numpy_reference_smoother.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

import pronet
from pronet.recorded.alignment import dcm_from_euler

Q = (1e-4,) * 3 + (1e-6,) * 3
P0 = np.array([1, 1, 1, 0.1, 0.1, 0.1, 1e-3, 1e-3, 5e-3, 1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-4])
DVL_SIGMA = 0.02
RUNS, SECONDS = 40, 120.0


def _passes(formulation: str) -> tuple[np.ndarray, ...]:
    """Velocity errors and their σ of the filter and the smoother, ``(runs, epochs, 3)``."""
    truth = pronet.builtin_trajectory("paper")
    n = int(round(SECONDS / truth.dt))
    k = np.arange(100, n + 1, 100)  # a 1 Hz DVL
    body = np.einsum("kji,kj->ki", dcm_from_euler(truth.rpy[k]), truth.vel_ned[k])
    cfg = pronet.FilterConfig(
        p0_sigma=P0, dvl_variance=[DVL_SIGMA**2] * 3, accel_bias_psd=1e-10,
        gyro_bias_psd=1e-14, formulation=formulation,
    )  # fmt: skip
    out: list[list[np.ndarray]] = [[], [], [], []]
    for seed in range(RUNS):
        rng = np.random.default_rng(seed)
        imu = truth.imu[:n] + rng.normal(size=6) * P0[9:] + rng.normal(size=(n, 6)) * np.sqrt(Q)
        dvl = body + rng.normal(size=body.shape) * DVL_SIGMA
        d = rng.normal(size=9) * P0[:9]
        start = pronet.lla_from_ned(d[:3], truth.lla[0])
        res = pronet.run_filter(
            imu, truth.time[1 : n + 1], dvl, truth.time[k], t0=0.0, lla0=start,
            vel0=truth.vel_ned[0] + d[3:6], rpy0=truth.rpy[0] + d[6:9], config=cfg,
            strategy=pronet.Strategy.constant(Q), smooth=True,
        )  # fmt: skip
        s = res.smoothed
        assert s is not None
        v = truth.vel_ned[: n + 1]
        for i, part in enumerate((res.vel - v, res.sigma[:, 3:6], s.vel - v, s.sigma[:, 3:6])):
            out[i].append(part)
    return tuple(np.array(x) for x in out)


@pytest.mark.slow
@pytest.mark.parametrize("formulation", ["invariant", "classic"])
def test_the_smoother_is_consistent_and_beats_the_filter(formulation) -> None:
    ef, sf, es, ss = _passes(formulation)
    nees_f = np.mean(np.sum((ef / sf) ** 2, axis=2))
    nees_s = np.mean(np.sum((es / ss) ** 2, axis=2))
    # Both consistent: a mean NEES of 3 over 40 runs × 12,001 correlated epochs.
    assert 2.5 < nees_f < 3.6 and 2.5 < nees_s < 3.6, (nees_f, nees_s)
    rms_f = np.sqrt(np.mean(np.sum(ef**2, axis=2), axis=0))
    rms_s = np.sqrt(np.mean(np.sum(es**2, axis=2), axis=0))
    # Never worse beyond the noise of 40 runs, and well better on the whole.
    assert (rms_s <= 1.15 * rms_f).all()
    assert rms_s.mean() < 0.85 * rms_f.mean(), (rms_s.mean(), rms_f.mean())
