"""The Rust filter agrees with the independent NumPy implementation of
docs/reference/filter.md (far from SE₂(3)'s anchor: test_numpy_reference_far.py; the
reference's own measurement models against their derivatives:
test_numpy_reference_models.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import pronet
from pronet.run import Recorded
from pronet.run import run as pronet_run

from numpy_reference_ekf import (
    dcm_from_euler,
    depth_prediction,
    euler_from_dcm,
    fix_prediction,
    gravity,
    radii,
    rates,
    run_reference_filter,
    strapdown_step,
)

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
            z = traj.vel_ned[i] + c @ np.cross(ideal[i - 1, 3:], lever_arm)
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
    [
        ("body", (0.5, -0.2, 1.0)),
        ("body", (0.0, 0.0, 0.0)),
        ("nav", (0, 0, 0)),
        ("nav", (0.5, -0.2, 1.0)),
    ],
)
@pytest.mark.parametrize("formulation", ["classic", "invariant", "se23"])
@pytest.mark.parametrize("covariance_step", [pytest.param(0.0, marks=pytest.mark.slow), 0.1])
def test_rust_filter_matches_reference(aiding, lever_arm, formulation, covariance_step) -> None:
    """At every IMU sample and at a 0.1 s covariance step (ten samples)."""
    _matches_reference(aiding, lever_arm, formulation, covariance_step, imu_dt=0.01)


@pytest.mark.parametrize("aiding", ["body", "nav"])
def test_rust_filter_matches_reference_where_the_nominal_imu_step_is_not_the_datas(
    aiding,
) -> None:
    """A 100 Hz IMU whose q is given per sample of a nominal 0.02 s step: the process
    noise's PSD is q·0.02 and the lever arm's gyro noise, per 0.01 s sample, 2q."""
    _matches_reference(aiding, (0.5, -0.2, 1.0), "invariant", 0.1, imu_dt=0.02)


def _matches_reference(aiding, lever_arm, formulation, covariance_step, imu_dt) -> None:
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = _inputs(60.0, np.array(lever_arm), aiding)
    cfg = pronet.FilterConfig(
        imu_dt=imu_dt,
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
        imu_dt=imu_dt,
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
