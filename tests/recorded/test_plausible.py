"""Implausible data that used to run: each case is one line on
stderr naming the file and column, exit 2 (a warning where the data is usable)."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest

from pronet.cli import main
from pronet.recorded.recordings import write_recording

from synthetic_recording import synthetic_recording


@pytest.fixture(scope="module")
def recording():
    return synthetic_recording(seed=4, duration=70.0, name="s").recording


def _written(tmp_path, recording) -> list[str]:
    """``recording`` written as CSVs under ``tmp_path / "s"``; the command that reads it."""
    write_recording(tmp_path / "s", recording)
    folder, out = str(tmp_path / "s"), str(tmp_path / "o")
    return ["real", "--data", folder, "--format", "generic", "--out", out]


def _edit(folder, kind, change):
    path = folder / f"{kind}.csv"
    table = pd.read_csv(path)
    table = change(table)
    table.to_csv(path, index=False, float_format="%.17g")


def _gyro_dead(t):
    t["gyro_y [rad/s]"] = 0.0
    return t


def _angles_in_rad_under_deg(t):
    return t.rename(
        columns={c: c.replace("[rad]", "[deg]") for c in ("roll [rad]", "pitch [rad]", "yaw [rad]")}
    )


def _position_in_rad_under_deg(t):
    return t.rename(columns={"lat [rad]": "lat [deg]", "lon [rad]": "lon [deg]"})


def _twice(t):
    t.insert(len(t.columns), "acc_x [m/s^2].1", t["acc_x [m/s^2]"] * 0)
    return t.rename(columns={"acc_x [m/s^2].1": "acc_x [m/s^2]"})


def _in_cm_per_s(t):
    for c in ("vel_n [m/s]", "vel_e [m/s]", "vel_d [m/s]"):
        t[c] = t[c] * 100
    return t


def _velocity_in_enu(t):
    n, e, d = (t[f"vel_{a} [m/s]"].copy() for a in "ned")
    t["vel_n [m/s]"], t["vel_e [m/s]"], t["vel_d [m/s]"] = e, n, -d
    return t


def _yaw_in_enu(t):
    t["yaw [rad]"] = np.pi / 2 - t["yaw [rad]"]
    return t


def _up_not_down(t):
    t["vel_d [m/s]"] = -t["vel_d [m/s]"]
    return t


def _unix(t):
    t["time [s]"] = t["time [s]"] + 1.7e9
    return t


def _dvl_stuck(t):
    t["vel_z [m/s]"] = 0.25
    return t


@pytest.mark.parametrize(
    ("kind", "change", "expected"),
    [
        (
            "imu",
            _gyro_dead,
            r"imu.csv: column 'gyro_y \[rad/s\]' is 0 in every one of its \d+ rows: a stuck or "
            r"dead channel",
        ),
        (
            "gt",
            _position_in_rad_under_deg,
            r"gt.csv: columns 'lat \[deg\]', 'lon \[deg\]' move 0.0\d+ times as far as the "
            r"velocity between rows; are they in rad under a \[deg\] header\?",
        ),
        ("dvl", _dvl_stuck, r"dvl.csv: column 'vel_z \[m/s\]' is 0.25 in every one"),
        (
            "gt",
            _angles_in_rad_under_deg,
            r"gt.csv: columns 'roll \[deg\]', 'pitch \[deg\]', 'yaw \[deg\]' turn 0.0\d+ times "
            r"as much as the gyro between rows; are the angles in rad under a \[deg\] header\?",
        ),
        (
            "imu",
            _twice,
            r"imu.csv: column 'acc_x' appears 2 times \(columns 2 \('acc_x \[m/s\^2\]'\) and 8",
        ),
        (
            "gt",
            _in_cm_per_s,
            r"gt.csv, row \d+: column 'vel_\w \[m/s\]' is -?\d+\.?\d* m/s, beyond any "
            r"underwater vehicle",
        ),
        (
            "gt",
            _velocity_in_enu,
            # this track runs near 45°, where east and north swapped hardly turn it: the
            # up axis says it (a track along a meridian: the test after this one)
            r"gt.csv: column 'vel_d \[m/s\]' moves 'height \[m\]' the wrong way .*(ENU)",
        ),
        (
            "gt",
            _yaw_in_enu,
            r"gt.csv: column 'yaw \[rad\]' turns against the gyro's z axis \(correlation "
            r"-[01]\.\d+ .*a heading in ENU",
        ),
        (
            "gt",
            _up_not_down,
            r"gt.csv: column 'vel_d \[m/s\]' moves 'height \[m\]' the wrong way \(cosine "
            r"-[01]\.\d+.*third axis is up",
        ),
        (
            "gt",
            _unix,
            r"gt.csv: column 'time \[s\]' runs 1700000\d+.* the gt and IMU stamps do not overlap",
        ),
    ],
)
def test_implausible_data_is_one_line_naming_file_and_column(
    tmp_path, capsys, recording, kind, change, expected
):
    argv = _written(tmp_path, recording)
    _edit(tmp_path / "s", kind, change)
    assert main([*argv, "--imu-lever-arm=0,0,0", "--dvl-lever-arm=0,0,0", "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith("pronet: section s: ") and re.search(expected, err), err


def test_a_velocity_with_north_and_east_swapped_is_told_from_its_track() -> None:
    """A truth along a meridian and then a parallel, 1.5 m/s, its velocity columns
    swapped (ENU read as NED): the steps of latitude and longitude point one way, the
    velocity's the other (cosine 0 where NED reads 1)."""
    from pronet.recorded.plausible import Table, position_units

    t = np.arange(200.0)
    north_then_east = np.where(t < 100, 1.5, 0.0), np.where(t < 100, 0.0, 1.5)
    lat = 0.5 + np.cumsum(north_then_east[0]) / 6_371_000.0
    lon = 0.2 + np.cumsum(north_then_east[1]) / (6_371_000.0 * np.cos(lat))
    labels = ["time [s]", "lat [rad]", "lon [rad]", "height [m]"]
    labels += [f"vel_{a} [m/s]" for a in "ned"] + ["roll [rad]", "pitch [rad]", "yaw [rad]"]
    zeros = np.zeros_like(t)
    ned = np.stack([t, lat, lon, zeros, *north_then_east, zeros, zeros, zeros, zeros], axis=1)
    assert position_units(Table(ned, "gt.csv", labels)) is None
    enu = ned.copy()
    enu[:, [4, 5]] = ned[:, [5, 4]]
    found = position_units(Table(enu, "gt.csv", labels))
    assert found is not None and "do not point along the track" in found, found
    assert "cosine 0.00" in found and "a velocity in ENU" in found


def test_a_lever_arm_beyond_10_m_is_a_warning_and_runs(tmp_path, capsys, recording):
    """Arms typed in cm (185 m) are usable: a warning naming the option, the run goes on;
    in mm (1.85 km) they are an error (tests/hostile)."""
    argv = _written(tmp_path, recording)
    argv += [
        "--imu-lever-arm=0,0,0",
        "--dvl-lever-arm=-185,-3,12",
        "--no-models",
        "--no-plots",
        "--quiet",
    ]
    assert main(argv) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == (
        "pronet: warning: --dvl-lever-arm: -185,-3,12 m (185 m long): its x of -185 m from "
        "the ground-truth point is beyond ±10 m; typed in cm or mm? (used as given)"
    )  # it named dvl_lever_arm, run_real's argument
    # and the filters, run as told, say their DVL disagrees: its lever arm among the causes
    (note,) = err[1:]
    assert note.startswith("pronet: section s: dvl: mean NIS") and "lever arm" in note
    # A vehicle file's arm is named by the file and its key, not by the option.
    vehicle = tmp_path / "v.toml"
    vehicle.write_text("imu_lever_arm = [0, 0, 0]\ndvl_lever_arm = [-185, -3, 12]\n")
    argv = [a for a in argv if "lever-arm" not in a] + ["--filter", str(vehicle)]
    argv[argv.index("--out") + 1] = str(tmp_path / "o2")
    assert main(argv) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0].startswith(f"pronet: warning: {vehicle}: dvl_lever_arm: -185,-3,12 m (185 m")


def test_vehicle_keys_pronet_real_does_not_apply_are_warned_of(tmp_path, capsys, recording):
    """A navigate vehicle file's depth and fix lever arms and surface depth: ``pronet
    real`` read them and ran as if they were not there, saying nothing; now one warning
    names them, and the run goes on. A file without them says nothing of it."""
    vehicle = tmp_path / "v.toml"
    vehicle.write_text("imu_lever_arm = [0, 0, 0]\ndvl_lever_arm = [0, 0, 0]\n"
                       "fix_lever_arm = [3, 0, -1]\nsurface_depth = 0.1\n")  # fmt: skip
    argv = [*_written(tmp_path, recording), "--filter", str(vehicle), "--no-models",
            "--no-plots", "--quiet"]  # fmt: skip
    assert main(argv) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err[0] == (
        f"pronet: warning: {vehicle}: fix_lever_arm, surface_depth are applied by pronet "
        "navigate only; pronet real takes the depth and the fixes at the IMU's point and the "
        "depth's surface as read (ignored here)"
    )
    vehicle.write_text("imu_lever_arm = [0, 0, 0]\ndvl_lever_arm = [0, 0, 0]\n")
    argv[argv.index("--out") + 1] = str(tmp_path / "o2")
    assert main(argv) == 0
    assert "navigate only" not in capsys.readouterr().err


def test_the_synthetic_and_snapir_like_data_pass_every_check(tmp_path, recording):
    from pronet.recorded.recordings import read_recording

    write_recording(tmp_path / "s", recording)
    assert np.array_equal(read_recording(tmp_path / "s").imu, recording.imu)


def test_a_biased_mems_gyro_on_a_straight_leg_is_not_taken_for_wrong_angle_units():
    """A MEMS gyro's bias (0.1 °/s: 1.7e-3 rad per 1 Hz truth row) on a straight leg
    whose truth attitude barely moves is no unit error: the steps are compared less
    their median, so the bias cancels (it once said "rad under a [deg] header"). The
    same leg with turns that come and go, in degrees under a [rad] header, still is."""
    from pronet.recorded.plausible import Table, attitude_units

    rng = np.random.default_rng(0)
    t_imu = np.arange(1, 6001) * 0.01  # 60 s at 100 Hz
    gyro = np.radians(0.1) + rng.normal(size=(6000, 3)) * 1e-4  # [rad/s]
    imu = np.column_stack([t_imu, np.zeros((6000, 3)), gyro])
    t_gt = np.arange(1.0, 60.0)
    rpy = 0.2 + rng.normal(size=(len(t_gt), 3)) * 1e-5  # [rad], straight and level
    gt = np.column_stack([t_gt, np.zeros((len(t_gt), 6)), rpy])
    labels = ["roll [rad]", "pitch [rad]", "yaw [rad]"]
    tables = (Table(imu, "imu.csv", []), Table(gt, "gt.csv", [""] * 7 + labels))
    assert attitude_units(*tables) is None
    # Weaving: the gyro turns ±0.05 rad/s over 10 s periods, the truth in degrees.
    weave = 0.05 * np.sin(2 * np.pi * t_imu / 10)
    imu[:, 6] += weave
    yaw = np.cumsum(weave) * 0.01
    gt[:, 9] = np.degrees(np.interp(t_gt, t_imu, yaw))
    found = attitude_units(Table(imu, "imu.csv", []), Table(gt, "gt.csv", [""] * 7 + labels))
    assert found is not None and "deg under a [rad] header" in found, found


@pytest.mark.parametrize(
    ("stream", "keep", "expected"),
    [
        (
            "gt",
            6,
            "/s: the ground truth has 6 rows over 5.01 s; its clock is estimated "
            "from 11 or more inside the IMU record",
        ),  # fmt: skip
        (
            "dvl",
            6,
            "/s: the DVL has 6 rows over 5.01 s; its clock is estimated from "
            "10 or more inside the IMU record",
        ),  # fmt: skip
    ],
)
def test_a_stream_too_short_to_estimate_its_clock_says_so(
    tmp_path, capsys, recording, stream, keep, expected
):
    """A 6 s truth or DVL was "the ground truth and the IMU do not overlap in time at any
    clock offset within ±2 s": they overlap, over too few rows."""
    argv = [*_written(tmp_path, recording), "--imu-lever-arm=0,0,0", "--dvl-lever-arm=0,0,0"]
    _edit(tmp_path / "s", stream, lambda table: table.iloc[:keep])
    assert main([*argv, "--no-models", "--no-plots", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert expected in err[0] and "overlap" not in err[0], err
