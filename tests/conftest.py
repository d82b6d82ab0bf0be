"""Shared fixtures: trajectories are built once per session."""

from __future__ import annotations

import os

import pytest
from hypothesis import settings

import pronet

# The same examples on every run (CI never flakes on a newly drawn case); set
# HYPOTHESIS_PROFILE=explore to draw new ones when hunting for bugs.
settings.register_profile("ci", derandomize=True)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

#: True IMU noise of the paper's scenario (per-sample variances).
PAPER_Q = (1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6)


@pytest.fixture(scope="session")
def paper_trajectory() -> pronet.Trajectory:
    return pronet.builtin_trajectory("paper")


@pytest.fixture(scope="session")
def default_dataset():
    """The default dataset (seed 0), the one the shipped models were trained on."""
    from pronet.learn.dataset import DatasetParams, build_dataset

    return build_dataset(DatasetParams())
