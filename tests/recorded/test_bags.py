"""ROS bags: ROS 1 and ROS 2 (sqlite3, mcap) bags written with the
rosbags library's own writers read as the recording they were written from, run through
``pronet real`` as the same numbers written as CSV files do (to 1e-12), and bad input
named in one line before any work; without the extra, the extra is named."""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from pronet._util.extras import MissingExtra
from pronet.cli import main
from pronet.recorded.alignment import find_sections
from pronet.recorded.bags import BagTopics, require_rosbags
from pronet.recorded.recordings import RecordingError, read_recording, write_recording

from synthetic_recording import DVL_LEVER_ARM, IMU_LEVER_ARM, synthetic_recording

ARMS = [
    "--imu-lever-arm=" + ",".join(map(str, IMU_LEVER_ARM)),
    "--dvl-lever-arm=" + ",".join(map(str, DVL_LEVER_ARM)),
]


def _rosbags():
    pytest.importorskip(
        "rosbags.highlevel", reason="the rosbags extra: pip install 'pronet[rosbags]'"
    )
    pytest.importorskip("scipy", reason="the tests' bag writer turns DCMs into quaternions")
    from ros_bag import UNIX, write_bag

    return UNIX, write_bag


def _bag(tmp_path, storage="mcap", duration=60.0, **kw):
    unix, write_bag = _rosbags()
    rec = synthetic_recording(seed=3, duration=duration, name="mission").recording
    name = "mission.bag" if storage == "rosbag1" else "mission"
    path, topics = write_bag(tmp_path / name, rec, storage, **kw)
    return rec, path, topics, unix


@pytest.mark.parametrize("storage", ["mcap", "sqlite3", "rosbag1"])
@pytest.mark.parametrize("truth", ["odometry", "pose"])
def test_a_bag_reads_as_the_recording_it_was_written_from(tmp_path, storage, truth):
    rec, path, topics, unix = _bag(tmp_path, storage, truth=truth)
    got = read_recording(path, topics)
    assert got.name == "mission" and got.source == str(path)
    # FLU → FRD is a sign flip: exact; stamps at the nanoseconds a bag keeps
    np.testing.assert_array_equal(got.imu, rec.imu)
    np.testing.assert_array_equal(got.dvl, rec.dvl)
    for mine, theirs in ((got.imu_time, rec.imu_time), (got.dvl_time, rec.dvl_time)):
        np.testing.assert_allclose(mine - unix, theirs, rtol=0, atol=3e-7)
    np.testing.assert_allclose(got.gt_time - unix, rec.gt_time, rtol=0, atol=3e-7)
    # ENU metres about the origin → latitude, longitude, height; quaternions → ZYX angles
    np.testing.assert_allclose(got.gt_lla[:, :2], rec.gt_lla[:, :2], rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.gt_lla[:, 2], rec.gt_lla[:, 2], rtol=0, atol=1e-6)
    np.testing.assert_allclose(got.gt_rpy, rec.gt_rpy, rtol=0, atol=1e-12)
    if truth == "odometry":  # the twist, in the body, rotated into NED
        np.testing.assert_allclose(got.gt_vel, rec.gt_vel, rtol=0, atol=1e-12)
    else:  # central differences of 1 Hz positions: the velocity to a few cm/s
        np.testing.assert_allclose(got.gt_vel[1:-1], rec.gt_vel[1:-1], rtol=0, atol=0.05)
    assert got.dvl_variance is None  # a TwistStamped states no R
    assert find_sections(path) == [path] and find_sections(tmp_path) == [path]


def test_the_frames_are_options(tmp_path):
    """A bag recorded in FRD is taken as it is (``body_frame="frd"``: no flips). Read as
    FLU, its gyro's z axis turns against the truth's yaw: refused in one line (it read,
    every vector but x flipped)."""
    rec = synthetic_recording(seed=3, duration=60.0, name="mission").recording
    origin = (*np.degrees(rec.gt_lla[0, :2]).tolist(), float(rec.gt_lla[0, 2]))
    _, write_bag = _rosbags()
    path, topics = write_bag(
        tmp_path / "mission", rec, "mcap", topics=BagTopics(origin=origin, body_frame="frd")
    )
    assert topics.body_frame == "frd"
    np.testing.assert_array_equal(read_recording(path, topics).imu, rec.imu)
    with pytest.raises(RecordingError, match="turns against the gyro's z axis"):
        read_recording(path, replace(topics, body_frame="flu"))
    with pytest.raises(ValueError, match="body_frame: expected flu or frd"):
        BagTopics(body_frame="rfu")


def test_the_dvl_covariance_is_r_as_the_median_of_the_set_diagonals(tmp_path):
    rng = np.random.default_rng(0)
    n = len(synthetic_recording(seed=3, duration=60.0).recording.dvl_time)
    cov = rng.uniform(1e-4, 3e-4, (n, 3))
    cov[::7] = 0.0  # "unknown": not set, left out
    cov[1, 0] = -1.0  # "not provided"
    _, path, topics, _ = _bag(tmp_path, dvl_covariance=cov)
    got = read_recording(path, topics)
    set_ = cov[(cov > 0).all(axis=1)]
    np.testing.assert_array_equal(got.dvl_variance, np.median(set_, axis=0))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"imu": "/imu/raw"}, "no topic '/imu/raw' for the IMU; the bag has: /dvl/twist "),
        ({"dvl": "/imu/data"}, "[/imu/data]: the DVL topic holds sensor_msgs/msg/Imu; expected"),
        ({"origin": None}, "[/odometry]: the truth's positions are local metres; give"),
    ],
)
def test_bad_topics_are_one_line_naming_bag_and_topic(tmp_path, change, message):
    _, path, topics, _ = _bag(tmp_path, duration=30.0)
    with pytest.raises(RecordingError) as err:
        read_recording(path, replace(topics, **change))
    assert str(path) in str(err.value) and message in str(err.value)
    assert "\n" not in str(err.value)


def test_the_cli_names_a_missing_topic_and_exits_2_before_any_work(tmp_path, capsys):
    _, path, topics, _ = _bag(tmp_path, duration=30.0)
    origin = ",".join(map(str, topics.origin))
    argv = ["real", "--format", "bag", "--data", str(path), "--origin", origin, *ARMS]
    out = tmp_path / "out"
    assert main([*argv, "--imu-topic", "/imu", "--out", str(out), "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert "no topic '/imu' for the IMU; the bag has: /dvl/twist" in err and "/odometry" in err
    assert not out.exists()
    assert main([*argv[:5], *ARMS, "--out", str(out)]) == 2  # no --origin
    assert "--format bag: needs --origin" in capsys.readouterr().err
    csv = ["real", "--format", "generic", "--data", str(path), *ARMS, "--out", str(out)]
    assert main([*csv, "--imu-topic", "/imu"]) == 2
    assert "--imu-topic: only with --format bag" in capsys.readouterr().err
    assert main(csv) == 2  # a bag given as the generic format: said so
    assert f"{path}: a ROS bag; read it with --format bag (format generic)" in (
        capsys.readouterr().err
    )
    assert not out.exists()


@pytest.mark.slow
@pytest.mark.parametrize("storage", ["mcap", "rosbag1"])
def test_a_bag_runs_through_pronet_real_as_its_csvs_do_to_1e_12(tmp_path, capsys, storage):
    """The worked example of docs/how-to/ros-bags.md: a bag, its topics and origin, the lever
    arms; the same numbers written as CSVs (``write_recording`` of the bag as read) give
    the same metrics to 1e-12, and the bag's covariance is the R used."""
    rec = synthetic_recording(seed=3, duration=100.0, name="mission").recording
    cov = np.full((len(rec.dvl_time), 3), 2.5e-4)
    _, path, topics, _ = _bag(tmp_path, storage, duration=100.0, dvl_covariance=cov)
    origin = ",".join(f"{v:.17g}" for v in topics.origin)
    argv = ["real", "--format", "bag", "--data", str(path), "--imu-topic", "/imu/data"]
    argv += ["--dvl-topic", "/dvl/twist", "--truth-topic", "/odometry", "--origin", origin]
    assert main([*argv, *ARMS, "--out", str(tmp_path / "bag"), "--no-plots", "--quiet"]) == 0
    as_read = read_recording(path, topics)
    csvs = write_recording(tmp_path / "csv" / "mission", as_read)
    assert read_recording(csvs).imu_time.tolist() == as_read.imu_time.tolist()
    # the CSVs state no R: the bag's, through --filter, for the same filter
    (tmp_path / "r.toml").write_text("[filter]\ndvl_variance = [2.5e-4, 2.5e-4, 2.5e-4]\n")
    argv = [
        "real",
        "--format",
        "generic",
        "--data",
        str(csvs),
        "--filter",
        str(tmp_path / "r.toml"),
    ]
    assert main([*argv, *ARMS, "--out", str(tmp_path / "csv-out"), "--no-plots", "--quiet"]) == 0
    capsys.readouterr()
    bag, csv = (pd.read_csv(tmp_path / d / "metrics.csv") for d in ("bag", "csv-out"))
    assert list(bag.strategy) == list(csv.strategy) and len(bag) > 5
    numbers = bag.select_dtypes("number").columns
    np.testing.assert_allclose(bag[numbers], csv[numbers], rtol=1e-12, atol=1e-12)
    config = json.loads((tmp_path / "bag" / "config.json").read_text())
    assert config["format"]["format"] == "bag" and config["format"]["dvl_topic"] == "/dvl/twist"
    assert config["dvl_variance_bag"] == {"mission": [2.5e-4] * 3}
    assert config["dvl_variance"]["mission"]["used"] == [2.5e-4] * 3
    table = (tmp_path / "bag" / "table.md").read_text()
    assert "| mission | 0.0158 / 0.0158 / 0.0158 (the bag's) |" in table
    assert "(the bag's)" not in (tmp_path / "csv-out" / "table.md").read_text()
    assert np.isfinite(bag.srmse).all() and bag.srmse.iloc[0] < 0.1
    # the command of docs/how-to/ros-bags.md's worked example is this one
    docs = (Path(__file__).parents[2] / "docs" / "how-to" / "ros-bags.md").read_text()
    assert "pronet real --format bag --data mission.bag --imu-topic /imu/data --dvl-topic " in docs
    assert "/dvl/twist \\\n    --truth-topic /odometry --origin 32.8,34.95,0" in docs


def test_without_the_extra_it_is_named_in_one_line(tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "rosbags", None)  # import rosbags… fails
    monkeypatch.setitem(sys.modules, "rosbags.highlevel", None)
    with pytest.raises(MissingExtra) as err:
        require_rosbags()
    assert str(err.value) == (
        "reading ROS bags needs rosbags, which is not installed: pip install 'pronet[rosbags]'"
    )
    argv = ["real", "--format", "bag", "--data", str(tmp_path), "--origin", "32,35,0", *ARMS]
    assert main([*argv, "--out", str(tmp_path / "out")]) == 2
    err_lines = capsys.readouterr().err.strip().splitlines()
    assert len(err_lines) == 1 and "pip install 'pronet[rosbags]'" in err_lines[0]


@pytest.mark.parametrize("storage", [pytest.param("mcap", marks=pytest.mark.slow), "rosbag1"])
@pytest.mark.parametrize("sigma_in_file", [True, False])
def test_depth_from_pressure_and_fixes_from_navsatfix(tmp_path, storage, sigma_in_file):
    """FluidPressure [Pa] read back as depth [m] through the documented conversion, and
    NavSatFix as fixes, its covariance (ENU) as σ north, east, down; a fix without a
    covariance, or a pressure without a variance, leaves σ as tuned; a NO_FIX status is
    a missing value; the topics are options, and pronet real runs on the bag."""
    unix, write_bag = _rosbags()
    from synthetic_recording import with_aiding

    rec = with_aiding(synthetic_recording(seed=3, duration=60.0, name="mission"), seed=3,
                      fix_every=10.0, sigma_in_file=sigma_in_file)  # fmt: skip
    name = "mission.bag" if storage == "rosbag1" else "mission"
    path, topics = write_bag(tmp_path / name, rec, storage, no_fix=(2,))
    assert topics.depth == "/depth/pressure" and topics.fix == "/gnss/fix"
    got = read_recording(path, topics)
    assert got.depth is not None and got.fixes is not None
    assert rec.depth is not None and rec.fixes is not None
    np.testing.assert_allclose(got.depth.time - unix, rec.depth.time, rtol=0, atol=3e-7)
    np.testing.assert_allclose(got.depth.depth, rec.depth.depth, rtol=0, atol=1e-9)
    kept = np.arange(len(rec.fixes.time)) != 2  # the third: NO_FIX, skipped
    assert got.fixes.skipped_reason == ("nan",)
    np.testing.assert_allclose(got.fixes.skipped_time - unix, rec.fixes.time[2], atol=3e-7)
    np.testing.assert_allclose(got.fixes.lla[:, :2], rec.fixes.lla[kept, :2], rtol=0, atol=1e-15)
    np.testing.assert_array_equal(got.fixes.lla[:, 2], rec.fixes.lla[kept, 2])  # NaN: horizontal
    if sigma_in_file:
        np.testing.assert_allclose(got.depth.sigma, rec.depth.sigma, rtol=1e-12)  # type: ignore[arg-type]
        np.testing.assert_allclose(got.fixes.sigma, rec.fixes.sigma[kept], rtol=1e-15)  # type: ignore[index]
    else:
        assert got.depth.sigma is None and got.fixes.sigma is None
    # a surface pressure of 2 bar: 10 m too shallow, refused against the truth
    with pytest.raises(RecordingError, match=r"\[/depth/pressure\]: column 'depth' lies a "
                       r"median -1\d\.\d+ m from the ground truth's depth"):  # fmt: skip
        read_recording(path, replace(topics, surface_pressure=2e5))
    with pytest.raises(RecordingError, match=r"\[/dvl/twist\]: the fix topic holds "):
        read_recording(path, replace(topics, fix="/dvl/twist"))
    assert read_recording(path, replace(topics, depth=None, fix=None)).fixes is None
    assert len(read_recording(path, replace(topics, dvl=None)).dvl) == 0  # GNSS/INS
    with pytest.raises(RecordingError, match="without a DVL topic, needs a depth or a fix"):
        read_recording(path, replace(topics, dvl=None, depth=None, fix=None))
    origin = ",".join(map(str, topics.origin or ()))
    argv = ["real", "--format", "bag", "--data", str(path), "--origin", origin, *ARMS,
            "--depth-topic", "/depth/pressure", "--fix-topic", "/gnss/fix", "--no-models",
            "--no-plots", "--quiet", "--no-dvl", "--out", str(tmp_path / "out")]  # fmt: skip
    assert main(argv) == 0
    config = json.loads((tmp_path / "out" / "config.json").read_text())
    assert config["format"]["fix_topic"] == "/gnss/fix" and config["format"]["dvl_topic"] is None
    assert config["aiding"]["sections"]["mission"]["fixes"]["rows"] == len(rec.fixes.time) - 1


def test_the_bag_format_refuses_what_is_no_bag(tmp_path, capsys):
    """``--format bag`` on a folder of CSVs read it as the generic format, with the bag
    options recorded as used: now one line naming the folder, before any work; the
    reader refuses bag topics for anything but a bag."""
    rec = synthetic_recording(seed=3, duration=30.0, name="csv").recording
    folder = write_recording(tmp_path / "data" / "csv", rec)
    out = tmp_path / "out"
    argv = ["real", "--data", str(folder), "--format", "bag", "--origin", "32,34,0", *ARMS]
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra")
    assert main([*argv, "--no-models", "--no-plots", "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"{folder}: not a ROS bag" in err and len(err.splitlines()) == 1, err
    assert not out.exists()
    with pytest.raises(RecordingError, match=r"csv: not a ROS bag .*--format generic"):
        read_recording(folder, BagTopics())


@pytest.mark.slow
def test_frame_and_origin_slips_in_a_bag_are_named(tmp_path, capsys):
    """Frame slips at the bag level: an ENU world read as NED is refused (the truth's
    yaw turns against the gyro's z), a FLU body read as FRD too (the truth turns over
    with the IMU, said as a warning, and its yaw turns against the gyro's z: it ran,
    rolled by 180°, its lever arms mirrored), and an
    ``--origin`` in radians is flagged by the health monitor: the DVL's NIS above its
    band, named in config.json, where the right origin's is not."""
    _, path, topics, _ = _bag(tmp_path, duration=100.0)
    o = topics.origin
    argv = ["real", "--format", "bag", "--data", str(path), "--imu-topic", "/imu/data"]
    argv += ["--dvl-topic", "/dvl/twist", "--truth-topic", "/odometry", *ARMS]
    argv += ["--no-plots", "--quiet", "--no-models"]
    right = ["--origin", f"{o[0]!r},{o[1]!r},{o[2]!r}"]

    def run(name: str, *extra: str) -> tuple[int, str, list[str]]:
        code = main([*argv, *extra, "--out", str(tmp_path / name)])
        config = tmp_path / name / "config.json"
        notes = json.loads(config.read_text())["notes"] if config.exists() else []
        return code, capsys.readouterr().err, notes

    code, err, _ = run("ned", *right, "--world-frame", "ned")
    assert code == 2 and "turns against the gyro's z axis" in err and "in ENU" in err, err
    code, err, _ = run("frd", *right, "--body-frame", "frd")
    assert code == 2 and "the roll is beyond ±90° at 100 % of the rows" in err
    assert "turns against the gyro's z axis" in err and "(FLU as FRD)" in err, err
    code, err, notes = run("right", *right)
    assert code == 0 and "roll is beyond" not in err
    assert not [n for n in notes if ": dvl: mean NIS" in n and "above its 95 % band" in n]
    radians = ",".join(repr(float(v)) for v in (np.radians(o[0]), np.radians(o[1]), o[2]))
    code, err, notes = run("radians", "--origin", radians)
    above = [n for n in notes if ": dvl: mean NIS" in n and "above its 95 % band" in n]
    assert code == 0 and len(above) == 1 and above[0] in err
