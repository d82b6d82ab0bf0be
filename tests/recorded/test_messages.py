"""pronet.recorded.messages: one ROS message at a time converted as the bag reader
converts a whole topic (the same numbers), on a bag of a simulated survey."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from mission_recording import simulate_mission, write_mission_bag

from pronet.recorded.messages import MessageConverter
from pronet.recorded.recordings import read_recording


@pytest.mark.parametrize("storage", [pytest.param("rosbag1", marks=pytest.mark.slow), "mcap"])
def test_each_message_converts_as_the_reader_converts_its_topic(tmp_path, storage) -> None:
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra")
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    m = simulate_mission(1, minutes=3.0)
    name = "mission.bag" if storage == "rosbag1" else "mission"
    bag, topics = write_mission_bag(m, tmp_path / name, storage)
    topics = dataclasses.replace(topics, heading=topics.imu)  # the AHRS's yaw
    rec = read_recording(bag, topics)
    convert = MessageConverter(topics)
    got: dict[str, list] = {k: [] for k in ("imu", "attitude", "dvl", "depth", "fix", "heading")}
    with AnyReader([bag], default_typestore=get_typestore(Stores.LATEST)) as reader:
        for connection, _, raw in reader.messages():
            msg = reader.deserialize(raw, connection.msgtype)
            if connection.topic == topics.imu:
                got["imu"].append(convert.imu(msg))
                got["attitude"].append(convert.orientation(msg))
                got["heading"].append(convert.heading(msg))
            elif connection.topic == topics.dvl:
                got["dvl"].append(convert.dvl(msg))
            elif connection.topic == topics.depth:
                got["depth"].append(convert.depth(msg))
            elif connection.topic == topics.fix:
                got["fix"].append(convert.fix(msg))
    t, imu = zip(*got["imu"], strict=True)
    np.testing.assert_array_equal(t, rec.imu_time)
    np.testing.assert_array_equal(np.array(imu), rec.imu)
    t, v, sigma = zip(*got["dvl"], strict=True)
    np.testing.assert_array_equal(t, rec.dvl_time)
    np.testing.assert_array_equal(np.array(v), rec.dvl)
    np.testing.assert_allclose(np.array(sigma) ** 2, [rec.dvl_variance] * len(t), rtol=1e-12)
    assert rec.depth is not None and rec.fixes is not None and rec.heading is not None
    t, depth, sigma = zip(*got["depth"], strict=True)
    np.testing.assert_array_equal(t, rec.depth.time)
    np.testing.assert_array_equal(depth, rec.depth.depth)
    fixes = [f for f in got["fix"] if f is not None]
    np.testing.assert_array_equal([f[0] for f in fixes], rec.fixes.time)
    np.testing.assert_array_equal(np.array([f[1] for f in fixes]), rec.fixes.lla)
    headings = [h for h in got["heading"] if h is not None]
    np.testing.assert_array_equal([h[0] for h in headings], rec.heading.time)
    np.testing.assert_array_equal([h[1] for h in headings], rec.heading.heading)
    # the AHRS's attitude with every IMU message, its yaw the heading's
    rpy = np.array([a[1] for a in got["attitude"] if a is not None])
    assert len(rpy) == len(imu)
    yaw = np.array([h[1] for h in got["heading"]])
    np.testing.assert_allclose(np.angle(np.exp(1j * (rpy[:, 2] - yaw))), 0.0, atol=1e-12)
