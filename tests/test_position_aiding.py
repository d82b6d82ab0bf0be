"""Position fixes and depth readings as filter updates (``run_filter`` with ``Depth`` and
``Fix`` streams): equal to the NumPy reference to 1e-8 (both formulations, the 19 states,
the smoother), what they do to the error, and the inputs they refuse."""

from __future__ import annotations

import math

import numpy as np
import pytest

import pronet

from numpy_reference_ekf import dcm_from_euler, run_reference_filter
from numpy_reference_smoother import rts_smooth
from test_numpy_reference_ekf import P0, Q, _inputs

R_EARTH = 6.38e6  # [m], for metres to radians at the test's tolerance


def _aiding(traj: pronet.Trajectory, seconds: float, rng: np.random.Generator):
    """Depth every second (σ 0.1 m) and fixes every 10 s (σ 2 m; every other one
    without its height), from the truth plus noise; the first fix before the run."""
    k = np.arange(100, int(seconds * 100) + 1, 100)
    depth = -traj.lla[k, 2] + rng.normal(size=len(k)) * 0.1
    f = np.arange(1000, int(seconds * 100) + 1, 1000)
    fix = traj.lla[f] + rng.normal(size=(len(f), 3)) * [2 / R_EARTH, 2 / R_EARTH, 2]
    fix[1::2, 2] = np.nan
    sigma = np.tile([2.0, 2.0, 2.0], (len(f), 1))
    fix_time = traj.time[f]
    fix = np.vstack([traj.lla[0], fix])
    fix_time = np.concatenate([[-5.0], fix_time])
    sigma = np.vstack([[2.0, 2.0, 2.0], sigma])
    return dict(depth=depth, depth_time=traj.time[k], depth_sigma=0.1, fix=fix,
                fix_time=fix_time, fix_sigma=sigma)  # fmt: skip


def _streams(aiding: dict) -> list:
    """The depth and fix streams of ``_aiding``'s arrays (the reference's keywords)."""
    a = aiding
    return [
        pronet.Depth(a["depth_time"], a["depth"], sigma=a["depth_sigma"]),
        pronet.Fix(a["fix_time"], a["fix"], sigma=a["fix_sigma"]),
    ]


DEPTH_ARM, FIX_ARM = (0.3, 0.1, 1.2), (-0.5, 0.2, -2.0)  # [m, body FRD]


def _arms_and_headings(traj: pronet.Trajectory, seconds: float, rng: np.random.Generator):
    """``_aiding``'s readings taken by a pressure sensor at ``DEPTH_ARM`` and an
    antenna at ``FIX_ARM``, told to the filter, and headings every 5 s (the truth plus
    2 mrad, σ per row): the first before the run, one given a turn away (±2π)."""
    aiding = _aiding(traj, seconds, rng)
    for key, arm, time in (("depth", DEPTH_ARM, aiding["depth_time"]),
                           ("fix", FIX_ARM, aiding["fix_time"][1:])):  # fmt: skip
        k = np.rint(time * 100).astype(int)
        offset = np.einsum("kij,j->ki", [dcm_from_euler(*traj.rpy[i]) for i in k], arm)
        if key == "depth":
            aiding["depth"] = aiding["depth"] + offset[:, 2]
        else:  # the truth plus noise moved by the arm's NED offset
            noisy = aiding["fix"][1:]
            at = np.nan_to_num(noisy)  # a horizontal fix: moved about height 0
            moved = [pronet.lla_from_ned(o, p) for o, p in zip(offset, at, strict=True)]
            aiding["fix"][1:] = np.where(np.isnan(noisy), np.nan, moved)
    h = np.arange(500, int(seconds * 100) + 1, 500)
    heading = traj.rpy[h, 2] + rng.normal(size=len(h)) * 2e-3
    heading[3] += -2 * math.pi if heading[3] > 0 else 2 * math.pi
    return dict(aiding, depth_lever_arm=DEPTH_ARM, fix_lever_arm=FIX_ARM,
                heading=np.concatenate([[0.3], heading]),
                heading_time=np.concatenate([[-2.0], traj.time[h]]),
                heading_sigma=np.r_[2e-3, np.linspace(2e-3, 4e-3, len(h))])  # fmt: skip


def _streams_with_arms(aiding: dict) -> list:
    """The depth, fix and heading streams of ``_arms_and_headings``'s arrays."""
    a = aiding
    return [
        pronet.Depth(a["depth_time"], a["depth"], sigma=a["depth_sigma"],
                     lever_arm=a["depth_lever_arm"]),
        pronet.Fix(a["fix_time"], a["fix"], sigma=a["fix_sigma"], lever_arm=a["fix_lever_arm"]),
        pronet.Heading(a["heading_time"], a["heading"], sigma=a["heading_sigma"]),
    ]  # fmt: skip


@pytest.mark.parametrize("formulation", ["classic", "invariant"])
@pytest.mark.parametrize("calibrated", [False, True])
@pytest.mark.parametrize("covariance_step", [pytest.param(0.0, marks=pytest.mark.slow), 0.1])
def test_fixes_and_depth_match_the_reference(formulation, calibrated, covariance_step) -> None:
    _match_the_reference(formulation, calibrated, covariance_step, arms=False)


@pytest.mark.parametrize(
    ("formulation", "calibrated", "covariance_step"),
    [("classic", False, 0.0), ("invariant", True, 0.1),
     pytest.param("classic", True, 0.1, marks=pytest.mark.slow),
     pytest.param("invariant", False, 0.0, marks=pytest.mark.slow)],
)  # fmt: skip
def test_lever_arms_and_headings_match_the_reference(
    formulation, calibrated, covariance_step
) -> None:
    """A depth sensor and a fix's antenna at their lever arms, and a heading stream
    (docs/reference/aiding.md, "Lever arms and heading"): the core is the reference to 1e-8, the
    smoother too."""
    _match_the_reference(formulation, calibrated, covariance_step, arms=True)


def _match_the_reference(formulation, calibrated, covariance_step, arms: bool) -> None:
    """60 s of the paper's trajectory with a DVL, depths and fixes (and with ``arms``
    their lever arms and headings) through the core and the reference: every output to
    1e-8, and the smoother's."""
    arm = (0.5, -0.2, 1.0)
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = _inputs(60.0, np.array(arm), "body")
    make, to_streams = (_arms_and_headings, _streams_with_arms) if arms else (_aiding, _streams)
    aiding = make(pronet.builtin_trajectory("paper"), 60.0, np.random.default_rng(8))
    calibration = (0.01, (0.02, 0.02, 0.03), 1e-8, 1e-9) if calibrated else None
    extra = {}
    if calibrated:
        extra = dict(dvl_calibration=True, dvl_scale_sigma=0.01,
                     dvl_misalignment_sigma=(0.02, 0.02, 0.03), dvl_scale_psd=1e-8,
                     dvl_misalignment_psd=1e-9)  # fmt: skip
    tuning = dict(accel_bias_psd=1e-6, gyro_bias_psd=1e-8, dvl_variance=(0.01,) * 3,
                  covariance_step=covariance_step)  # fmt: skip
    cfg = pronet.FilterConfig(p0_sigma=P0, lever_arm=arm, formulation=formulation,
                              **tuning, **extra)  # fmt: skip
    rust = pronet.run_filter(
        imu, imu_time, [pronet.Dvl(dvl_time, dvl), *to_streams(aiding)], t0=0.0, lla0=lla0,
        vel0=vel0, rpy0=rpy0, config=cfg, strategy=pronet.Strategy.constant(Q), smooth=True,
    )  # fmt: skip
    log: list = []
    ref = run_reference_filter(
        imu, imu_time, dvl, dvl_time, 0.0, lla0, vel0, rpy0, q=Q, p0_sigma=P0, imu_dt=0.01,
        lever_arm=arm, formulation=formulation, calibration=calibration, log=log,
        **tuning, **aiding,
    )  # fmt: skip
    assert rust.fix_epoch[0] == -1 and np.isnan(rust.fix_nis[0])  # before the run
    np.testing.assert_array_equal(rust.fix_epoch[1:], np.arange(1, 7) * 1000)
    np.testing.assert_array_equal(rust.depth_epoch, np.arange(1, 61) * 100)
    rtol = 1e-8
    np.testing.assert_allclose(rust.depth_nis, ref["depth_nis"], rtol=rtol)
    np.testing.assert_allclose(rust.fix_nis[1:], ref["fix_nis"], rtol=rtol)
    if arms:
        heading = rust.streams[-1]
        assert heading.kind == "heading" and heading.epoch[0] == -1
        np.testing.assert_array_equal(heading.epoch[1:], np.arange(1, 13) * 500)
        np.testing.assert_allclose(heading.nis[1:], ref["heading_nis"], rtol=rtol)
        assert np.mean(heading.nis[1:]) < 5.0  # readings where the sensors sit: consistent
    np.testing.assert_allclose(rust.vel, ref["vel"], rtol=rtol, atol=1e-8)
    np.testing.assert_allclose(rust.rpy, ref["rpy"], rtol=rtol, atol=1e-10)
    np.testing.assert_allclose(rust.bias, ref["bias"], rtol=rtol, atol=1e-11)
    np.testing.assert_allclose(rust.sigma, ref["sigma"], rtol=rtol, atol=0.0)
    np.testing.assert_allclose(rust.lla[:, :2], ref["lla"][:, :2], rtol=0, atol=1e-8 * 60 / 6.4e6)
    np.testing.assert_allclose(rust.lla[:, 2], ref["lla"][:, 2], rtol=rtol, atol=1e-8)
    # The smoother across the position updates' resets too (their calibration part).
    smoothed = rts_smooth(ref, log, formulation)
    assert rust.smoothed is not None
    np.testing.assert_allclose(rust.smoothed.vel, smoothed["vel"], rtol=rtol, atol=1e-8)
    np.testing.assert_allclose(rust.smoothed.sigma, smoothed["sigma"], rtol=rtol, atol=0)
    np.testing.assert_allclose(
        rust.smoothed.lla[:, :2], smoothed["lla"][:, :2], rtol=0, atol=1e-8 * 60 / 6.4e6
    )
    if calibrated:
        np.testing.assert_allclose(
            rust.smoothed.calibration[:, :4], smoothed["calibration"], rtol=rtol, atol=1e-10
        )
        np.testing.assert_allclose(
            rust.smoothed.calibration_sigma[:, :4], smoothed["calibration_sigma"], rtol=rtol, atol=0
        )


def _pass(seconds: float, seed: int, streams: list | None = None):
    """A noisy IMU along the paper's trajectory, no DVL (``streams``: its aiding), from
    the truth."""
    traj = pronet.builtin_trajectory("paper")
    n = int(round(seconds / traj.dt))
    rng = np.random.default_rng(seed)
    bias = np.array([2e-3] * 3 + [2e-5] * 3)  # [m/s², rad/s]
    imu = traj.imu[:n] + rng.normal(size=(n, 6)) * np.sqrt(Q) + bias
    cfg = pronet.FilterConfig(accel_bias_psd=1e-10, gyro_bias_psd=1e-14)
    out = pronet.run_filter(
        imu, traj.time[1 : n + 1], streams or [], t0=0.0, lla0=traj.lla[0],
        vel0=traj.vel_ned[0], rpy0=traj.rpy[0], config=cfg,
        strategy=pronet.Strategy.constant(Q),
    )  # fmt: skip
    origin = traj.lla[0]
    error = pronet.local_ned(out.lla, origin) - pronet.local_ned(traj.lla[: n + 1], origin)
    return traj, out, error


def test_fixes_alone_bound_the_drift_and_depth_holds_the_height() -> None:
    """Without a DVL: a fix every 10 s (σ 2 m) keeps the horizontal error within a few
    σ where free inertial drifts away; a depth every second (σ 0.1 m) holds the height,
    and the filter's σ says so."""
    seconds, rng = 300.0, np.random.default_rng(3)
    free_traj, _, free = _pass(seconds, 1)
    aiding = _aiding(free_traj, seconds, rng)
    _, out, aided = _pass(seconds, 1, _streams(aiding))
    horizontal = np.hypot(aided[:, 0], aided[:, 1])
    assert np.hypot(*free[-1, :2]) > 100.0  # free inertial: 2 mg of bias for 300 s
    assert horizontal[3000:].max() < 15.0, horizontal.max()
    assert np.abs(aided[100:, 2]).max() < 0.5
    assert out.sigma[-1, 2] < 0.2 and out.sigma[-1, 0] < 10.0
    nis = out.fix_nis[np.isfinite(out.fix_nis)]
    assert 0.5 < nis.mean() < 6.0  # χ² of 2–3 dof, from a filter told its model


def test_a_fix_across_the_antimeridian_is_the_fix_it_names() -> None:
    """A run eastward across the antimeridian (longitude from 30 m short of π to past
    it, as the strapdown integrates it): its fixes given in ±180° (near −π once
    across) aid it as the same fixes given unwrapped do, to 1e-6 m and in NIS to 1e-9
    (without the wrap: an innovation of 40 000 km)."""
    segments = [[120.0, 0.0, 0.0, 0.0]]
    r_e = pronet.earth_radii(0.5)[1] - 20.0
    lon0 = math.pi - 30.0 / (r_e * math.cos(0.5))
    traj = pronet.trajectory_from_segments(segments, lla0=(0.5, lon0, -20.0), speed0=1.5,
                                           rpy0=(0.0, 0.0, 1.2))  # fmt: skip
    assert traj.lla[-1, 1] > math.pi  # crossed
    n, rng = len(traj.time) - 1, np.random.default_rng(5)
    imu = traj.imu + rng.normal(size=(n, 6)) * np.sqrt(Q) + np.array([2e-3] * 3 + [2e-5] * 3)
    f = np.arange(1000, n + 1, 1000)
    fix = traj.lla[f] + rng.normal(size=(len(f), 3)) * [2 / R_EARTH, 2 / R_EARTH, 2]
    kw = dict(t0=0.0, lla0=traj.lla[0], vel0=traj.vel_ned[0], rpy0=traj.rpy[0],
              config=pronet.FilterConfig(accel_bias_psd=1e-10, gyro_bias_psd=1e-14),
              strategy=pronet.Strategy.constant(Q))  # fmt: skip

    def run(lla):
        fixes = pronet.Fix(traj.time[f], lla, sigma=[2.0, 2.0, 2.0])
        return pronet.run_filter(imu, traj.time[1:], [fixes], **kw)  # type: ignore[arg-type]

    unwrapped = run(fix)
    plus_minus = fix.copy()
    plus_minus[:, 1] = np.angle(np.exp(1j * fix[:, 1]))  # ±180°: near −π once across
    assert (plus_minus[:, 1] < 0).sum() >= 3 and (plus_minus[:, 1] > 0).any()
    wrapped = run(plus_minus)
    np.testing.assert_allclose(wrapped.fix_nis, unwrapped.fix_nis, rtol=1e-9)
    assert unwrapped.fix_nis.max() < 30.0
    error = pronet.local_ned(wrapped.lla, traj.lla[0]) - pronet.local_ned(
        unwrapped.lla, traj.lla[0]
    )
    assert np.abs(error).max() < 1e-6


@pytest.mark.parametrize(
    ("stream", "message"),
    [
        (lambda: pronet.Depth([1.0, 2.0], [1.0], sigma=0.1), "^time: has 2 rows"),
        (lambda: pronet.Depth([1.0], [1.0], sigma=0.0), "^sigma: must be a fin"),
        (lambda: pronet.Depth([1.0], [np.nan], sigma=0.1), "^depth"),
        (
            lambda: pronet.Fix([1.0], [[0.5, 0.6, 0.0]], sigma=[[2.0, 0.0, 2.0]]),
            "^sigma: row 0 must hold 3 finite",
        ),
        (lambda: pronet.Fix([1.0], [[0.5, 0.6, np.nan]], sigma=[[2.0, 2.0, np.nan]]), None),
        (
            lambda: pronet.Fix([1.0], [[math.radians(89.5), 0.6, 0.0]], sigma=[2.0] * 3),
            "^lla: row 0: latitude must be within ±89°",
        ),
        (
            lambda: pronet.Fix([1.0, 2.0], [[0.5, 0.6, 0.0], [0.5, 7.0, 0.0]], sigma=[2.0] * 3),
            r"^lla: row 1: longitude 7 rad must be within \[−π, 2π\]",
        ),
        (
            lambda: pronet.Fix([1.0], [[0.5, -3.5, 0.0]], sigma=[2.0] * 3),
            r"^lla: row 0: longitude -3.5 rad must be within \[−π, 2π\]",
        ),
        (
            lambda: pronet.Fix([1.0], [[0.5, np.inf, 0.0]], sigma=[2.0] * 3),
            "^lla: row 0 must hold a finite latitude",
        ),
        (
            lambda: pronet.Fix([2.0, 1.0], [[0.5, 0.6, 0.0]], sigma=[2.0] * 3),
            "^time: has 2 rows",
        ),
    ],
)
def test_bad_aiding_is_refused_by_name(stream, message) -> None:
    traj = pronet.builtin_trajectory("paper")
    kw = dict(t0=0.0, lla0=traj.lla[0], vel0=traj.vel_ned[0], rpy0=traj.rpy[0],
              strategy=pronet.Strategy.constant(Q))  # fmt: skip
    if message is None:  # a horizontal fix: its vertical σ is not read
        out = pronet.run_filter(traj.imu[:300], traj.time[1:301], [stream()], **kw)  # type: ignore[arg-type]
        assert out.fix_epoch.tolist() == [100] and np.isfinite(out.fix_nis[0])
        return
    with pytest.raises(ValueError, match=message):
        stream()
