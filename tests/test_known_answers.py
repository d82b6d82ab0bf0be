"""Known answers of the Earth model and the ideal IMU, the stationary test, and the
round trip of every built-in trajectory, through the public Python API."""

from __future__ import annotations

import math

import numpy as np
import pytest

import pronet

OMEGA_IE = 7.292115e-5


def test_normal_gravity_matches_wgs84_at_equator_and_pole() -> None:
    assert pronet.normal_gravity(0.0) == pytest.approx(9.7803253359, abs=1e-6)
    assert pronet.normal_gravity(math.pi / 2) == pytest.approx(9.8321849378, abs=1e-6)


def _at_rest(lat_deg: float, rpy0: tuple[float, float, float]) -> pronet.Trajectory:
    return pronet.trajectory_from_segments(
        [pronet.Segment(60.0)],
        lla0=(math.radians(lat_deg), math.radians(34.0), -5.0),
        speed0=0.0,
        rpy0=rpy0,
    )


def _dcm(roll: float, pitch: float, yaw: float) -> np.ndarray:
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def test_ideal_imu_at_rest_is_earth_rate_and_minus_gravity() -> None:
    rpy = (0.03, -0.02, 1.2)
    traj = _at_rest(32.0, rpy)
    lat, h = traj.lla[0, 0], traj.lla[0, 2]
    c = _dcm(*rpy)
    w_ie_n = OMEGA_IE * np.array([math.cos(lat), 0.0, -math.sin(lat)])
    g_n = np.array([0.0, 0.0, pronet.normal_gravity(lat, h)])
    imu = traj.imu
    np.testing.assert_allclose(imu[:, :3], np.tile(-c.T @ g_n, (len(imu), 1)), atol=1e-9)
    np.testing.assert_allclose(imu[:, 3:], np.tile(c.T @ w_ie_n, (len(imu), 1)), atol=1e-15)


def test_one_hour_at_rest_mechanized_stays_put() -> None:
    traj = _at_rest(32.0, (0.0, 0.0, 0.4))
    sample = traj.imu[0]
    imu = np.tile(sample, (360_000, 1))
    nav = pronet.mechanize(imu, 0.01, traj.lla[0], (0.0, 0.0, 0.0), traj.rpy[0])
    rn, re = pronet.earth_radii(traj.lla[0, 0])
    d = nav.lla[-1] - traj.lla[0]
    drift = np.array([d[0] * rn, d[1] * re * math.cos(traj.lla[0, 0]), d[2]])
    assert np.linalg.norm(drift) < 0.01, drift
    assert np.abs(nav.vel).max() < 1e-5


@pytest.mark.parametrize("name", pronet.builtin_trajectory_names())
def test_round_trip_of_every_builtin_trajectory(name: str) -> None:
    traj = pronet.builtin_trajectory(name)
    nav = pronet.mechanize(traj.imu, traj.dt, traj.lla[0], traj.vel_ned[0], traj.rpy[0])
    rn, re = pronet.earth_radii(traj.lla[0, 0])
    d = nav.lla - traj.lla
    pos_err = np.sqrt(
        (d[:, 0] * rn) ** 2 + (d[:, 1] * re * math.cos(traj.lla[0, 0])) ** 2 + d[:, 2] ** 2
    )
    assert pos_err.max() < 0.1
    assert np.abs(nav.vel - traj.vel_ned).max() < 1e-3
    att = (nav.rpy - traj.rpy + math.pi) % (2 * math.pi) - math.pi
    assert np.abs(att).max() < 1e-5


def test_builtin_trajectories_have_the_documented_lengths(paper_trajectory) -> None:
    assert paper_trajectory.duration == pytest.approx(330.0)
    assert paper_trajectory.imu.shape == (33_000, 6)
    np.testing.assert_allclose(paper_trajectory.vel_ned[0], [1.0, 0.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(
        paper_trajectory.lla[0], [math.radians(32), math.radians(34), -5.0], atol=1e-15
    )
    for name in ("train-straight", "train-turns", "train-zigzag", "train-helix"):
        assert pronet.builtin_trajectory(name).imu.shape == (40_000, 6)


WGS84_B = 6356752.314245  # the WGS-84 semi-minor axis [m], as published


def test_local_ned_known_answers_on_the_wgs84_ellipsoid() -> None:
    a = 6378137.0
    equator = (0.0, 0.0, 0.0)
    np.testing.assert_allclose(pronet.local_ned([0.0, 0.0, 100.0], equator), [0, 0, -100])
    # A quarter turn east along the equator: a east of and a below the origin's plane.
    np.testing.assert_allclose(pronet.local_ned([0.0, math.pi / 2, 0.0], equator), [0, a, a])
    # The north pole: the semi-minor axis north, a below.
    pole = pronet.local_ned([[math.pi / 2, 0.0, 0.0]], equator)
    np.testing.assert_allclose(pole, [[WGS84_B, 0.0, a]], atol=1e-6)
    # Small offsets: the radii of curvature (the core's) times the angles.
    origin = np.array([math.radians(32.0), math.radians(34.0), -5.0])
    d = 1e-7
    ned = pronet.local_ned(origin + [d, 0.0, 0.0], origin)
    m, n = pronet.earth_radii(origin[0])
    assert ned[0] == pytest.approx(d * (m + origin[2]), rel=1e-6) and abs(ned[1]) < 1e-9
    ned = pronet.local_ned(origin + [0.0, d, 0.0], origin)
    assert ned[1] == pytest.approx(d * (n + origin[2]) * math.cos(origin[0]), rel=1e-6)


@pytest.mark.parametrize("lat_deg", [-89.0, -32.0, 0.0, 45.0, 89.0])
def test_lla_from_ned_inverts_local_ned(lat_deg: float) -> None:
    origin = np.array([math.radians(lat_deg), math.radians(-170.0), 120.0])
    ned = np.random.default_rng(3).uniform(-1e5, 1e5, size=(50, 3))
    lla = pronet.lla_from_ned(ned, origin)
    assert lla.shape == (50, 3)
    np.testing.assert_allclose(pronet.local_ned(lla, origin), ned, atol=1e-6)
    np.testing.assert_allclose(pronet.lla_from_ned(np.zeros(3), origin), origin, atol=1e-9)
    with pytest.raises(ValueError, match="^origin"):
        pronet.local_ned(lla, [3.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="^lla"):
        pronet.local_ned([[0.0, 0.0]], origin)
