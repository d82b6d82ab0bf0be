"""The Rust filter agrees with the independent NumPy implementation of docs/reference/filter.md;
the reference's own measurement models (lever arms, heading) against their derivatives."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

import pronet
from pronet.run import Recorded
from pronet.run import run as pronet_run

import numpy_reference_se23
from numpy_reference_ekf import (
    dcm_from_euler,
    depth_h_row,
    depth_prediction,
    error_dynamics,
    euler_from_dcm,
    exp_so3,
    fix_innovation,
    fix_prediction,
    gravity,
    heading_h_row,
    heading_innovation,
    heading_prediction,
    nav_velocity_h,
    nav_velocity_prediction,
    position_h_row,
    radii,
    rates,
    run_reference_filter,
    strapdown_step,
)
from numpy_reference_se23 import displacement, position, position_h_psi, to_se23

Q = np.array([1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6])
P0 = np.array([1, 1, 1, 0.1, 0.1, 0.1, 1e-3, 1e-3, 5e-3, 1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-4])


def _inputs(seconds: float, lever_arm, aiding: str, seed: int = 4, traj=None):
    """``seconds`` of a noisy, biased IMU along ``traj`` (the paper's by default), a
    DVL every second (σ 0.1 m/s) and a start a little off the truth."""
    traj = traj or pronet.builtin_trajectory("paper")
    n = int(round(seconds / traj.dt))
    rng = np.random.default_rng(seed)
    ideal = traj.imu[:n]
    bias = np.array([0.003, -0.002, 0.001, 2e-4, -1e-4, 3e-4])
    imu = ideal + bias + rng.normal(size=ideal.shape) * np.sqrt(Q)
    imu_time = traj.time[1 : n + 1]
    k = np.arange(100, n + 1, 100)
    dvl = []
    for i in k:
        r, p_, y = traj.rpy[i]
        c = dcm_from_euler(r, p_, y)
        if aiding == "body":
            z = c.T @ traj.vel_ned[i] + np.cross(ideal[i - 1, 3:], lever_arm)
        else:
            z = traj.vel_ned[i].copy()
        dvl.append(z + rng.normal(size=3) * 0.1)
    # Start 2 m north, 0.05 m/s and a few mrad off the truth.
    lla0 = traj.lla[0] + np.array([2.0 / 6.36e6, 0.0, 0.5])
    vel0 = traj.vel_ned[0] + np.array([0.05, -0.03, 0.01])
    rpy0 = traj.rpy[0] + np.array([1e-3, -1e-3, 4e-3])
    return imu, imu_time, np.array(dvl), traj.time[k], lla0, vel0, rpy0


def test_reference_strapdown_stays_at_rest() -> None:
    lla = np.array([math.radians(32), math.radians(34), -5.0])
    c = dcm_from_euler(0.02, -0.01, 0.7)
    w_ie, _, g = rates(lla, np.zeros(3))
    f, w = -c.T @ g, c.T @ w_ie
    v = np.zeros(3)
    pos, cc = lla.copy(), c.copy()
    for _ in range(1000):
        pos, v, cc = strapdown_step(pos, v, cc, f, w, 0.01)
    # 10 s at rest: only rounding of the Rodrigues terms remains.
    assert np.abs(v).max() < 1e-10 and np.abs(pos - lla).max() < 1e-12
    assert gravity(0.0, 0.0) == pytest.approx(9.7803253359, abs=1e-9)


@pytest.mark.parametrize(
    ("aiding", "lever_arm"),
    [("body", (0.5, -0.2, 1.0)), ("body", (0.0, 0.0, 0.0)), ("nav", (0, 0, 0))],
)
@pytest.mark.parametrize("formulation", ["classic", "invariant", "se23"])
@pytest.mark.parametrize("covariance_step", [pytest.param(0.0, marks=pytest.mark.slow), 0.1])
def test_rust_filter_matches_reference(aiding, lever_arm, formulation, covariance_step) -> None:
    """At every IMU sample and at a 0.1 s covariance step (ten samples)."""
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = _inputs(60.0, np.array(lever_arm), aiding)
    cfg = pronet.FilterConfig(
        p0_sigma=P0,
        accel_bias_psd=1e-6,
        gyro_bias_psd=1e-8,
        dvl_variance=(0.01,) * 3,
        lever_arm=lever_arm,
        aiding=aiding,
        formulation=formulation,
        covariance_step=covariance_step,
    )
    rust = pronet.run_filter(
        imu,
        imu_time,
        [pronet.Dvl(dvl_time, dvl)],
        t0=0.0,
        lla0=lla0,
        vel0=vel0,
        rpy0=rpy0,
        config=cfg,
        strategy=pronet.Strategy.constant(Q),
    )
    ref = run_reference_filter(
        imu,
        imu_time,
        dvl,
        dvl_time,
        0.0,
        lla0,
        vel0,
        rpy0,
        q=Q,
        accel_bias_psd=1e-6,
        gyro_bias_psd=1e-8,
        dvl_variance=(0.01,) * 3,
        p0_sigma=P0,
        imu_dt=0.01,
        lever_arm=lever_arm,
        aiding=aiding,
        formulation=formulation,
        covariance_step=covariance_step,
    )
    # The filter worked: the updates pulled the estimate to the truth.
    assert len(ref["nis"]) == 60
    rtol = 1e-8
    # Absolute floors where a quantity passes through zero: 1e-8 relative of its scale.
    np.testing.assert_allclose(rust.vel, ref["vel"], rtol=rtol, atol=1e-8 * 1.0)  # ~1 m/s
    np.testing.assert_allclose(rust.rpy, ref["rpy"], rtol=rtol, atol=1e-8 * 1e-2)  # ~0.01 rad
    np.testing.assert_allclose(rust.bias, ref["bias"], rtol=rtol, atol=1e-8 * 1e-3)
    np.testing.assert_allclose(rust.sigma, ref["sigma"], rtol=rtol, atol=0.0)
    # Latitude/longitude: 1e-8 relative of the distance travelled (60 m) in radians.
    np.testing.assert_allclose(rust.lla[:, :2], ref["lla"][:, :2], rtol=0, atol=1e-8 * 60 / 6.4e6)
    np.testing.assert_allclose(rust.lla[:, 2], ref["lla"][:, 2], rtol=rtol, atol=1e-8)
    np.testing.assert_allclose(rust.innovation, ref["innovation"], rtol=rtol, atol=1e-8 * 0.1)
    np.testing.assert_allclose(rust.nis, ref["nis"], rtol=rtol)


@pytest.mark.parametrize("formulation", ["classic", "invariant", "se23"])
@pytest.mark.parametrize("covariance_step", [0.0, 0.07])
def test_rust_filter_with_dvl_calibration_states_matches_reference(
    formulation, covariance_step
) -> None:
    """The 19-state filter (DVL scale factor and misalignment) against the dense NumPy
    one, on readings of a DVL with a 0.5 % scale error and a mounting of (0.1°, −0.2°,
    0.5°), lever arm and random-walk PSDs included: equal to 1e-8 relative, at every
    IMU sample and at a 0.07 s covariance step (seven samples, the last step of each
    second closed early by the DVL update)."""
    arm = np.array([0.5, -0.2, 1.0])
    imu, imu_time, dvl_body, dvl_time, lla0, vel0, rpy0 = _inputs(60.0, arm, "body")
    mounting = np.radians([0.1, -0.2, 0.5])
    m_true = dcm_from_euler(*mounting).T  # body -> DVL
    dvl = (1.005 * (m_true @ dvl_body.T)).T
    calibration = (0.01, (0.02, 0.02, 0.03), 1e-8, 1e-9)
    cfg = pronet.FilterConfig(
        p0_sigma=P0,
        accel_bias_psd=1e-6,
        gyro_bias_psd=1e-8,
        dvl_variance=(0.01,) * 3,
        lever_arm=arm,
        dvl_calibration=True,
        dvl_scale_sigma=calibration[0],
        dvl_misalignment_sigma=calibration[1],
        dvl_scale_psd=calibration[2],
        dvl_misalignment_psd=calibration[3],
        formulation=formulation,
        covariance_step=covariance_step,
    )
    args = (imu, imu_time, dvl, dvl_time)
    start = dict(lla0=lla0, vel0=vel0, rpy0=rpy0)
    streams = [pronet.Dvl(dvl_time, dvl)]
    rust = pronet.run_filter(
        imu, imu_time, streams, t0=0.0, **start, config=cfg, strategy=pronet.Strategy.constant(Q)
    )
    ref = run_reference_filter(
        *args, 0.0, lla0, vel0, rpy0, q=Q, accel_bias_psd=1e-6, gyro_bias_psd=1e-8,
        dvl_variance=(0.01,) * 3, p0_sigma=P0, imu_dt=0.01, lever_arm=arm,
        calibration=calibration, formulation=formulation, covariance_step=covariance_step,
    )  # fmt: skip
    assert len(ref["nis"]) == 60 and rust.calibration.shape == (len(imu) + 1, 7)
    rtol = 1e-8
    np.testing.assert_allclose(rust.vel, ref["vel"], rtol=rtol, atol=1e-8 * 1.0)
    np.testing.assert_allclose(rust.rpy, ref["rpy"], rtol=rtol, atol=1e-8 * 1e-2)
    np.testing.assert_allclose(rust.bias, ref["bias"], rtol=rtol, atol=1e-8 * 1e-3)
    np.testing.assert_allclose(rust.sigma, ref["sigma"], rtol=rtol, atol=0.0)
    np.testing.assert_allclose(rust.lla[:, :2], ref["lla"][:, :2], rtol=0, atol=1e-8 * 60 / 6.4e6)
    np.testing.assert_allclose(rust.innovation, ref["innovation"], rtol=rtol, atol=1e-8 * 0.1)
    np.testing.assert_allclose(rust.nis, ref["nis"], rtol=rtol)
    # Scale ~0.005 and angles ~0.01 rad: 1e-8 relative of those scales.
    cal, cal_sigma = rust.calibration[:, :4], rust.calibration_sigma[:, :4]
    np.testing.assert_allclose(cal, ref["calibration"], rtol=rtol, atol=1e-10)
    np.testing.assert_allclose(cal_sigma, ref["calibration_sigma"], rtol=rtol)
    # without dvl_bias_sigma the correlated error's columns stay exactly 0
    assert not rust.calibration[:, 4:].any() and not rust.calibration_sigma[:, 4:].any()
    # The updates moved the states (how well they learn: test_dvlcalibration.py).
    assert np.abs(rust.calibration[-1] - rust.calibration[0]).max() > 1e-4
    # Without the states the arrays are empty.
    plain = pronet.run_filter(
        imu, imu_time, streams, t0=0.0, **start, config=pronet.FilterConfig(p0_sigma=P0),
        strategy=pronet.Strategy.constant(Q),
    )  # fmt: skip
    assert plain.calibration.shape == plain.calibration_sigma.shape == (0, 7)


# SE₂(3) (docs/reference/filter.md, "The SE₂(3) formulation"): its position error is taken about
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
    1e-3, innovations 0.1 m/s; latitude and longitude: 1e-8 of the distance travelled)."""
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
        np.testing.assert_allclose(rust[key], ref[key], rtol=rtol, err_msg=key)


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


@pytest.mark.parametrize("calibration", [False, True])
def test_a_pass_keeping_the_last_epoch_is_the_same_pass(calibration) -> None:
    """``epochs="last"`` keeps the full pass's last epoch and every update bit for bit,
    with and without the calibration states; an unknown value names the argument."""
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = _inputs(30.0, np.zeros(3), "body")
    cfg = pronet.FilterConfig(p0_sigma=P0, dvl_calibration=calibration)

    def run(epochs: str) -> pronet.FilterResult:
        return pronet.run_filter(
            imu, imu_time, [pronet.Dvl(dvl_time, dvl)], t0=0.0, lla0=lla0, vel0=vel0, rpy0=rpy0,
            config=cfg, strategy=pronet.Strategy.mehra(5, Q), epochs=epochs,  # type: ignore[arg-type]
        )  # fmt: skip

    full, last = run("all"), run("last")
    # the same through the one run path, from a Recorded that asks for the last epoch
    rec = Recorded(imu, imu_time, dvl, dvl_time, 0.0, lla0, vel0, rpy0, cfg, epochs="last")
    via_run = pronet_run(pronet.Strategy.mehra(5, Q), rec).result
    np.testing.assert_array_equal(via_run.sigma, last.sigma)
    np.testing.assert_array_equal(via_run.nis, full.nis)
    assert len(full.time) == len(imu) + 1 and len(last.time) == 1
    for name in ("time", "lla", "vel", "rpy", "bias", "sigma", "calibration", "calibration_sigma"):
        kept = getattr(full, name)[-1:]  # (0, 7) stays (0, 7) without the states
        np.testing.assert_array_equal(getattr(last, name), kept)
    assert last.calibration.shape == ((1, 7) if calibration else (0, 7))
    updates = ("dvl_epoch", "innovation", "innovation_cov", "nis", "gain", "accepted")
    for name in ("covariance", "adaptive_q", *updates):
        np.testing.assert_array_equal(getattr(last, name), getattr(full, name))
    with pytest.raises(ValueError, match='^epochs: must be "all" or "last", got "every"$'):
        run("every")
    with pytest.raises(ValueError, match="^epochs: expected a string, got "):
        run(1)  # type: ignore[arg-type]


@pytest.mark.parametrize("xi", [1, 5])
def test_mehra_q_is_k_c_kt_from_the_recorded_innovations(xi) -> None:
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = _inputs(30.0, np.zeros(3), "body")

    def run(strategy: pronet.Strategy) -> pronet.FilterResult:
        return pronet.run_filter(
            imu, imu_time, [pronet.Dvl(dvl_time, dvl)], t0=0.0, lla0=lla0, vel0=vel0, rpy0=rpy0,
            config=pronet.FilterConfig(p0_sigma=P0), strategy=strategy,
        )  # fmt: skip

    out = run(pronet.Strategy.mehra(xi, Q))
    nu, gain = out.innovation, out.gain
    steps = np.diff(np.concatenate([[0], out.dvl_epoch]))  # IMU steps per DVL interval
    assert np.all(np.isnan(out.adaptive_q[: xi - 1]))  # prior Q until ξ innovations exist
    for k in range(xi - 1, len(nu)):
        c = sum(np.outer(v, v) for v in nu[k - xi + 1 : k + 1]) / xi
        q_hat = gain[k] @ c @ gain[k].T
        # K C Kᵀ sums terms of both signs: an entry far below the largest carries the
        # rounding of the largest, so the floor is relative to the matrix's scale.
        scale = np.abs(q_hat).max()
        np.testing.assert_allclose(
            out.adaptive_q[k] * steps[k], q_hat, rtol=1e-12, atol=1e-13 * scale
        )
    # Constant Q sets Q^c, never a discrete Q directly.
    assert np.all(np.isnan(run(pronet.Strategy.constant(Q)).adaptive_q))


# The reference alone (no call into the core): the lever arms and the heading measurement
# (docs/reference/aiding.md, "Lever arms and heading").

LLA = np.array([math.radians(32.5), math.radians(34.8), -12.0])
VEL = np.array([1.3, -0.4, 0.2])
C_TRUE = dcm_from_euler(0.05, -0.08, 2.3)
RATE = np.array([0.02, -0.03, 0.1])  # the true body rate [rad/s]
ARM = np.array([0.7, -0.3, 1.2])
#: Perturbation scales per block: δp [m] (it enters linearly but for the radii), and
#: δv, ψ, δb_a, δb_g.
SCALES = np.repeat([1e-2, 1e-5, 1e-5, 1e-5, 1e-5], 3)


#: SE₂(3)'s anchor in the measurement tests: the truth 3.9 km from it.
ANCHOR = position(np.array([-3000.0, 2500.0, 30.0]), LLA)


def _estimate(dx: np.ndarray, formulation: str):
    """``(lla, v, C, ω)`` of the estimate whose error from the truth above is ``dx``
    (15; δV in place of δv but in the classic formulation, δP in place of δp in
    SE₂(3)): ``Ĉ = Exp(−ψ) C``, ``v̂ = v + δv`` or ``v̂ = Ĉ Cᵀ v + δV``
    (docs/reference/filter.md's exact ``δV``), ``p̂ = Ĉ Cᵀ p + δP`` about ``ANCHOR`` (its exact
    ``δP``), ``ω̂ = ω − δb_g``."""
    rn, re = radii(LLA[0])
    lla = LLA + np.array(
        [dx[0] / (rn + LLA[2]), dx[1] / ((re + LLA[2]) * math.cos(LLA[0])), -dx[2]]
    )
    c = exp_so3(-dx[6:9]) @ C_TRUE
    if formulation == "se23":
        lla = position(c @ C_TRUE.T @ displacement(LLA, ANCHOR) + dx[0:3], ANCHOR)
    v = (VEL if formulation == "classic" else c @ C_TRUE.T @ VEL) + dx[3:6]
    return lla, v, c, RATE - dx[12:15]


def _model(name: str, formulation: str):
    """``(h, H)`` of a measurement at an estimate ``(lla, v, C, ω)``: ``h(x̂) − h(x) ≈
    H δx``. The fix is read through the filter's innovation, ``−ν``, against the fix
    of the true antenna. In SE₂(3) the position rows gain ``[p̂×]`` on ψ."""
    z_fix = fix_prediction(LLA, C_TRUE, ARM)
    invariant = formulation != "classic"

    def position_rows(s, rows, axes):
        if formulation == "se23":
            for row, i in zip(rows, axes, strict=True):
                row[6:9] += position_h_psi(displacement(s[0], ANCHOR), i)
        return rows

    models = {
        "depth": (
            lambda s: np.array([depth_prediction(s[0], s[2], ARM)]),
            lambda s: position_rows(s, depth_h_row(s[2], ARM)[None], [2]),
        ),
        "fix": (
            lambda s: -np.array([fix_innovation(z_fix, s[0], s[2], ARM, i) for i in range(3)]),
            lambda s: position_rows(
                s, np.array([position_h_row(i, s[2], ARM) for i in range(3)]), [0, 1, 2]
            ),  # fmt: skip
        ),
        "heading": (
            lambda s: np.array([heading_prediction(s[2])]),
            lambda s: heading_h_row(s[2])[None],
        ),
        "nav velocity": (
            lambda s: nav_velocity_prediction(s[1], s[2], s[3], ARM),
            lambda s: nav_velocity_h(s[1], s[2], s[3], ARM, invariant),
        ),
    }
    return models[name]


MODELS = ["depth", "fix", "heading", "nav velocity"]


@pytest.mark.parametrize("name", MODELS)
@pytest.mark.parametrize("formulation", ["classic", "invariant", "se23"])
def test_measurement_h_is_the_derivative_of_the_prediction(name, formulation) -> None:
    """Every column of H against central differences of the prediction (zero columns
    included). The fix's position columns carry terms of order |r|/R (2e-7 here: the
    metres of an arm at the estimate's latitude and height against the truth's), which
    the filter leaves out; everything else agrees to rounding (in SE₂(3), 3.9 km from
    the anchor, to the differences' third-order terms, ψ² |p̂| ~ 5e-8, and for a fix
    but for the metres of the anchor, ``_anchor_metres``, to the rounding of the
    latitude moved by ψ |p̂|, 3e-5, and the metres of its arm at the latitude so moved,
    |r| |p̂| (1 + tan φ)/R ~ 1.5e-3)."""
    h, big_h = _model(name, formulation)
    truth = _estimate(np.zeros(15), formulation)
    steps = np.repeat([1.0, 1e-4, 1e-5, 1e-4, 1e-6], 3)
    jac = np.zeros_like(big_h(truth))
    for k in range(15):
        e = np.zeros(15)
        e[k] = steps[k]
        jac[:, k] = (h(_estimate(e, formulation)) - h(_estimate(-e, formulation))) / (2 * steps[k])
    atol = 1e-9 + (2 * np.linalg.norm(ARM) / 6.36e6 if name == "fix" else 0.0)
    want = big_h(truth)
    if formulation == "se23":
        atol += 1e-7
        if name == "fix":
            want = _anchor_metres(want, truth[0])
            arm_metres = np.linalg.norm(ARM) * np.linalg.norm(displacement(LLA, ANCHOR)) / 6.36e6
            atol += 1e-4 + 2 * arm_metres
    np.testing.assert_allclose(jac, want, rtol=0, atol=atol)


def _anchor_metres(big_h: np.ndarray, lla: np.ndarray) -> np.ndarray:
    """The derivative of a fix's innovation in SE₂(3) from its H: δP is in metres at
    the anchor (``displacement``), the innovation in metres at the estimate, so its
    north and east rows are H's with the position error's part (δP and ``[p̂×]`` on ψ)
    scaled by the estimate's metres per anchor metre, ``1 − tan φ Δφ`` east (3e-4 off
    here, 1 % 100 km north of an anchor at 32°): a term of order |p̂|/R the filter
    leaves out, as it does in ``ṗ̂ = v̂`` (docs/reference/filter.md)."""
    rn, re = radii(lla[0])
    rn0, re0 = radii(ANCHOR[0])
    scale = [
        (rn + lla[2]) / (rn0 + ANCHOR[2]),
        (re + lla[2]) * math.cos(lla[0]) / ((re0 + ANCHOR[2]) * math.cos(ANCHOR[0])),
    ]
    assert 2e-4 < 1 - scale[1] < 4e-4  # the truth 3 km north of the anchor at 32.5°
    want = big_h.copy()
    disp = displacement(lla, ANCHOR)
    for i, s in enumerate(scale):
        want[i, 0:3] *= s
        want[i, 6:9] += (s - 1) * position_h_psi(disp, i)
    return want


@pytest.mark.parametrize(
    ("formulation", "name"),
    [(f, n) for f in ("classic", "invariant", "se23") for n in MODELS if (f, n) != ("se23", "fix")],
)
def test_measurement_h_predicts_the_change_to_second_order(name, formulation) -> None:
    """``h(x̂) − h(x)`` against ``H δx`` for one estimate off the truth in every state at
    once: with H at the truth, the central difference agrees to 1e-6 relative (its
    remainder is third order); with H at the estimate, as the filter linearizes, the
    remainder is second order: under 10 ε relative at perturbations ε (ψ, δv, δb; δp
    1e-2 m) and 100 times less when they shrink tenfold (but for the fix, whose
    remainder is the rounding of the latitude, 1e-9 m). In SE₂(3) δP shrinks with the
    rest, since it multiplies ψ (``[δP×]ψ``); its fix is first order off by the metres
    of the anchor (``_anchor_metres``), and left out."""
    h, big_h = _model(name, formulation)
    truth = _estimate(np.zeros(15), formulation)
    u = np.random.default_rng(3).normal(size=15)
    dx = u * SCALES
    central = (h(_estimate(dx, formulation)) - h(_estimate(-dx, formulation))) / 2
    linear = big_h(truth) @ dx
    assert np.linalg.norm(central - linear) <= 1e-6 * np.linalg.norm(linear)
    remainders = []
    for eps in (1e-5, 1e-6):
        dx = u * (eps if formulation == "se23" else np.where(SCALES == 1e-2, 1e-2, eps))
        est = _estimate(dx, formulation)
        linear = big_h(est) @ dx
        remainder = np.linalg.norm(h(est) - h(truth) - linear)
        assert remainder <= 10 * eps * np.linalg.norm(linear)
        remainders.append(remainder)
    if name != "fix":
        assert 50 < remainders[0] / remainders[1] < 200


def _log_so3(r: np.ndarray) -> np.ndarray:
    """The rotation vector of ``r`` (inverse of ``exp_so3`` below π)."""
    s = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]) / 2
    angle = math.atan2(np.linalg.norm(s), (np.trace(r) - 1) / 2)
    return s * (angle / np.linalg.norm(s)) if angle > 0 else s


def _se23_error(est, truth) -> np.ndarray:
    """``[δP, δV, ψ]`` of an estimate ``(lla, v, C)`` against the truth, exactly:
    ``δP = p̂ − Ĉ Cᵀ p`` about ``ANCHOR``, ``δV = v̂ − Ĉ Cᵀ v``, ``Ĉ = Exp(−ψ) C``."""
    (lla_hat, v_hat, c_hat), (lla, v, c) = est, truth
    r = c_hat @ c.T
    d_p = displacement(lla_hat, ANCHOR) - r @ displacement(lla, ANCHOR)
    return np.concatenate([d_p, v_hat - r @ v, -_log_so3(r)])


def test_se23_position_rows_of_f_are_the_derivative_of_the_strapdown() -> None:
    """The position rows of SE₂(3)'s Φ = I + F Δt + (F Δt)²/2 + (F Δt)³/6 (the
    reference's F, 3.9 km from the anchor) against central differences of one
    strapdown step of an estimate off the truth in each state (δP 1 m, δV 1e-3 m/s, ψ
    1e-4 rad, biases; the step's Φ is F's to third order), error taken exactly
    (``_se23_error``): each block within 0.5 % of its size in F Δt, what ``ṗ̂ = v̂``
    leaves out at |p̂|/R (docs/reference/filter.md) with the differences' rounding (0.2 % at
    most here). The position–attitude block is 1.9e-3 in F Δt, 180 times that
    tolerance; with its sign flipped the gap is twice the block. (The velocity rows'
    Schuler terms rest on the rotation of the navigation frame, which this error leaves
    out: they are not checked here.)"""
    f_body, w_body, dt = np.array([0.3, -0.2, -9.7]), np.array([0.02, -0.03, 0.1]), 0.01
    truth = strapdown_step(LLA, VEL, C_TRUE, f_body, w_body, dt)
    steps = np.repeat([1.0, 1e-3, 1e-4, 1e-3, 1e-5], 3)
    numeric = np.zeros((3, 15))
    for k in range(15):
        e = np.zeros(15)
        e[k] = steps[k]
        ends = []
        for dx in (e, -e):
            lla, v, c, _ = _estimate(dx, "se23")
            est = strapdown_step(lla, v, c, f_body - dx[9:12], w_body - dx[12:15], dt)
            ends.append(_se23_error(est, truth)[:3])
        numeric[:, k] = (ends[0] - ends[1]) / (2 * steps[k])

    def phi(sign: float) -> np.ndarray:
        fm, gam = error_dynamics(LLA, VEL, C_TRUE, C_TRUE @ f_body, True)
        saved, numpy_reference_se23.POS_ATT_SIGN = numpy_reference_se23.POS_ATT_SIGN, sign
        try:
            fm, _ = to_se23(fm, gam, LLA, VEL, C_TRUE, displacement(LLA, ANCHOR))
        finally:
            numpy_reference_se23.POS_ATT_SIGN = saved
        fd = fm * dt
        return (np.eye(15) + fd + fd @ fd / 2 + fd @ fd @ fd / 6)[:3], fd[:3]

    want, fd = phi(1.0)
    for cols in (slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15)):
        gap = np.abs(numeric[:, cols] - want[:, cols]).max()
        assert gap <= 5e-3 * np.abs(fd[:, cols]).max() + 1e-6, (cols, gap)
    assert np.abs(fd[:, 6:9]).max() > 1e-3
    flipped, _ = phi(-1.0)
    assert np.abs(numeric[:, 6:9] - flipped[:, 6:9]).max() > 0.5 * np.abs(fd[:, 6:9]).max()


def test_measurement_models_read_their_signs_and_wrap() -> None:
    """A pressure sensor 1 m below a level IMU reads 1 m deeper; an antenna 2 m above it
    is 2 m higher; a heading across ±π wraps; zero arms leave the plain models."""
    level = dcm_from_euler(0.0, 0.0, 0.4)
    assert depth_prediction(LLA, level, (0.0, 0.0, 1.0)) == pytest.approx(-LLA[2] + 1.0)
    assert fix_prediction(LLA, level, (0.0, 0.0, -2.0))[2] == pytest.approx(LLA[2] + 2.0)
    c = dcm_from_euler(0.0, 0.0, -math.pi + 1e-3)
    assert heading_innovation(math.pi - 1e-3, c) == pytest.approx(-2e-3, abs=1e-12)
    assert heading_innovation(-math.pi + 2e-3, c) == pytest.approx(1e-3, abs=1e-12)
    zero = np.zeros(3)
    assert depth_prediction(LLA, C_TRUE, zero) == -LLA[2]
    np.testing.assert_array_equal(depth_h_row(C_TRUE, zero, 19), np.eye(19)[2])
    np.testing.assert_array_equal(nav_velocity_prediction(VEL, C_TRUE, RATE, zero), VEL)
    assert heading_h_row(C_TRUE, 19)[8] == -1.0 and not heading_h_row(C_TRUE, 19)[15:].any()


# A vehicle at rest (the noise-free IMU of test_reference_strapdown_stays_at_rest keeps
# it there), a body-frame DVL reading zero every second, the estimate started 2 m,
# 0.05 m/s and a few mrad off.
REST_LLA = np.array([math.radians(32), math.radians(34), -5.0])
REST_C = dcm_from_euler(0.02, -0.01, 0.7)


def _rest_inputs(seconds: float):
    w_ie, _, g = rates(REST_LLA, np.zeros(3))
    n = int(round(seconds / 0.01))
    imu = np.tile(np.concatenate([-REST_C.T @ g, REST_C.T @ w_ie]), (n, 1))
    imu_time = 0.01 * np.arange(1, n + 1)
    dvl_time = np.arange(1.0, seconds + 1e-9, 1.0)
    lla0 = REST_LLA + np.array([2.0 / 6.36e6, 0.0, 0.5])
    rpy0 = euler_from_dcm(REST_C) + np.array([1e-3, -1e-3, 4e-3])
    return imu, imu_time, np.zeros((len(dvl_time), 3)), dvl_time, lla0, (0.05, -0.03, 0.01), rpy0


def _rest_run(seconds: float = 10.0, **kwargs):
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = _rest_inputs(seconds)
    tuning = dict(accel_bias_psd=1e-6, gyro_bias_psd=1e-8, dvl_variance=(0.01,) * 3)
    return run_reference_filter(
        imu, imu_time, dvl, dvl_time, 0.0, lla0, vel0, rpy0, q=Q, p0_sigma=P0, imu_dt=0.01,
        **tuning, **kwargs,
    )  # fmt: skip


def _rest_aiding(seconds: float, depth_arm=(0.0, 0.0, 0.0), fix_arm=(0.0, 0.0, 0.0)):
    """Depth every second and fixes every 3 s (every other one without its height),
    noise-free, of sensors at ``depth_arm`` and ``fix_arm``; a fix before the run."""
    depth_time = np.arange(0.503, seconds, 1.0)
    depth = np.full(len(depth_time), depth_prediction(REST_LLA, REST_C, depth_arm))
    fix_time = np.concatenate([[-1.0], np.arange(2.996, seconds, 3.0)])
    fix = np.tile(fix_prediction(REST_LLA, REST_C, fix_arm), (len(fix_time), 1))
    fix[2::2, 2] = np.nan
    return dict(depth=depth, depth_time=depth_time, depth_sigma=0.1, fix=fix,
                fix_time=fix_time, fix_sigma=np.full((len(fix_time), 3), 0.05))  # fmt: skip


@pytest.mark.parametrize(
    ("aiding", "formulation", "covariance_step", "calibration"),
    [
        ("body", "classic", 0.0, None),
        ("body", "invariant", 0.1, (0.01, (0.02, 0.02, 0.03), 1e-8, 1e-9)),
        ("nav", "classic", 0.1, None),
        ("nav", "invariant", 0.0, None),
    ],
)
def test_zero_lever_arms_are_the_run_without_them(
    aiding, formulation, covariance_step, calibration
) -> None:
    """Explicit zero arms (depth, fix, and the DVL's with navigation-frame aiding) and a
    per-row σ equal to the scalar one give the run without them bit for bit."""
    common = dict(aiding=aiding, formulation=formulation, covariance_step=covariance_step,
                  calibration=calibration, **_rest_aiding(8.0))  # fmt: skip
    plain = _rest_run(8.0, **common)
    common["depth_sigma"] = np.full(len(common["depth"]), 0.1)
    zeros = _rest_run(8.0, depth_lever_arm=np.zeros(3), fix_lever_arm=(0, 0, 0),
                      lever_arm=np.zeros(3), **common)  # fmt: skip
    assert len(plain["depth_nis"]) == 8 and len(plain["fix_nis"]) == 2
    assert plain.keys() == zeros.keys()
    for key in plain:
        np.testing.assert_array_equal(zeros[key], plain[key], err_msg=key)


def test_lever_arms_of_depth_and_fixes_are_taken_off() -> None:
    """Readings of a pressure sensor 1.2 m below the IMU and an antenna on a 2 m mast
    (fixes σ 5 cm): told the arms, the filter puts the IMU where it is and the NIS stay
    small; told nothing, it is pulled half a metre and more towards the sensors, and
    their NIS say so."""
    depth_arm, fix_arm = np.array([0.3, 0.1, 1.2]), np.array([-0.5, 0.2, -2.0])
    aiding = _rest_aiding(10.0, depth_arm, fix_arm)
    told = _rest_run(depth_lever_arm=depth_arm, fix_lever_arm=fix_arm, **aiding)
    untold = _rest_run(**aiding)
    rn, re = radii(REST_LLA[0])

    def error(out):
        d = out["lla"][-1] - REST_LLA
        return np.array([d[0] * (rn + d[2]), d[1] * (re + d[2]) * math.cos(REST_LLA[0]), -d[2]])

    assert np.abs(error(told)).max() < 0.05 and np.abs(error(untold)).max() > 0.4
    assert told["depth_nis"][-3:].max() < 0.1 < untold["depth_nis"][-3:].max()
    assert told["fix_nis"][1:].max() < 1.0 and untold["fix_nis"][-1] > 100.0


@pytest.mark.parametrize("covariance_step", [0.0, 0.1])
@pytest.mark.parametrize("formulation", ["classic", "invariant"])
def test_heading_updates_shrink_the_heading_sigma(formulation, covariance_step) -> None:
    """Headings every 2 s (1 mrad) besides the DVL: σ of ψ_z drops at every heading
    epoch, ends far below the run without them, and one NIS per row applied (a row
    before the run is skipped). At a covariance step the epoch closes one early."""
    yaw = euler_from_dcm(REST_C)[2]
    heading_time = np.concatenate([[-0.5], np.arange(2.037, 10.0, 2.0)])
    offsets = np.array([0.0, 4e-4, -7e-4, 2e-4, 9e-4])
    heading = yaw + offsets  # z's within 1 mrad of the truth
    common = dict(formulation=formulation, covariance_step=covariance_step)
    log: list = []
    out = _rest_run(heading=heading, heading_time=heading_time, heading_sigma=1e-3, log=log,
                    **common)  # fmt: skip
    without = _rest_run(**common)
    assert len(out["heading_nis"]) == len(heading) - 1
    epochs = [int(np.argmin(np.abs(out["time"] - t))) for t in heading_time[1:]]
    for e in epochs:
        assert out["sigma"][e, 8] < out["sigma"][e - 1, 8]
        assert log[e][0] is not None  # a covariance step closed here
    last = epochs[-1]
    assert out["sigma"][last, 8] < 1e-3 < 0.005 < without["sigma"][last, 8]
    assert out["sigma"][-1, 8] < 0.25 * without["sigma"][-1, 8]
    # The estimate is pulled to the readings: within its σ (a few) of the truth.
    assert abs(out["rpy"][-1, 2] - yaw) < 3 * out["sigma"][-1, 8]
    # A per-row σ the same for every row is the scalar one.
    again = _rest_run(heading=heading, heading_time=heading_time,
                      heading_sigma=np.full(len(heading), 1e-3), **common)  # fmt: skip
    np.testing.assert_array_equal(again["heading_nis"], out["heading_nis"])
    np.testing.assert_array_equal(again["sigma"], out["sigma"])
