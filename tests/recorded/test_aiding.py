"""Depth readings and position fixes in recorded data: the generic format's optional
``depth`` and ``fix`` tables read back as written, their missing values skipped, their
mistakes refused in one line naming file, row and column; ``pronet real`` filters with
them (every row, forward and smoothed), ignores them on request and runs without a
DVL."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import pronet
from pronet.cli import main
from pronet.recorded.aiding import DEFAULT_FIX_SIGMA, AidingTuning, DepthReadings, filter_aiding
from pronet.recorded.alignment import load_section
from pronet.recorded.passes import aided_section, run_section
from pronet.recorded.real import run_real
from pronet.recorded.recordings import RecordingError, read_recording, write_recording
from pronet.recorded.tuning import real_filter_config, white_noise_q
from pronet.recorded.vehicle import load_vehicle

from synthetic_recording import (
    DVL_LEVER_ARM,
    GT_CLOCK,
    IMU_LEVER_ARM,
    synthetic_recording,
    with_aiding,
)

ARMS = {"imu_lever_arm": IMU_LEVER_ARM, "dvl_lever_arm": DVL_LEVER_ARM}
CONSTANT = "constant (estimated q)"


@pytest.fixture(scope="module")
def aided_80s():
    """An 80 s synthetic recording with depth every 0.5 s and fixes every 10 s."""
    return with_aiding(synthetic_recording(seed=4), seed=4, fix_every=10.0)


@pytest.mark.parametrize("suffix", ["", ".npz"])
@pytest.mark.parametrize("sigma_in_file", [True, False])
def test_depth_and_fixes_read_back_as_written(tmp_path, suffix, sigma_in_file) -> None:
    rec = with_aiding(synthetic_recording(seed=2), seed=2, sigma_in_file=sigma_in_file)
    path = write_recording(tmp_path / f"sec{suffix}", rec)
    if not suffix:
        assert {p.name for p in path.iterdir()} == {
            f"{k}.csv" for k in ("imu", "dvl", "gt", "depth", "fix")
        }
    back = read_recording(path)
    assert back.depth is not None and back.fixes is not None and rec.fixes is not None
    assert rec.depth is not None
    np.testing.assert_array_equal(back.depth.time, rec.depth.time)
    np.testing.assert_array_equal(back.depth.depth, rec.depth.depth)
    np.testing.assert_array_equal(back.fixes.lla, rec.fixes.lla)  # NaN heights as NaN
    assert np.isnan(back.fixes.lla[1::2, 2]).all() and np.isfinite(back.fixes.lla[::2]).all()
    if sigma_in_file:
        np.testing.assert_array_equal(back.fixes.sigma, rec.fixes.sigma)  # type: ignore[arg-type]
    else:
        assert back.fixes.sigma is None and back.depth.sigma is None
    assert back.depth.skipped_reason == () and len(back.dvl) == len(rec.dvl)


def test_missing_values_are_skipped_and_a_blank_height_is_a_horizontal_fix(tmp_path, aided_80s):
    folder = write_recording(tmp_path / "sec", aided_80s)
    depth = (folder / "depth.csv").read_text().splitlines()
    depth[3] = depth[3].split(",")[0] + ",,0.05"  # an empty depth cell
    depth[5] = depth[5].split(",")[0] + ",nan,0.05"
    (folder / "depth.csv").write_text("\n".join(depth) + "\n")
    fix = (folder / "fix.csv").read_text().splitlines()
    cells = fix[1].split(",")
    fix[1] = ",".join([cells[0], "", *cells[2:]])  # no latitude: skipped
    cells = fix[3].split(",")
    fix[3] = ",".join([*cells[:3], "", *cells[4:]])  # no height: horizontal
    (folder / "fix.csv").write_text("\n".join(fix) + "\n")
    rec = read_recording(folder)
    assert rec.depth is not None and rec.fixes is not None and aided_80s.depth is not None
    assert rec.depth.skipped_reason == ("nan", "nan")
    np.testing.assert_array_equal(rec.depth.skipped_time, aided_80s.depth.time[[2, 4]])
    assert len(rec.depth.time) == len(aided_80s.depth.time) - 2
    assert aided_80s.fixes is not None and rec.fixes.skipped_reason == ("nan",)
    assert len(rec.fixes.time) == len(aided_80s.fixes.time) - 1
    assert np.isnan(rec.fixes.lla[1, 2])  # the third fix, now the second: horizontal
    section, _ = load_section(folder, "generic", **ARMS)
    out = run_section(section, pronet.Strategy.constant(white_noise_q(section.imu)),
                      real_filter_config(section.alignment.filter_lever_arm))  # fmt: skip
    assert (out.result.fix_epoch >= 0).all() and np.isfinite(out.result.fix_nis).all()
    assert len(out.result.depth_epoch) == len(rec.depth.time)


def _edit(folder: Path, name: str, row: int, column: str, value: str) -> None:
    lines = (folder / name).read_text().splitlines()
    header = [h.split("[")[0].strip() for h in lines[0].split(",")]
    cells = lines[row].split(",")
    cells[header.index(column)] = value
    lines[row] = ",".join(cells)
    (folder / name).write_text("\n".join(lines) + "\n")


def _scale(folder: Path, name: str, column: str, factor: float, offset: float = 0.0) -> None:
    table = pd.read_csv(folder / name)
    label = next(c for c in table.columns if c.split("[")[0].strip() == column)
    table[label] = table[label] * factor + offset
    table.to_csv(folder / name, index=False, float_format="%.17g")


def _degrees(folder: Path) -> None:
    """fix.csv's latitude and longitude in degrees, under ``[deg]`` headers."""
    table = pd.read_csv(folder / "fix.csv")
    for name in ("lat", "lon"):
        table[f"{name} [rad]"] = np.degrees(table[f"{name} [rad]"])
    table.columns = [c.replace("[rad]", "[deg]") for c in table.columns]
    table.to_csv(folder / "fix.csv", index=False, float_format="%.17g")


def _add_column(folder: Path, name: str, label: str, value: str) -> None:
    lines = (folder / name).read_text().splitlines()
    lines = [f"{lines[0]},{label}"] + [f"{line},{value}" for line in lines[1:]]
    (folder / name).write_text("\n".join(lines) + "\n")


_LAT = r"beyond -1\.55334 … 1\.55334 rad \(-89° … 89°: the filter's latitudes"
_LON = r"beyond -3\.14159 … 6\.28319 rad \(-180° … 360°: a longitude in the ±180° or the 0–360°"


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda f: _edit(f, "depth.csv", 4, "sigma", "0"),
         r"depth\.csv, row 4: 'sigma \[m\]' is 0; a 1σ must be > 0 m"),
        (lambda f: _edit(f, "fix.csv", 2, "sigma_e", "-2"),
         r"fix\.csv, row 2: 'sigma_e \[m\]' is -2; a 1σ must be > 0 m"),
        # σ 1e-9 m once ended in a numerical failure naming neither file nor σ
        (lambda f: _edit(f, "fix.csv", 3, "sigma_n", "1e-9"),
         r"fix\.csv, row 3: 'sigma_n \[m\]' is 1e-09; a fix's 1σ must be at least 0\.001 m"),
        (lambda f: _edit(f, "depth.csv", 7, "depth", "abc"),
         r"depth\.csv, row 7: 'depth \[m\]' is 'abc', not a number"),
        (lambda f: _edit(f, "fix.csv", 3, "time", "1.0"),
         r"fix\.csv, row 3: time 1\.0 s does not increase"),
        (lambda f: _edit(f, "fix.csv", 5, "lat", "2.0"),
         rf"fix\.csv, row 5: 'lat \[rad\]' is 2, {_LAT}"),
        (lambda f: _edit(f, "fix.csv", 3, "lat", str(math.radians(89.5))),  # the core's ±89°
         rf"fix\.csv, row 3: 'lat \[rad\]' is 1\.562069681, {_LAT}"),
        (lambda f: (_degrees(f), _edit(f, "fix.csv", 2, "lat", "95")),  # the file's unit
         r"fix\.csv, row 2: 'lat \[deg\]' is 95, beyond -89 … 89 deg \(the filter's latitudes"),
        (lambda f: _edit(f, "fix.csv", 3, "lon", "7.0"),
         rf"fix\.csv, row 3: 'lon \[rad\]' is 7, {_LON}"),
        (lambda f: _edit(f, "fix.csv", 4, "lon", "-3.2"),
         rf"fix\.csv, row 4: 'lon \[rad\]' is -3\.2, {_LON}"),
        (lambda f: (_degrees(f), _scale(f, "fix.csv", "lon", 1.0, 360.0)),
         r"fix\.csv, row 1: 'lon \[deg\]' is 394\.\d+, beyond -180 … 360 deg \(a longitude in"),
        (lambda f: _add_column(f, "fix.csv", "sigma [m]", "3"),  # one σ: not the fixes' three
         r"fix\.csv: column 'sigma \[m\]' is not a σ column of the fix table; its σ columns "
         r"are sigma_n \[m\], sigma_e \[m\], sigma_d \[m\]$"),
        (lambda f: _add_column(f, "depth.csv", "sigma_d [m]", "0.2"),
         r"depth\.csv: column 'sigma_d \[m\]' is not a σ column of the depth table; its σ "
         r"columns are sigma \[m\]$"),
        (lambda f: _edit(f, "fix.csv", 5, "lon", "inf"),
         r"fix\.csv, row 5: 'lon \[rad\]' is inf, not finite"),
        (lambda f: _scale(f, "depth.csv", "depth", -1.0),  # a height, not a depth
         r"depth\.csv: column 'depth' lies a median -\d+\.?\d* m from the ground truth's depth"),
        (lambda f: _scale(f, "depth.csv", "depth", 1.0, 10.1),  # absolute pressure
         r"depth\.csv: column 'depth' lies a median \+\d+\.\d+ m .* gauge pressure"),
        (lambda f: _scale(f, "depth.csv", "depth", 3.28084),  # feet
         r"depth\.csv: column 'depth' lies a median \+\d+\.?\d* m"),
        (lambda f: _scale(f, "fix.csv", "lat", 180 / np.pi),  # degrees under [rad]
         rf"fix\.csv, row 1: 'lat \[rad\]' is 32\.\d+, {_LAT}"),
        (lambda f: _scale(f, "fix.csv", "lon", 1.001),
         r"fix\.csv: columns 'lat', 'lon' lie a median \d+ m from the ground truth"),
        (lambda f: _scale(f, "fix.csv", "time", 1.0, 1.7e9),  # Unix stamps on one stream
         r"fix\.csv: column 'time \[s\]' runs .* the fix and IMU stamps do not overlap"),
        (lambda f: [_scale(f, n, "time", 1.0, 1.7e9 + 86400.0 * (n == "depth.csv"))
                    for n in ("imu.csv", "dvl.csv", "gt.csv", "depth.csv", "fix.csv")],
         r"depth\.csv: column 'time \[s\]' runs 17000864\d\d.* the depth and IMU stamps do "
         r"not overlap"),  # Unix stamps, the depth's a day off: the scale acts about the start
        (lambda f: (f / "fix.csv").write_text(
            (f / "fix.csv").read_text().replace("sigma_d [m]", "sigma_down [m]")),
         r"fix\.csv: column 'sigma_down \[m\]' is not a σ column of the fix table"),
        (lambda f: (f / "fix.csv").write_text(
            (f / "fix.csv").read_text().replace(",sigma_d [m]", ",notes")),
         r"fix\.csv: has sigma_n, sigma_e but not sigma_d; give all three or none"),
        (lambda f: (f / "depth.csv").write_text(
            (f / "depth.csv").read_text().replace("depth [m]", "depth [ft]")),
         r"depth\.csv: column 'depth \[ft\]' has unit \[ft\]; expected one of m"),
        (lambda f: _scale(f, "depth.csv", "depth", 1025 * 9.80665),  # in pascals
         r"depth\.csv, row \d+: 'depth \[m\]' is \d+\.?\d* m, beyond -10000 … 12000 m "
         r"\(metres, positive down: the deepest ocean is 11 km\); in pascals or another"),
        (lambda f: (f / "depth.csv").write_text("time [s],depth [m]\n1.0,,\n"),
         r"depth\.csv, row 1: has 3 fields, the header 2"),
    ],
)  # fmt: skip
def test_a_bad_depth_or_fix_table_is_one_line_naming_file_row_and_column(
    tmp_path, aided_80s, change, message
) -> None:
    folder = write_recording(tmp_path / "sec", aided_80s)
    change(folder)
    with pytest.raises(RecordingError, match=message) as caught:
        read_recording(folder)
    assert "\n" not in str(caught.value) and str(folder) in str(caught.value)


def test_fixes_in_degrees_and_the_npz_arrays_obey_the_same_rules(tmp_path, aided_80s) -> None:
    """Degrees read as the radians they are, within the ranges; an ``.npz``'s fix and
    depth arrays are refused as a folder's tables are, naming the array and row."""
    folder = write_recording(tmp_path / "sec", aided_80s)
    _degrees(folder)
    assert aided_80s.fixes is not None
    back = read_recording(folder).fixes
    assert back is not None
    np.testing.assert_allclose(back.lla, aided_80s.fixes.lla, rtol=1e-15)
    npz = write_recording(tmp_path / "sec.npz", aided_80s)
    arrays = dict(np.load(npz))
    arrays["fix"][2, 2] = 7.0
    np.savez(tmp_path / "lon.npz", **arrays)
    with pytest.raises(
        RecordingError, match=rf"lon\.npz\[fix\], row 3: 'lon \[rad\]' is 7, {_LON}"
    ):
        read_recording(tmp_path / "lon.npz")
    arrays = dict(np.load(npz))
    arrays["fix"][1, 1] = np.radians(89.5)
    np.savez(tmp_path / "lat.npz", **arrays)
    with pytest.raises(
        RecordingError, match=rf"lat\.npz\[fix\], row 2: 'lat \[rad\]' is 1\.56\d+, {_LAT}"
    ):
        read_recording(tmp_path / "lat.npz")
    arrays = dict(np.load(npz))
    arrays["depth_columns"] = np.array(["time [s]", "depth [m]", "sigma_d [m]"])
    np.savez(tmp_path / "sigma.npz", **arrays)
    with pytest.raises(RecordingError, match=r"sigma\.npz\[depth\]: column 'sigma_d \[m\]' is not"):
        read_recording(tmp_path / "sigma.npz")


def test_the_dvl_is_optional_but_one_aiding_stream_is_needed(tmp_path, aided_80s) -> None:
    folder = write_recording(tmp_path / "sec", replace(aided_80s, dvl=np.empty((0, 3)),
                                                       dvl_time=np.empty(0)))  # fmt: skip
    assert not (folder / "dvl.csv").exists()
    rec = read_recording(folder)
    assert len(rec.dvl) == 0 and rec.fixes is not None
    npz = write_recording(tmp_path / "sec.npz", rec)
    assert len(read_recording(npz).dvl) == 0
    arrays = dict(np.load(npz))
    del arrays["fix_columns"]  # half a table is not left out silently
    np.savez(tmp_path / "half.npz", **arrays)
    with pytest.raises(RecordingError, match=r"half\.npz: needs arrays 'fix' and 'fix_columns'"):
        read_recording(tmp_path / "half.npz")
    for name in ("depth.csv", "fix.csv"):
        (folder / name).unlink()
    with pytest.raises(RecordingError, match=r"no dvl\.csv or dvl\.csv\.gz \(nor depth\.csv"):
        read_recording(folder)


def _run(data: Path, out: Path, **kw) -> dict[str, dict[str, float]]:
    """``pronet real`` on ``data`` (no models, no plots): metrics per row label."""
    run_real(data, out, fmt="generic", use_models=False, plots=False, **ARMS, **kw)
    table = pd.read_csv(out / "metrics.csv")
    return {row["strategy"]: row for row in table.to_dict("records")}


@pytest.fixture(scope="module")
def miscalibrated(tmp_path_factory):
    """400 s with a DVL reading 1 % long and turned 0.57° in yaw (a calibration error
    within what real installations show, docs/results/snapir.md), depth every 0.5 s and
    fixes every 30 s (σ 2 m): the folder, with and without its DVL."""
    base = tmp_path_factory.mktemp("miscalibrated")
    rec = synthetic_recording(seed=1, duration=400.0, dvl_mounting=(0.01, (0.0, 0.0, 0.01)))
    aided = with_aiding(rec, seed=1)
    with_dvl = write_recording(base / "with_dvl" / "sec", aided)
    no_dvl = replace(aided, dvl=np.empty((0, 3)), dvl_time=np.empty(0))
    return with_dvl, write_recording(base / "no_dvl" / "sec", no_dvl)


def test_fixes_bound_the_horizontal_error_where_the_dvl_alone_drifts(tmp_path, miscalibrated):
    """The miscalibrated DVL alone drifts; the fixes pull every row back, and with the
    DVL calibration states the error stays within the fixes' 3σ. Measured (metrics.csv):
    the constant row's final error 11.3 m alone, 7.4 m with the fixes (the 15-state
    filter, told the DVL is exact to 0.02 m/s, keeps its position σ near 0.5 m and
    weights 2 m fixes little); the calibration row 1.9 m alone, 1.5 m with them."""
    with_dvl, _ = miscalibrated
    alone = _run(with_dvl.parent, tmp_path / "alone", use_depth=False, use_fixes=False)
    aided = _run(with_dvl.parent, tmp_path / "aided")
    calibration = "constant (estimated q), DVL calibration"
    assert alone[CONSTANT]["final_horizontal_error"] > 3 * 2.0  # beyond the fixes' 3σ
    assert aided[CONSTANT]["final_horizontal_error"] < alone[CONSTANT]["final_horizontal_error"]
    assert aided[calibration]["final_horizontal_error"] < 3 * 2.0
    assert aided[calibration]["max_horizontal_error"] < alone[CONSTANT]["max_horizontal_error"]
    config = json.loads((tmp_path / "aided" / "config.json").read_text())
    used = config["aiding"]["sections"]["sec"]
    assert used["fixes"]["rows"] == 13 and used["depth"]["rows"] == 800
    assert used["fixes"]["sigma_m"] == [2.0, 2.0, 2.0] and used["depth"]["sigma_m"] == 0.05
    table = (tmp_path / "aided" / "table.md").read_text()
    assert "### Depth and position fixes" in table
    assert "| sec | 800 (0 skipped, 1 outside the run) | 0.05 |" in table
    assert "### Depth and position fixes" not in (tmp_path / "alone" / "table.md").read_text()
    ignored = json.loads((tmp_path / "alone" / "config.json").read_text())["aiding"]
    assert ignored["sections"]["sec"] == {"depth": None, "fixes": None}


def test_gnss_ins_without_a_dvl_runs_forward_and_smoothed(tmp_path, miscalibrated):
    """No DVL: the fixes bound what free inertial lets drift, every strategy row runs
    forward and smoothed, and the rows that need DVL updates are left out with their
    reason. Measured: the constant row's final error 2.9 m (maximum 7.4 m, before the
    filter has seen a few fixes), smoothed maximum 2.9 m and SRMSE 0.090 -> 0.026 m/s;
    free inertial 21 m after the 400 s."""
    _, no_dvl = miscalibrated
    rows = _run(no_dvl.parent, tmp_path / "gnss", smooth=True)
    assert rows[CONSTANT]["final_horizontal_error"] < 3 * 2.0
    smoothed = rows[f"{CONSTANT}, smoothed"]
    assert (
        np.isfinite(smoothed["srmse"])
        and smoothed["max_horizontal_error"] < rows[CONSTANT]["max_horizontal_error"]
    )
    config = json.loads((tmp_path / "gnss" / "config.json").read_text())
    assert "mehra xi=1" in config["rows_not_run"]["sec"]
    # --no-dvl on the recording with its DVL is the recording without it, to the bit
    ignored = _run(miscalibrated[0].parent, tmp_path / "no-dvl", smooth=True, use_dvl=False)
    assert ignored.keys() == rows.keys()
    for label, row in rows.items():
        assert ignored[label]["final_horizontal_error"] == row["final_horizontal_error"], label
        assert ignored[label]["srmse"] == row["srmse"], label
    section, _ = load_section(no_dvl, "generic", **ARMS)
    q, cfg = white_noise_q(section.imu), real_filter_config(section.alignment.filter_lever_arm)
    free = run_section(section, pronet.Strategy.constant(q), cfg, aided=False)
    assert free.metrics.final_horizontal > 3 * rows[CONSTANT]["final_horizontal_error"]
    with pytest.raises(ValueError, match="no DVL reading, depth or position fix .ignored: "
                       "--no-depth, --no-fixes.: nothing aids the IMU"):  # fmt: skip
        aided_section(section, AidingTuning(use_depth=False, use_fixes=False))


def test_depth_holds_the_height_of_a_gnss_ins_run(miscalibrated):
    """Horizontal fixes every other time, depth every 0.5 s (σ 0.05 m): the vertical
    error stays within a few depth σ; without the depth it is what the fixes' heights
    leave (σ 2 m every 60 s)."""
    _, no_dvl = miscalibrated
    section, _ = load_section(no_dvl, "generic", **ARMS)
    q, cfg = white_noise_q(section.imu), real_filter_config(section.alignment.filter_lever_arm)
    down = {}
    for use_depth in (True, False):
        aided = aided_section(section, AidingTuning(use_depth=use_depth))
        result = run_section(aided, pronet.Strategy.constant(q), cfg).result
        truth = np.interp(result.time, section.truth_time, section.truth_lla[:, 2])
        down[use_depth] = np.abs(result.lla[:, 2] - truth)[result.time > section.truth_time[0] + 10]
    assert down[True].max() < 0.3 < down[False].max()


def test_the_vehicle_file_sets_the_sigma_a_recording_lacks(tmp_path) -> None:
    toml = tmp_path / "auv.toml"
    toml.write_text("depth_sigma = 0.2\nfix_sigma = [5.0, 5.0, 10.0]\n")
    vehicle = load_vehicle(toml)
    tuning = vehicle.aiding(AidingTuning())
    assert tuning.depth_sigma == 0.2 and tuning.fix_sigma == (5.0, 5.0, 10.0)
    assert load_vehicle("mems").aiding(AidingTuning()).fix_sigma == DEFAULT_FIX_SIGMA
    # a σ of the wrong length, zero, or not a number (true or "0.3" read as one before)
    for text in ("fix_sigma = [5.0, 0.0]", "depth_sigma = true", 'depth_sigma = "0.3"',
                 'fix_sigma = ["1", "1", "1"]', "fix_sigma = 2.0"):  # fmt: skip
        toml.write_text(text + "\n")
        with pytest.raises(ValueError, match=r"auv\.toml: depth_sigma, fix_sigma: a number"):
            load_vehicle(toml)


def test_the_command_line_ignores_the_fixes_on_request(tmp_path, aided_80s, capsys) -> None:
    folder = write_recording(tmp_path / "sec", aided_80s)
    arms = [f"--imu-lever-arm={','.join(map(str, IMU_LEVER_ARM))}",
            f"--dvl-lever-arm={','.join(map(str, DVL_LEVER_ARM))}"]  # fmt: skip
    argv = ["real", "--data", str(folder), "--format", "generic", "--no-models", "--no-plots"]
    assert main([*argv, *arms, "--no-fixes", "--out", str(tmp_path / "out"), "--quiet"]) == 0
    aiding = json.loads((tmp_path / "out" / "config.json").read_text())["aiding"]
    assert aiding["use_fixes"] is False and aiding["sections"]["sec"]["fixes"] is None
    assert aiding["sections"]["sec"]["depth"]["rows"] == 160


def test_rows_outside_the_run_are_counted_apart_from_those_used(tmp_path, aided_80s) -> None:
    """A fix stamped before the run and fixes after its end (the IMU's 80 s) are applied
    at no epoch: table.md and config.json count them apart (``outside_run``), so that
    what is reported as used was; the first depth row (0.5 s) lies before the run's
    start (the first truth row at or after the first IMU sample)."""
    folder = write_recording(tmp_path / "sec", aided_80s)
    _scale(folder, "fix.csv", "time", 1.0, 25.0)  # 35 … 105 s: 85, 95, 105 s after the end
    _edit(folder, "fix.csv", 1, "time", "-5")
    _run(folder, tmp_path / "out")
    config = json.loads((tmp_path / "out" / "config.json").read_text())
    used = config["aiding"]["sections"]["sec"]
    assert used["fixes"]["rows"] == 8 and used["fixes"]["skipped"] == 0
    assert used["fixes"]["outside_run"] == 4 and used["depth"]["outside_run"] == 1
    table = (tmp_path / "out" / "table.md").read_text()
    assert "| sec | 160 (0 skipped, 1 outside the run) | 0.05 |" in table
    assert "| 8 (0 skipped, 4 outside the run) | 2 / 2 / 2 |" in table
    section, _ = load_section(folder, "generic", **ARMS)
    q, cfg = white_noise_q(section.imu), real_filter_config(section.alignment.filter_lever_arm)
    result = run_section(section, pronet.Strategy.constant(q), cfg).result
    assert (result.fix_epoch < 0).tolist() == [True] + [False] * 4 + [True] * 3
    assert (result.depth_epoch < 0).tolist() == [True] + [False] * 159


def test_the_dvl_clock_is_refused_for_a_recording_without_a_dvl(tmp_path, aided_80s) -> None:
    """``--aiding-clock dvl`` on a recording without DVL readings names the file (it
    once stamped the depth and fixes on the ground truth's clock, reported as the
    DVL's), once per section prefix, before any filter runs."""
    no_dvl = replace(aided_80s, dvl=np.empty((0, 3)), dvl_time=np.empty(0))
    folder = write_recording(tmp_path / "data" / "sec", no_dvl)
    with pytest.raises(
        ValueError, match=r"^aiding_clock 'dvl' \(--aiding-clock dvl\): .*sec has no DVL"
    ):
        load_section(folder, "generic", **ARMS, aiding_clock="dvl")
    with pytest.raises(ValueError) as caught:
        _run(folder.parent, tmp_path / "out", aiding_clock="dvl")
    assert str(caught.value).startswith("section sec: aiding_clock 'dvl' (--aiding-clock dvl): ")
    assert not (tmp_path / "out").exists()
    on_gt, _ = load_section(folder, "generic", **ARMS, aiding_clock="gt")
    assert on_gt.fixes is not None


def test_a_section_level_reason_names_its_section_once(tmp_path, aided_80s) -> None:
    folder = write_recording(tmp_path / "data" / "sec", replace(aided_80s, depth=None, fixes=None))
    with pytest.raises(ValueError) as caught:
        _run(folder.parent, tmp_path / "out", use_dvl=False)
    assert str(caught.value).startswith("section sec: no DVL reading, depth or position fix")
    assert str(caught.value).count("section sec") == 1


def test_depth_and_fixes_stamped_on_another_streams_clock(tmp_path, aided_80s) -> None:
    """Depth and fixes stamped by the ground truth's logger (offset −0.45 s, scale
    0.9975): ``aiding_clock="gt"`` puts them on the IMU clock through its estimated
    clock; as given (``"imu"``) they stay up to 0.65 s late over the 80 s."""
    assert aided_80s.depth is not None and aided_80s.fixes is not None
    true_depth, true_fix = aided_80s.depth.time, aided_80s.fixes.time

    def logger(t: np.ndarray) -> np.ndarray:  # IMU time → the truth logger's stamps
        return (t - GT_CLOCK.offset) / GT_CLOCK.scale

    rec = replace(aided_80s, depth=aided_80s.depth.on_clock(logger),
                  fixes=aided_80s.fixes.on_clock(logger))  # fmt: skip
    folder = write_recording(tmp_path / "sec", rec)
    on_gt, _ = load_section(folder, "generic", **ARMS, aiding_clock="gt")
    as_given, _ = load_section(folder, "generic", **ARMS)
    epoch = float(rec.imu_time[0])  # every section time counts from the first IMU stamp
    assert on_gt.depth is not None and on_gt.fixes is not None and as_given.fixes is not None
    np.testing.assert_allclose(on_gt.fixes.time, true_fix - epoch, rtol=0, atol=1e-3)
    np.testing.assert_allclose(on_gt.depth.time, true_depth - epoch, rtol=0, atol=1e-3)
    late = as_given.fixes.time - (true_fix - epoch)
    assert 0.4 < late.min() and late.max() < 0.7
    with pytest.raises(ValueError, match="aiding_clock: expected one of imu, dvl, gt"):
        load_section(folder, "generic", **ARMS, aiding_clock="depth")


def test_each_depth_row_keeps_its_own_sigma() -> None:
    # Outliers marked with a huge σ must weigh as little as it says, not take the median's.
    sigma = np.array([0.05, 0.05, 1e6, 0.05, 1e6])
    depth = DepthReadings(time=np.arange(5.0), depth=np.full(5, 10.0), sigma=sigma)
    (stream,) = filter_aiding(depth, None)
    np.testing.assert_array_equal(stream.sigma, sigma)


def test_a_recording_without_a_dvl_names_no_dvl_stream(tmp_path, aided_80s) -> None:
    """A GNSS/INS recording (no dvl.csv), or one with --no-dvl: its passes carry an empty
    DVL stream, which every row flagged as "dvl: no reading applied", on stderr and in
    config.json's notes. A stream without a reading has nothing to say; the depth and
    fixes are still reported."""
    no_dvl = replace(aided_80s, dvl=np.empty((0, 3)), dvl_time=np.empty(0))
    folder = write_recording(tmp_path / "data" / "sec", no_dvl)
    with_dvl = write_recording(tmp_path / "with" / "sec", aided_80s)
    for data, out, kw in ((folder, "gnss", {}), (with_dvl, "ignored", {"use_dvl": False})):
        _run(data.parent, tmp_path / out, **kw)
        notes = json.loads((tmp_path / out / "config.json").read_text())["notes"]
        assert not any("dvl:" in note for note in notes), notes
    section, _ = load_section(folder, "generic", **ARMS)
    q, cfg = white_noise_q(section.imu), real_filter_config(section.alignment.filter_lever_arm)
    aided = aided_section(section, AidingTuning())
    streams = run_section(aided, pronet.Strategy.constant(q), cfg).result.health.streams
    assert [s.name for s in streams] == ["dvl", "depth", "fix"]
    assert streams[0].flag == "" and streams[0].rows == 0
