"""Shared fixtures: trajectories are built once per session."""

from __future__ import annotations

import pytest

import pronet

#: True IMU noise of the paper's scenario (per-sample variances).
PAPER_Q = (1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6)


@pytest.fixture(scope="session")
def paper_trajectory() -> pronet.Trajectory:
    return pronet.builtin_trajectory("paper")
