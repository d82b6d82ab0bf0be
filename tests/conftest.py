"""Shared fixtures: trajectories are built once per session."""

from __future__ import annotations

import os
from pathlib import Path

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


#: The test files that take longest (``pytest --durations``, two workers), longest first.
#: They are collected before the rest, so that with one file per worker (CI's
#: ``--dist loadfile --no-loadscope-reorder``: files in the collection's order) they
#: start at once and the short files fill in around them, instead of one worker running
#: them alone at the end (xdist's default order, most tests first, puts them last).
LONGEST_FIRST = (
    "test_accuracy_gate.py",
    "test_gate_mutants.py",
    "learn/test_torchfilter.py",
    "test_bench_run.py",
    "recorded/test_navigate.py",
    "test_numpy_reference_smoother.py",
    "cli/test_cli.py",
    "experiments/test_study.py",
    "test_compare_builds.py",
    "learn/test_recorded_training.py",
)
TESTS = Path(__file__).resolve().parent


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Put the files of :data:`LONGEST_FIRST` first, in its order; the rest keep theirs."""
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}

    def key(item: pytest.Item) -> int:
        try:
            name = item.path.resolve().relative_to(TESTS).as_posix()
        except ValueError:  # collected from outside tests/
            return len(rank)
        return rank.get(name, len(rank))

    items.sort(key=key)  # stable: the order within a file, and of the rest, is kept
