"""The initial state from the data alone (pronet.recorded.initial): levelling, heading
by gyrocompassing and from a stream, position and depth moved by their lever arms, the
given parts, the refusals, and the honesty of the 1σ each method earns (error within
3σ at >= 95 % over seeds, and the σ not inflated either).

The IMU at rest is built by hand from the model the filter uses: ``f = −Cᵀ g^n`` and
``ω = Cᵀ ω_ie^n`` with WGS-84 normal gravity, then biases and white noise added.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import pronet
from pronet.recorded.initial import GivenState, InitialSettings, initial_state
from pronet.recorded.levelling import StillSettings, psi_sigma, still_intervals

OMEGA = 7.292115e-5
LLA = np.array([math.radians(32.0), math.radians(34.0), -5.0])
#: The vehicle tunings' P0: position, velocity and attitude (unused here), then the
#: accelerometer and gyro bias 1σ of a FOG-grade and a MEMS IMU.
FOG_P0 = np.array([0.1] * 3 + [0.02] * 3 + [2e-4, 2e-4, 1e-3] + [5e-4] * 3 + [1e-7] * 3)
MEMS_P0 = np.array([0.1] * 3 + [0.02] * 3 + [2e-4, 2e-4, 1e-3] + [9.8e-3] * 3 + [1.7e-3] * 3)
#: Per-sample white noise at 100 Hz: accelerometer [m/s²] and gyro [rad/s].
FOG_NOISE = (4.9e-3, 1.5e-5)
MEMS_NOISE = (2e-2, 3e-3)


def rotation(rpy: np.ndarray) -> np.ndarray:
    """Body-to-NED DCM, ``Rz(yaw) Ry(pitch) Rx(roll)``, written out independently."""
    r, p, y = rpy
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def still_imu(rpy, p0, noise, rng, seconds=60.0, rate=100.0, lla=LLA):
    """A still IMU at ``rpy`` with biases drawn from ``p0``'s bias 1σ and white noise."""
    n = int(seconds * rate)
    c = rotation(np.asarray(rpy))
    g = pronet.normal_gravity(lla[0], lla[2])
    f = -c.T @ np.array([0.0, 0.0, g])
    w = c.T @ np.array([OMEGA * math.cos(lla[0]), 0.0, -OMEGA * math.sin(lla[0])])
    imu = np.empty((n, 6))
    imu[:, :3] = f + rng.normal(0.0, p0[9:12]) + rng.normal(0.0, noise[0], (n, 3))
    imu[:, 3:] = w + rng.normal(0.0, p0[12:15]) + rng.normal(0.0, noise[1], (n, 3))
    return np.arange(n) / rate, imu


def attitude_error(rpy_hat, rpy):
    """ψ (about N, E, D) of ``Ĉ = (I − [ψ×]) C``."""
    m = np.eye(3) - rotation(np.asarray(rpy_hat)) @ rotation(np.asarray(rpy)).T
    m = 0.5 * (m - m.T)
    return np.array([m[2, 1], m[0, 2], m[1, 0]])


def random_attitude(rng):
    return np.array(
        [rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-math.pi, math.pi)]
    )


def honest(z: np.ndarray) -> None:
    """Normalised errors ``z``: within 3 at >= 95 %, and their RMS within [0.6, 1.5] (the
    σ neither overconfident nor inflated)."""
    z = np.abs(np.ravel(z))
    assert np.mean(z <= 3.0) >= 0.95, f"within 3σ at {np.mean(z <= 3.0):.1%}"
    rms = float(np.sqrt(np.mean(z**2)))
    assert 0.6 <= rms <= 1.5, f"RMS of error/σ {rms:.2f}"


def fixes_of(rng, lla_imu, c, arm, sigma, times):
    """Fixes of an antenna at ``arm`` [m, body FRD] from the IMU, σ N, E, D [m]."""
    ned = c @ np.asarray(arm) + rng.normal(0.0, sigma, (len(times), 3))
    lla = pronet.lla_from_ned(ned, lla_imu)
    return np.asarray(times, dtype=float), lla, np.asarray(sigma, dtype=float)


def test_levelling_is_within_its_sigma_over_seeds():
    z = []
    for seed in range(120):
        rng = np.random.default_rng(seed)
        rpy = random_attitude(rng)
        t, imu = still_imu(rpy, MEMS_P0, MEMS_NOISE, rng, seconds=20.0)
        state = initial_state(
            t,
            imu,
            MEMS_P0,
            given=GivenState(lla=LLA, heading=rpy[2], heading_sigma=1e-6),
        )
        assert state.methods["attitude"].startswith("levelled over 20.0 s still")
        psi = attitude_error(state.rpy, rpy)
        z.append(psi[:2] / state.p0_sigma[6:8])
    honest(np.array(z))


def test_gyrocompassing_a_fog_gyro_is_within_its_sigma():
    z, sigma = [], []
    for seed in range(100):
        rng = np.random.default_rng(1000 + seed)
        rpy = random_attitude(rng)
        t, imu = still_imu(rpy, FOG_P0, FOG_NOISE, rng, seconds=120.0)
        fixes = fixes_of(rng, LLA, rotation(rpy), [0.0, 0.0, 0.0], [1.5, 1.5, 3.0], [1.0, 2.0])
        state = initial_state(t, imu, FOG_P0, fixes=fixes)
        assert state.methods["heading"].startswith("gyrocompassed over 120.0 s still")
        psi = attitude_error(state.rpy, rpy)
        z.append(psi / state.p0_sigma[6:9])
        sigma.append(state.p0_sigma[8])
    z = np.array(z)
    honest(z[:, 2])
    honest(z[:, :2])
    # the heading is worth having: well below a degree at 32° N with a 1e-7 rad/s bias
    assert np.degrees(np.max(sigma)) < 0.5


def test_gyrocompassing_a_mems_gyro_is_refused_in_one_line():
    rng = np.random.default_rng(3)
    rpy = np.array([0.02, -0.01, 1.0])
    t, imu = still_imu(rpy, MEMS_P0, MEMS_NOISE, rng, seconds=30.0)
    fixes = fixes_of(rng, LLA, rotation(rpy), [0.0, 0.0, 0.0], [1.5, 1.5, 3.0], [1.0])
    with pytest.raises(ValueError) as err:
        initial_state(t, imu, MEMS_P0, fixes=fixes)
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith("initial heading: no heading stream, no AHRS orientation")
    assert "cannot gyrocompass at 32.0° N" in message and "bias σ 1.7e-03 rad/s" in message
    assert message.endswith("give one of them")


def test_heading_from_a_stream_is_its_wrapped_mean_with_its_sigma():
    rng = np.random.default_rng(4)
    rpy = np.array([0.05, 0.1, math.pi - 0.01])  # readings straddle ±π
    t, imu = still_imu(rpy, MEMS_P0, MEMS_NOISE, rng, seconds=30.0)
    times = np.arange(0.0, 30.0, 0.1)
    sigma = math.radians(1.0)
    readings = np.angle(np.exp(1j * (rpy[2] + rng.normal(0.0, sigma, len(times)))))
    state = initial_state(
        t, imu, MEMS_P0, heading=(times, readings, sigma), given=GivenState(lla=LLA)
    )
    assert state.methods["heading"] == "heading stream (10 readings, wrapped mean)"
    error = math.remainder(state.rpy[2] - rpy[2], 2 * math.pi)
    assert abs(error) < 3 * sigma / math.sqrt(10) + 1e-3
    # the stream's σ, not divided by the readings' count (the roll's adds little level)
    assert sigma <= state.p0_sigma[8] <= 1.001 * sigma
    # one reading in the window (a compass thinned to 1 Hz, as pronet navigate feeds it):
    # it said "heading stream (1 readings, wrapped mean)"
    once = np.arange(0.0, 30.0, 1.0)
    one = initial_state(
        t, imu, MEMS_P0, heading=(once, readings[::10], sigma), given=GivenState(lla=LLA)
    )
    assert one.methods["heading"] == "heading stream (1 reading)"


def test_position_and_depth_are_moved_from_their_sensors_to_the_imu():
    """A pitched, yawed vehicle with an antenna and a depth sensor off the IMU by 1-2 m:
    the IMU's position is recovered within 3σ; leaving the arms out is not."""
    arm_fix = np.array([1.0, -0.5, -1.5])
    arm_depth = np.array([-2.0, 0.3, 0.5])
    z, z_without = [], []
    for seed in range(100):
        rng = np.random.default_rng(2000 + seed)
        rpy = np.array([rng.uniform(-0.1, 0.1), rng.uniform(0.2, 0.35), rng.uniform(-3, 3)])
        c = rotation(rpy)
        t, imu = still_imu(rpy, MEMS_P0, MEMS_NOISE, rng, seconds=20.0)
        fixes = fixes_of(rng, LLA, c, arm_fix, [0.3, 0.3, 0.5], np.arange(1.0, 20.0))
        depth_times = np.arange(0.5, 20.0, 0.5)
        depth = -LLA[2] + (c @ arm_depth)[2] + rng.normal(0.0, 0.05, len(depth_times))
        streams = dict(fixes=fixes, depth=(depth_times, depth, 0.05))
        given = GivenState(heading=rpy[2], heading_sigma=0.01)
        state = initial_state(
            t,
            imu,
            MEMS_P0,
            **streams,
            fix_lever_arm=arm_fix,
            depth_lever_arm=arm_depth,
            given=given,
        )
        assert state.methods["position"].startswith("mean of 10 fixes while still")
        assert state.methods["position"].endswith("moved by the antenna's lever arm)")
        assert state.methods["depth"] == (
            "pressure depth (mean of 10 readings), moved by the sensor's lever arm"
        )
        error = pronet.local_ned(state.lla, LLA)
        z.append(error / state.p0_sigma[:3])
        plain = initial_state(t, imu, MEMS_P0, **streams, given=given)
        z_without.append(pronet.local_ned(plain.lla, LLA) / plain.p0_sigma[:3])
    honest(np.array(z))
    assert np.mean(np.abs(np.array(z_without)) > 3.0) > 0.5


def test_given_parts_win_with_their_sigma():
    rng = np.random.default_rng(5)
    rpy = np.array([0.02, -0.01, 1.0])
    t, imu = still_imu(rpy, FOG_P0, FOG_NOISE, rng, seconds=30.0)
    fixes = fixes_of(rng, LLA, rotation(rpy), [0.0, 0.0, 0.0], [1.5, 1.5, 3.0], [1.0, 2.0])
    given = GivenState(
        lla=[0.5, 0.6, -7.0],
        lla_sigma=[2.0, 3.0, 0.4],
        rpy=[0.1, 0.0, -2.0],
        rpy_sigma=[0.01, 0.02, 0.05],
        vel=[0.3, -0.1, 0.0],
        vel_sigma=[0.05, 0.06, 0.07],
    )
    depth = (t[:5], np.full(5, 3.0), 0.1)
    state = initial_state(t, imu, FOG_P0, fixes=fixes, depth=depth, given=given)
    assert set(state.methods.values()) == {"given"}
    np.testing.assert_array_equal(state.lla, [0.5, 0.6, -7.0])
    np.testing.assert_array_equal(state.rpy, [0.1, 0.0, -2.0])
    np.testing.assert_array_equal(state.vel, [0.3, -0.1, 0.0])
    np.testing.assert_array_equal(state.p0_sigma[:6], [2.0, 3.0, 0.4, 0.05, 0.06, 0.07])
    np.testing.assert_allclose(state.p0_sigma[6:9], psi_sigma(state.rpy, [0.01, 0.02, 0.05]))
    np.testing.assert_array_equal(state.p0_sigma[9:], FOG_P0[9:])
    # a depth alone, the rest from the data
    state = initial_state(t, imu, FOG_P0, fixes=fixes, given=GivenState(depth=4.0))
    assert state.lla[2] == -4.0 and state.p0_sigma[2] == 0.5
    assert state.methods["depth"] == "given" and state.methods["position"] != "given"


def test_still_interval_ends_where_a_steady_acceleration_starts():
    """At rest for 25 s, then a steady acceleration from a window's boundary (no window's
    spread shows it: only its mean moves), then a turn: the still interval ends at 25 s
    and the levelling is within its σ (levelling into the acceleration would tilt it by
    a/g = 0.01 rad, 10σ)."""
    tr = pronet.trajectory_from_segments(
        [[25.0, 0.0, 0.0, 0.0], [15.0, 0.1, 0.0, 0.0], [10.0, 0.0, 0.03, 0.0]],
        lla0=LLA,
        speed0=0.0,
        rpy0=[0.04, -0.05, 0.7],
        dt=0.01,
    )
    rng = np.random.default_rng(6)
    noise = rng.normal(0.0, 1.0, tr.imu.shape) * np.repeat(MEMS_NOISE, 3)
    imu = tr.imu + np.concatenate([rng.normal(0.0, MEMS_P0[9:12]), [0.0] * 3]) + noise
    time = tr.time[1:]
    found = still_intervals(time, imu, float(MEMS_P0[12]), StillSettings())
    assert found[0][0] == time[0] and 24.0 <= found[0][1] <= 25.0
    state = initial_state(time, imu, MEMS_P0, given=GivenState(lla=LLA, heading=0.7))
    assert state.t0 == pytest.approx(found[0][1])
    psi = attitude_error(state.rpy, tr.rpy[0])
    assert np.all(np.abs(psi[:2]) <= 3 * state.p0_sigma[6:8])
    # the turn alone has no still interval
    turning = time > 41.0
    assert still_intervals(time[turning], imu[turning], float(MEMS_P0[12]), StillSettings()) == []


def test_moving_start_from_an_ahrs_a_dvl_and_the_nearest_fix():
    tr = pronet.trajectory_from_segments(
        [[60.0, 0.0, 0.02, 0.0]], lla0=LLA, speed0=1.5, rpy0=[0.0, 0.05, 0.3], dt=0.01
    )
    rng = np.random.default_rng(7)
    time = tr.time[1:]
    imu = tr.imu + rng.normal(0.0, 1.0, tr.imu.shape) * np.repeat(MEMS_NOISE, 3)
    arm_dvl = np.array([0.5, 0.0, 0.8])
    k = np.arange(500, 6001, 25)  # the DVL from 5 s at 4 Hz
    body = np.einsum("kji,kj->ki", [rotation(r) for r in tr.rpy[k]], tr.vel_ned[k])
    dvl = body + np.cross(tr.imu[k - 1, 3:], arm_dvl) + rng.normal(0.0, 0.01, (len(k), 3))
    j = np.arange(0, 6001, 10)  # the AHRS at 10 Hz, σ 0.5° and 2°
    ahrs_sigma = np.radians([0.5, 0.5, 2.0])
    ahrs = tr.rpy[j] + rng.normal(0.0, ahrs_sigma, (len(j), 3))
    f = np.arange(350, 6001, 100)  # fixes at 1 Hz from 3.5 s, without noise
    fixes = (tr.time[f], tr.lla[f], [1.5, 1.5, 3.0])
    state = initial_state(
        time,
        imu,
        MEMS_P0,
        dvl=(tr.time[k], dvl, [0.01, 0.01, 0.01]),
        dvl_lever_arm=arm_dvl,
        orientation=(tr.time[j], ahrs, ahrs_sigma),
        fixes=fixes,
    )
    assert state.t0 == pytest.approx(5.0)  # the first DVL reading: the last stream to start
    assert state.methods["velocity"] == (
        "first DVL reading rotated to NED (0.00 s from t0, lever arm removed)"
    )
    assert state.methods["attitude"].startswith("AHRS orientation")
    assert state.methods["heading"].startswith("AHRS orientation")
    i0 = 500
    dv = state.vel - tr.vel_ned[i0]
    assert np.all(np.abs(dv) <= 3 * state.p0_sigma[3:6])
    # the fix 0.5 s before t0, moved by the velocity over it (0.75 m)
    assert state.methods["position"] == "fix nearest t0 (0.50 s from t0)"
    dp = pronet.local_ned(state.lla, tr.lla[i0])
    assert np.all(np.abs(dp) <= 3 * state.p0_sigma[:3])
    assert np.hypot(dp[0], dp[1]) < 0.05


def test_steady_cruise_the_dvl_contradicts_is_not_taken_as_rest():
    """A recording that starts mid-leg, straight at 1.5 m/s: the IMU alone is as steady
    as at rest (it was taken as "still": the velocity zero with σ 0.02 m/s). The DVL
    reads 1.5 m/s over the interval: it is levelled over as "steady" (roll and pitch
    within their σ), and the velocity is the DVL's (within its σ), with an AHRS or
    without. A DVL at rest leaves the interval still."""
    tr = pronet.trajectory_from_segments(
        [[60.0, 0.0, 0.0, 0.0]], lla0=LLA, speed0=1.5, rpy0=[0.0, 0.05, 0.3], dt=0.01
    )
    rng = np.random.default_rng(8)
    time = tr.time[1:]
    imu = tr.imu + rng.normal(0.0, 1.0, tr.imu.shape) * np.repeat(MEMS_NOISE, 3)
    assert still_intervals(time, imu, float(MEMS_P0[12]), StillSettings())  # steady
    k = np.arange(25, 6001, 25)
    body = np.einsum("kji,kj->ki", [rotation(r) for r in tr.rpy[k]], tr.vel_ned[k])
    dvl = (tr.time[k], body + rng.normal(0.0, 0.01, (len(k), 3)), [0.01, 0.01, 0.01])
    j = np.arange(0, 6001, 10)
    ahrs_sigma = np.radians([0.5, 0.5, 2.0])
    ahrs = (tr.time[j], tr.rpy[j] + rng.normal(0.0, ahrs_sigma, (len(j), 3)), ahrs_sigma)
    given = GivenState(lla=LLA, heading=0.3)
    for orientation in (ahrs, None):
        state = initial_state(time, imu, MEMS_P0, dvl=dvl, orientation=orientation, given=given)
        assert state.methods["velocity"] == "DVL reading nearest t0 rotated to NED (0.00 s from t0)"
        i0 = int(np.argmin(np.abs(tr.time - state.t0)))
        assert np.all(np.abs(state.vel - tr.vel_ned[i0]) <= 3 * state.p0_sigma[3:6])
        psi = attitude_error(state.rpy, tr.rpy[i0])
        assert np.all(np.abs(psi[:2]) <= 3 * state.p0_sigma[6:8])
    assert state.methods["attitude"].startswith(
        "levelled over 60.0 s steady (the DVL reads 1.5 m/s) (0.01–"
    )
    rest_time, rest_imu = still_imu([0.0, 0.05, 0.3], MEMS_P0, MEMS_NOISE, rng)
    r = np.arange(25, len(rest_time), 25)
    rest_dvl = (rest_time[r], rng.normal(0.0, 0.01, (len(r), 3)), [0.01, 0.01, 0.01])
    still = initial_state(rest_time, rest_imu, MEMS_P0, dvl=rest_dvl, given=given)
    assert still.methods["velocity"] == "zero (still)"
    assert still.methods["attitude"].startswith("levelled over 60.0 s still")


def test_an_imu_in_flu_levelled_upside_down_is_refused():
    """An IMU in FLU (y and z negated) read as FRD levels to a roll near 180°: it ran,
    roll −180° in the trajectory; refused, naming the frame. Rolled 80° it levels."""
    rng = np.random.default_rng(9)
    time, imu = still_imu([0.02, -0.03, 0.5], MEMS_P0, MEMS_NOISE, rng)
    flu = imu * np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0])
    given = GivenState(lla=LLA, heading=0.5)
    upside = r"the vehicle is upside down \(roll -?17\d\.\d°\): the IMU's z axis points up"
    with pytest.raises(ValueError, match=r"^initial roll and pitch: levelled over .*, " + upside):
        initial_state(time, flu, MEMS_P0, given=given)
    time, imu = still_imu([math.radians(80.0), 0.0, 0.5], MEMS_P0, MEMS_NOISE, rng)
    state = initial_state(time, imu, MEMS_P0, given=given)
    assert abs(state.rpy[0] - math.radians(80.0)) < 0.05


def test_the_whole_state_from_data_is_honest_over_seeds():
    """Levelling, gyrocompassing, fixes and a depth, each off the IMU: every part of the
    state within 3σ of the truth at >= 95 % of the seeds, and its σ not inflated."""
    arm_fix, arm_depth = np.array([0.4, 0.2, -1.0]), np.array([-1.0, 0.0, 0.3])
    z = []
    for seed in range(100):
        rng = np.random.default_rng(3000 + seed)
        rpy = random_attitude(rng)
        c = rotation(rpy)
        t, imu = still_imu(rpy, FOG_P0, FOG_NOISE, rng, seconds=90.0)
        fixes = fixes_of(rng, LLA, c, arm_fix, [1.5, 1.5, 3.0], np.arange(60.0, 90.0))
        depth_times = np.arange(0.0, 90.0, 1.0)
        depth = -LLA[2] + (c @ arm_depth)[2] + rng.normal(0.0, 0.1, len(depth_times))
        state = initial_state(
            t,
            imu,
            FOG_P0,
            fixes=fixes,
            depth=(depth_times, depth, 0.1),
            fix_lever_arm=arm_fix,
            depth_lever_arm=arm_depth,
        )
        error = np.concatenate(
            [pronet.local_ned(state.lla, LLA), state.vel, attitude_error(state.rpy, rpy)]
        )
        z.append(error[[0, 1, 2, 6, 7, 8]] / state.p0_sigma[[0, 1, 2, 6, 7, 8]])
        assert np.all(state.vel == 0.0) and state.methods["velocity"] == "zero (still)"
    z = np.array(z)
    for part in range(z.shape[1]):
        honest(z[:, part])


def test_psi_sigma_is_the_spread_of_psi_from_euler_errors():
    rng = np.random.default_rng(8)
    rpy = np.array([0.3, 0.6, 2.0])
    sigma = np.array([0.01, 0.02, 0.03])
    draws = rpy + rng.normal(0.0, sigma, (20000, 3))
    psi = np.array([attitude_error(d, rpy) for d in draws])
    np.testing.assert_allclose(psi.std(axis=0), psi_sigma(rpy, sigma), rtol=0.03)


def _still(seed=9, p0=MEMS_P0, noise=MEMS_NOISE):
    rng = np.random.default_rng(seed)
    rpy = np.array([0.02, -0.01, 1.0])
    t, imu = still_imu(rpy, p0, noise, rng, seconds=30.0)
    return t, imu, fixes_of(rng, LLA, rotation(rpy), [0.0, 0.0, 0.0], [1.5, 1.5, 3.0], [1.0])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (
            dict(given=GivenState(heading=1.0)),
            "initial position: no fix and no given position: give fixes or the initial position",
        ),
        (
            dict(given=GivenState(heading=1.0, lla=[0.5, 0.6, float("nan")])),
            "initial depth: no depth sensor, no fixes and no given depth or height: give a depth"
            " sensor, fixes with a height or the initial depth",
        ),
        (
            dict(still="none", given=GivenState(lla=LLA, heading=1.0)),
            "initial roll and pitch: no still interval asked for, no AHRS orientation and no"
            " given attitude: give a still interval, an AHRS orientation or the initial roll,"
            " pitch and yaw",
        ),
        (
            dict(still="none", given=GivenState(lla=LLA, rpy=[0.0, 0.0, 1.0])),
            "initial velocity: no still interval asked for at t0 = 0.00 s and no DVL: give the"
            " initial velocity or a still interval",
        ),
        (
            dict(given=GivenState(lla=LLA), heading=([0.0], [1.0], 0.02)),
            "initial heading: no heading stream reading within 1 s of t0 = 29.99 s, no AHRS"
            " orientation and no given heading; this gyro (bias σ 1.7e-03 rad/s) cannot"
            " gyrocompass at 32.0° N (σ 28 rad > 0.1 rad; it needs a bias ≪ Ω cos φ = 6.2e-05"
            " rad/s): give one of them",
        ),
    ],
)
def test_each_part_that_cannot_be_found_says_what_to_give(kwargs, message):
    t, imu, _ = _still()
    with pytest.raises(ValueError) as err:
        initial_state(t, imu, MEMS_P0, **kwargs)
    assert str(err.value) == message


def test_horizontal_fixes_take_the_depth_from_the_sensor_or_refuse():
    t, imu, fixes = _still()
    horizontal = (fixes[0], fixes[1] * [1.0, 1.0, np.nan], fixes[2])
    with pytest.raises(ValueError, match="^initial depth: no depth sensor, no fix with a height"):
        initial_state(t, imu, MEMS_P0, fixes=horizontal, given=GivenState(heading=1.0))
    state = initial_state(
        t,
        imu,
        MEMS_P0,
        fixes=horizontal,
        depth=([10.0, 20.0], [5.0, 5.2], [0.1, 0.1]),
        given=GivenState(heading=1.0),
    )
    assert state.lla[2] == pytest.approx(-5.1)
    assert state.p0_sigma[2] == pytest.approx(0.1 / math.sqrt(2))
    assert state.methods["depth"] == "pressure depth (mean of 2 readings)"


def test_a_given_attitude_says_when_no_still_interval_was_found():
    tr = pronet.trajectory_from_segments([[30.0, 0.0, 0.05, 0.0]], lla0=LLA, speed0=1.0, dt=0.01)
    rng = np.random.default_rng(10)
    imu = tr.imu + rng.normal(0.0, 1.0, tr.imu.shape) * np.repeat(MEMS_NOISE, 3)
    state = initial_state(
        tr.time[1:],
        imu,
        MEMS_P0,
        given=GivenState(lla=LLA, rpy=[0.0, 0.0, 0.0], vel=[1.0, 0.0, 0.0]),
    )
    assert state.methods["attitude"] == "given (no still interval of 5 s or more in the IMU)"
    assert state.t0 == tr.time[1]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(imu=np.zeros((3000, 5))), r"^imu: expected shape \(3000, 6\), got \(3000, 5\)$"),
        (dict(base_p0=MEMS_P0[:3]), r"^base_p0: expected shape \(15,\), got \(3,\)$"),
        (
            dict(base_p0=np.where(np.arange(15) == 4, 0.0, MEMS_P0)),
            r"^base_p0 \(a vehicle file's p0_sigma\): expected 15 positive finite 1σ, got 0 for "
            r"dv_e \(index 4\)",
        ),  # fmt: skip
        (dict(fixes=([1.0], [[0.5, 0.6, 0.0]], [1.0, 2.0])), "^fixes sigma: expected one value"),
        (dict(depth=([1.0, 0.5], [3.0, 3.0], 0.1)), "^depth time: expected finite, non-decreasing"),
        (dict(heading=([1.0], [1.0], -0.1)), "^heading sigma: expected positive finite values"),
        (dict(dvl=([1.0], [1.0, 0.0, 0.0], 0.01)), r"^dvl: expected time \(k,\) and values"),
        (dict(fix_lever_arm=[0.0, np.inf, 0.0]), "^fix_lever_arm: expected finite metres"),
        (dict(still=(5.0, 3.0)), "^still: expected t_start < t_end within the IMU's"),
        (dict(still="sometimes"), "^still: expected 'auto', 'none' or"),
        (dict(t0=99.0), r"^t0: 99.0 s is outside the IMU's 0.000–29.990 s$"),
        (
            dict(
                imu_time=np.arange(1, 21) * 0.01,
                imu=np.zeros((20, 6)),
                still="none",
                given=GivenState(heading=1.0),
                fixes=([5.0], [[0.5, 0.6, 0.0]], 1.0),
            ),
            r"^t0: the streams' first readings \(5.00 s\) come after the IMU's end \(its 20 "
            r"samples end at 0.20 s\)$",
        ),  # fmt: skip
        (dict(given=GivenState(rpy=[0, 0, 0], heading=1.0)), "^given: rpy and heading"),
        (dict(given=GivenState(lla=[0.5, 0.6, 1.0], depth=2.0)), "^given: a depth and a height"),
        (dict(given=GivenState(vel=[0, 0, 0], vel_sigma=[0.1, 0.0, 0.1])), "^given vel_sigma"),
        (dict(settings=None, still=(0.0, 0.05)), "at least 10 samples"),
        # accepted before: a heading in degrees, a longitude in degrees, a depth in Pa
        (dict(given=GivenState(heading=400.0)), r"^given heading: 400 rad is beyond ±6.28319"),
        (dict(given=GivenState(lla=[0.5, 7.0, np.nan])), "^given lla: longitude 7 is beyond"),
        (dict(given=GivenState(depth=101325.0)), "^given depth: 101325 m is beyond -10000"),
    ],
)
def test_unusable_inputs_are_refused_naming_them(kwargs, message):
    t, imu, _ = _still()
    args = dict(imu_time=t, imu=imu, base_p0=MEMS_P0) | kwargs
    with pytest.raises(ValueError, match=message):
        initial_state(**args)


def test_settings_are_checked():
    with pytest.raises(ValueError, match="^InitialSettings.reading_window: expected a positive"):
        InitialSettings(reading_window=0.0)
    with pytest.raises(ValueError, match="^InitialSettings.max_fixes: expected a positive integer"):
        InitialSettings(max_fixes=0)
    with pytest.raises(ValueError, match="^StillSettings.factor: expected a number above 1"):
        StillSettings(factor=0.5)


def _survey(seed):
    """A MEMS vehicle at rest for 60 s, then under way for 240 s, with fixes (σ 1.5 m),
    a depth (σ 5 cm), each 1 m off the IMU, and a 1° heading at 1 Hz."""
    rng = np.random.default_rng(seed)
    segments = [[60, 0, 0, 0], [10, 0.15, 0, 0], [60, 0, 0.02, 0], [60, 0, -0.03, 0]]
    segments += [[60, 0, 0, 0], [60, 0, 0.02, 0]]
    tr = pronet.trajectory_from_segments(
        segments, lla0=LLA, speed0=0.0, rpy0=[0.03, -0.02, 0.8], dt=0.01
    )
    noise = np.repeat(MEMS_NOISE, 3)
    bias = np.concatenate([rng.normal(0.0, MEMS_P0[9:12]), rng.normal(0.0, MEMS_P0[12:])])
    imu = tr.imu + bias + rng.normal(0.0, 1.0, tr.imu.shape) * noise
    arm_fix, arm_depth = np.array([1.0, 0.0, -0.5]), np.array([-0.8, 0.2, 0.4])
    k = np.arange(100, len(tr.time), 100)
    c = np.array([rotation(r) for r in tr.rpy[k]])
    ned = c @ arm_fix + rng.normal(0.0, [1.5, 1.5, 3.0], (len(k), 3))
    fix = np.array([pronet.lla_from_ned(ned[i], tr.lla[j]) for i, j in enumerate(k)])
    depth = -tr.lla[k, 2] + (c @ arm_depth)[:, 2] + rng.normal(0.0, 0.05, len(k))
    sigma_y = math.radians(1.0)
    yaw = np.angle(np.exp(1j * (tr.rpy[k, 2] + rng.normal(0.0, sigma_y, len(k)))))
    streams = dict(
        fixes=(tr.time[k], fix, [1.5, 1.5, 3.0]),
        depth=(tr.time[k], depth, 0.05),
        heading=(tr.time[k], yaw, sigma_y),
    )
    filter_streams = [
        pronet.Depth(tr.time[k], depth, sigma=0.05, lever_arm=arm_depth),
        pronet.Fix(tr.time[k], fix, sigma=[1.5, 1.5, 3.0], lever_arm=arm_fix),
        pronet.Heading(tr.time[k], yaw, sigma=sigma_y),
    ]
    arms = dict(fix_lever_arm=arm_fix, depth_lever_arm=arm_depth)
    return tr, imu, streams, filter_streams, arms, noise


@pytest.mark.parametrize("seed", [0, 1])
def test_a_pass_started_from_the_data_is_as_good_and_as_honest_as_from_the_truth(seed):
    tr, imu, streams, filter_streams, arms, noise = _survey(seed)
    time = tr.time[1:]
    state = initial_state(time, imu, MEMS_P0, **streams, **arms)
    assert state.t0 == pytest.approx(60.0, abs=1.0)
    k0 = int(np.argmin(np.abs(tr.time - state.t0)))
    truth_p0 = np.concatenate([[0.1] * 3, [0.02] * 3, [2e-4, 2e-4, 1e-3], MEMS_P0[9:]])
    starts = {
        "data": (state.lla, state.vel, state.rpy, state.p0_sigma),
        "truth": (tr.lla[k0], tr.vel_ned[k0], tr.rpy[k0], truth_p0),
    }
    rms = {}
    for label, (lla0, vel0, rpy0, p0) in starts.items():
        config = pronet.FilterConfig(
            p0_sigma=p0,
            accel_bias_psd=MEMS_P0[9] ** 2 / 400,
            gyro_bias_psd=MEMS_P0[12] ** 2 / 400,
            imu_dt=0.01,
        )
        after = time > state.t0
        result = pronet.run_filter(
            imu[after],
            time[after],
            filter_streams,
            t0=state.t0,
            lla0=lla0,
            vel0=vel0,
            rpy0=rpy0,
            config=config,
            strategy=pronet.Strategy.constant(noise**2),
        )
        rows = k0 + np.arange(len(result.time))
        dp = pronet.local_ned(result.lla, LLA) - pronet.local_ned(tr.lla[rows], LLA)
        rms[label] = float(np.sqrt(np.mean(dp[:, 0] ** 2 + dp[:, 1] ** 2)))
        if label == "data":
            every = slice(None, None, 10)
            pairs = zip(result.rpy[every], tr.rpy[rows][every], strict=True)
            psi = np.array([attitude_error(a, b) for a, b in pairs])
            sigma = result.sigma[every]
            z = np.abs(np.c_[dp[every] / sigma[:, :3], psi / sigma[:, 6:9]])
            assert np.all(np.mean(z <= 3.0, axis=0) >= 0.95), np.mean(z <= 3.0, axis=0)
    assert rms["data"] <= 1.1 * rms["truth"], rms
