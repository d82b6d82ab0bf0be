"""Recordings without a ground truth (a vehicle's own mission): the generic folder, the
``.npz`` and ROS 1 and ROS 2 bags read without one, their truth arrays empty and said
so (``has_truth``); no clock is estimated (the DVL's the identity unless given, and the
alignment says so); whatever scores against a truth refuses them in one line."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pronet.cli import main
from pronet.recorded import missing
from pronet.recorded.alignment import (
    Alignment,
    Clock,
    estimate_dvl_clock,
    estimate_gt_clock,
    load_section,
)
from pronet.recorded.bags import topic_types
from pronet.recorded.dvltruth import truth_calibration
from pronet.recorded.metrics import section_metrics
from pronet.recorded.passes import start_index
from pronet.recorded.recordings import Recording, RecordingError, read_recording, write_recording

from synthetic_recording import DVL_LEVER_ARM, IMU_LEVER_ARM, synthetic_recording, with_aiding

ARMS = {"imu_lever_arm": IMU_LEVER_ARM, "dvl_lever_arm": DVL_LEVER_ARM}
CLI_ARMS = [
    "--imu-lever-arm=" + ",".join(map(str, IMU_LEVER_ARM)),
    "--dvl-lever-arm=" + ",".join(map(str, DVL_LEVER_ARM)),
]


def without_truth(rec: Recording) -> Recording:
    empty = np.empty((0, 3))
    return replace(rec, gt_time=np.empty(0), gt_lla=empty, gt_vel=empty, gt_rpy=empty)


@pytest.fixture(scope="module")
def mission():
    """A 60 s recording with depth and fixes, and the same without its ground truth."""
    rec = with_aiding(synthetic_recording(seed=5, duration=60.0, name="mission"), seed=5)
    return rec, without_truth(rec)


@pytest.mark.parametrize("where", ["mission", "mission.npz"])
def test_a_folder_and_an_npz_without_truth_read(tmp_path, mission, where):
    rec, bare = mission
    path = write_recording(tmp_path / where, bare)
    if path.is_dir():
        assert {p.name for p in path.iterdir()} == {"imu.csv", "dvl.csv", "depth.csv", "fix.csv"}
    else:
        assert not {"gt", "gt_columns"} & set(np.load(path).files)
    got = read_recording(path)
    assert not got.has_truth and rec.has_truth
    assert got.gt_time.shape == (0,) and got.gt_lla.shape == got.gt_rpy.shape == (0, 3)
    assert got.gt_vel.shape == (0, 3)
    for name in ("imu_time", "imu", "dvl_time", "dvl"):
        np.testing.assert_array_equal(getattr(got, name), getattr(rec, name), err_msg=name)
    assert got.depth is not None and got.fixes is not None and rec.fixes is not None
    np.testing.assert_array_equal(got.fixes.lla, rec.fixes.lla)


def test_no_clock_is_estimated_without_truth_and_the_alignment_says_so(tmp_path, mission):
    rec, bare = mission
    folder = write_recording(tmp_path / "mission", bare)
    aligned, stamped = load_section(folder, "generic", **ARMS)
    assert not aligned.has_truth and not stamped.has_truth
    assert aligned.truth_time.shape == (0,) and aligned.truth_lla.shape == (0, 3)
    a = aligned.alignment
    assert (a.how, a.gt_clock_how, a.dvl_clock_how) == ("assumed", "none", "assumed")
    assert a.dvl_clock == Clock() and a.filter_lever_arm == Alignment(**ARMS).filter_lever_arm
    np.testing.assert_array_equal(aligned.dvl_time, rec.dvl_time - rec.imu_time[0])
    given = Clock(offset=1.0, scale=0.9975)
    on_given, _ = load_section(folder, "generic", **ARMS, dvl_clock=given)
    assert (on_given.alignment.how, on_given.alignment.dvl_clock_how) == ("given", "given")
    np.testing.assert_array_equal(on_given.dvl_time, given(rec.dvl_time - rec.imu_time[0]))
    # with the truth, as before: both estimated; a given DVL clock is used as given
    with_truth, _ = load_section(write_recording(tmp_path / "truth", rec), "generic", **ARMS)
    assert (with_truth.alignment.gt_clock_how, with_truth.alignment.dvl_clock_how) == (
        "estimated",
        "estimated",
    )
    for estimate in (
        lambda: estimate_gt_clock(bare),
        lambda: estimate_dvl_clock(bare, Clock()),
    ):
        with pytest.raises(ValueError, match="no ground truth to estimate"):
            estimate()
    with pytest.raises(ValueError, match=r"aiding_clock 'gt' .*has no ground truth"):
        load_section(folder, "generic", **ARMS, aiding_clock="gt")


def test_what_scores_against_a_truth_refuses_a_section_without_one(tmp_path, mission):
    _, bare = mission
    aligned, _ = load_section(write_recording(tmp_path / "mission", bare), "generic", **ARMS)
    refused = "section mission has no ground truth: "
    with pytest.raises(ValueError, match=f"^{refused}pronet real scores against one; pronet "):
        start_index(aligned)
    with pytest.raises(ValueError, match=f"^{refused}its errors are taken against one$"):
        section_metrics(aligned, None)  # type: ignore[arg-type]  # refused before it is read
    with pytest.raises(ValueError, match=f"^{refused}the DVL is fitted against one$"):
        truth_calibration(aligned)


def test_pronet_real_on_a_recording_without_truth_is_one_line(tmp_path, mission, capsys):
    _, bare = mission
    folder = write_recording(tmp_path / "data" / "mission", bare)
    out = tmp_path / "out"
    argv = ["real", "--format", "generic", "--data", str(folder), *CLI_ARMS, "--no-models"]
    assert main([*argv, "--no-plots", "--quiet", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "pronet: section mission: no ground truth: pronet real scores against one; pronet "
        "navigate runs without"
    ]
    assert not out.exists()


def test_zero_dvl_rows_without_truth_follow_the_dvl_s_own_speed(tmp_path, mission):
    """All-zero rows amid the readings of a moving vehicle are dropouts, with or without
    a truth; amid readings near rest they are readings."""
    rec, bare = mission
    dvl = rec.dvl.copy()
    dvl[[10, 11, 30]] = 0.0
    for recording in (rec, bare):
        got = read_recording(write_recording(tmp_path / "x", replace(recording, dvl=dvl)))
        assert got.dvl_skipped_reason == ("zero",) * 3
        np.testing.assert_array_equal(got.dvl_skipped_time, rec.dvl_time[[10, 11, 30]])
    t = np.arange(8.0)
    vel = np.array([[1.5, 0, 0], [0, 0, 0], [1.4, 0, 0], [0.05, 0, 0], [0, 0, 0], [0.04, 0, 0],
                    [np.nan, 0, 0], [0, 0, 0]])  # fmt: skip
    speed = missing.own_speed(t, vel, None)
    np.testing.assert_allclose(speed[[1, 4, 7]], [1.45, 0.045, 0.04])
    why = missing.classify(vel, None, speed)
    assert why.tolist() == ["", "zero", "", "", "", "", "nan", ""]
    assert (missing.own_speed(t[:2], np.zeros((2, 3)), None) == 0).all()


def test_a_dvl_in_cm_per_s_without_truth_is_refused(tmp_path, mission):
    _, bare = mission
    folder = write_recording(tmp_path / "cm", replace(bare, dvl=bare.dvl * 10))
    with pytest.raises(RecordingError, match=r"dvl: its median speed 1\d\.\d+ m/s is beyond any"):
        read_recording(folder)


def _rosbags():
    pytest.importorskip(
        "rosbags.highlevel", reason="the rosbags extra: pip install 'pronet[rosbags]'"
    )
    pytest.importorskip("scipy", reason="the tests' bag writer turns DCMs into quaternions")
    from ros_bag import UNIX, write_bag

    return UNIX, write_bag


@pytest.mark.parametrize("storage", ["mcap", "sqlite3", "rosbag1"])
def test_ros_bags_without_truth_read(tmp_path, mission, storage):
    unix, write_bag = _rosbags()
    rec, _ = mission
    name = "mission.bag" if storage == "rosbag1" else "mission"
    path, topics = write_bag(tmp_path / name, rec, storage, truth="none")
    assert topics.truth is None and topics.origin is None  # no origin needed without a truth
    got = read_recording(path, topics)
    assert not got.has_truth and got.gt_lla.shape == (0, 3)
    np.testing.assert_array_equal(got.imu, rec.imu)
    np.testing.assert_array_equal(got.dvl, rec.dvl)
    np.testing.assert_allclose(got.imu_time - unix, rec.imu_time, rtol=0, atol=3e-7)
    assert got.depth is not None and got.fixes is not None and rec.depth is not None
    np.testing.assert_allclose(got.depth.depth, rec.depth.depth, rtol=0, atol=1e-9)
    aligned, _ = load_section(path, topics, **ARMS)
    assert not aligned.has_truth and aligned.alignment.how == "assumed"
    assert topic_types(path) == {
        "/imu/data": "sensor_msgs/msg/Imu",
        "/dvl/twist": "geometry_msgs/msg/TwistStamped",
        "/depth/pressure": "sensor_msgs/msg/FluidPressure",
        "/gnss/fix": "sensor_msgs/msg/NavSatFix",
    }
    # read as pronet real reads it (a truth topic named): one line naming the topic
    with pytest.raises(RecordingError) as err:
        read_recording(path, replace(topics, truth="/odometry", origin=(32.0, 35.0, 0.0)))
    message = str(err.value)
    assert "no topic '/odometry' for the truth; the bag has: " in message and "\n" not in message
    assert message.endswith("; pronet navigate runs without a truth")
