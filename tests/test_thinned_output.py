"""``run_filter(output_step=...)``: the kept epochs are the every-epoch pass's rows, bit
for bit, forward and smoothed (the node-only smoother integrating the forward solution
again between updates), in both formulations, with the 19 states, every sample and a
covariance step, with depth readings and position fixes; and the bad periods it refuses.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_position_aiding import _aiding, _streams

import pronet

from test_numpy_reference_ekf import P0, Q, _inputs

SECONDS = 30.0


def _run(formulation: str, calibrated: bool, covariance_step: float, **kw):
    arm = (0.5, -0.2, 1.0)
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = _inputs(SECONDS, np.array(arm), "body")
    aiding = _aiding(pronet.builtin_trajectory("paper"), SECONDS, np.random.default_rng(3))
    cfg = pronet.FilterConfig(
        p0_sigma=P0, lever_arm=arm, formulation=formulation, dvl_calibration=calibrated,
        accel_bias_psd=1e-6, gyro_bias_psd=1e-8, dvl_variance=(0.01,) * 3,
        covariance_step=covariance_step,
    )  # fmt: skip
    return pronet.run_filter(
        imu, imu_time, [pronet.Dvl(dvl_time, dvl), *_streams(aiding)], t0=0.0, lla0=lla0,
        vel0=vel0, rpy0=rpy0, config=cfg, strategy=pronet.Strategy.constant(Q), **kw,
    )  # fmt: skip


FIELDS = ("lla", "vel", "rpy", "bias", "sigma", "calibration", "calibration_sigma")


@pytest.mark.parametrize("formulation", ["classic", "invariant"])
@pytest.mark.parametrize("calibrated", [False, True])
@pytest.mark.parametrize("covariance_step", [0.0, 0.1])
def test_kept_epochs_equal_every_epoch_bit_for_bit(formulation, calibrated, covariance_step):
    every = _run(formulation, calibrated, covariance_step, smooth=True)
    assert len(every.epoch) == 0 and every.smoothed is not None
    for step in (1.0, 0.237):
        thin = _run(formulation, calibrated, covariance_step, smooth=True, output_step=step)
        assert thin.smoothed is not None
        # t0, the epoch nearest each multiple of the period (the first whose half step
        # after it reaches the multiple: a tie goes to the earlier), the last.
        t = every.time
        reach = t + 0.5 * np.diff(t, append=2 * t[-1] - t[-2])
        multiples = np.arange(1, int(SECONDS / step) + 1) * step
        nearest = np.searchsorted(reach, multiples[multiples <= reach[-1]])
        nearest = np.unique(np.concatenate([[0], nearest, [len(t) - 1]]))
        assert len(nearest) > SECONDS / step
        np.testing.assert_array_equal(thin.epoch, nearest)
        np.testing.assert_array_equal(thin.time, every.time[thin.epoch])
        for name in FIELDS if calibrated else FIELDS[:5]:
            np.testing.assert_array_equal(
                getattr(thin, name), getattr(every, name)[thin.epoch], err_msg=name
            )
            np.testing.assert_array_equal(
                getattr(thin.smoothed, name),
                getattr(every.smoothed, name)[thin.epoch],
                err_msg=f"smoothed {name}",
            )
        for name in ("dvl_epoch", "nis", "depth_nis", "fix_nis", "covariance"):
            np.testing.assert_array_equal(getattr(thin, name), getattr(every, name))
    # The smoother moved every kept row's solution: the equality is not the forward's.
    assert (thin.smoothed.vel != thin.vel).any(axis=1)[1:-1].all()


def test_an_output_step_without_smoothing_and_its_update_table():
    every = _run("invariant", False, 0.1)
    thin = _run("invariant", False, 0.1, output_step=2.0)
    np.testing.assert_array_equal(thin.vel, every.vel[thin.epoch])
    np.testing.assert_array_equal(thin.sigma, every.sigma[thin.epoch])
    assert thin.smoothed is None
    # The DVL runs at 1 Hz: every other update's epoch is kept, and has its time.
    table = thin.to_dataframe(rows="updates")
    kept = np.isin(thin.dvl_epoch, thin.epoch)
    assert kept.sum() == 15 and not kept.all()
    np.testing.assert_array_equal(table["time"][kept], every.time[thin.dvl_epoch[kept]])
    assert table["time"][~kept].isna().all()


@pytest.mark.parametrize(
    "extra, message",
    [
        ({"output_step": 0.0}, r"^output_step: must be a finite period > 0 \[s\], got 0$"),
        ({"output_step": -1.0}, r"^output_step: must be a finite period > 0"),
        ({"output_step": float("nan")}, r"^output_step: must be a finite period > 0"),
        ({"output_step": "1"}, r"^output_step: expected a real number"),
        ({"output_step": 1.0, "epochs": "last"}, r'^output_step: .*not with epochs="last"$'),
    ],
)
def test_bad_output_steps_are_refused_in_one_line(extra, message):
    with pytest.raises(ValueError, match=message):
        _run("classic", False, 0.0, smooth=True, **extra)
