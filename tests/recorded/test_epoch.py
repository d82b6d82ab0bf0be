"""Clocks on any epoch: the clock estimates and every result are
invariant to a constant added to every stamp (Unix time, +1.7e9 s)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pronet.recorded import real
from pronet.recorded.alignment import align, estimate_alignment, since_epoch
from pronet.recorded.recordings import Recording
from pronet.recorded.tuning import real_filter_config

from synthetic_recording import (
    DVL_CLOCK,
    DVL_LEVER_ARM,
    GT_CLOCK,
    IMU_LEVER_ARM,
    synthetic_recording,
)

UNIX = 1.7e9


def _shifted(rec: Recording, c: float) -> Recording:
    return replace(
        rec,
        imu_time=rec.imu_time + c,
        dvl_time=rec.dvl_time + c,
        gt_time=rec.gt_time + c,
        dvl_skipped_time=rec.dvl_skipped_time + c,
    )


@pytest.fixture(scope="module")
def pair() -> tuple[Recording, Recording]:
    """The same section stamped in Unix time and relative to a start: the relative
    stamps are the Unix ones less 1.7e9 (exact), so both hold the same instants."""
    unix = _shifted(synthetic_recording(seed=2, duration=90.0).recording, UNIX)
    return _shifted(unix, -UNIX), unix


def test_unix_time_stamps_give_the_relative_clocks(pair):
    relative, unix = pair
    a = estimate_alignment(relative, IMU_LEVER_ARM, DVL_LEVER_ARM)
    b = estimate_alignment(unix, IMU_LEVER_ARM, DVL_LEVER_ARM)
    for clock in ("gt_clock", "dvl_clock"):
        x, y = getattr(a, clock), getattr(b, clock)
        assert abs(x.offset - y.offset) <= 1e-9 and abs(x.scale - y.scale) <= 1e-9
    # and they are the true clocks, moved to the section's start (first IMU stamp)
    t0 = relative.imu_time[0]
    for est, true in ((a.gt_clock, GT_CLOCK), (a.dvl_clock, DVL_CLOCK)):
        assert est.scale == pytest.approx(true.scale, abs=2e-4)
        assert est.offset == pytest.approx(true.since(t0).offset, abs=0.02)
        assert true.since(t0)(relative.gt_time - t0) == pytest.approx(true(relative.gt_time) - t0)


def test_unix_time_stamps_give_the_relative_results(pair):
    relative, unix = pair
    one, two = (align(r, estimate_alignment(r, IMU_LEVER_ARM, DVL_LEVER_ARM)) for r in pair)
    assert two.epoch == unix.imu_time[0] and one.epoch == relative.imu_time[0]
    np.testing.assert_allclose(one.truth_time, two.truth_time, rtol=0, atol=1e-9)
    np.testing.assert_allclose(one.dvl_time, two.dvl_time, rtol=0, atol=1e-9)
    config = real_filter_config(one.alignment.filter_lever_arm)
    q = (1e-4,) * 3 + (1e-8,) * 3
    from pronet import _core

    runs = [real.run_section(s, _core.Strategy.constant(q), config) for s in (one, two)]
    for key in ("srmse", "smae", "final_horizontal", "max_horizontal", "mean_nis"):
        x, y = (getattr(r.metrics, key) for r in runs)
        assert abs(x - y) <= 1e-9 * max(1.0, abs(x)), key


def test_stamps_from_zero_are_kept_as_they_are(pair):
    relative, _ = pair
    from_zero = _shifted(relative, -float(relative.imu_time[0]))
    same, epoch = since_epoch(from_zero)
    assert same is from_zero and epoch == 0.0
