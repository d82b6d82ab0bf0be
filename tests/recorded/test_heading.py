"""Heading readings in recorded data: the generic format's ``heading`` table (rad, deg,
magnetic with its declination) and a bag's heading topic (an AHRS's ``sensor_msgs/Imu``,
the IMU topic's own orientation, a quaternion, a pose; ENU/FLU and NED/FRD), read as
the truth's yaw they were written from; their σ and missing values; their mistakes
refused in one line naming file and column; ``pronet real`` filtering with them on
request, its rows unchanged without; a bag's raw pressure kept to re-reference the
depth."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pronet.cli import main
from pronet.recorded.aiding import AidingTuning, filter_aiding, tuned_heading
from pronet.recorded.alignment import load_section
from pronet.recorded.bags import BagTopics
from pronet.recorded.heading import HeadingReadings, wrap
from pronet.recorded.real import run_real
from pronet.recorded.recordings import RecordingError, read_recording, write_recording
from pronet.recorded.vehicle import load_vehicle

from synthetic_recording import DVL_LEVER_ARM, IMU_LEVER_ARM, synthetic_recording

ARMS = {"imu_lever_arm": IMU_LEVER_ARM, "dvl_lever_arm": DVL_LEVER_ARM}
CLI_ARMS = [
    "--imu-lever-arm=" + ",".join(map(str, IMU_LEVER_ARM)),
    "--dvl-lever-arm=" + ",".join(map(str, DVL_LEVER_ARM)),
]


@pytest.fixture(scope="module")
def rec():
    """A 60 s recording (its yaw 0.3 rad and turning)."""
    return synthetic_recording(seed=6, duration=60.0, name="mission").recording


def _heading_csv(folder: Path, header: str, rows: np.ndarray) -> None:
    body = "\n".join(",".join(f"{v:.17g}" for v in row) for row in rows)
    (folder / "heading.csv").write_text(f"{header}\n{body}\n")


@pytest.mark.parametrize(
    ("header", "unit", "offset", "turn", "declination"),
    [
        ("time [s],heading [rad],sigma [rad]", 1.0, 0.0, -2 * math.pi, None),
        ("time [s],heading [deg],sigma [deg]", 180 / math.pi, 0.0, -360.0, None),
        ("time [s],magnetic_heading [deg],sigma [deg]", 180 / math.pi, -4.5, 0.0, 4.5),
        ("time [s],magnetic_heading [rad],sigma [rad]", 1.0, math.radians(12.0), 0.0, -12.0),
    ],
)
def test_a_heading_table_reads_as_the_true_heading(
    tmp_path, rec, header, unit, offset, turn, declination
):
    folder = write_recording(tmp_path / "mission", rec)
    yaw = rec.gt_rpy[:, 2]
    sigma = np.full(len(yaw), math.radians(1.0))
    written = yaw * unit + offset
    written[::2] += turn  # every other row a whole turn off: wrapped back
    _heading_csv(folder, header, np.column_stack([rec.gt_time, written, sigma * unit]))
    got = read_recording(folder, declination=declination).heading
    assert got is not None and got.source == str(folder / "heading.csv")
    np.testing.assert_array_equal(got.time, rec.gt_time)
    assert ((got.heading > -math.pi) & (got.heading <= math.pi)).all()
    np.testing.assert_allclose(got.heading, yaw, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.sigma, sigma, rtol=1e-14)  # type: ignore[arg-type]
    magnetic = declination is not None
    assert (got.declination is not None) == magnetic
    # written back (true, SI) and read again as it was; an .npz alike
    as_read = read_recording(folder, declination=declination)
    for path in (write_recording(tmp_path / n, as_read) for n in ("back", "back.npz")):
        back = read_recording(path).heading
        assert back is not None
        np.testing.assert_array_equal(back.heading, got.heading)


def test_the_wrap_keeps_what_lies_inside_to_the_bit():
    inside = np.array([-math.pi + 1e-15, -1.0, 0.0, 0.3, math.pi])
    assert wrap(inside).tolist() == inside.tolist()
    outside = np.array([-math.pi, 3 * math.pi / 2, 7.0])
    expected = [math.pi, -math.pi / 2, 7.0 - 2 * math.pi]
    np.testing.assert_allclose(wrap(outside), expected, rtol=0, atol=1e-15)


def test_missing_headings_are_skipped_and_the_sigma_is_refused_without_a_tuning(tmp_path, rec):
    folder = write_recording(tmp_path / "mission", rec)
    rows = [f"{t:.17g},{y:.17g}" for t, y in zip(rec.gt_time, rec.gt_rpy[:, 2], strict=True)]
    rows[3], rows[7] = f"{rec.gt_time[3]:.17g},", f"{rec.gt_time[7]:.17g},nan"
    (folder / "heading.csv").write_text("time [s],heading [rad]\n" + "\n".join(rows) + "\n")
    heading = read_recording(folder).heading
    assert heading is not None and heading.sigma is None
    assert heading.skipped_reason == ("nan", "nan")
    np.testing.assert_array_equal(heading.skipped_time, rec.gt_time[[3, 7]])
    with pytest.raises(ValueError) as caught:
        tuned_heading(heading, AidingTuning())
    assert str(caught.value) == (
        f"{folder / 'heading.csv'}: the heading has no σ (no sigma column, or a covariance not "
        "set in every message): give heading_sigma [deg] in the vehicle file"
    )
    with pytest.raises(ValueError, match="give heading_sigma"):
        filter_aiding(None, None, heading)
    tuned = tuned_heading(heading, AidingTuning(heading_sigma=0.02))
    assert tuned is not None and (tuned.sigma == 0.02).all()
    assert tuned_heading(heading, AidingTuning(use_heading=False)) is None
    (stream,) = filter_aiding(None, None, tuned)
    np.testing.assert_array_equal(stream.time, heading.time)


def _write(folder: Path, text: str) -> None:
    (folder / "heading.csv").write_text(text)


def _yaw_rows(rec, factor=1.0, offset=0.0, sigma="0.02") -> str:
    yaw = rec.gt_rpy[:, 2] * factor + offset
    return "\n".join(f"{t:.17g},{y:.17g},{sigma}" for t, y in zip(rec.gt_time, yaw, strict=True))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        (lambda r: "time [s],magnetic_heading [rad],sigma [rad]\n" + _yaw_rows(r),
         r"heading\.csv: column 'magnetic_heading \[rad\]' is a magnetic heading: give the "
         r"magnetic declination \[deg, east positive\] \(declination in the vehicle file, or "
         r"--declination DEG\)$"),
        (lambda r: "time [s],heading [rad],sigma [rad]\n" + _yaw_rows(r, sigma="0"),
         r"heading\.csv, row 1: 'sigma \[rad\]' is 0; a heading's 1σ must be > 0 and at most "
         r"180° \(π rad\)$"),
        (lambda r: "time [s],heading [deg],sigma [deg]\n" + _yaw_rows(r, 57.3, sigma="200"),
         r"heading\.csv, row 1: 'sigma \[deg\]' is 200; a heading's 1σ must be > 0"),
        (lambda r: "time [s],heading [grad],sigma [rad]\n" + _yaw_rows(r),
         r"heading\.csv: column 'heading \[grad\]' has unit \[grad\]; expected rad, deg$"),
        (lambda r: "time [s],heading [rad],sigma [m]\n" + _yaw_rows(r),
         r"heading\.csv: column 'sigma \[m\]' has unit \[m\]; expected rad, deg$"),
        (lambda r: "time [s],heading [rad],sigma_yaw [rad]\n" + _yaw_rows(r),
         r"heading\.csv: column 'sigma_yaw \[rad\]' is not a σ column of the heading table; "
         r"its σ columns are sigma \[rad \| deg\]$"),
        (lambda r: "time [s],yaw [rad],sigma [rad]\n" + _yaw_rows(r),
         r"heading\.csv: missing column 'heading \[rad \| deg\]' \(from true north\) or "
         r"'magnetic_heading \[rad \| deg\]'; has: time \[s\], sigma \[rad\]$"),
        (lambda r: "time [s],heading [rad],magnetic_heading [rad]\n" + _yaw_rows(r),
         r"heading\.csv: has both 'heading' \(true north\) and 'magnetic_heading'; keep one$"),
        (lambda r: "time [s],heading [rad],sigma [rad]\n" + _yaw_rows(r, 180 / math.pi, 360),
         r"heading\.csv, row 1: 'heading \[rad\]' is \d+\.\d+, beyond -6\.28319 … 6\.28319 rad"),
        (lambda r: "time [s],heading [rad],sigma [rad]\n" + _yaw_rows(r, 1.0, math.pi / 2),
         r"heading\.csv: the heading lies a median \d+\.?\d*° from the ground truth's yaw \(at "
         r"most 30°\); magnetic without its declination, a yaw from east"),
        # a median rounded to the bound: the figure once ("median 30° (at most 30°)")
        (lambda r: "time [s],heading [rad],sigma [rad]\n" + _yaw_rows(r, 1.0, 0.524),
         r"heading\.csv: the heading lies a median just over 30° \(the most accepted\) from "
         r"the ground truth's yaw; magnetic without its declination, a yaw from east"),
    ],
)  # fmt: skip
def test_a_bad_heading_table_is_one_line_naming_file_and_column(tmp_path, rec, text, message):
    folder = write_recording(tmp_path / "mission", rec)
    _write(folder, text(rec))
    with pytest.raises(RecordingError, match=message) as caught:
        read_recording(folder)
    assert "\n" not in str(caught.value) and str(folder / "heading.csv") in str(caught.value)


def test_a_magnetic_heading_in_an_npz_needs_its_declination(tmp_path, rec):
    npz = write_recording(tmp_path / "mission.npz", rec)
    arrays = dict(np.load(npz))
    arrays["heading"] = np.column_stack([rec.gt_time, np.degrees(rec.gt_rpy[:, 2]) - 3.0])
    arrays["heading_columns"] = np.array(["time [s]", "magnetic_heading [deg]"])
    np.savez(tmp_path / "magnetic.npz", **arrays)
    with pytest.raises(RecordingError, match=r"magnetic\.npz\[heading\]: column 'magnetic_"):
        read_recording(tmp_path / "magnetic.npz")
    got = read_recording(tmp_path / "magnetic.npz", declination=3.0).heading
    assert got is not None and got.sigma is None
    np.testing.assert_allclose(got.heading, rec.gt_rpy[:, 2], rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match=r"declination: expected -180 … 180 deg"):
        read_recording(tmp_path / "magnetic.npz", declination=270.0)


def _rosbags():
    pytest.importorskip(
        "rosbags.highlevel", reason="the rosbags extra: pip install 'pronet[rosbags]'"
    )
    pytest.importorskip("scipy", reason="the tests' bag writer turns DCMs into quaternions")
    import ros_bag

    return ros_bag


def _origin(rec) -> tuple[float, float, float]:
    lat, lon = np.degrees(rec.gt_lla[0, :2])
    return float(lat), float(lon), float(rec.gt_lla[0, 2])


@pytest.mark.parametrize("frames", [("flu", "enu"), ("frd", "ned")])
@pytest.mark.parametrize(
    ("heading", "storage"),
    [("imu", "mcap"), ("imu", "rosbag1"), ("own", "sqlite3"), ("own", "rosbag1"),
     ("quaternion", "mcap"), ("pose", "mcap"), ("pose_covariance", "rosbag1")],
)  # fmt: skip
def test_a_bag_heading_is_the_yaw_it_was_written_from(tmp_path, rec, heading, storage, frames):
    """The heading topic's yaw converted with the bag's frames as the truth's orientation
    is: equal to the yaw the writer put in (the truth's rows, or the truth interpolated
    at the IMU's stamps for the IMU topic's own orientation), and to the truth as read."""
    ros_bag = _rosbags()
    topics = BagTopics(origin=_origin(rec), body_frame=frames[0], world_frame=frames[1])
    name = "mission.bag" if storage == "rosbag1" else "mission"
    path, topics = ros_bag.write_bag(tmp_path / name, rec, storage, topics=topics, heading=heading)
    assert (topics.heading == topics.imu) == (heading == "own")
    got = read_recording(path, topics)
    assert got.heading is not None and got.heading.sigma is None  # covariance unknown
    _, rpy = ros_bag.heading_attitude(rec, heading)
    np.testing.assert_allclose(wrap(got.heading.heading - rpy[:, 2]), 0.0, rtol=0, atol=1e-9)
    if heading != "own":
        np.testing.assert_allclose(wrap(got.heading.heading - got.gt_rpy[:, 2]), 0.0, atol=1e-9)
    np.testing.assert_array_equal(got.imu, rec.imu)  # the frames honoured both ways
    assert got.heading.source == f"{path}[{topics.heading}]"


@pytest.mark.parametrize("heading", ["imu", "own", "pose_covariance"])
def test_a_bag_heading_sigma_comes_from_its_covariance(tmp_path, rec, heading):
    ros_bag = _rosbags()
    n = len(ros_bag.heading_attitude(rec, heading)[0])
    variance = np.random.default_rng(1).uniform(1e-5, 1e-4, n)
    path, topics = ros_bag.write_bag(
        tmp_path / "b", rec, heading=heading, heading_variance=variance
    )
    got = read_recording(path, topics).heading
    assert got is not None
    np.testing.assert_allclose(got.sigma, np.sqrt(variance), rtol=1e-15)  # type: ignore[arg-type]
    variance[4] = 0.0  # one message "unknown": σ as tuned for the topic
    path, topics = ros_bag.write_bag(
        tmp_path / "c", rec, heading=heading, heading_variance=variance
    )
    assert read_recording(path, topics).heading.sigma is None  # type: ignore[union-attr]


def test_imu_messages_without_orientation_are_skipped_with_their_reason(tmp_path, rec):
    ros_bag = _rosbags()
    variance = np.full(len(rec.imu_time), 3e-5)
    path, topics = ros_bag.write_bag(tmp_path / "b", rec, heading="own", heading_variance=variance,
                                     no_orientation=(0, 1, 500))  # fmt: skip
    got = read_recording(path, topics).heading
    assert got is not None and got.skipped_reason == ("no orientation",) * 3
    assert len(got.time) == len(rec.imu_time) - 3
    np.testing.assert_allclose(got.sigma, math.sqrt(3e-5), rtol=1e-15)  # type: ignore[arg-type]
    # the bags pronet real has always read: IMU messages without any orientation
    path, topics = ros_bag.write_bag(tmp_path / "c", rec)
    with pytest.raises(RecordingError) as caught:
        read_recording(path, replace(topics, heading=topics.imu))
    assert str(caught.value) == (
        f"{path}[/imu/data]: no usable heading in its {len(rec.imu_time)} rows (no orientation)"
    )
    with pytest.raises(RecordingError, match=r"\[/dvl/twist\]: the heading topic holds geometry"):
        read_recording(path, replace(topics, heading="/dvl/twist"))


def test_a_magnetic_bag_heading_is_turned_true_with_the_declination(tmp_path, rec):
    ros_bag = _rosbags()
    path, topics = ros_bag.write_bag(tmp_path / "b", rec, heading="imu", magnetic_declination=-7.0)
    assert topics.heading_magnetic and topics.record()["heading_magnetic"] is True
    with pytest.raises(RecordingError, match=r"\[/ahrs\]: column 'magnetic_heading \[rad\]' is "
                       r"a magnetic heading: give the magnetic declination"):  # fmt: skip
        read_recording(path, topics)
    got = read_recording(path, topics, declination=-7.0).heading
    assert got is not None
    np.testing.assert_allclose(wrap(got.heading - rec.gt_rpy[:, 2]), 0.0, rtol=0, atol=1e-9)


def test_pronet_real_reads_a_bag_heading_topic_on_request(tmp_path, rec, capsys):
    ros_bag = _rosbags()
    variance = np.full(len(rec.gt_time), math.radians(0.5) ** 2)
    path, _ = ros_bag.write_bag(
        tmp_path / "mission",
        rec,
        heading="imu",
        heading_variance=variance,
        magnetic_declination=-7.0,
    )
    argv = ["real", "--format", "bag", "--data", str(path), "--origin",
            ",".join(f"{v:.17g}" for v in _origin(rec)), *CLI_ARMS, "--no-models", "--no-plots",
            "--quiet", "--heading-topic", "/ahrs", "--heading-magnetic"]  # fmt: skip
    assert main([*argv, "--out", str(tmp_path / "a")]) == 2
    assert "[/ahrs]: column 'magnetic_heading [rad]' is a magnetic" in capsys.readouterr().err
    assert main([*argv, "--declination=-7", "--out", str(tmp_path / "b")]) == 0
    config = json.loads((tmp_path / "b" / "config.json").read_text())
    assert config["format"]["heading_topic"] == "/ahrs" and config["format"]["heading_magnetic"]
    used = config["aiding"]["sections"]["mission"]["heading"]
    assert used["rows"] == len(rec.gt_time) and used["sigma_deg"] == pytest.approx(0.5)
    assert main([*argv, "--no-heading", "--out", str(tmp_path / "c")]) == 0  # not read
    assert "heading" not in json.loads((tmp_path / "c" / "config.json").read_text())["aiding"][
        "sections"]["mission"]  # fmt: skip
    generic = ["real", "--format", "generic", "--data", str(path), *CLI_ARMS]
    assert main([*generic, "--heading-topic", "/ahrs", "--out", str(tmp_path / "d")]) == 2
    assert "--heading-topic: only with --format bag" in capsys.readouterr().err


def test_a_bag_keeps_the_raw_pressure_to_re_reference_the_depth(tmp_path):
    ros_bag = _rosbags()
    from synthetic_recording import with_aiding

    aided = with_aiding(synthetic_recording(seed=6, duration=60.0), seed=6)
    path, topics = ros_bag.write_bag(tmp_path / "b", aided, topics=BagTopics(
        origin=_origin(aided), surface_pressure=101_900.0, water_density=1020.0))  # fmt: skip
    assumed = read_recording(path, replace(topics, surface_pressure=101_325.0)).depth
    measured = read_recording(path, topics).depth
    assert assumed is not None and measured is not None and aided.depth is not None
    assert assumed.water_density == 1020.0 and assumed.pressure is not None
    np.testing.assert_allclose(assumed.pressure, aided.depth.depth * 1020.0 * 9.80665 + 101_900.0)
    again = assumed.rereferenced(101_900.0)
    np.testing.assert_allclose(again.depth, measured.depth, rtol=0, atol=1e-12)
    np.testing.assert_allclose(again.depth, aided.depth.depth, rtol=0, atol=1e-9)
    assert np.median(assumed.depth - again.depth) == pytest.approx(575 / (1020.0 * 9.80665))
    back = read_recording(write_recording(tmp_path / "csv", read_recording(path, topics))).depth
    assert back is not None and back.pressure is not None
    np.testing.assert_array_equal(back.pressure, measured.pressure)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="holds no pressure to re-reference"):
        replace(back, pressure=None).rereferenced(1e5)
    with pytest.raises(ValueError, match="needs the water's density"):
        back.rereferenced(1e5)  # a table's pressure: the density must be given
    np.testing.assert_allclose(
        back.rereferenced(101_900.0, 1020.0).depth, measured.depth, atol=1e-12
    )


# ------------------------------------------------------------------------ pronet real


@pytest.fixture(scope="module")
def with_heading(tmp_path_factory):
    """An 80 s recording with a 1 Hz heading table (σ 0.5°): the truth's yaw plus noise."""
    base = tmp_path_factory.mktemp("heading")
    rec = synthetic_recording(seed=7).recording
    noise = np.random.default_rng(7).normal(size=len(rec.gt_time)) * math.radians(0.5)
    heading = HeadingReadings(rec.gt_time, wrap(rec.gt_rpy[:, 2] + noise),
                              np.full(len(rec.gt_time), math.radians(0.5)))  # fmt: skip
    return (
        write_recording(base / "with" / "sec", replace(rec, heading=heading)),
        write_recording(base / "without" / "sec", rec),
    )


def _rows(out: Path) -> pd.DataFrame:
    return pd.read_csv(out / "metrics.csv").drop(columns=["seconds"], errors="ignore")


def test_pronet_real_uses_a_heading_on_request_and_is_unchanged_without(tmp_path, with_heading):
    folder, plain = with_heading
    kw = {"fmt": "generic", "use_models": False, "plots": False, **ARMS}
    run_real(plain, tmp_path / "plain", **kw)
    run_real(folder, tmp_path / "ignored", use_heading=False, **kw)
    run_real(folder, tmp_path / "aided", **kw)
    plain_rows, ignored, aided = (_rows(tmp_path / d) for d in ("plain", "ignored", "aided"))
    numbers = [c for c in plain_rows.select_dtypes("number").columns if c != "wall_seconds"]
    pd.testing.assert_frame_equal(plain_rows[numbers], ignored[numbers])  # to the bit
    assert not aided[numbers].equals(plain_rows[numbers])
    config = json.loads((tmp_path / "aided" / "config.json").read_text())["aiding"]
    assert config["use_heading"] is True and config["heading_sigma_deg"] is None
    assert config["sections"]["sec"]["heading"] == {
        "rows": 80, "skipped": 0, "outside_run": 1, "sigma_deg": pytest.approx(0.5)}  # fmt: skip
    table = (tmp_path / "aided" / "table.md").read_text()
    assert "### Heading (mean NIS: constant (estimated q))" in table
    assert "| sec | 80 (0 skipped, 1 outside the run) | 0.5 |" in table
    for d in ("plain", "ignored"):
        assert "### Heading" not in (tmp_path / d / "table.md").read_text()
        assert "heading" not in json.loads((tmp_path / d / "config.json").read_text())[
            "aiding"]["sections"]["sec"]  # fmt: skip
    section, _ = load_section(folder, "generic", **ARMS)
    assert section.heading is not None and len(section.heading.time) == 80


def test_the_cli_takes_the_heading_flags_and_the_vehicle_file_its_sigma(
    tmp_path, with_heading, capsys
):
    folder, _ = with_heading
    text = (folder / "heading.csv").read_text().replace(",sigma [rad]", ",note")
    (folder.parent.parent / "bare" / "sec").mkdir(parents=True)
    bare = folder.parent.parent / "bare" / "sec"
    for f in folder.iterdir():
        (bare / f.name).write_text(f.read_text())
    (bare / "heading.csv").write_text(text.replace("heading [rad]", "magnetic_heading [rad]"))
    argv = ["real", "--format", "generic", "--data", str(bare), *CLI_ARMS, "--no-models",
            "--no-plots", "--quiet"]  # fmt: skip
    assert main([*argv, "--out", str(tmp_path / "a")]) == 2
    assert "is a magnetic heading: give the magnetic declination" in capsys.readouterr().err
    assert main([*argv, "--declination", "0", "--out", str(tmp_path / "b")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].endswith("give heading_sigma [deg] in the vehicle file")
    toml = tmp_path / "auv.toml"
    toml.write_text("heading_sigma = 0.5\ndeclination = 0.0\n")
    vehicle = load_vehicle(toml)
    assert vehicle.heading_sigma == pytest.approx(math.radians(0.5)) and vehicle.declination == 0
    assert main([*argv, "--filter", str(toml), "--out", str(tmp_path / "c")]) == 0
    config = json.loads((tmp_path / "c" / "config.json").read_text())["aiding"]
    assert config["heading_sigma_deg"] == pytest.approx(0.5) and config["declination_deg"] == 0
    assert main([*argv, "--no-heading", "--out", str(tmp_path / "d")]) == 0
    capsys.readouterr()
    rows = {d: _rows(tmp_path / d) for d in ("c", "d")}
    assert (rows["c"]["final_horizontal_error"] != rows["d"]["final_horizontal_error"]).any()
    for text, message in (
        ("heading_sigma = 0\n", "heading_sigma: a number of degrees > 0"),
        ("declination = 200\n", "declination: expected -180 … 180 deg"),
    ):
        toml.write_text(text)
        with pytest.raises(ValueError, match=message):
            load_vehicle(toml)
