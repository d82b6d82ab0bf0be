"""The aiding sensors as streams (``pronet.Dvl``, ``Depth``, ``Fix``) in one filter pass:
what each stream's result holds, two velocity streams at once, a σ given per row or
once, a stream's own σ, frame, lever arm and gate against the ``FilterConfig``'s, the
lever arms of a depth sensor and of a fix's antenna, and the deprecated arrays form.
(Hostile arguments: ``tests/hostile/test_filter.py``.)"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_position_aiding import _aiding, _streams

import pronet
from pronet.recorded.alignment import dcm_from_euler

from test_numpy_reference_ekf import P0, Q, _inputs

SECONDS = 60.0
ARM = (0.5, -0.2, 1.0)


def _pass(streams, config=None, **kw) -> pronet.FilterResult:
    """The reference tests' 60 s along the paper's trajectory with ``streams``."""
    imu, imu_time, _, _, lla0, vel0, rpy0 = _inputs(SECONDS, np.array(ARM), "body")
    config = config or pronet.FilterConfig(p0_sigma=P0, accel_bias_psd=1e-6, gyro_bias_psd=1e-8)
    return pronet.run_filter(
        imu, imu_time, streams, t0=0.0, lla0=lla0, vel0=vel0, rpy0=rpy0, config=config,
        strategy=pronet.Strategy.constant(Q), **kw,
    )  # fmt: skip


def _dvl(**kw) -> pronet.Dvl:
    """The reference tests' 1 Hz body-frame DVL (0.1 m/s noise) at ``ARM``."""
    _, _, dvl, dvl_time, *_ = _inputs(SECONDS, np.array(ARM), "body")
    return pronet.Dvl(dvl_time, dvl, **kw)


def _equal(a: pronet.FilterResult, b: pronet.FilterResult) -> None:
    """Every array of the two results equal, bit for bit (NaN where NaN)."""
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if f.name == "streams":
            assert len(x) == len(y)
            for s, t in zip(x, y, strict=True):
                for g in dataclasses.fields(s):
                    np.testing.assert_array_equal(getattr(s, g.name), getattr(t, g.name))
        elif f.name == "health":
            assert x.flags == y.flags, (x.flags, y.flags)
            for s, t in zip(x.streams, y.streams, strict=True):
                np.testing.assert_array_equal(s.nis, t.nis)
        elif f.name == "smoothed":
            assert (x is None) == (y is None)
            if x is not None:
                for g in dataclasses.fields(x):
                    np.testing.assert_array_equal(getattr(x, g.name), getattr(y, g.name))
        else:
            np.testing.assert_array_equal(x, y, err_msg=f.name)


def test_each_stream_has_its_rows_and_the_first_of_a_kind_the_top_level_keys() -> None:
    aiding = _streams(
        _aiding(pronet.builtin_trajectory("paper"), SECONDS, np.random.default_rng(3))
    )
    dvl = _dvl(lever_arm=ARM)
    # a second velocity stream: every other row of the first again, at the same epochs
    second = pronet.Dvl(dvl.time[::2], dvl.velocity[::2], sigma=0.2, lever_arm=ARM)
    out = _pass([dvl, *aiding, second])
    assert [s.kind for s in out.streams] == ["velocity", "depth", "fix", "velocity"]
    for s, given in zip(out.streams, [dvl, *aiding, second], strict=True):
        r = len(given.time)
        assert s.epoch.shape == s.nis.shape == (r,) and s.epoch.dtype == np.int64
        inside = s.epoch >= 0
        assert np.isfinite(s.nis[inside]).all() and np.isnan(s.nis[~inside]).all()
        if s.kind == "velocity":
            assert s.innovation is not None and s.innovation.shape == (r, 3)
            assert s.innovation_cov is not None and s.innovation_cov.shape == (r, 3, 3)
            assert s.gain is not None and s.gain.shape == (r, 15, 3)
            assert s.accepted is not None and s.accepted.dtype == np.bool_
            assert s.adaptive_q is not None and s.adaptive_q.shape == (r, 15, 15)
        else:
            assert s.innovation is s.gain is s.accepted is s.adaptive_q is None
    first, depth, fix, _ = out.streams
    assert out.nis is first.nis and out.dvl_epoch is first.epoch and out.gain is first.gain
    assert out.depth_nis is depth.nis and out.fix_epoch is fix.epoch
    # The second velocity stream was applied too, after the first at the same epochs.
    np.testing.assert_array_equal(out.streams[3].epoch, first.epoch[::2])
    assert np.isfinite(out.streams[3].nis).all()
    # Without streams: no rows anywhere, a pure inertial pass.
    free = _pass([])
    assert free.streams == () and free.nis.shape == (0,) and free.gain.shape == (0, 15, 3)
    assert free.depth_epoch.shape == free.fix_nis.shape == (0,)


def test_two_velocity_streams_of_alternate_rows_are_the_one_stream() -> None:
    """A DVL split into two streams (even and odd rows, never at one epoch) is the same
    pass bit for bit; a body-frame DVL and a NED velocity in one pass both aid it."""
    dvl = _dvl(lever_arm=ARM)
    t, v = dvl.time, dvl.velocity
    one = _pass([dvl])
    split = _pass(
        [pronet.Dvl(t[::2], v[::2], lever_arm=ARM), pronet.Dvl(t[1::2], v[1::2], lever_arm=ARM)]
    )
    np.testing.assert_array_equal(split.vel, one.vel)
    np.testing.assert_array_equal(split.sigma, one.sigma)
    np.testing.assert_array_equal(split.streams[1].nis, one.nis[1::2])
    # A NED velocity (the truth plus 0.1 m/s) beside the DVL: both update, consistently.
    traj = pronet.builtin_trajectory("paper")
    k = np.arange(50, int(SECONDS * 100), 100)
    rng = np.random.default_rng(9)
    ned = pronet.Dvl(
        traj.time[k], traj.vel_ned[k] + rng.normal(size=(len(k), 3)) * 0.1, frame="ned"
    )
    both = _pass([dvl, ned])
    assert (both.streams[1].epoch == k).all() and both.streams[1].accepted.all()  # type: ignore[union-attr]
    for s in both.streams:
        assert 1.0 < np.mean(s.nis) < 6.0  # χ² of 3 dof, both told their noise
    assert (both.sigma[-1, 3:6] < one.sigma[-1, 3:6]).all()  # twice the velocity updates


def test_a_sigma_per_row_equals_the_same_sigma_given_once() -> None:
    dvl = _dvl(lever_arm=ARM)
    m = len(dvl.time)
    once = _pass([_dvl(sigma=[0.1, 0.2, 0.3], lever_arm=ARM)])
    rows = _pass([_dvl(sigma=np.tile([0.1, 0.2, 0.3], (m, 1)), lever_arm=ARM)])
    _equal(rows, once)
    aiding = _aiding(pronet.builtin_trajectory("paper"), SECONDS, np.random.default_rng(3))
    d, f = len(aiding["depth"]), len(aiding["fix"])
    depth_once = pronet.Depth(aiding["depth_time"], aiding["depth"], sigma=0.1)
    depth_rows = pronet.Depth(aiding["depth_time"], aiding["depth"], sigma=np.full(d, 0.1))
    fix_once = pronet.Fix(aiding["fix_time"], aiding["fix"], sigma=[2.0, 2.0, 2.0])
    fix_rows = pronet.Fix(aiding["fix_time"], aiding["fix"], sigma=np.full((f, 3), 2.0))
    _equal(_pass([dvl, depth_rows, fix_rows]), _pass([dvl, depth_once, fix_once]))


def test_a_streams_own_sigma_frame_lever_arm_and_gate_are_the_configs_to_the_bit() -> None:
    """``Dvl(sigma=s)`` is ``FilterConfig(dvl_variance=s²)``; its frame, lever arm and
    gate are the config's ``aiding``, ``lever_arm``, ``innovation_gate``; with none
    given a stream takes the config's."""
    s, gate = np.array([0.05, 0.08, 0.12]), 7.8
    tuning = dict(p0_sigma=P0, accel_bias_psd=1e-6, gyro_bias_psd=1e-8)
    told = pronet.FilterConfig(**tuning, dvl_variance=s * s, lever_arm=ARM, innovation_gate=gate)  # type: ignore[arg-type]
    by_config = _pass([_dvl()], told)
    by_stream = _pass([_dvl(sigma=s, lever_arm=ARM, gate=gate, frame="body")])
    _equal(by_stream, by_config)
    assert not by_config.accepted.all()  # the gate acted
    ned = pronet.FilterConfig(**tuning, aiding="nav")  # type: ignore[arg-type]
    _equal(_pass([_dvl(frame="ned")]), _pass([_dvl()], ned))
    # A stream's own values win over the config's.
    _equal(_pass([_dvl(sigma=s, lever_arm=ARM, gate=gate, frame="body")], ned), by_config)


def _truth_at(k: np.ndarray, arm: tuple[float, float, float]) -> np.ndarray:
    """The position ``[lat, lon, h]`` of a point at ``arm`` [m, body FRD] from the IMU
    along the paper's trajectory at epochs ``k``."""
    traj = pronet.builtin_trajectory("paper")
    offset = dcm_from_euler(traj.rpy[k]) @ np.asarray(arm)  # NED [m]
    return np.array([pronet.lla_from_ned(o, p) for o, p in zip(offset, traj.lla[k], strict=True)])


@pytest.mark.parametrize("kind", ["depth", "fix"])
def test_a_sensors_lever_arm_is_where_it_reads(kind) -> None:
    """A depth sensor 2 m below and 3 m ahead of the IMU, or a fix's antenna 4 m ahead
    and 1.5 m above it: with the arm told, the filter puts the IMU where it is (and its
    NIS is χ² of 1 or 3 dof); without, it puts the IMU where the sensor is."""
    traj = pronet.builtin_trajectory("paper")
    k = np.arange(100, int(SECONDS * 100) + 1, 100 if kind == "depth" else 500)
    arm = (3.0, 0.0, 2.0) if kind == "depth" else (4.0, 0.0, -1.5)
    rng = np.random.default_rng(11)
    at = _truth_at(k, arm)
    depth = -at[:, 2] + rng.normal(size=len(k)) * 0.05

    def stream(lever_arm):
        if kind == "depth":
            return pronet.Depth(traj.time[k], depth, sigma=0.05, lever_arm=lever_arm)
        return pronet.Fix(traj.time[k], at, sigma=[0.3, 0.3, 0.3], lever_arm=lever_arm)

    dvl = _dvl(lever_arm=ARM)
    told, untold = _pass([dvl, stream(arm)]), _pass([dvl, stream((0.0, 0.0, 0.0))])
    n = len(told.time)
    origin = traj.lla[0]
    truth = pronet.local_ned(traj.lla[:n], origin)
    error = pronet.local_ned(told.lla, origin)[-1] - truth[-1]  # NED [m]
    untold_error = pronet.local_ned(untold.lla, origin)[-1] - truth[-1]
    if kind == "depth":
        assert abs(error[2]) < 0.3 and 1.5 < untold_error[2] < 2.5, (error, untold_error)
        assert np.mean(told.streams[1].nis) < 3.0
    else:
        assert np.abs(error).max() < 1.0 and np.hypot(*untold_error[:2]) > 3.0
        assert -2.0 < untold_error[2] < -1.0, (error, untold_error)
        assert np.mean(told.streams[1].nis) < 9.0


def test_the_deprecated_arrays_form_warns_once_and_is_the_streams_form() -> None:
    """``run_filter(imu, imu_time, dvl, dvl_time, depth=..., fix=...)``: one
    DeprecationWarning naming the streams form, then the same pass bit for bit; streams
    and the old arrays together are refused."""
    imu, imu_time, dvl, dvl_time, lla0, vel0, rpy0 = _inputs(SECONDS, np.array(ARM), "body")
    aiding = _aiding(pronet.builtin_trajectory("paper"), SECONDS, np.random.default_rng(3))
    kw = dict(t0=0.0, lla0=lla0, vel0=vel0, rpy0=rpy0, strategy=pronet.Strategy.mehra(3, Q),
              config=pronet.FilterConfig(p0_sigma=P0, lever_arm=ARM), smooth=True,
              warn=False)  # fmt: skip
    streams = [pronet.Dvl(dvl_time, dvl), *_streams(aiding)]
    new = pronet.run_filter(imu, imu_time, streams, **kw)  # type: ignore[arg-type]
    with pytest.warns(DeprecationWarning, match=r"deprecated: pass the sensors as streams") as w:
        old = pronet.run_filter(imu, imu_time, dvl, dvl_time, **kw, **aiding)  # type: ignore[call-overload]
    assert len(w) == 1 and w[0].filename == __file__
    _equal(old, new)
    assert len(new.depth_nis) and len(new.fix_nis) and np.isfinite(new.adaptive_q).any()
    with pytest.raises(ValueError, match="^streams: give the sensors as streams or as"):
        pronet.run_filter(imu, imu_time, streams, **kw, depth=aiding["depth"])  # type: ignore[call-overload]


def test_streams_show_what_they_hold() -> None:
    dvl = pronet.Dvl([1.0, 2.0], [[1.0, 0, 0]] * 2, sigma=0.1, frame="ned", gate=9.0)
    assert repr(dvl) == (
        'Dvl(2 rows over [1, 2] s, sigma=[0.1, 0.1, 0.1], frame="ned", lever_arm=None, gate=9.0)'
    )
    assert dvl.frame == "ned" and dvl.gate == 9.0 and dvl.lever_arm is None
    np.testing.assert_array_equal(dvl.sigma, [0.1] * 3)  # type: ignore[arg-type]
    np.testing.assert_array_equal(dvl.velocity, [[1.0, 0, 0]] * 2)
    plain = pronet.Dvl([], np.empty((0, 3)))
    assert plain.sigma is plain.frame is plain.gate is None and repr(plain).startswith("Dvl(0 rows")
    depth = pronet.Depth([5.0], [10.0], sigma=[0.2], lever_arm=(0, 0, 1))
    assert repr(depth) == "Depth(1 row at 5 s, sigma=(1) per row, lever_arm=[0.0, 0.0, 1.0])"
    assert depth.lever_arm == [0.0, 0.0, 1.0] and depth.sigma.tolist() == [0.2]  # type: ignore[union-attr]
    fix = pronet.Fix([1.0, 2.0], [[0.5, 0.6, np.nan]] * 2, sigma=np.full((2, 3), 2.0))
    assert repr(fix) == "Fix(2 rows over [1, 2] s, sigma=(2, 3) per row, lever_arm=[0.0, 0.0, 0.0])"
    assert np.isnan(fix.lla[:, 2]).all() and fix.sigma.shape == (2, 3)
    heading = pronet.Heading([1.0, 2.0, 3.0], [0.1, -3.1, 6.2], sigma=0.01)
    assert repr(heading) == "Heading(3 rows over [1, 3] s, sigma=0.01)"
    assert heading.sigma == 0.01 and heading.heading.tolist() == [0.1, -3.1, 6.2]


def test_a_heading_stream_is_applied_in_turn_and_has_no_top_level_keys() -> None:
    """A compass (truth + 2 mrad, 5 Hz) beside the DVL: its result is the stream's
    (kind ``"heading"``, one NIS per row, χ² of 1 dof), the top-level keys are the
    DVL's as without it, and the heading's σ ends far below the DVL-only pass's."""
    traj = pronet.builtin_trajectory("paper")
    k = np.arange(20, int(SECONDS * 100) + 1, 20)
    rng = np.random.default_rng(5)
    compass = pronet.Heading(traj.time[k], traj.rpy[k, 2] + rng.normal(size=len(k)) * 2e-3,
                             sigma=2e-3)  # fmt: skip
    dvl = _dvl(lever_arm=ARM)
    alone, aided = _pass([dvl]), _pass([dvl, compass])
    assert [s.kind for s in aided.streams] == ["velocity", "heading"]
    h = aided.streams[1]
    np.testing.assert_array_equal(h.epoch, k)
    assert h.innovation is h.gain is h.accepted is h.adaptive_q is None
    assert 0.5 < np.mean(h.nis) < 1.6  # χ² of 1 dof over 300 rows
    assert aided.nis is aided.streams[0].nis and aided.depth_nis.shape == (0,)
    assert aided.sigma[-1, 8] < 0.2 * alone.sigma[-1, 8]
    # The order given is the order at an epoch: with the heading first, another pass,
    # apart only by where each update is linearized (≪ the compass's 2 mrad).
    first = _pass([compass, dvl])
    assert not np.array_equal(first.rpy, aided.rpy)
    np.testing.assert_allclose(first.rpy, aided.rpy, atol=1e-4)
