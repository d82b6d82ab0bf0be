"""A pass's solution as a :class:`~pronet.recorded.solution.Solution` of the vehicle's
reference point (:func:`~pronet.recorded.solution.solution_of`), and the point at a lever
arm (:func:`~pronet.recorded.alignment.moved_point`): where a point 1 m ahead of a vehicle
heading east lies, and how fast it moves while the vehicle turns."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest

import pronet
from pronet.recorded.alignment import moved_point
from pronet.recorded.solution import Solution, solution_of

LLA = np.array([[math.radians(32.0), math.radians(34.0), -10.0]])


def test_a_point_ahead_of_a_vehicle_heading_east_is_east_of_it() -> None:
    rpy = np.array([[0.0, 0.0, math.pi / 2]])
    gyro = np.array([[0.0, 0.0, 0.1]])  # turning right at 0.1 rad/s
    lla, vel = moved_point(LLA, np.zeros((1, 3)), rpy, (1.0, 0.0, 0.5), gyro)
    ned = pronet.local_ned(lla[0], LLA[0])
    np.testing.assert_allclose(ned, [0.0, 1.0, 0.5], atol=1e-6)
    # ω × r = (0, 0.1, 0) in the body (to the right), i.e. south when heading east
    np.testing.assert_allclose(vel[0], [-0.1, 0.0, 0.0], atol=1e-12)
    same, still = moved_point(LLA, np.ones((1, 3)), rpy, (0.0, 0.0, 0.0), gyro)
    assert np.array_equal(same, LLA) and np.array_equal(still, np.ones((1, 3)))


def test_a_solution_is_the_pass_moved_to_the_reference_point() -> None:
    n = 4
    est = SimpleNamespace(
        time=np.arange(n) * 0.1,
        lla=np.repeat(LLA, n, axis=0),
        vel=np.zeros((n, 3)),
        rpy=np.zeros((n, 3)),
        bias=np.zeros((n, 6)),
        sigma=np.full((n, 15), 0.5),
    )
    imu = np.zeros((n - 1, 6))
    imu[:, 5] = 0.2  # yaw rate in every sample
    s = solution_of("forward", est, 1.7e9, imu, reference_arm=(-2.0, 0.0, 0.0))
    assert s.label == "forward" and s.epoch == 1.7e9 and s.sigma.shape == (n, 15)
    ned = pronet.local_ned(s.lla, LLA[0])
    np.testing.assert_allclose(ned[:, 0], -2.0, atol=1e-6)  # 2 m behind, heading north
    np.testing.assert_allclose(s.vel[:, 1], -0.4, atol=1e-12)  # the tail swings west
    with pytest.raises(ValueError, match=r"^Solution.sigma: expected shape \(4, 15\)"):
        Solution("forward", s.time, 0.0, s.lla, s.vel, s.rpy, s.sigma[:, :9])
