"""Recorded data: readers and their errors, clock and lever-arm handling, the ProNet
loop on recorded IMU, ``pronet real``, and accuracy on the Snapir AUV data when it is
present (``../shared/data/snapir``; it is never copied into the project)."""

from __future__ import annotations

import gzip
import json
import os
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pronet
from pronet.cli import main
from pronet.learn.hybrid import ConstantRegressor, q_schedule
from pronet.recorded import alignment, passes, real
from pronet.recorded.alignment import (
    Alignment,
    align,
    estimate_alignment,
)
from pronet.recorded.dvltruth import truth_calibration
from pronet.recorded.metrics import section_metrics
from pronet.recorded.recordings import (
    Recording,
    RecordingError,
    read_recording,
    read_snapir,
    write_recording,
)
from pronet.recorded.tables import TRUTH_LABEL
from pronet.results import RUN_COLUMNS
from pronet.strategies import Learned

from synthetic_recording import (
    DVL_CLOCK,
    DVL_LEVER_ARM,
    GT_CLOCK,
    IMU_LEVER_ARM,
    synthetic_recording,
)

#: The Snapir data: ``$PRONET_SNAPIR_DIR``, else ``../shared/data/snapir`` beside the project.
SNAPIR = Path(
    os.environ.get(
        "PRONET_SNAPIR_DIR", Path(__file__).resolve().parents[3] / "shared" / "data" / "snapir"
    )
)
REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def synthetic():
    return synthetic_recording(seed=0)


def assert_same_recording(a: Recording, b: Recording) -> None:
    for field in ("imu_time", "imu", "dvl_time", "dvl", "gt_time", "gt_lla", "gt_vel", "gt_rpy"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)


# ---------------------------------------------------------------- readers


@pytest.mark.parametrize("where", ["folder", "recording.npz"])
def test_generic_format_round_trips(tmp_path, synthetic, where):
    path = write_recording(tmp_path / where, synthetic.recording)
    assert_same_recording(read_recording(path), synthetic.recording)


def test_gzip_csv_and_units_are_converted(tmp_path, synthetic):
    """Gzip files are read, and degrees become radians."""
    folder = write_recording(tmp_path / "rec", synthetic.recording)
    gt = (folder / "gt.csv").read_text().splitlines()
    head = gt[0].replace("lat [rad]", "lat [deg]").replace("yaw [rad]", "yaw [deg]")
    rows = [np.array(line.split(","), float) for line in gt[1:]]
    for r in rows:
        r[[1, 9]] = np.degrees(r[[1, 9]])
    body = "\n".join(",".join(repr(float(v)) for v in r) for r in rows)
    (folder / "gt.csv").unlink()
    with gzip.open(folder / "gt.csv.gz", "wt") as fh:
        fh.write(head + "\n" + body + "\n")
    back = read_recording(folder)
    np.testing.assert_allclose(back.gt_lla, synthetic.recording.gt_lla, rtol=1e-15)
    np.testing.assert_allclose(back.gt_rpy, synthetic.recording.gt_rpy, rtol=1e-14, atol=1e-15)


def write_snapir_layout(folder: Path, rec: Recording) -> Path:
    """``rec`` in the publisher's layout: gzip CSVs with its headers and column order."""
    folder.mkdir(parents=True)
    tables = {
        "imu": (
            "Time [s],ACC X [m/s^2],ACC Y [m/s^2],ACC Z [m/s^2],"
            "GYRO X [rad/s],GYRO Y [rad/s],GYRO Z [rad/s]",
            np.column_stack([rec.imu_time, rec.imu]),
        ),
        "dvl": (
            "Time [s],DVL X [m/s],DVL Y [m/s],DVL Z [m/s]",
            np.column_stack([rec.dvl_time, rec.dvl]),
        ),
        "gt": (
            "Time [s],Longitude [rad],Latitude [rad],Altitude [m],V North [m/s],"
            "V East [m/s],V Down [m/s],Roll [rad],Pitch [rad],Yaw [rad]",
            np.column_stack(
                [rec.gt_time, rec.gt_lla[:, 1], rec.gt_lla[:, 0], rec.gt_lla[:, 2]]
                + [rec.gt_vel, rec.gt_rpy]
            ),
        ),
    }
    for kind, (head, data) in tables.items():
        with gzip.open(folder / f"{kind}.csv.gz", "wt") as fh:
            fh.write(head + "\n")
            np.savetxt(fh, data, delimiter=",", fmt="%.17g")
    return folder


def test_snapir_layout_is_read(tmp_path, synthetic):
    folder = write_snapir_layout(tmp_path / "trajectory01", synthetic.recording)
    rec = read_snapir(folder)
    assert rec.name == "trajectory01"
    assert_same_recording(rec, synthetic.recording)


def csv_folder(tmp_path, synthetic) -> Path:
    return write_recording(tmp_path / "rec", synthetic.recording)


def edit_line(path: Path, index: int, edit) -> None:
    lines = path.read_text().splitlines()
    lines[index] = edit(lines[index])
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize(
    ("file", "corrupt", "expected"),
    [
        (
            "imu",
            lambda p: edit_line(p, 0, lambda s: s.replace("acc_z [m/s^2]", "acc_q [m/s^2]")),
            "missing column 'acc_z'",
        ),
        (
            "gt",
            lambda p: edit_line(p, 5, lambda s: "0.0" + s[s.index(",") :]),
            "row 5: time 0.0 s does not increase",
        ),
        (  # a NaN in the DVL's velocity is a missing reading (test_missing_dvl.py)
            "gt",
            lambda p: edit_line(p, 3, lambda s: s[: s.rindex(",")] + ",nan"),
            "row 3: 'yaw [rad]' is nan, not finite",
        ),
        ("imu", lambda p: p.write_text(""), "is empty"),
        (
            "dvl",
            lambda p: p.write_text(p.read_text().replace(",", ";")),
            "the file must be comma-separated",
        ),
        (
            "imu",
            lambda p: edit_line(p, 7, lambda s: s.replace(",", ",abc", 1)),
            "row 7: 'acc_x [m/s^2]' is",
        ),
        (
            "gt",
            lambda p: edit_line(p, 0, lambda s: s.replace("height [m]", "height [ft]")),
            "unit [ft]",
        ),
        ("imu", lambda p: edit_line(p, 9, lambda s: s + ",1.0"), "row 9: has 8 fields"),
        (
            "dvl",
            lambda p: p.write_text(p.read_text().splitlines()[0] + "\n"),
            "no data rows",
        ),
    ],
    ids=[
        "missing-column",
        "unsorted-time",
        "nan",
        "empty",
        "semicolons",
        "not-a-number",
        "unknown-unit",
        "ragged-row",
        "header-only",
    ],
)
def test_malformed_csv_gives_a_clear_error(tmp_path, synthetic, file, corrupt, expected):
    folder = csv_folder(tmp_path, synthetic)
    corrupt(folder / f"{file}.csv")
    with pytest.raises(RecordingError) as info:
        read_recording(folder)
    assert f"{file}.csv" in str(info.value)
    assert expected in str(info.value)


def test_implausible_rates_and_missing_files(tmp_path, synthetic):
    rec = synthetic.recording
    with pytest.raises(RecordingError, match="sample rate 0.1 Hz is implausible for imu"):
        write_recording(tmp_path / "slow", replace(rec, imu_time=rec.imu_time * 1000))
        read_recording(tmp_path / "slow")
    folder = csv_folder(tmp_path, synthetic)
    (folder / "dvl.csv").unlink()
    with pytest.raises(RecordingError, match=r"no dvl.csv or dvl.csv.gz"):
        read_recording(folder)
    with pytest.raises(RecordingError, match="does not exist"):
        read_recording(tmp_path / "nowhere")
    with pytest.raises(RecordingError, match="does not exist"):
        read_snapir(tmp_path / "nowhere")


@pytest.mark.parametrize(
    ("mistake", "message"),
    [
        ("accel in g", r"imu: the mean specific force is (0\.99|1\.0)\d* m/s², not near gravity"),
        ("gyro in deg/s", r"imu: 1 % of the angular rates exceed .* rad/s, beyond any vehicle"),
        ("dvl in cm/s", r"dvl: its median speed .* m/s against the ground truth's"),
        ("imu gap", r"imu\.csv, row 3001: a gap of 2\.01 s after"),
    ],
)
def test_implausible_data_is_caught_before_filtering(tmp_path, synthetic, mistake, message):
    rec = synthetic.recording
    imu, imu_time, dvl = rec.imu.copy(), rec.imu_time.copy(), rec.dvl.copy()
    if mistake == "accel in g":
        imu[:, :3] /= 9.80665
    elif mistake == "gyro in deg/s":
        imu[:, 3:] = np.degrees(imu[:, 3:]) * 20  # a brisk turn, read as rad/s
    elif mistake == "dvl in cm/s":
        dvl *= 100
    else:
        imu_time[3000:] += 2.0
    write_recording(tmp_path / "bad", replace(rec, imu=imu, imu_time=imu_time, dvl=dvl))
    with pytest.raises(RecordingError, match=message):
        read_recording(tmp_path / "bad")


def test_two_files_for_one_stream_are_refused(tmp_path, synthetic):
    folder = csv_folder(tmp_path, synthetic)
    (folder / "imu.csv.gz").write_bytes(gzip.compress((folder / "imu.csv").read_bytes()))
    with pytest.raises(RecordingError, match=r"both imu\.csv and imu\.csv\.gz"):
        read_recording(folder)


def test_malformed_npz_gives_a_clear_error(tmp_path, synthetic):
    good = write_recording(tmp_path / "good.npz", synthetic.recording)
    arrays = dict(np.load(good))
    cases = {
        "missing": ({k: v for k, v in arrays.items() if k != "dvl"}, "needs arrays 'dvl'"),
        "pickled": ({**arrays, "gt": np.array([object()], dtype=object)}, "[gt]: an object array"),
        # The case: column names saved as an object array; named, with the fix.
        "names": (
            {**arrays, "imu_columns": arrays["imu_columns"].astype(object)},
            "[imu_columns]: an object array, which cannot be read without pickle (refused: "
            "loading it could run code); save it as an array of strings: "
            "np.array(names, dtype=str)",
        ),
        "bytes": (
            {**arrays, "dvl_columns": arrays["dvl_columns"].astype(bytes)},
            "[dvl_columns]: must be a 1-D array of strings, got |S",
        ),
        "shape": ({**arrays, "imu": arrays["imu"][:, :3]}, "must be a 2-D numeric array"),
        "nan": (
            {**arrays, "imu": np.where(np.arange(7) == 2, np.nan, arrays["imu"])},
            "row 1: 'acc_y [m/s^2]' is nan",
        ),
    }
    for name, (content, expected) in cases.items():
        path = tmp_path / f"{name}.npz"
        np.savez(path, **content)
        with pytest.raises(RecordingError, match=re.escape(expected)) as info:
            read_recording(path)
        assert str(path) in str(info.value)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(RecordingError, match="not a readable .npz"):
        read_recording(tmp_path / "junk.npz")


# ---------------------------------------------------------------- alignment


def test_clocks_are_estimated_and_the_truth_moved_to_the_imu(synthetic):
    rec = synthetic.recording
    al = estimate_alignment(rec, IMU_LEVER_ARM, DVL_LEVER_ARM)
    assert al.gt_clock.offset == pytest.approx(GT_CLOCK.offset, abs=0.01)
    assert al.gt_clock.scale == pytest.approx(GT_CLOCK.scale, abs=1e-4)
    assert al.dvl_clock.offset == pytest.approx(DVL_CLOCK.offset, abs=0.05)
    assert al.filter_lever_arm == pytest.approx(np.subtract(DVL_LEVER_ARM, IMU_LEVER_ARM))
    section = align(rec, al)
    # On the true clock the truth, moved to the IMU, is the trajectory's.
    # (the clocks of the simulation count from 0, the section's times from its epoch)
    e = rec.imu_time[0]
    exact = align(rec, replace(al, gt_clock=GT_CLOCK.since(e), dvl_clock=DVL_CLOCK.since(e)))
    assert exact.epoch == e
    traj = synthetic.trajectory
    idx = np.round((exact.truth_time + e) / traj.dt).astype(int)
    np.testing.assert_allclose(exact.truth_time + e, traj.time[idx], atol=1e-9)
    r_n, r_e = pronet.earth_radii(float(traj.lla[0, 0]))
    dp = (exact.truth_lla - traj.lla[idx]) * [r_n, r_e * np.cos(traj.lla[0, 0]), 1.0]
    assert np.abs(dp).max() < 1e-5  # metres
    np.testing.assert_allclose(exact.truth_vel, traj.vel_ned[idx], atol=1e-3)
    assert np.abs(section.truth_time - exact.truth_time).max() < 0.01


def test_alignment_makes_the_filter_measurably_better(synthetic):
    rec = synthetic.recording
    q = real.white_noise_q(rec.imu)
    metrics = {}
    for name, al in {
        "handled": estimate_alignment(rec, IMU_LEVER_ARM, DVL_LEVER_ARM),
        "stamps": Alignment(how="none"),
    }.items():
        section = align(rec, al)
        config = real.real_filter_config(al.filter_lever_arm)
        metrics[name] = real.run_section(section, pronet.Strategy.constant(q), config).metrics
    assert metrics["handled"].srmse < 0.02
    assert metrics["stamps"].srmse > 2 * metrics["handled"].srmse
    assert metrics["stamps"].final_horizontal > 2 * metrics["handled"].final_horizontal


def test_the_heading_ratio_compares_the_heading_error_with_its_sigma(synthetic):
    """``heading_ratio`` is the RMS of (yaw error / heading σ) at the truth rows: a truth
    turned by 10 σ in yaw reads about 10 more."""
    rec = synthetic.recording
    section = align(rec, estimate_alignment(rec, IMU_LEVER_ARM, DVL_LEVER_ARM))
    config = real.real_filter_config(section.alignment.filter_lever_arm)
    strategy = pronet.Strategy.constant(real.white_noise_q(rec.imu))
    run = real.run_section(section, strategy, config)
    assert 0 < run.metrics.heading_ratio < 3  # the filter's heading is honest here
    sigma = float(np.median(run.result.sigma[:, 8]))
    turned = replace(section, truth_rpy=section.truth_rpy + [0.0, 0.0, 10 * sigma])
    ratio = section_metrics(turned, run.result).heading_ratio
    assert 7 < ratio < 13, ratio


# ---------------------------------------------------------------- ProNet loop on recorded data


def test_q_schedule_instants_follow_the_ensemble_rule():
    imu = np.random.default_rng(1).normal(size=(1050, 6))
    t = 0.5 + np.arange(1, 1051) * 0.01
    seen = []

    class Recorder:
        def predict(self, windows):
            seen.append(windows.copy())
            return np.full((len(windows), 6), 2e-3)

    s = q_schedule(Recorder(), imu, t, prior_q=[1e-3] * 6, window=200, tuning_period=1.0)
    np.testing.assert_allclose(s.time, t[[199, 299, 399, 499, 599, 699, 799, 899, 999]])
    (windows,) = seen
    assert windows.dtype == np.float32 and windows.shape == (9, 6, 200)
    np.testing.assert_array_equal(windows[2], imu[200:400].T.astype(np.float32))
    assert s.clipped == 0 and s.non_finite == 0

    class Bad:
        def predict(self, windows):
            q = np.full((len(windows), 6), 3e-3)
            q[1, 0], q[2, 1] = np.nan, -1.0
            return q

    s = q_schedule(Bad(), imu, t, prior_q=[1e-3] * 6)
    assert s.q[1, 0] == 3e-3 and s.q[2, 1] == 1e-9  # previous kept; clipped
    assert (s.non_finite, s.clipped) == (1, 1)

    class Short:
        def predict(self, windows):
            return np.ones((len(windows), 5))

    with pytest.raises(ValueError, match="regressor: predict returned shape"):
        q_schedule(Short(), imu, t, prior_q=[1e-3] * 6)


def test_learned_row_with_a_constant_regressor_equals_the_constant_row(synthetic):
    section = align(synthetic.recording, estimate_alignment(synthetic.recording))
    q = real.white_noise_q(section.imu)
    config = real.real_filter_config((0.0, 0.0, 0.0))
    constant = real.run_section(section, pronet.Strategy.constant(q), config)
    learned = real.run_section(section, Learned(ConstantRegressor(q), q), config)
    np.testing.assert_array_equal(learned.result.sigma, constant.result.sigma)
    np.testing.assert_array_equal(learned.result.vel, constant.result.vel)
    doubled = real.run_section(
        section, Learned(ConstantRegressor(np.multiply(q, 2)), q), config
    )
    first = int(doubled.schedule.time[0] / 0.01) - 1
    late = doubled.result.time > doubled.schedule.time[0] + 1
    assert (doubled.result.sigma[late, 3] > constant.result.sigma[late, 3]).all()
    np.testing.assert_array_equal(
        doubled.result.sigma[: first - 100], constant.result.sigma[: first - 100]
    )


# ---------------------------------------------------------------- the CLI


@pytest.mark.slow
def test_pronet_real_writes_tables_and_plots(tmp_path, capsys):
    data = tmp_path / "data"
    for i in (1, 2):
        rec = synthetic_recording(seed=i, duration=70.0, name=f"run{i}").recording
        write_recording(data / f"run{i}.npz", rec)
    out = tmp_path / "out"
    argv = ["real", "--data", str(data), "--format", "generic", "--out", str(out), "--quiet"]
    argv += ["--dvl-lever-arm=" + ",".join(map(str, DVL_LEVER_ARM))]
    code = main(argv + ["--imu-lever-arm=" + ",".join(map(str, IMU_LEVER_ARM))])
    assert code == 0
    text = capsys.readouterr().out
    labels = ("constant (estimated q)", "mehra xi=5", "detrend net", "HCF-ensemble")
    for label in (*labels, "detvar", "adaptive"):
        assert label in text
    assert "stamps as given, no lever arms" in text and "inertial only, first 60 s" in text
    files = {p.name for p in out.iterdir()}
    assert {"table.md", "metrics.csv", "metrics.json", "config.json"} <= files
    for name in ("run1", "run2"):
        assert {f"track_{name}.png", f"velocity_error_{name}.png", f"q_{name}.png"} <= files
    metrics = json.loads((out / "metrics.json").read_text())
    aligned = [r for r in metrics if r["scenario"] in ("run1", "run2")]
    # the paper's seven rows, detvar, adaptive, the three grade models, the three variant
    # rows (R from the data, the DVL calibration states, both), inertial only
    assert sum(r["scenario"] == "run1" for r in aligned) == 16 and len(aligned) == 32
    for label in real.REAL_VARIANT_ROWS:
        assert label in text
    assert "DVL calibration: final estimate ± 1σ" in text
    header = (out / "metrics.csv").read_text().splitlines()[0]
    assert header == ",".join(RUN_COLUMNS)
    config = json.loads((out / "config.json").read_text())
    assert config["clocks"]["run1"]["gt"][0] == pytest.approx(GT_CLOCK.offset, abs=0.01)
    # The DVL noise of each section: the datasheet's used, both estimates reported (the
    # synthetic DVL's σ is 0.01 m/s; 70 rows say it to within a factor of two).
    noise = config["dvl_variance"]["run1"]
    assert config["dvl_noise"] == "datasheet" and noise["used"] == [0.02**2] * 3
    for key in ("second_difference", "matched", "matched_calibrated"):
        assert all(0.25e-4 < v < 4e-4 for v in noise[key]), (key, noise[key])
    # The calibrated rows' final DVL scale and mounting, with 1σ, per section.
    calibration = config["dvl_calibration"][f"run1: {real.DVL_CALIBRATION}"]
    assert len(calibration["scale_roll_pitch_yaw"]) == len(calibration["sigma"]) == 4
    # ... and the calibration the ground truth implies (this synthetic DVL is ideal)
    truth = config["dvl_calibration_from_truth"]["run1"]
    scale, sigma = truth["scale_roll_pitch_yaw"][0], truth["sigma"][0]
    assert truth["rows"] >= 60 and abs(scale) <= 3 * sigma < 0.01
    assert f"| run1 | {TRUTH_LABEL} |" in text
    assert "DVL noise 1σ, x / y / z [m/s]" in text
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]  # no leftovers
    assert main(argv) == 2  # the folder exists: refused, not overwritten
    capsys.readouterr()
    as_json = [*argv[:5], "--sections", "run2", "--out", str(tmp_path / "js"), "--json"]
    as_json += [argv[8], "--imu-lever-arm=" + ",".join(map(str, IMU_LEVER_ARM))]
    assert main(as_json) == 0
    printed = json.loads(capsys.readouterr().out)  # stdout: one JSON document
    assert printed["folder"] == str(tmp_path / "js")
    assert {r["scenario"].split(" ")[0] for r in printed["metrics"]} == {"run2"}
    # --no-plots: the same tables and metrics, no figures
    bare = tmp_path / "bare"
    arm = "--imu-lever-arm=" + ",".join(map(str, IMU_LEVER_ARM))
    assert main([*argv[:5], "--out", str(bare), "--quiet", "--no-plots", arm, argv[8]]) == 0
    assert not list(bare.glob("*.png"))
    assert (bare / "metrics.csv").read_text() == (out / "metrics.csv").read_text()


def test_pronet_real_runs_either_formulation(tmp_path, capsys):
    """``--formulation classic`` and ``--covariance-step`` reach every filter of the run
    (the config records them, the numbers move), the default is the invariant one at
    every IMU sample, and a bad name or step is refused."""
    data = tmp_path / "data"
    write_recording(data / "run1.npz", synthetic_recording(seed=1, duration=70.0).recording)
    arm = "--imu-lever-arm=" + ",".join(map(str, IMU_LEVER_ARM))
    argv = ["real", "--data", str(data), "--format", "generic", "--quiet", "--no-plots"]
    argv += ["--no-models", arm, "--dvl-lever-arm=" + ",".join(map(str, DVL_LEVER_ARM))]
    metrics = {}
    runs = (
        ("default", [], 'formulation="invariant", covariance_step=0'),
        ("classic", ["--formulation", "classic"], 'formulation="classic"'),
        ("step", ["--covariance-step", "0.2"], 'formulation="invariant", covariance_step=0.2'),
    )
    for name, extra, recorded in runs:
        out = tmp_path / name
        assert main([*argv, "--out", str(out), *extra]) == 0
        config = json.loads((out / "config.json").read_text())
        assert recorded in config["filter"]
        metrics[name] = [r["srmse"] for r in json.loads((out / "metrics.json").read_text())]
    assert len(metrics["default"]) == len(metrics["classic"]) == len(metrics["step"]) > 5
    assert metrics["default"] != metrics["classic"]
    assert metrics["default"] != metrics["step"]
    capsys.readouterr()
    with pytest.raises(SystemExit) as refused:
        main([*argv, "--out", str(tmp_path / "bad"), "--formulation", "psi"])
    assert refused.value.code == 2
    assert "--formulation: invalid choice: 'psi'" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()
    assert main([*argv, "--out", str(tmp_path / "bad"), "--covariance-step", "-0.1"]) != 0
    assert "covariance_step: must be a finite number of seconds >= 0" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_sections_run_side_by_side_give_the_numbers_of_one_thread(synthetic):
    section = align(synthetic.recording, estimate_alignment(synthetic.recording))
    stamped = align(synthetic.recording, alignment.Alignment(how="none"))
    other = replace(section, name="copy")
    pairs = [(section, stamped), (other, stamped)]
    one = real.run_sections(pairs, {}, 1.0, threads=1)
    two = real.run_sections(pairs, {}, 1.0, threads=2)
    assert [r.label for r in one.runs] == [r.label for r in two.runs]
    for a, b in zip(one.runs + one.inertial, two.runs + two.inertial, strict=True):
        assert a.section == b.section
        np.testing.assert_array_equal(a.result.vel, b.result.vel)
    assert one.q_estimated == two.q_estimated
    assert list(two.constants) == [section.name, "copy"]  # in the order given


def test_pronet_real_refuses_bad_data_before_any_work(tmp_path, capsys):
    data = tmp_path / "data"
    write_recording(data / "run1", synthetic_recording(seed=1, duration=30.0).recording)
    (data / "run1" / "imu.csv").write_text("time [s];acc_x\n")
    out = tmp_path / "out"
    argv = ["real", "--data", str(data), "--format", "generic", "--out", str(out)]
    assert main([*argv, "--imu-lever-arm=0,0,0", "--dvl-lever-arm=0,0,0"]) == 2
    assert "comma-separated" in capsys.readouterr().err
    assert not out.exists()


# ---------------------------------------------------------------- the Snapir AUV data


def test_recorded_data_never_enters_the_project():
    """The data is read from where it lies; no recording file is in the tree."""
    tracked = [
        p
        for top in ("python", "tests", "docs", "benches", "rust")
        for p in (REPO / top).rglob("*")
        if p.name in {"imu.csv.gz", "dvl.csv.gz", "gt.csv.gz"} or "snapir" in p.name.lower()
    ]
    assert tracked == []


@pytest.mark.slow
@pytest.mark.skipif(not SNAPIR.is_dir(), reason="the Snapir data is not on this machine")
def test_snapir_accuracy_matches_a_standard_ekf():
    """Constant Q on sections 1–11: mean velocity SRMSE ≤ 0.047 m/s and mean final
    horizontal error ≤ 2.5 m (the open-source reference reaches 0.047 m/s and 2.4 m);
    the same runs on the stamps as given, without lever arms, are measurably worse."""
    loaded = alignment.load_snapir_sections(SNAPIR)
    assert len(loaded) == 11
    handled, stamped = [], []
    for aligned, as_stamped in loaded:
        strategy = pronet.Strategy.constant(real.white_noise_q(aligned.imu))
        for section, into in ((aligned, handled), (as_stamped, stamped)):
            config = real.real_filter_config(section.alignment.filter_lever_arm)
            into.append(real.run_section(section, strategy, config).metrics)
    srmse = np.mean([m.srmse for m in handled])
    final = np.mean([m.final_horizontal for m in handled])
    assert srmse <= 0.047, [round(m.srmse, 4) for m in handled]
    assert final <= 2.5, [round(m.final_horizontal, 2) for m in handled]
    assert np.mean([m.srmse for m in stamped]) > 2 * srmse
    assert np.mean([m.final_horizontal for m in stamped]) > 2 * final


@pytest.mark.slow
@pytest.mark.skipif(not SNAPIR.is_dir(), reason="the Snapir data is not on this machine")
def test_snapir_r_from_the_data_makes_every_section_consistent():
    """Sections 1–11: with the DVL noise matched to each section's innovations, the
    constant row's mean NIS lies between 1.5 and 6 on every section (with the
    datasheet's 0.02 m/s it spans about 0.6–25), with or without the DVL calibration
    states, and the matching converges. The accuracy of the rows is pinned by the
    accuracy gate, whatever it is."""
    for aligned, _ in alignment.load_snapir_sections(SNAPIR):
        plan = real.plan_section(aligned, {}, 1.0, dvl_noise="data")
        first = next(iter(plan.strategies.values()))
        noise = plan.dvl_noise
        assert noise.matched.converged and noise.matched_calibrated.converged, aligned.name
        for config in (plan.config, plan.variants[real.BOTH]):
            run = real.run_section(aligned, first, config)
            assert 1.5 <= run.metrics.mean_nis <= 6.0, (aligned.name, run.metrics.mean_nis)


@pytest.mark.skipif(not SNAPIR.is_dir(), reason="the Snapir data is not on this machine")
def test_snapir_ground_truth_sees_a_dvl_within_tenths_of_a_percent_and_degree():
    """Sections 1–11, no filter: the DVL against the post-processed truth (docs/real.md)
    is within 0.6 % in scale and 0.5° in pitch and yaw on every section, each to within
    0.25 % and 0.2° (1σ), with residuals under 0.1 m/s. The filter's calibration states,
    which land far from these, are judged against them there."""
    for aligned, _ in alignment.load_snapir_sections(SNAPIR):
        fit = truth_calibration(aligned)
        k, _, pitch, yaw = fit.estimate
        assert abs(k) < 0.006 and fit.sigma[0] < 0.0025, (aligned.name, fit)
        assert max(abs(pitch), abs(yaw)) < np.radians(0.5), (aligned.name, fit)
        assert max(fit.sigma[2], fit.sigma[3]) < np.radians(0.2), (aligned.name, fit)
        assert fit.rms_residual < 0.1, (aligned.name, fit)


@pytest.mark.slow
@pytest.mark.skipif(not SNAPIR.is_dir(), reason="the Snapir data is not on this machine")
def test_the_regressors_for_real_sensor_grades_hold_the_constant_row_on_snapir():
    """Sections 1–11: each shipped regressor (trained for real sensor grades) keeps the
    mean SRMSE within 1.05x and the mean final horizontal error within 1.10x of the
    constant row's (the paper's regressors lose 2–7x here)."""
    from pronet.learn import models

    regressors = {k: models.load(k) for k in models.GRADE_MODELS}
    metrics: dict[str, list] = {}
    for aligned, _ in alignment.load_snapir_sections(SNAPIR):
        q = real.white_noise_q(aligned.imu)
        config = real.real_filter_config(aligned.alignment.filter_lever_arm)
        rows = real.real_strategies(q, regressors, 1.0)
        for label in ("constant (estimated q)", *(f"{n} (grades)" for n in _GRADE_LABELS)):
            run = real.run_section(aligned, rows[label], config, label=label)
            metrics.setdefault(label, []).append(run.metrics)
    const = metrics.pop("constant (estimated q)")
    srmse, final = np.mean([m.srmse for m in const]), np.mean([m.final_horizontal for m in const])
    for label, ms in metrics.items():
        assert np.mean([m.srmse for m in ms]) <= 1.05 * srmse, label
        assert np.mean([m.final_horizontal for m in ms]) <= 1.10 * final, label


_GRADE_LABELS = ("HCF-ensemble", "baseline net", "detrend net")


def test_run_filter_checks_its_q_schedule(synthetic):
    section = align(synthetic.recording, Alignment(how="none"))
    i0 = passes.start_index(section)
    args = dict(
        imu=section.imu[100:400],
        imu_time=section.imu_time[100:400],
        dvl=section.dvl[:0],
        dvl_time=section.dvl_time[:0],
        t0=section.imu_time[99],
        lla0=section.truth_lla[i0],
        vel0=section.truth_vel[i0],
        rpy0=section.truth_rpy[i0],
    )
    q = [1e-4] * 6
    with pytest.raises(ValueError, match="q_time: q_time and q go together"):
        pronet.run_filter(**args, strategy=pronet.Strategy.external(q), q_time=[2.0])
    with pytest.raises(ValueError, match="strategy: a q schedule needs an external strategy"):
        pronet.run_filter(**args, strategy=pronet.Strategy.constant(q), q_time=[2.0], q=[q])
    with pytest.raises(ValueError, match=r"q: expected shape \(n, 6\)"):
        pronet.run_filter(**args, strategy=pronet.Strategy.external(q), q_time=[2.0], q=q)
    with pytest.raises(ValueError, match="q: row 0 must be finite and >= 0"):
        pronet.run_filter(
            **args, strategy=pronet.Strategy.external(q), q_time=[2.0], q=[[np.nan] * 6]
        )


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    kind=st.sampled_from(["imu", "dvl", "gt"]),
    cut=st.floats(0.0, 1.0),
    noise=st.binary(max_size=64),
)
@pytest.mark.slow
def test_hostile_files_read_or_raise_naming_the_file(tmp_path_factory, synthetic, kind, cut, noise):
    """A CSV truncated anywhere and followed by arbitrary bytes: read correctly, or a
    RecordingError (a ValueError) naming the file; never another exception."""
    folder = csv_folder(tmp_path_factory.mktemp("hostile"), synthetic)
    path = folder / f"{kind}.csv"
    data = path.read_bytes()
    path.write_bytes(data[: int(cut * len(data))] + noise)
    try:
        rec = read_recording(folder)
    except RecordingError as exc:
        assert f"{kind}.csv" in str(exc), str(exc)
        return
    for arr in (rec.imu, rec.dvl, rec.gt_lla):
        assert np.isfinite(arr).all()


def test_the_fast_csv_path_reads_what_the_careful_reader_reads(tmp_path, synthetic):
    from pronet.recorded import recordings

    folder = csv_folder(tmp_path, synthetic)
    path = folder / "imu.csv"
    text = path.read_text()
    width = len(text.partition("\n")[0].split(","))
    fast = recordings._parse_numbers(text, width)
    assert fast is not None  # a plain table: pandas' parser read it
    lines = text.splitlines()
    careful = np.array([[float(c) for c in line.split(",")] for line in lines[1:] if line])
    assert np.array_equal(fast.view(np.int64), careful.view(np.int64))  # bit for bit
    # anything else goes to the careful reader: a short row (named), an extra text
    # column the file does not need (read as before)
    assert recordings._parse_numbers("a,b\n1,2\n  \n3,4\n", 2) is None  # a line of blanks
    edit_line(path, 4, lambda s: s[: s.rindex(",")])
    with pytest.raises(RecordingError, match=r"imu.csv, row 4: has 6 fields, the header 7"):
        read_recording(folder)
    path.write_text("\n".join([lines[0] + ",note"] + [f"{s},ok" for s in lines[1:]]) + "\n")
    assert recordings._parse_numbers(path.read_text(), width + 1) is None
    np.testing.assert_array_equal(
        read_recording(folder).imu, read_recording(csv_folder(tmp_path / "b", synthetic)).imu
    )


def test_a_misspelt_section_name_is_refused_not_dropped(tmp_path, synthetic):
    data = tmp_path / "data"
    for name in ("run1", "run2"):
        write_recording(data / f"{name}.npz", synthetic.recording)
    assert [p.stem for p in real.select_sections(data, ["run2"])] == ["run2"]
    with pytest.raises(ValueError, match=r"^--sections: no section named rn2 in .*; there are "):
        real.select_sections(data, ["run1", "rn2"])


@pytest.mark.slow
def test_a_failing_section_is_reported_and_the_others_still_run(tmp_path, capsys):
    """One section's accelerations in g (caught while reading): ``pronet real`` runs the
    other, exits 0, and reports the failure on stderr, in table.md, metrics.csv,
    metrics.json and config.json; when every section fails nothing is written."""
    data = tmp_path / "data"
    good = synthetic_recording(seed=1, duration=70.0, name="good").recording
    write_recording(data / "good.npz", good)
    in_g = good.imu / np.r_[[9.80665] * 3, [1.0] * 3]
    write_recording(data / "bad.npz", replace(good, name="bad", imu=in_g))
    argv = ["real", "--data", str(data), "--format", "generic", "--no-models", "--no-plots"]
    argv += ["--imu-lever-arm=0,0,0", "--dvl-lever-arm=0,0,0"]
    out = tmp_path / "out"
    assert main([*argv, "--out", str(out), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert re.search(r"^pronet: section bad: .*imu: the mean specific force", err, re.M), err
    table = (out / "table.md").read_text()
    assert "### Sections not run" in table and "| bad | " in table
    assert "mean over 1 sections" in table
    config = json.loads((out / "config.json").read_text())
    assert config["sections"] == ["good"] and list(config["failed_sections"]) == ["bad"]
    rows = (out / "metrics.csv").read_text().splitlines()
    lines = [line for line in rows if line.startswith("bad,")]
    records = json.loads((out / "metrics.json").read_text())
    strategies = [r["strategy"] for r in records if r["scenario"] == "good"]
    n_rows = sum(not s.startswith("inertial only") for s in strategies)  # one per strategy
    assert len(lines) == n_rows > 0 and all("mean specific force" in line for line in lines)
    failed = [r for r in records if r["scenario"] == "bad"]
    assert all(r["failed_runs"] == 1 and r["srmse"] is None for r in failed)
    # every section failing: one line, exit 2, no folder
    none = tmp_path / "none"
    assert main([*argv, "--sections", "bad", "--out", str(none), "--quiet"]) == 2
    assert re.fullmatch(r"pronet: section bad: .*\n", capsys.readouterr().err)
    assert not none.exists()


def test_a_section_failing_in_the_filter_is_left_out(synthetic, monkeypatch):
    section = align(synthetic.recording, estimate_alignment(synthetic.recording))
    stamped = align(synthetic.recording, alignment.Alignment(how="none"))
    real_evaluate = real.evaluate_section

    def fails_on_copy(aligned, *args, **kwargs):
        if aligned.name == "copy":
            raise ValueError("numerical failure: S is not positive definite")
        return real_evaluate(aligned, *args, **kwargs)

    monkeypatch.setattr(real, "evaluate_section", fails_on_copy)
    pairs = [(replace(section, name="copy"), stamped), (section, stamped)]
    done = real.run_sections(pairs, {}, 1.0, threads=2, failed={"unread": "imu: empty"})
    reason = "numerical failure: S is not positive definite"
    assert done.failed == {"unread": "imu: empty", "copy": reason}
    assert [a.name for a, _ in done.sections] == [section.name]
    assert {r.section for r in done.runs} == {section.name}


def test_a_failing_section_is_named(synthetic, monkeypatch):
    section = align(synthetic.recording, estimate_alignment(synthetic.recording))
    stamped = align(synthetic.recording, alignment.Alignment(how="none"))

    def fails(*args, **kwargs):
        raise ValueError("numerical failure: S is not positive definite")

    monkeypatch.setattr(real, "evaluate_section", fails)
    with pytest.raises(ValueError, match=r"^section synthetic: numerical failure"):
        real.run_sections([(section, stamped)], {}, 1.0, threads=1)


@pytest.mark.parametrize(
    ("option", "value"), [("--dvl-lever-arm", "1e9,0,0"), ("--imu-lever-arm", "0,0,-2000")]
)
def test_a_lever_arm_beyond_any_vehicle_is_named_as_one(tmp_path, capsys, option, value):
    """A lever arm of 1e9 m was reported as a latitude beyond the poles: now the option
    is named, in metres, before any section is read."""
    (tmp_path / "data").mkdir()
    out = tmp_path / "out"
    argv = ["real", "--data", str(tmp_path / "data"), "--format", "generic", "--out", str(out)]
    assert main([*argv, f"{option}={value}"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"pronet: {option}: must be within ±1000 m (no vehicle is longer)")
    assert err.count("\n") == 1 and not out.exists()


@pytest.mark.slow
def test_pronet_real_smooth_adds_a_smoothed_row_after_each_strategy_row(tmp_path, capsys):
    """``--smooth``: each strategy and variant row is followed by its smoothed one,
    scored at the same ground-truth rows (the final error the filter's: nothing comes
    after the last epoch; the rows with the DVL calibration states smoothed over all 19,
    their calibration too); over the default covariance step (0.1 s, the smoother's grid
    its closes) and at every IMU sample."""
    from pronet.recorded.passes import smoothed_run

    data = tmp_path / "data"
    write_recording(data / "run1.npz", synthetic_recording(seed=1, duration=70.0).recording)
    out = tmp_path / "out"
    arms = ["--dvl-lever-arm=" + ",".join(map(str, DVL_LEVER_ARM)),
            "--imu-lever-arm=" + ",".join(map(str, IMU_LEVER_ARM))]  # fmt: skip
    argv = ["real", "--data", str(data), "--format", "generic", "--quiet", "--no-models", *arms]
    assert main([*argv, "--out", str(out), "--smooth"]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    rows = {r["strategy"]: r for r in metrics if r["scenario"] == "run1"}
    plain = [label for label in rows if not label.endswith(", smoothed")]
    others = {*real.REAL_VARIANT_ROWS, f"inertial only, first {passes.INERTIAL_SECONDS:g} s"}
    strategies = [label for label in plain if label not in others]
    assert strategies and all(f"{label}, smoothed" in rows for label in strategies)
    variants = [label for label in real.REAL_VARIANT_ROWS if label in rows]
    assert variants == list(real.REAL_VARIANT_ROWS)
    assert all(f"{label}, smoothed" in rows for label in variants)
    calibrated = rows[real.DVL_CALIBRATION]
    assert rows[f"{real.DVL_CALIBRATION}, smoothed"]["srmse"] != calibrated["srmse"]
    first = rows["constant (estimated q)"]
    smoothed = rows["constant (estimated q), smoothed"]
    assert smoothed["srmse"] != first["srmse"]
    assert smoothed["final_horizontal_error"] == pytest.approx(
        first["final_horizontal_error"], rel=1e-6
    )
    assert json.loads((out / "config.json").read_text())["smooth"] is True
    every = tmp_path / "every"
    assert main([*argv, "--out", str(every), "--smooth", "--covariance-step", "0"]) == 0
    per_sample = {r["strategy"]: r for r in json.loads((every / "metrics.json").read_text())}
    assert per_sample["constant (estimated q), smoothed"]["srmse"] == pytest.approx(
        smoothed["srmse"], rel=0.05
    )
    # A row of a pass run without smoothing has no smoothed twin.
    aligned, _ = alignment.load_section(
        data / "run1.npz", "generic", imu_lever_arm=IMU_LEVER_ARM, dvl_lever_arm=DVL_LEVER_ARM
    )
    done = real.run_section(aligned, pronet.Strategy.constant([1e-4] * 6), pronet.FilterConfig())
    with pytest.raises(ValueError, match="was run without smooth=True"):
        smoothed_run(aligned, done)
