"""Missing DVL readings: NaN, empty, sentinel, all-zero and
``valid = 0`` rows are skipped as updates, counted per section and reported, never
fatal."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from pronet.cli import main
from pronet.recorded import missing
from pronet.recorded.alignment import load_section
from pronet.recorded.recordings import RecordingError, read_recording, write_recording

from synthetic_recording import DVL_LEVER_ARM, IMU_LEVER_ARM, synthetic_recording

ARMS = {"imu_lever_arm": IMU_LEVER_ARM, "dvl_lever_arm": DVL_LEVER_ARM}


def _with_dropouts(folder, duration=80.0):
    """A synthetic section as CSVs whose DVL loses the bottom: a 20 s run of NaN rows
    (rows 20-39), an empty cell, RDI's -32.768, an all-zero row, and valid = 0."""
    rec = synthetic_recording(seed=3, duration=duration, name="dropout").recording
    write_recording(folder, rec)
    dvl = pd.read_csv(folder / "dvl.csv")
    dvl["valid"] = 1
    vel = ["vel_x [m/s]", "vel_y [m/s]", "vel_z [m/s]"]
    dvl.loc[20:39, vel] = np.nan
    dvl.loc[45, "vel_y [m/s]"] = -32.768
    dvl.loc[50, vel] = 0.0
    dvl.loc[55, "valid"] = 0
    text = dvl.to_csv(index=False, float_format="%.17g", na_rep="nan")
    lines = text.splitlines()
    lines[1 + 47] = lines[1 + 47].replace(lines[1 + 47].split(",")[2], "", 1)  # an empty cell
    (folder / "dvl.csv").write_text("\n".join(lines) + "\n")
    return rec


def test_missing_rows_are_skipped_and_counted_by_reason(tmp_path):
    rec = _with_dropouts(tmp_path / "s")
    got = read_recording(tmp_path / "s")
    assert len(got.dvl) == len(rec.dvl) - 24
    assert missing.counts(got.dvl_skipped_reason) == {
        "invalid": 1,
        "nan": 21,
        "sentinel": 1,
        "zero": 1,
    }
    assert np.isfinite(got.dvl).all()
    np.testing.assert_array_equal(got.dvl_skipped_time[:20], rec.dvl_time[20:40])
    aligned, _ = load_section(tmp_path / "s", "generic", **ARMS)
    assert len(aligned.dvl_skipped_time) == 24
    # the longest stretch without a used row: rows 19 and 40 are 21 DVL steps apart
    step = float(np.median(np.diff(aligned.dvl_time)))
    gap = missing.longest_gap(aligned.dvl_time, aligned.dvl_skipped_time)
    assert gap == pytest.approx(21 * step, rel=1e-9)


def test_a_dvl_in_cm_per_s_is_refused_not_taken_for_markers(tmp_path):
    """Readings in cm/s of a vehicle's own mission (no ground truth to compare the
    speed with): most rows beyond the marker's 32.768, each its own value (a marker
    repeats one), refused naming the file; the same rows as markers are skipped."""
    rec = synthetic_recording(seed=3, duration=60.0, name="cm").recording
    write_recording(tmp_path / "m", rec)
    (tmp_path / "m" / "gt.csv").unlink()
    dvl = pd.read_csv(tmp_path / "m" / "dvl.csv")
    vel = ["vel_x [m/s]", "vel_y [m/s]", "vel_z [m/s]"]
    dvl.loc[:, vel] *= 100.0
    dvl.loc[:14, vel] *= 0.1  # the vehicle slow at first: under 32.768 in cm/s
    dvl.loc[:14, "vel_x [m/s]"] += 3.0  # (and still moving in m/s below)
    beyond = dvl[vel].abs().max(axis=1) >= missing.DVL_SENTINEL
    assert 0.5 < beyond.mean() < 1.0  # not every row: the all-rows check says nothing
    dvl.to_csv(tmp_path / "m" / "dvl.csv", index=False, float_format="%.17g")
    with pytest.raises(RecordingError, match=r"dvl.*different values.*in m/s\?"):
        read_recording(tmp_path / "m")
    # the same count of rows, each RDI's marker: skipped, not refused
    m_per_s = pd.read_csv(tmp_path / "m" / "dvl.csv")
    m_per_s.loc[:, vel] /= 100.0
    m_per_s.loc[beyond, "vel_x [m/s]"] = -32.768
    m_per_s.to_csv(tmp_path / "m" / "dvl.csv", index=False, float_format="%.17g")
    got = read_recording(tmp_path / "m")
    assert missing.counts(got.dvl_skipped_reason)["sentinel"] == beyond.sum()


def test_the_same_rows_in_an_npz_are_skipped_alike(tmp_path):
    _with_dropouts(tmp_path / "s")
    csv = read_recording(tmp_path / "s")
    dvl = pd.read_csv(tmp_path / "s" / "dvl.csv")
    arrays = {}
    for kind in ("imu", "gt"):
        table = pd.read_csv(tmp_path / "s" / f"{kind}.csv")
        arrays[kind] = table.to_numpy(dtype=float)
        arrays[f"{kind}_columns"] = np.array(table.columns, dtype=str)
    arrays["dvl"] = dvl.to_numpy(dtype=float)
    arrays["dvl_columns"] = np.array(dvl.columns, dtype=str)
    np.savez(tmp_path / "s.npz", **arrays)
    npz = read_recording(tmp_path / "s.npz")
    np.testing.assert_array_equal(npz.dvl, csv.dvl)
    assert npz.dvl_skipped_reason == csv.dvl_skipped_reason


def test_a_zero_row_at_rest_is_a_reading_and_a_bad_flag_is_named(tmp_path):
    vel = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [np.inf, 0.0, 0.0], [99.99, 0, 0]])
    why = missing.classify(vel, None, np.array([0.0, 1.0, 1.0, 1.0]))
    assert list(why) == ["", "", "sentinel", "sentinel"]
    rec = synthetic_recording(seed=3, duration=30.0).recording
    write_recording(tmp_path / "s", rec)
    dvl = pd.read_csv(tmp_path / "s" / "dvl.csv")
    dvl["valid"] = 1
    dvl.loc[4, "valid"] = 2
    dvl.to_csv(tmp_path / "s" / "dvl.csv", index=False, float_format="%.17g")
    with pytest.raises(RecordingError, match=r"dvl.csv, row 5: 'valid' is 2.0; it must be 1"):
        read_recording(tmp_path / "s")
    dvl.loc[:, "valid"] = 0
    dvl.to_csv(tmp_path / "s" / "dvl.csv", index=False, float_format="%.17g")
    message = r"dvl: no usable reading in its 29 rows \(29 invalid\)"
    with pytest.raises(RecordingError, match=message):
        read_recording(tmp_path / "s")


def test_a_section_with_a_20_s_dropout_runs_and_reports_it(tmp_path, capsys):
    """The acceptance case: the section runs, its error is reported, and the skipped
    rows are counted in table.md, metrics.csv and config.json."""
    _with_dropouts(tmp_path / "data" / "dropout", duration=120.0)
    out = tmp_path / "out"
    arms = [f"--imu-lever-arm={','.join(map(str, IMU_LEVER_ARM))}"]
    arms += [f"--dvl-lever-arm={','.join(map(str, DVL_LEVER_ARM))}"]
    argv = ["real", "--data", str(tmp_path / "data"), "--format", "generic", "--out", str(out)]
    assert main([*argv, "--quiet", "--no-plots", *arms]) == 0
    table = (out / "table.md").read_text()
    assert "DVL readings skipped as missing (missed updates)" in table
    metrics = pd.read_csv(out / "metrics.csv")
    first = metrics[(metrics.scenario == "dropout")].iloc[0]
    assert np.isfinite(first.srmse) and first.srmse < 0.2
    assert first.missed_updates == 24
    inertial = metrics[metrics.strategy.str.startswith("inertial only")]
    assert (inertial.missed_updates == 0).all()
    config = json.loads((out / "config.json").read_text())
    skipped = config["dvl_skipped"]["dropout"]
    assert skipped["nan"] == 21 and skipped["skipped"] == 24
    capsys.readouterr()
