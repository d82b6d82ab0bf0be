"""Issue 58, sections 6 and 8: conversion mistakes at the API and in the readers that
ran to a silently wrong answer, and the cases left from the third round.

At the API (``run_filter``, ``local_ned``) the readers' plausibility rules hold
(:mod:`pronet._util.plausibility`): gravity's sign against the initial attitude and its
magnitude, ``t0`` against the first IMU time, a depth's magnitude, angles in range;
each refusal is one line naming the argument, raised before any computation. Every
table of a pass keeps the epoch. The readers take a byte-order mark, name a one-row
ground truth and flag a jittered IMU; a stream that never falls within the run is warned
of, and a strategy spec with nothing after its colon is refused.
"""

from __future__ import annotations

import dataclasses
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

from pronet.recorded.plausible import PlausibilityWarning
from pronet.recorded.recordings import RecordingError, read_recording, write_recording
from pronet.strategies import StrategySpec

from synthetic_recording import synthetic_recording

N = 3000  # 30 s of the paper's 100 Hz IMU
FLU = np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0])  # FRD <-> FLU: y and z flip


# ------------------------------------------------------------------ section 6


# ------------------------------------------------------------------ section 8


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("rec") / "section"
    write_recording(out, synthetic_recording(seed=5, duration=30.0).recording)
    return out


def _copy(folder: Path, tmp_path: Path) -> Path:
    out = tmp_path / folder.name
    shutil.copytree(folder, out)
    return out


def test_a_byte_order_mark_before_the_header_is_read(folder, tmp_path) -> None:
    """A UTF-8 byte-order mark (Excel writes one) was reported as "missing column
    'time'" while the listed header showed it."""
    copy = _copy(folder, tmp_path)
    for name in ("imu.csv", "gt.csv"):
        path = copy / name
        path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    got, want = read_recording(copy), read_recording(folder)
    np.testing.assert_array_equal(got.imu, want.imu)
    np.testing.assert_array_equal(got.gt_lla, want.gt_lla)


def test_a_one_row_truth_file_is_named(folder, tmp_path) -> None:
    """It was "the streams do not overlap in time" from the clock search."""
    copy = _copy(folder, tmp_path)
    gt = copy / "gt.csv"
    gt.write_text("\n".join(gt.read_text().splitlines()[:2]) + "\n")
    with pytest.raises(RecordingError, match=r"gt\.csv: one data row; a ground truth needs"):
        read_recording(copy)


@pytest.mark.parametrize("text", ["constant:", "constant: ", "adaptive:", "oracle:", "detvar:"])
def test_a_spec_with_nothing_after_its_colon_is_refused(text) -> None:
    """``constant:`` ran as factor 1 under the label ``constant:``."""
    with pytest.raises(ValueError, match=rf"^strategy {text!r}: nothing after ':'"):
        StrategySpec.parse(text)


def test_a_large_imu_jitter_is_flagged_and_a_small_one_is_not(tmp_path) -> None:
    """50.5 Hz stamped ±2 ms (a logger's clock): two rows went far off and nothing was
    flagged. The 10 % jitter of ``tests/recorded/test_rates.py`` (samples the means over
    their own steps, which the filter integrates exactly) is not flagged."""
    rec = synthetic_recording(seed=5, duration=30.0, imu_rate=50.5).recording
    noise = np.random.default_rng(0).uniform(-0.002, 0.002, len(rec.imu_time))
    copy = tmp_path / "jittered"
    write_recording(copy, dataclasses.replace(rec, imu_time=rec.imu_time + noise))
    with pytest.warns(PlausibilityWarning, match=r"imu\.csv: the IMU steps jitter by 1[0-9] %"):
        read_recording(copy)
    fine = tmp_path / "fine"
    write_recording(fine, synthetic_recording(seed=5, duration=30.0, jitter=0.1).recording)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        read_recording(fine)
