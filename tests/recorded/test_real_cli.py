"""``pronet real``: its tables and plots, formulations, sections side by side, smoothed
rows, and what it refuses or reports before and during the work."""

from __future__ import annotations

import json
import re
from dataclasses import replace

import numpy as np
import pytest

import pronet
from pronet.cli import main
from pronet.recorded import alignment, passes, real
from pronet.recorded.alignment import (
    align,
    estimate_alignment,
)
from pronet.recorded.recordings import (
    write_recording,
)
from pronet.recorded.tables import TRUTH_LABEL
from pronet.results import RUN_COLUMNS

from synthetic_recording import (
    DVL_LEVER_ARM,
    GT_CLOCK,
    IMU_LEVER_ARM,
    synthetic_recording,
    with_aiding,
)


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
    # the DVL innovations' whiteness, per section and row: a number per cell
    table = (out / "table.md").read_text()
    white = table.split("DVL innovations' lag-1 autocorrelation\n")[-1].split("\n\n")[0]
    rows = [line for line in white.splitlines() if line.startswith("| run")]
    cells = [c.strip() for line in rows for c in line.split("|")[2:-1]]
    assert len(cells) == 2 * 15 and all(re.fullmatch(r"[+-]0\.\d\d", c) for c in cells)
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
    assert "covariance_step: must be a finite number of seconds from 0" in capsys.readouterr().err
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
    assert "mean over 1 section\n" in table  # one section, not "1 sections"
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


def _real_quietly(tmp_path, rec):
    """``pronet real`` (no models, no plots, quiet) on ``rec`` written as section run1,
    the synthetic recording's lever arms; its result folder."""
    data, out = tmp_path / "data", tmp_path / "out"
    write_recording(data / "run1.npz", rec)
    arm = "--imu-lever-arm=" + ",".join(map(str, IMU_LEVER_ARM))
    argv = ["real", "--data", str(data), "--format", "generic", "--quiet", "--no-plots"]
    argv += ["--no-models", arm, "--dvl-lever-arm=" + ",".join(map(str, DVL_LEVER_ARM))]
    assert main([*argv, "--out", str(out)]) == 0
    return out


def test_pronet_real_says_which_stream_the_filters_know_is_wrong(tmp_path, capsys):
    """Every fix 300 m north of the vehicle (inside the readers' 1 km check): each
    section's fix stream is named once on stderr with its NIS and causes, the rows that
    share it counted, and the same lines in table.md and config.json."""
    rec = with_aiding(synthetic_recording(seed=4), seed=4, fix_every=10.0)
    assert rec.fixes is not None
    north = pronet.lla_from_ned(np.tile([300.0, 0.0, 0.0], (len(rec.fixes.time), 1)),
                                rec.fixes.lla[0])  # fmt: skip
    moved = rec.fixes.lla + (north - rec.fixes.lla[0]) * [1.0, 1.0, 0.0]
    out = _real_quietly(tmp_path, replace(rec, fixes=replace(rec.fixes, lla=moved)))
    err = capsys.readouterr().err
    notes = json.loads((out / "config.json").read_text())["notes"]
    fix = [n for n in notes if "fix: mean NIS" in n]  # the sensor, as navigate names it
    assert (
        len(fix) == 1 and fix[0].startswith("section run1: fix: mean NIS") and " rows: " in fix[0]
    )
    assert "the antenna's lever arm" in fix[0] and f"pronet: {fix[0]}" in err
    assert fix[0] in (out / "table.md").read_text()


def test_pronet_real_says_which_row_never_filled_its_window(tmp_path, capsys):
    """A 60 s section with 61 DVL readings, two of them after the IMU's last sample: the
    adaptive row's window of 60 could fill (it runs), but the pass accepts 59, so the row
    is the constant one under another name; its pass runs with ``warn=False`` and
    nothing said so. Now one line on stderr, in table.md and in config.json's notes."""
    rec = synthetic_recording(seed=1, duration=60.0).recording
    late = rec.dvl_time[-1] + np.array([5.0, 6.0])
    rec = replace(
        rec,
        dvl_time=np.append(rec.dvl_time, late),
        dvl=np.vstack([rec.dvl, rec.dvl[-2:]]),
    )
    out = _real_quietly(tmp_path, rec)
    err = capsys.readouterr().err
    config = json.loads((out / "config.json").read_text())
    assert "adaptive" not in config["rows_not_run"].get("run1", {})
    (line,) = [n for n in config["notes"] if "never filled" in n]
    assert line == (
        "section run1: adaptive's window of 60 velocity updates was never filled (59 "
        "accepted in the pass): it ran on its prior q throughout, as a constant strategy "
        "would; a window shorter than the pass's updates adapts (row adaptive; 1 of 9 rows: "
        "adaptive)"
    )
    assert f"pronet: {line}\n" in err and line in (out / "table.md").read_text()
