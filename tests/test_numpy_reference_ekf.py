"""The Rust filter agrees with the independent NumPy implementation of docs/filter.md."""

from __future__ import annotations

import math

import numpy as np
import pytest

import pronet
from pronet.run import Recorded
from pronet.run import run as pronet_run

from numpy_reference_ekf import dcm_from_euler, gravity, rates, run_reference_filter, strapdown_step

Q = np.array([1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6])
P0 = np.array([1, 1, 1, 0.1, 0.1, 0.1, 1e-3, 1e-3, 5e-3, 1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-4])


def _inputs(seconds: float, lever_arm, aiding: str, seed: int = 4):
    traj = pronet.builtin_trajectory("paper")
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
@pytest.mark.parametrize("formulation", ["classic", "invariant"])
@pytest.mark.parametrize("covariance_step", [0.0, 0.1])
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
        dvl,
        dvl_time,
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


@pytest.mark.parametrize("formulation", ["classic", "invariant"])
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
    rust = pronet.run_filter(
        *args, t0=0.0, **start, config=cfg, strategy=pronet.Strategy.constant(Q)
    )
    ref = run_reference_filter(
        *args, 0.0, lla0, vel0, rpy0, q=Q, accel_bias_psd=1e-6, gyro_bias_psd=1e-8,
        dvl_variance=(0.01,) * 3, p0_sigma=P0, imu_dt=0.01, lever_arm=arm,
        calibration=calibration, formulation=formulation, covariance_step=covariance_step,
    )  # fmt: skip
    assert len(ref["nis"]) == 60 and rust.calibration.shape == (len(imu) + 1, 4)
    rtol = 1e-8
    np.testing.assert_allclose(rust.vel, ref["vel"], rtol=rtol, atol=1e-8 * 1.0)
    np.testing.assert_allclose(rust.rpy, ref["rpy"], rtol=rtol, atol=1e-8 * 1e-2)
    np.testing.assert_allclose(rust.bias, ref["bias"], rtol=rtol, atol=1e-8 * 1e-3)
    np.testing.assert_allclose(rust.sigma, ref["sigma"], rtol=rtol, atol=0.0)
    np.testing.assert_allclose(rust.lla[:, :2], ref["lla"][:, :2], rtol=0, atol=1e-8 * 60 / 6.4e6)
    np.testing.assert_allclose(rust.innovation, ref["innovation"], rtol=rtol, atol=1e-8 * 0.1)
    np.testing.assert_allclose(rust.nis, ref["nis"], rtol=rtol)
    # Scale ~0.005 and angles ~0.01 rad: 1e-8 relative of those scales.
    np.testing.assert_allclose(rust.calibration, ref["calibration"], rtol=rtol, atol=1e-10)
    np.testing.assert_allclose(rust.calibration_sigma, ref["calibration_sigma"], rtol=rtol)
    # The updates moved the states (how well they learn: test_dvlcalibration.py).
    assert np.abs(rust.calibration[-1] - rust.calibration[0]).max() > 1e-4
    # Without the states the arrays are empty.
    plain = pronet.run_filter(
        *args, t0=0.0, **start, config=pronet.FilterConfig(p0_sigma=P0),
        strategy=pronet.Strategy.constant(Q),
    )  # fmt: skip
    assert plain.calibration.shape == plain.calibration_sigma.shape == (0, 4)


@pytest.mark.parametrize("calibration", [False, True])
def test_a_pass_keeping_the_last_epoch_is_the_same_pass(calibration) -> None:
    """``epochs="last"`` keeps the full pass's last epoch and every update bit for bit,
    with and without the calibration states; an unknown value names the argument."""
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = _inputs(30.0, np.zeros(3), "body")
    cfg = pronet.FilterConfig(p0_sigma=P0, dvl_calibration=calibration)

    def run(epochs: str) -> pronet.FilterResult:
        return pronet.run_filter(
            imu, imu_time, dvl, dvl_time, t0=0.0, lla0=lla0, vel0=vel0, rpy0=rpy0,
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
        kept = getattr(full, name)[-1:]  # (0, 4) stays (0, 4) without the states
        np.testing.assert_array_equal(getattr(last, name), kept)
    assert last.calibration.shape == ((1, 4) if calibration else (0, 4))
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
            imu, imu_time, dvl, dvl_time, t0=0.0, lla0=lla0, vel0=vel0, rpy0=rpy0,
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
