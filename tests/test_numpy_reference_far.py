"""The Rust filter against the NumPy reference on a run far from SE₂(3)'s anchor: the
[p̂×] terms of its position error matter only there (docs/reference/filter.md, "The
SE₂(3) formulation"), so a vehicle travels 4.8 km with a DVL, depths and fixes at their
lever arms; every formulation is compared, and the comparison is shown able to fail."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

import pronet

import numpy_reference_se23
from numpy_reference_ekf import (
    dcm_from_euler,
    depth_prediction,
    fix_prediction,
    run_reference_filter,
)
from numpy_reference_se23 import displacement
from test_numpy_reference_ekf import P0, Q, _inputs

# SE₂(3) (docs/reference/heading.md, "The SE₂(3) formulation"): its position error is taken about
# the run's first position, so its [p̂×] terms need a run that goes far from there. An
# 80 m/s vehicle (unphysical with a DVL; the algebra does not care) travels 4.8 km in
# 60 s, with turns and a dive.
FAR_SEGMENTS = [
    pronet.Segment(10.0),
    pronet.Segment(15.0, yaw_rate=0.06),
    pronet.Segment(5.0, pitch_rate=-0.02),
    pronet.Segment(5.0, pitch_rate=0.02),
    pronet.Segment(15.0, accel=1.0),
    pronet.Segment(10.0, yaw_rate=-0.05),
]
FAR_DEPTH_ARM, FAR_FIX_ARM = np.array([0.3, 0.1, 1.2]), np.array([-0.5, 0.2, -2.0])
FAR_DVL_ARM = (0.5, -0.2, 1.0)


def _far_track() -> pronet.Trajectory:
    lla0 = np.array([math.radians(32.0), math.radians(34.0), -5.0])
    return pronet.trajectory_from_segments(FAR_SEGMENTS, lla0=lla0, speed0=80.0, rpy0=(0, 0, 0.3))


def _far_aiding(traj: pronet.Trajectory, seconds: float) -> dict:
    """A pressure sensor at ``FAR_DEPTH_ARM`` every second (σ 0.1 m) and an antenna at
    ``FAR_FIX_ARM`` every 10 s (σ 2 m, every other fix without its height), read where
    the truth puts them, plus noise; the reference's keywords."""
    rng = np.random.default_rng(11)
    k = np.arange(50, int(seconds * 100) + 1, 100)
    c = [dcm_from_euler(*traj.rpy[i]) for i in k]
    depth = [depth_prediction(traj.lla[i], ci, FAR_DEPTH_ARM) for i, ci in zip(k, c, strict=True)]
    f = np.arange(1000, int(seconds * 100) + 1, 1000)
    fix = np.array([fix_prediction(traj.lla[i], dcm_from_euler(*traj.rpy[i]), FAR_FIX_ARM)
                    for i in f])  # fmt: skip
    fix += rng.normal(size=fix.shape) * [2 / 6.37e6, 2 / 6.37e6, 2.0]
    fix[1::2, 2] = np.nan
    return dict(
        depth=np.array(depth) + rng.normal(size=len(k)) * 0.1, depth_time=traj.time[k],
        depth_sigma=0.1, fix=fix, fix_time=traj.time[f], fix_sigma=np.full((len(f), 3), 2.0),
        depth_lever_arm=FAR_DEPTH_ARM, fix_lever_arm=FAR_FIX_ARM,
    )  # fmt: skip


def far_inputs(covariance_step: float) -> tuple[tuple, dict, dict]:
    """The far run's inputs ``(imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0)``, its
    depth and fix streams (the reference's keywords) and the filter's tuning."""
    traj = _far_track()
    inputs = _inputs(60.0, np.array(FAR_DVL_ARM), "body", traj=traj)
    tuning = dict(accel_bias_psd=1e-6, gyro_bias_psd=1e-8, dvl_variance=(0.01,) * 3,
                  covariance_step=covariance_step, lever_arm=FAR_DVL_ARM)  # fmt: skip
    return inputs, _far_aiding(traj, 60.0), tuning


@functools.lru_cache(maxsize=8)
def _far_run(formulation: str, covariance_step: float, reference: bool, pos_att_sign=1.0):
    """The core's (``reference`` False) or the reference's run far from the anchor: a
    body-frame DVL at a lever arm, depths and fixes at theirs. ``pos_att_sign`` −1 flips
    the reference's SE₂(3) position–attitude block of F (a broken reference)."""
    (imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0), aiding, tuning = far_inputs(covariance_step)
    if not reference:
        cfg = pronet.FilterConfig(p0_sigma=P0, formulation=formulation, **tuning)
        streams = [
            pronet.Dvl(dvl_time, dvl),
            pronet.Depth(aiding["depth_time"], aiding["depth"], sigma=0.1, lever_arm=FAR_DEPTH_ARM),
            pronet.Fix(aiding["fix_time"], aiding["fix"], sigma=aiding["fix_sigma"],
                       lever_arm=FAR_FIX_ARM),
        ]  # fmt: skip
        out = pronet.run_filter(imu, imu_time, streams, t0=0.0, lla0=lla0, vel0=vel0, rpy0=rpy0,
                                config=cfg, strategy=pronet.Strategy.constant(Q))  # fmt: skip
        keys = ("lla", "vel", "rpy", "bias", "sigma", "innovation", "nis", "depth_nis", "fix_nis")
        return {key: np.asarray(getattr(out, key)) for key in keys}
    saved, numpy_reference_se23.POS_ATT_SIGN = numpy_reference_se23.POS_ATT_SIGN, pos_att_sign
    try:
        return run_reference_filter(
            imu, imu_time, dvl, dvl_time, 0.0, lla0, vel0, rpy0, q=Q, p0_sigma=P0, imu_dt=0.01,
            formulation=formulation, **tuning, **aiding,
        )  # fmt: skip
    finally:
        numpy_reference_se23.POS_ATT_SIGN = saved


#: How far the far run travels [m]: its latitude and longitude are compared to 1e-8 of it.
FAR_DISTANCE = 5000.0


def _assert_far_equal(rust: dict, ref: dict) -> None:
    """Every output to 1e-8 relative, with absolute floors of 1e-8 of each quantity's
    scale where it passes through zero (velocity 80 m/s, attitude 0.3 rad and biases
    1e-3, innovations 0.1 m/s, NIS 1 per degree of freedom; latitude and longitude:
    1e-8 of the distance travelled)."""
    rtol = 1e-8
    np.testing.assert_allclose(rust["vel"], ref["vel"], rtol=rtol, atol=1e-8 * 80.0)
    np.testing.assert_allclose(rust["rpy"], ref["rpy"], rtol=rtol, atol=1e-8 * 0.3)
    np.testing.assert_allclose(rust["bias"], ref["bias"], rtol=rtol, atol=1e-8 * 1e-3)
    np.testing.assert_allclose(rust["sigma"], ref["sigma"], rtol=rtol, atol=0.0)
    horizontal = 1e-8 * FAR_DISTANCE / 6.4e6
    np.testing.assert_allclose(rust["lla"][:, :2], ref["lla"][:, :2], rtol=0, atol=horizontal)
    np.testing.assert_allclose(rust["lla"][:, 2], ref["lla"][:, 2], rtol=rtol, atol=1e-8)
    np.testing.assert_allclose(rust["innovation"], ref["innovation"], rtol=rtol, atol=1e-9)
    for key in ("nis", "depth_nis", "fix_nis"):
        np.testing.assert_allclose(rust[key], ref[key], rtol=rtol, atol=1e-8, err_msg=key)


@pytest.mark.parametrize(
    ("formulation", "covariance_step"),
    [("se23", 0.1), ("se23", 0.0), ("invariant", 0.1)],
)
def test_rust_filter_matches_reference_far_from_the_anchor(formulation, covariance_step) -> None:
    """4.8 km from the anchor with a DVL, depths and fixes at their lever arms: the
    core equals the reference to 1e-8 (the invariant formulation on the same data too)."""
    rust = _far_run(formulation, covariance_step, reference=False)
    ref = _far_run(formulation, covariance_step, reference=True)
    assert len(ref["nis"]) == 60 and len(ref["depth_nis"]) == 60 and len(ref["fix_nis"]) == 6
    distance = np.linalg.norm(displacement(ref["lla"][-1], ref["lla"][0]))
    assert 4000 < distance < FAR_DISTANCE
    _assert_far_equal(rust, ref)
    # The filter worked: the position ends within a few of its σ of the truth (a few m).
    truth = _far_track().lla[len(ref["lla"]) - 1]
    error = displacement(ref["lla"][-1], truth)
    assert (np.abs(error) < 4 * ref["sigma"][-1, :3]).all(), (error, ref["sigma"][-1, :3])


def test_the_far_comparison_can_fail() -> None:
    """The equality above is not vacuous: the reference with the sign of SE₂(3)'s
    position–attitude block of F flipped differs from the core beyond the tolerance,
    and so does the invariant formulation on the same data (its [v̂×] block in place of
    SE₂(3)'s, no [p̂×] on the position rows)."""
    rust = _far_run("se23", 0.1, reference=False)
    flipped = _far_run("se23", 0.1, reference=True, pos_att_sign=-1.0)
    with pytest.raises(AssertionError, match="Not equal to tolerance"):
        _assert_far_equal(rust, flipped)
    assert np.abs(flipped["sigma"][:, 6:9] / rust["sigma"][:, 6:9] - 1).max() > 1e-4
    invariant = _far_run("invariant", 0.1, reference=False)
    with pytest.raises(AssertionError, match="Not equal to tolerance"):
        _assert_far_equal(rust, invariant)
    assert np.abs(invariant["sigma"][:, :3] / rust["sigma"][:, :3] - 1).max() > 1e-3
