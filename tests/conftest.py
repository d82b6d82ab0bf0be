"""Shared fixtures: trajectories are built once per session."""

from __future__ import annotations

import pytest

import pronet

#: True IMU noise of the paper's scenario (per-sample variances).
PAPER_Q = (1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6)


@pytest.fixture(scope="session")
def paper_trajectory() -> pronet.Trajectory:
    return pronet.builtin_trajectory("paper")


@pytest.fixture(scope="session")
def default_dataset():
    """The default dataset (seed 0), the one the shipped models were trained on."""
    from pronet.dataset import DatasetParams, build_dataset

    return build_dataset(DatasetParams())
