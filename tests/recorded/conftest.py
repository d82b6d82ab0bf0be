"""Fixtures of the recorded-data tests."""

from __future__ import annotations

import pytest

from synthetic_recording import synthetic_recording


@pytest.fixture(scope="module")
def synthetic():
    """A synthetic recording with its known clocks and lever arms (seed 0)."""
    return synthetic_recording(seed=0)
