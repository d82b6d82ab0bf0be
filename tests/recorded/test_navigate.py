"""``pronet navigate`` on a simulated MEMS survey whose truth is kept outside the
recording (``tests/mission_recording.py``): one command on a bag without truth writes
the trajectory, the track, an odometry bag and the report; the accuracy and consistency
of the data-initialised filter with fixes, with a compass alone, against the truth-
initialised one; the lever arms of the depth sensor and the fix antenna; the files read
back; and, on a recording with truth, the same score as ``pronet real``'s row."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from mission_recording import LeverArms as MissionArms
from mission_recording import (
    Mission,
    simulate_mission,
    write_generic,
    write_mission_bag,
    write_vehicle_file,
)

import pronet
from pronet.recorded.initialinputs import GivenState
from pronet.recorded.navigate import (
    LeverArms,
    NavigateOptions,
    lever_arms,
    navigate_recording,
)
from pronet.recorded.solution import Navigation, Solution
from pronet.recorded.vehicle import load_vehicle

MINUTES_FAST = 6.0
MINUTES = 22.0


def _errors(solution: Solution, m: Mission) -> tuple[np.ndarray, np.ndarray]:
    """The solution's NED position error [m] and heading error [rad] against the
    mission's truth at the same stamps (the truth at every IMU epoch)."""
    stamps = solution.epoch + solution.time
    k = np.clip(np.searchsorted(m.truth.time, stamps - 1e-6), 0, len(m.truth.time) - 1)
    # every epoch an IMU sample's, the first (the initial state's time) within a step
    assert np.abs(m.truth.time[k] - stamps)[1:].max() < 1e-5
    origin = m.truth.lla[0]
    ned = pronet.local_ned(solution.lla, origin) - pronet.local_ned(m.truth.lla[k], origin)
    yaw = np.angle(np.exp(1j * (solution.rpy[:, 2] - m.truth.rpy[k, 2])))
    return ned, yaw


def _horizontal_rms(solution: Solution, m: Mission) -> float:
    ned, _ = _errors(solution, m)
    return float(np.sqrt(np.mean(ned[:, 0] ** 2 + ned[:, 1] ** 2)))


def _within_3_sigma(solution: Solution, m: Mission) -> tuple[float, float]:
    """The shares of epochs whose position (every axis) and heading lie within 3σ."""
    ned, yaw = _errors(solution, m)
    position = np.all(np.abs(ned) <= 3 * solution.sigma[:, :3], axis=1).mean()
    return float(position), float(np.mean(np.abs(yaw) <= 3 * solution.sigma[:, 8]))


def _navigate(folder: Path, vehicle: Path, **options) -> Navigation:
    tuning = load_vehicle(vehicle)
    opts = NavigateOptions(surface_depth=tuning.surface_depth or 0.0, **options)
    return navigate_recording(folder, "generic", tuning, lever_arms(tuning), opts)


@pytest.fixture(scope="module")
def short() -> Mission:
    return simulate_mission(0, minutes=MINUTES_FAST)


@pytest.mark.parametrize("storage", ["rosbag1", pytest.param("mcap", marks=pytest.mark.slow)])
def test_one_command_on_a_bag_without_truth_writes_the_files(tmp_path, short, storage) -> None:
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra")
    from pronet.cli import main

    bag = tmp_path / ("mission.bag" if storage == "rosbag1" else "mission")
    _, topics = write_mission_bag(short, bag, storage)
    assert topics.truth is None
    out = tmp_path / f"out-{storage}"
    code = main([
        "navigate", "--data", str(bag), "--format", "bag", "--depth-topic", str(topics.depth),
        "--fix-topic", str(topics.fix), "--heading-topic", topics.imu, "--filter",
        str(write_vehicle_file(tmp_path, short)), "--out", str(out), "--no-plots", "--quiet",
    ])  # fmt: skip
    assert code == 0
    written = {p.name for p in out.iterdir()}
    odometry = "odometry.bag" if storage == "rosbag1" else "odometry"
    assert {"trajectory.csv", "track.geojson", "report.md", "config.json", odometry} <= written
    config = json.loads((out / "config.json").read_text())
    assert config["streams_used"] == {"dvl": True, "depth": True, "fix": True, "heading": True}
    # the surface pressure measured beside the fixes at the surface: 101,900 Pa
    assert config["surface_pressure"]["pa"] == pytest.approx(short.surface_pressure, abs=100)
    report = (out / "report.md").read_text()
    assert "levelled" in report and "heading stream" in report


def test_the_files_read_back_with_the_solutions_sigma(tmp_path, short) -> None:
    folder = write_generic(short, tmp_path / "mission")
    nav = _navigate(folder, write_vehicle_file(tmp_path, short))
    from pronet.recorded.export import write_all

    write_all(nav, tmp_path / "out", figures=False)
    table = pd.read_csv(tmp_path / "out" / "trajectory.csv")
    for solution in nav.solutions:
        rows = table[table["solution"] == solution.label]
        assert len(rows) == len(solution.time)
        np.testing.assert_allclose(rows["sigma_n [m]"], solution.sigma[:, 0], rtol=1e-12)
        np.testing.assert_allclose(rows["sigma_d [m]"], solution.sigma[:, 2], rtol=1e-12)
        np.testing.assert_allclose(rows["lat [deg]"], np.degrees(solution.lla[:, 0]), rtol=1e-12)
    track = json.loads((tmp_path / "out" / "track.geojson").read_text())
    assert track["type"] == "FeatureCollection"
    lines = [f for f in track["features"] if f["geometry"]["type"] == "LineString"]
    assert {f["properties"]["solution"] for f in lines} == {"forward", "smoothed"}
    lon, lat = lines[0]["geometry"]["coordinates"][0]
    assert lon == pytest.approx(np.degrees(nav.forward.lla[0, 1]), abs=1e-9)
    assert lat == pytest.approx(np.degrees(nav.forward.lla[0, 0]), abs=1e-9)


@pytest.mark.slow
def test_lever_arms_of_a_metre_are_needed_and_flagged_when_left_out(tmp_path) -> None:
    """The depth sensor and the fix antenna 1 m from the IMU each: told, the position
    within 3σ at ≥ 95 % of epochs; left out, the report's NIS flags both (over the 22
    minutes: over 6 the fixes' NIS does not see 0.8 m against their 1.5 m; and a depth
    sensor's arm straight down is a height offset no NIS can see, its forward part
    shows as the vehicle pitches)."""
    arms = MissionArms(depth=(0.8, 0.0, 0.6), fix=(0.8, 0.0, -0.6))
    m = simulate_mission(1, minutes=MINUTES, lever_arms=arms)
    folder = write_generic(m, tmp_path / "mission")
    told = _navigate(folder, write_vehicle_file(tmp_path, m))
    position, _ = _within_3_sigma(told.forward, m)
    assert position >= 0.95, position
    assert not any(r.flag for r in told.streams if r.name in ("depth", "fix"))
    untold = _navigate(folder, write_vehicle_file(tmp_path, m, arms=False))
    flags = {r.name: r.flag for r in untold.streams}
    for stream in ("depth", "fix"):
        assert flags[stream].startswith(f"{stream}: mean NIS "), flags
        assert "lever arm" in flags[stream]
        assert any(n.startswith(f"{stream}: no lever arm given") for n in untold.notes)
    assert _within_3_sigma(untold.forward, m)[0] < 0.95


def test_a_recording_with_truth_scores_as_pronet_real(tmp_path, short, capsys) -> None:
    """The same tuning, the truth's first row as start: navigate's score of the filter is
    pronet real's constant row's, number for number."""
    from pronet.recorded.alignment import load_section
    from pronet.recorded.passes import run_section
    from pronet.recorded.real import plan_section

    folder = write_generic(short, tmp_path / "mission", truth=True)
    vehicle = load_vehicle(write_vehicle_file(tmp_path, short, arms=False))
    arms = LeverArms(dvl=vehicle.dvl_lever_arm)
    opts = NavigateOptions(init="truth", smooth=False, use_heading=False, surface_offset=0.0)
    nav = navigate_recording(folder, "generic", vehicle, arms, opts)
    section, _ = load_section(folder, "generic", imu_lever_arm=(0.0, 0.0, 0.0),
                              dvl_lever_arm=vehicle.dvl_lever_arm, read_heading=False)  # fmt: skip
    plan = plan_section(section, {}, 1.0, base=vehicle.base)
    row = run_section(section, next(iter(plan.strategies.values())), plan.config)
    assert nav.score is not None
    assert nav.score["forward"] == dataclasses.asdict(row.metrics)
    # the same by the command: its JSON result holds the score
    from pronet.cli import main

    vehicle_file = write_vehicle_file(tmp_path, short, arms=False)
    code = main([
        "navigate", "--data", str(folder), "--filter", str(vehicle_file), "--init", "truth",
        "--surface-offset", "0", "--no-heading", "--no-smooth", "--no-plots", "--json",
        "--out", str(tmp_path / "out"),
    ])  # fmt: skip
    assert code == 0
    printed = json.loads(capsys.readouterr().out)
    # JSON has no NaN: the share with the truth's own error (none stated here) is null
    stated = {k: v for k, v in nav.score["forward"].items() if v == v}
    assert printed["score"]["forward"].pop("velocity_3sigma_truth") is None
    assert printed["score"]["forward"] == pytest.approx(stated, rel=1e-15)


@pytest.mark.slow
def test_a_22_minute_survey_with_fixes_navigates_to_decimetres(tmp_path) -> None:
    """Fixes at 1 Hz (σ 1.5 m), the compass, from the data alone: forward horizontal RMS
    ≤ 0.5 m, smoothed ≤ 0.25 m, heading within 3σ at ≥ 95 % of epochs; and within 10 % of
    the truth-initialised pass, consistent (position within 3σ at ≥ 95 %)."""
    m = simulate_mission(0, minutes=MINUTES)
    folder = write_generic(m, tmp_path / "mission", truth=True)
    vehicle = write_vehicle_file(tmp_path, m)
    nav = _navigate(folder, vehicle)
    assert nav.smoothed is not None
    forward, smoothed = _horizontal_rms(nav.forward, m), _horizontal_rms(nav.smoothed, m)
    assert forward <= 0.5 and smoothed <= 0.25, (forward, smoothed)
    position, heading = _within_3_sigma(nav.forward, m)
    assert heading >= 0.95 and position >= 0.95, (position, heading)
    truth = _navigate(folder, vehicle, init="truth")
    assert forward <= 1.1 * _horizontal_rms(truth.forward, m), (forward, truth)


@pytest.mark.slow
def test_a_compass_without_fixes_holds_the_heading_and_halves_the_drift(tmp_path) -> None:
    """No fixes, a 1° compass: heading within 3σ at ≥ 95 % of epochs and the final
    horizontal error at most half the DVL-only one."""
    m = simulate_mission(0, minutes=MINUTES)
    folder = write_generic(m, tmp_path / "mission")
    vehicle = write_vehicle_file(tmp_path, m)
    # the start needs a position and, DVL-only, a heading (a MEMS gyro cannot
    # gyrocompass): both runs are given them, as a surface fix and a compass would
    given = GivenState(
        lla=m.truth.lla[0], lla_sigma=(1.5,) * 3, heading=float(m.truth.rpy[0, 2]),
        heading_sigma=float(m.sensors.heading_sigma),
    )  # fmt: skip
    compass = _navigate(folder, vehicle, use_fixes=False, given=given, smooth=False)
    dvl_only = _navigate(folder, vehicle, use_fixes=False, use_heading=False, given=given,
                         smooth=False)  # fmt: skip
    _, heading = _within_3_sigma(compass.forward, m)
    final = [np.hypot(*_errors(n.forward, m)[0][-1, :2]) for n in (compass, dvl_only)]
    assert heading >= 0.95, heading
    assert final[0] <= 0.5 * final[1], final
    # the pass says when the DVL-only heading σ leaves the range the position's σ holds in
    said = [
        [n for n in nav.notes if "the heading's 1σ reached" in n] for nav in (compass, dvl_only)
    ]
    assert said[0] == [] and len(said[1]) == 1, said


def test_a_recording_without_a_dvl_or_a_run_without_it_navigates(tmp_path, short) -> None:
    """A recording without ``dvl.csv``, and one with it run with ``use_dvl=False``
    (``--no-dvl``; the vehicle file has the DVL's lever arm): each navigates on the
    fixes, depth and compass, the same pass, and its report names no DVL stream."""
    full = write_generic(short, tmp_path / "mission")
    vehicle = write_vehicle_file(tmp_path, short)
    without = tmp_path / "without-dvl"
    without.mkdir()
    for f in full.iterdir():
        if f.name != "dvl.csv":
            (without / f.name).write_bytes(f.read_bytes())
    left_out = _navigate(full, vehicle, use_dvl=False)
    absent = _navigate(without, vehicle)
    for nav in (left_out, absent):
        assert [r.name for r in nav.streams] == ["depth", "fix", "heading"]
        assert not any(n.startswith("dvl") for n in nav.notes)
        assert _horizontal_rms(nav.forward, short) < 5.0
    np.testing.assert_array_equal(left_out.forward.lla, absent.forward.lla)


def test_given_parts_of_the_initial_state_are_refused_with_init_truth() -> None:
    """``--init truth --init-position …`` took the truth and dropped the position
    without a word: refused, naming both, before any file is read."""
    given = GivenState(lla=(0.5, 0.6, float("nan")), depth=2.0)
    with pytest.raises(ValueError, match="^init: 'truth' takes .* are for init='data'$"):
        NavigateOptions(init="truth", given=given)
    assert NavigateOptions(init="data", given=given).given is given


def test_navigate_warns_of_a_lever_arm_beyond_10_m(tmp_path, short) -> None:
    """The arms of ``pronet navigate`` typed in cm: each warned of by name, a given one
    as ``given_as`` names it (the command's option), the vehicle file's by its key."""
    from pronet import PlausibilityWarning

    vehicle = load_vehicle(write_vehicle_file(tmp_path, short, arms=False))
    with pytest.warns(PlausibilityWarning) as said:
        lever_arms(vehicle, imu=(120.0, 0.0, 0.0), fix=(-178.0, -4.0, -104.0))
    assert [str(w.message).split(":")[0] for w in said] == ["imu_lever_arm", "fix_lever_arm"]
    vehicle = dataclasses.replace(vehicle, dvl_lever_arm=(0.5, 0.0, 30.0))
    with pytest.warns(PlausibilityWarning) as said:
        lever_arms(vehicle, fix=(-178.0, -4.0, -104.0), given_as="--{}-lever-arm")
    assert [str(w.message).split(":")[0] for w in said] == ["dvl_lever_arm", "--fix-lever-arm"]
    assert str(said[0].message).startswith("dvl_lever_arm: 0.5,0,30 m (30 m long): its z of 30")


def test_a_surface_depth_out_of_range_is_refused_as_the_vehicle_file_refuses_it() -> None:
    with pytest.raises(ValueError, match=r"^surface_depth: .* from 0 to 10, got -1.0$"):
        NavigateOptions(surface_depth=-1.0)


def test_no_still_interval_and_no_ahrs_names_what_the_command_takes(tmp_path, short) -> None:
    """``still="none"`` and no AHRS: the initial roll and pitch cannot be found; the line
    said to give "the initial roll, pitch and yaw", which no option of the command
    takes: it now names the still interval and the truth's start."""
    folder = write_generic(short, tmp_path / "rec")
    vehicle = write_vehicle_file(tmp_path, short)
    with pytest.raises(ValueError) as refused:
        _navigate(folder, vehicle, still="none")
    said = str(refused.value)
    assert said.startswith("initial roll and pitch: no still interval asked for")
    assert said.endswith(
        "give a still interval (still=, --still START,END), an AHRS orientation, or start "
        "from the ground truth where the recording has one (init='truth', --init truth)"
    )


def test_a_still_interval_outside_the_recording_is_named_by_its_option(tmp_path, short, capsys):
    """``--still 5,2`` was refused as ``still: expected t_start < t_end ...``, the
    library's argument, not the option typed; now ``--still: ...``."""
    from pronet.cli import main

    folder = write_generic(short, tmp_path / "rec")
    vehicle = write_vehicle_file(tmp_path, short)
    argv = ["navigate", "--data", str(folder), "--filter", str(vehicle), "--quiet"]
    assert main([*argv, "--out", str(tmp_path / "out"), "--still", "5,2"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("pronet: --still: expected t_start < t_end within the IMU's "), err


def test_a_window_the_pass_never_fills_is_said_on_the_command_line(tmp_path, short, capsys):
    """``--strategy mehra:2500`` on the 6-minute survey: 2,663 DVL readings (refused
    above that, as a window that could never fill), but 240 fall before the start levelled
    from the data, so the pass accepts 2,423 and Mehra never adapts: the pass ran with
    ``warn=False`` and said nothing of it. Now one line on stderr, in the notes of
    report.md and of the JSON result, in the warning's words."""
    from pronet.cli import main

    folder = write_generic(short, tmp_path / "mission")
    out = tmp_path / "out"
    code = main([
        "navigate", "--data", str(folder), "--filter", str(write_vehicle_file(tmp_path, short)),
        "--strategy", "mehra:2500", "--no-smooth", "--no-plots", "--json", "--out", str(out),
    ])  # fmt: skip
    assert code == 0
    said = capsys.readouterr()
    line = (
        "strategy mehra:2500: mehra's window of 2500 velocity updates was never filled "
        "(2423 accepted in the pass): it ran on its prior q throughout, as a constant "
        "strategy would; a window shorter than the pass's updates adapts"
    )
    assert f"pronet: {line}\n" in said.err
    assert line in json.loads(said.out)["notes"]
    assert line in (out / "report.md").read_text()


def test_the_command_names_streams_by_sensor_and_file_not_the_api(tmp_path, short, capsys):
    """What ``pronet navigate`` says of a stream names the sensor or the file the user
    gave, not ``run_filter``'s ``streams[i]``: a DVL whose one reading falls before the
    start levelled from the data ("streams[0] (Dvl): none of its 1 row …"), and a
    ``--surface-offset`` typed in pascals ("streams[1]: depth row 0 is −101325 m …",
    which blamed the depth: now the option, and the file its depth came from, with the
    file's row: it said "depth row 0", counting the kept readings, for the file's third
    row after two empty ones)."""
    from pronet.cli import main

    folder = write_generic(short, tmp_path / "mission")
    vehicle = str(write_vehicle_file(tmp_path, short))
    dvl = folder / "dvl.csv"
    dvl.write_text("".join(dvl.read_text().splitlines(keepends=True)[:2]))
    argv = ["navigate", "--data", str(folder), "--filter", vehicle, "--no-smooth", "--no-plots"]
    assert main([*argv, "--quiet", "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    assert "pronet: warning: dvl: none of its 1 row (" in err and "streams[" not in err
    depth = folder / "depth.csv"
    lines = depth.read_text().splitlines(keepends=True)
    for i in (1, 2):  # the first two data rows without a depth: skipped, still rows
        time, _, *rest = lines[i].split(",")
        lines[i] = ",".join([time, "", *rest])
    depth.write_text("".join(lines))
    out = tmp_path / "refused"
    assert main([*argv, "--surface-offset", "101325", "--out", str(out)]) == 2
    assert capsys.readouterr().err == (
        f"pronet: --surface-offset: 101325 m taken off {folder / 'depth.csv'}: depth row 3 is "
        "-101325 m, beyond -10000 … 12000 m (metres, positive down: the deepest ocean is "
        "11 km); in pascals or another unit?\n"
    )
    assert not out.exists()


def test_config_json_records_the_clocks_applied(tmp_path, short) -> None:
    """``config.json`` did not say which clocks navigate put the streams on: a recording
    with a ground truth has its truth's and its DVL's clocks estimated (stamps 0.45 s and
    1 s off, a scale 0.25 % short: the synthetic recording's), one without keeps its
    stamps (the DVL's assumed, no truth). Now recorded as ``pronet real`` records them,
    with how each was found."""
    from pronet.cli import main
    from pronet.recorded.recordings import write_recording

    from synthetic_recording import (
        DVL_CLOCK,
        DVL_LEVER_ARM,
        GT_CLOCK,
        IMU_LEVER_ARM,
        synthetic_recording,
    )

    data = write_recording(
        tmp_path / "run1.npz", synthetic_recording(seed=1, duration=70.0).recording
    )
    arms = [
        f"--{s}-lever-arm=" + ",".join(map(str, a))
        for s, a in (("imu", IMU_LEVER_ARM), ("dvl", DVL_LEVER_ARM))
    ]
    argv = ["navigate", "--init", "truth", *arms, "--no-plots", "--quiet", "--no-smooth"]
    assert main([*argv, "--data", str(data), "--out", str(tmp_path / "truth")]) == 0
    clocks = json.loads((tmp_path / "truth" / "config.json").read_text())["clocks"]
    assert clocks["how"] == {"gt": "estimated", "dvl": "estimated"}
    assert clocks["gt"] == pytest.approx([GT_CLOCK.offset, GT_CLOCK.scale], abs=0.01)
    assert clocks["dvl"] == pytest.approx([DVL_CLOCK.offset, DVL_CLOCK.scale], abs=0.1)
    assert clocks["aiding"] == [0.0, 1.0] and clocks["epoch_s"] == pytest.approx(0.01)
    folder = write_generic(short, tmp_path / "mission")
    vehicle = str(write_vehicle_file(tmp_path, short))
    argv = ["navigate", "--filter", vehicle, "--no-plots", "--quiet", "--no-smooth"]
    assert main([*argv, "--data", str(folder), "--out", str(tmp_path / "none")]) == 0
    clocks = json.loads((tmp_path / "none" / "config.json").read_text())["clocks"]
    assert clocks == {
        "epoch_s": short.imu_time[0], "gt": [0.0, 1.0], "dvl": [0.0, 1.0],
        "aiding": [0.0, 1.0], "how": {"gt": "none", "dvl": "assumed"},
    }  # fmt: skip


def test_every_word_of_the_command_is_one_line_before_the_work(tmp_path, short, capsys):
    """A lever arm typed in cm was warned of as Python prints a warning (the module's
    path, ``PlausibilityWarning`` and the source line ``arms = lever_arms(``: the
    options were read before the command took over its warnings), then as
    ``dvl_lever_arm: -60,10,30 m reaches 60 m`` (the arm is 67.8 m long; the option
    is ``--dvl-lever-arm``): now the option, the length and the component; a NaN
    ``--surface-offset`` was named ``surface offset``, not the option; and
    ``--init-heading-sigma`` without ``--init-heading`` was dropped without a word (the
    heading stream's σ used); an ``--out`` below a file was found after the whole pass
    and named ``out_dir``. Now each is one line naming the option, before the work, and
    a refusal leaves no folder."""
    from pronet.cli import main

    folder = write_generic(short, tmp_path / "mission")
    vehicle = str(write_vehicle_file(tmp_path, short))
    out = tmp_path / "out"
    argv = ["navigate", "--data", str(folder), "--filter", vehicle, "--out", str(out)]
    assert main([*argv, "--dvl-lever-arm=-60,10,30", "--surface-offset", "nan"]) == 2
    assert capsys.readouterr().err == (
        "pronet: warning: --dvl-lever-arm: -60,10,30 m (67.8 m long): its x of -60 m from "
        "the reference point is beyond ±10 m; typed in cm or mm? (used as given)\n"
        "pronet: --surface-offset: must be a finite number of metres, got nan\n"
    )
    (tmp_path / "file").write_text("x")  # an --out below a file: said before the work
    below = ["navigate", "--data", str(folder), "--filter", vehicle, "--out", f"{tmp_path}/file/o"]
    assert main(below) == 2
    assert capsys.readouterr().err == (
        f"pronet: --out: {tmp_path}/file/o: {tmp_path}/file is a file, not a folder\n"
    )
    assert main([*argv, "--init-heading-sigma", "2"]) == 2
    assert capsys.readouterr().err == (
        "pronet: --init-heading-sigma: the 1σ of --init-heading, which is not given (the "
        "heading found in the data has the σ its method earns)\n"
    )
    assert not out.exists()


@pytest.mark.parametrize(
    ("option", "said"),
    [
        (["--init-heading", "400"], "--init-heading: 400° is beyond -360 … 360° (a heading "
         "from true north); in another unit?"),
        (["--init-heading", "nan"], "--init-heading: expected a finite number of degrees, got nan"),
        (["--init-heading", "30", "--init-heading-sigma", "-1"],
         "--init-heading-sigma: expected a 1σ in degrees > 0, got -1"),
        (["--init-position", "95,34,2"], "--init-position: latitude 95° is beyond ±89°, got "
         "'95,34,2'"),
        (["--init-position", "32,34,nan"], "--init-position: expected finite LAT,LON,DEPTH, got "
         "'32,34,nan'"),
        (["--init-position", "32,400,2"], "--init-position: longitude 400° is beyond -180 … "
         "360°, got '32,400,2'"),
        (["--init-position", "32,34,101325"], "--init-position: depth 101325 m is beyond -10000 "
         "… 12000 m (metres, positive down: the deepest ocean is 11 km), got '32,34,101325'; in "
         "pascals?"),
        (["--init-position", "32,34"], "--init-position: expected LAT,LON,DEPTH in deg, deg, m, "
         "got '32,34'"),
    ],
)  # fmt: skip
def test_the_initial_state_options_are_refused_as_typed(tmp_path, capsys, option, said):
    """``--init-heading 400`` ran (a heading file refuses beyond ±360°); a negative
    ``--init-heading-sigma`` said ``given heading_sigma: … got -0.01745`` (radians, for
    the degrees typed), a bad ``--init-position`` ``given lla`` or ``given depth`` (in
    radians: ``[nan, 0.593…, nan]``) after the recording was read, a longitude of 400° or
    a depth in pascals ran, and ``32,34`` said ``expected three comma-separated
    numbers`` (``x,y,z in metres`` for a word). Now one line naming the option and the
    value as typed, before anything is read."""
    from pronet.cli import main

    out = tmp_path / "out"
    argv = ["navigate", "--data", str(tmp_path / "none"), "--out", str(out), *option]
    with pytest.raises(SystemExit) as refused:
        main(argv)
    assert refused.value.code == 2
    assert capsys.readouterr().err == f"pronet: {said} (see pronet navigate --help)\n"
    assert not out.exists()


def test_a_short_imu_or_a_folder_of_recordings_names_the_file(tmp_path, short, capsys):
    """An IMU file of one row said ``imu_time: needs at least two samples, got 1`` and
    one of two ``t0: the streams' first readings (0.75 s) come after the IMU's end``;
    ``--data`` given a folder of recordings (``pronet real``'s Snapir folder) said ``no
    imu.csv``. Now the IMU file with its rows, and the recordings the folder holds."""
    from pronet.cli import main

    data = tmp_path / "data"
    folder = write_generic(short, data / "trajectory01")
    imu = (folder / "imu.csv").read_text().splitlines(keepends=True)
    vehicle = str(write_vehicle_file(tmp_path, short))
    out = tmp_path / "out"
    argv = ["navigate", "--filter", vehicle, "--out", str(out), "--no-plots", "--data"]
    for rows, said in (
        (1, "1 data row: an IMU needs at least 2 (a step to integrate)"),
        (2, "its 2 data rows end at 1700000000.010 s, 0.0312 s before any other stream's "
            f"first reading ({data / 'trajectory02' / 'depth.csv'}): too short to navigate"),
    ):  # fmt: skip
        cut = write_generic(short, data / f"trajectory0{rows}")
        (cut / "imu.csv").write_text("".join(imu[: rows + 1]))
        assert main([*argv, str(cut)]) == 2
        assert capsys.readouterr().err == f"pronet: {cut / 'imu.csv'}: {said}\n"
    (data / "notes").mkdir()  # no recording: not named
    assert main([*argv, str(data)]) == 2
    assert capsys.readouterr().err == (
        f"pronet: --data: {data} is a folder of 2 recordings (trajectory01, trajectory02); "
        f"pronet navigate takes one (--data {data / 'trajectory01'}), pronet real all of them\n"
    )
    assert not out.exists()
