"""Conversion mistakes at the API and in the readers that
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
import math
import shutil
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import pronet
from pronet import _core
from pronet.recorded.plausible import PlausibilityWarning
from pronet.recorded.recordings import RecordingError, read_recording, write_recording
from pronet.strategies import StrategySpec

from conftest import PAPER_Q
from synthetic_recording import synthetic_recording

N = 3000  # 30 s of the paper's 100 Hz IMU
FLU = np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0])  # FRD <-> FLU: y and z flip


@pytest.fixture(scope="module")
def paper():
    traj = pronet.builtin_trajectory("paper")
    dvl_t = np.arange(1.0, 30.0)
    k = np.round(dvl_t / traj.dt).astype(int)
    dvl = pronet.Dvl(dvl_t, traj.vel_ned[k], frame="ned")
    return traj, dvl


def _run(paper, imu=None, imu_time=None, streams=None, **kw):
    traj, dvl = paper
    args = dict(t0=0.0, lla0=traj.lla[0], vel0=traj.vel_ned[0], rpy0=traj.rpy[0],
                strategy=pronet.Strategy.constant(PAPER_Q))  # fmt: skip
    args.update(kw)
    return pronet.run_filter(
        traj.imu[:N] if imu is None else imu,
        traj.time[1 : N + 1] if imu_time is None else imu_time,
        [dvl] if streams is None else streams,
        **args,
    )


# ------------------------------------------------------------------ section 6


def test_an_imu_left_in_flu_is_refused_naming_imu(paper) -> None:
    """FLU's specific force points down where the initial attitude puts it up (the
    probe: it diverged at 2.45 s, 108 m at the end)."""
    traj, _ = paper
    with pytest.raises(ValueError, match=r"^imu, rpy0: .*FRD.*FLU") as err:
        _run(paper, imu=traj.imu[:N] * FLU)
    assert "\n" not in str(err.value)


def test_an_upside_down_imu_with_its_attitude_runs(paper) -> None:
    """FLU is FRD turned over about x: with the roll that says so, the data are legitimate."""
    traj, _ = paper
    rpy0 = traj.rpy[0] + [math.pi, 0.0, 0.0]
    out = _run(paper, imu=traj.imu[:N] * FLU, rpy0=rpy0, streams=[])
    assert np.isfinite(out.lla).all()


def test_accelerations_in_g_are_refused_naming_imu(paper) -> None:
    traj, _ = paper
    imu = traj.imu[:N].copy()
    imu[:, :3] /= 9.80665
    with pytest.raises(
        ValueError, match=r"^imu: the mean specific force is 0\.99\d* m/s², not near gravity"
    ):
        _run(paper, imu=imu)


def test_a_depth_in_pascals_is_refused_naming_the_stream(paper) -> None:
    """15 m of water as 150,000 Pa ran to a height of −150 km."""
    _, dvl = paper
    depth = pronet.Depth(np.arange(1.0, 30.0), np.full(29, 150_000.0), sigma=0.1)
    with pytest.raises(ValueError, match=r"^streams\[1\]: depth row 0 is 150000 m, beyond"):
        _run(paper, streams=[dvl, depth])


def test_unix_imu_stamps_with_a_relative_t0_are_refused_naming_t0(paper) -> None:
    """A first step of 56 years (the probe: 33,000 km)."""
    traj, dvl = paper
    unix = 1.7e9
    dvl = pronet.Dvl(dvl.time + unix, dvl.velocity, frame="ned")
    with pytest.raises(ValueError, match=r"^t0: 0 s is 1\.7e\+09 s before the first IMU"):
        _run(paper, imu_time=traj.time[1 : N + 1] + unix, streams=[dvl])


def test_mechanize_refuses_the_slips_run_filter_refuses(paper) -> None:
    """The strapdown alone took an IMU in FLU, accelerations in g and a ``lla0`` in
    degrees without a word; the same data, right, integrate."""
    traj, _ = paper
    args = (traj.dt, traj.lla[0], traj.vel_ned[0], traj.rpy[0])
    in_g = traj.imu[:N].copy()
    in_g[:, :3] /= 9.80665
    with pytest.raises(ValueError, match=r"^imu, rpy0: .*FRD.*FLU"):
        pronet.mechanize(traj.imu[:N] * FLU, *args)
    with pytest.raises(ValueError, match=r"^imu: the mean specific force is 0\.99"):
        pronet.mechanize(in_g, *args)
    degrees = np.degrees(traj.lla[0]) * [1, 1, 0] + [0, 0, 1] * traj.lla[0]
    with pytest.raises(ValueError, match=r"^lla0: latitude 32 is beyond"):
        pronet.mechanize(traj.imu[:N], traj.dt, degrees, traj.vel_ned[0], traj.rpy[0])
    out = pronet.mechanize(traj.imu[:N], *args)
    assert np.abs(out.vel[-1] - traj.vel_ned[N]).max() < 0.05


def test_core_flags_are_true_or_false_naming_the_argument(paper) -> None:
    """``_core.monte_carlo(smooth=1)`` was a TypeError ("'int' object is not an
    instance of 'bool'"): the core's own entry points name ``smooth`` as the API does."""
    traj, dvl = paper
    sim = pronet.builtin_trajectory("paper")
    calls = {
        "monte_carlo": lambda s: _core.monte_carlo(
            sim, _core.SensorConfig(), _core.FilterConfig(), _core.Strategy.constant(PAPER_Q),
            n_runs=1, smooth=s,
        ),
        "Ensemble": lambda s: _core.Ensemble(
            sim, _core.SensorConfig(), _core.FilterConfig(), PAPER_Q, n_runs=1, smooth=s
        ),
        "run_filter": lambda s: _core.run_filter(
            traj.imu[:N], traj.time[1 : N + 1], [dvl], t0=0.0, lla0=traj.lla[0],
            vel0=traj.vel_ned[0], rpy0=traj.rpy[0], config=_core.FilterConfig(),
            strategy=_core.Strategy.constant(PAPER_Q), smooth=s,
        ),
    }  # fmt: skip
    for name, call in calls.items():
        for wrong in (1, 0.0, "yes"):
            with pytest.raises(ValueError, match=r"^smooth: expected True or False, got "):
                call(wrong)
        assert call(np.False_) is not None, name


def test_local_ned_refuses_degrees_naming_the_argument(paper) -> None:
    traj, _ = paper
    origin = traj.lla[0]
    degrees = np.degrees(traj.lla[:5]) * [1, 1, 0] + [0, 0, 1] * traj.lla[:5]
    with pytest.raises(ValueError, match=r"^lla: row 0: latitude 32 is beyond"):
        pronet.local_ned(degrees, origin)
    with pytest.raises(ValueError, match=r"^lla: longitude 34 is beyond"):
        pronet.local_ned([0.5, 34.0, 0.0], origin)
    with pytest.raises(ValueError, match=r"^origin: longitude 34 is beyond"):
        pronet.local_ned(traj.lla[:5], [0.5, 34.0, 0.0])
    with pytest.raises(ValueError, match=r"^origin: longitude 34 is beyond"):
        pronet.lla_from_ned([0.0, 0.0, 0.0], [0.5, 34.0, 0.0])
    # both conventions of longitude stay places
    east = pronet.local_ned([[0.5, 2 * math.pi - 0.1, 0.0]], [0.5, -0.1, 0.0])
    assert np.abs(east).max() < 1e-6


def test_every_table_of_a_pass_keeps_the_epoch(paper) -> None:
    """A thinned pass's table lost the epoch index, so that a join by ``dvl_epoch``
    picked the wrong row: every table is indexed by the epoch."""
    every = _run(paper, smooth=True)
    thin = _run(paper, smooth=True, output_step=2.0)
    last = _run(paper, epochs="last")
    updates = thin.to_dataframe("updates")
    for result, table in (
        (thin, thin.to_dataframe()),
        (thin.smoothed, thin.smoothed.to_dataframe()),
    ):
        assert table.index.name == "epoch"
        np.testing.assert_array_equal(table.index, thin.epoch)
        joined = updates.join(table[["vel_n"]], on="dvl_epoch")
        kept = np.isin(thin.dvl_epoch, thin.epoch)
        source = every if result is thin else every.smoothed
        np.testing.assert_array_equal(joined["vel_n"][kept], source.vel[thin.dvl_epoch[kept], 0])
        assert joined["vel_n"][~kept].isna().all()
    table = every.to_dataframe()
    assert table.index.equals(pd.RangeIndex(N + 1, name="epoch"))
    assert every.smoothed.to_dataframe().index.equals(table.index)
    np.testing.assert_array_equal(last.to_dataframe().index, [N])
    np.testing.assert_array_equal(last.epoch, [N])


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


def test_a_dvl_the_clock_search_cannot_overlap_names_the_file_and_streams(folder, tmp_path) -> None:
    """A DVL with 3 rows (fewer than the 10 its clock search compares): it said
    "recording: the streams do not overlap in time", then "the DVL and the ground truth do
    not overlap" (they do, over too few rows); now the count."""
    from pronet.recorded.alignment import estimate_alignment

    copy = _copy(folder, tmp_path)
    dvl = copy / "dvl.csv"
    dvl.write_text("\n".join(dvl.read_text().splitlines()[:4]) + "\n")
    with pytest.raises(
        ValueError,
        match=r"^.*section: the DVL has 3 rows over .* s; its clock is estimated from 10 ",
    ):
        estimate_alignment(read_recording(copy))


def test_a_stream_after_the_imu_record_is_warned_of(paper) -> None:
    """The pass ran pure-inertial and said nothing; a stream partly inside is not warned of."""
    traj, dvl = paper
    late = pronet.Dvl(dvl.time + 100.0, dvl.velocity, frame="ned")
    with pytest.warns(PlausibilityWarning, match=r"^streams\[1\] \(Dvl\): none of its 29 rows"):
        out = _run(paper, streams=[dvl, late])
    assert (out.streams[1].epoch == -1).all()
    partly = pronet.Dvl(dvl.time + 15.0, dvl.velocity, frame="ned")
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        _run(paper, streams=[partly])


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
