"""The bag reader's NumPy decoding of raw messages (:mod:`pronet.recorded.bagfields`)
gives the deserializer's bits: whole bags of each kind (ROS 1 ``.bag``, ROS 2 sqlite3
and mcap) whose frame_ids vary in length from message to message read the same through
both paths, and every message the fast path must not decode (big-endian CDR, padding
beyond what the deserializer allows, a frame_id that is not UTF-8 or not terminated,
a type of another layout) goes to the deserializer: the same numbers, or its error."""

from __future__ import annotations

from dataclasses import replace
from itertools import count
from types import SimpleNamespace

import numpy as np
import pytest

from pronet.recorded import bagfields
from pronet.recorded.bags import bag_streams

from synthetic_recording import synthetic_recording, with_aiding

#: Frame ids of every length 0–11 and beyond, ASCII and not (UTF-8 of 2 and 3 bytes).
FRAME_IDS = ("", "a", "ab", "imu", "base", "base_", "base_l", "base_li", "base_lin")
FRAME_IDS += ("base_link", "imu_link_10", "imu_link_011", "bäse_lïnk", "船体", "x" * 37)
IMU = "sensor_msgs/msg/Imu"
IMU_FIELDS = ("linear_acceleration.x", "angular_velocity.z", "orientation_covariance[8]")


def _rosbags():
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra")
    pytest.importorskip("scipy", reason="the tests' bag writer turns DCMs into quaternions")
    import ros_bag

    return ros_bag


def _varying_frame_ids(monkeypatch, ros_bag) -> None:
    """Every message the tests' writer builds gets the next of :data:`FRAME_IDS`."""
    header, made = ros_bag.BagMessages.header, count()

    def varying(self, stamp):
        return replace(header(self, stamp), frame_id=FRAME_IDS[next(made) % len(FRAME_IDS)])

    monkeypatch.setattr(ros_bag.BagMessages, "header", varying)


@pytest.mark.parametrize("storage", ["rosbag1", "sqlite3", "mcap"])
@pytest.mark.parametrize("heading", ["own", "imu"])
def test_a_bag_reads_to_the_bit_as_its_deserialized_messages(
    tmp_path, monkeypatch, storage, heading
):
    ros_bag = _rosbags()
    _varying_frame_ids(monkeypatch, ros_bag)
    syn = synthetic_recording(seed=5, duration=40.0, imu_rate=200.0, dvl_rate=5.0)
    rec = with_aiding(syn, fix_every=5.0)
    cov = np.full((len(rec.dvl_time), 3), 1e-4)
    variance = np.full(len(ros_bag.heading_attitude(rec, heading)[0]), 2e-4)
    name = "m.bag" if storage == "rosbag1" else "m"
    path, topics = ros_bag.write_bag(
        tmp_path / name, rec, storage, dvl_covariance=cov, heading=heading,
        heading_variance=variance, no_orientation=(3, 9),
    )  # fmt: skip
    decoded = []
    real_decode = bagfields._decode

    def spy(raws, *args):
        ok, ints, values = real_decode(raws, *args)
        decoded.append((len(raws), int(ok.sum())))
        return ok, ints, values

    monkeypatch.setattr(bagfields, "_decode", spy)
    fast, r_fast = bag_streams(path, topics)
    assert decoded and all(n == ok for n, ok in decoded), decoded  # every message decoded
    assert decoded[0][0] == len(rec.imu_time)
    monkeypatch.setattr(bagfields, "fast_path_applies", lambda reader, connections: False)
    slow, r_slow = bag_streams(path, topics)
    assert len(decoded) == (1 if heading == "own" else 2)  # the deserializer only, now
    assert fast.keys() == slow.keys() == {"imu", "dvl", "gt", "depth", "fix", "heading"}
    for kind, table in fast.items():
        assert table.labels == slow[kind].labels and table.reasons == slow[kind].reasons
        assert table.values.tobytes() == slow[kind].values.tobytes(), kind
    assert r_fast == r_slow and fast["heading"].reasons.count("no orientation") == 2
    np.testing.assert_array_equal(fast["imu"].values[:, 1:], rec.imu)  # FLU written, FRD read


def _reader(ros1: bool = False):
    """What :func:`bagfields.topic_fields` asks of a rosbags reader, on the stock types."""
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra")
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    deserialize = store.deserialize_ros1 if ros1 else store.deserialize_cdr
    return SimpleNamespace(typestore=store, is2=not ros1, deserialize=deserialize), store


def _imu(store, k: int, frame_id: str = "base_link", ros1: bool = False):
    t = store.types
    value = float(k) + 0.125
    vec = t["geometry_msgs/msg/Vector3"](x=value, y=-value, z=1e-300 * value)
    stamp = t["builtin_interfaces/msg/Time"](sec=1_700_000_000 + k, nanosec=999_999_999 - k)
    header = t["std_msgs/msg/Header"](
        **({"seq": k} if ros1 else {}), stamp=stamp, frame_id=frame_id
    )
    cov = np.arange(9.0) * value
    return t[IMU](
        header=header, orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=cov, angular_velocity=vec, angular_velocity_covariance=cov,
        linear_acceleration=vec, linear_acceleration_covariance=cov,
    )  # fmt: skip


@pytest.mark.parametrize("ros1", [False, True])
def test_messages_the_fast_path_refuses_are_deserialized_in_their_place(ros1):
    reader, store = _reader(ros1)
    serialize = store.serialize_ros1 if ros1 else store.serialize_cdr
    raws = [bytes(serialize(_imu(store, k, FRAME_IDS[k % 15], ros1), IMU)) for k in range(60)]
    if not ros1:
        raws[7] = bytes(store.serialize_cdr(_imu(store, 7), IMU, little_endian=False))
        raws[8] = raws[8] + b"\0\0\0"  # padding the deserializer allows
    fast = bagfields.topic_fields(reader, IMU, raws, IMU_FIELDS)
    slow = bagfields.topic_fields(reader, IMU, raws, IMU_FIELDS, fast=False)
    assert fast.tobytes() == slow.tobytes()
    assert slow[1, 0] == 1_700_000_001 + 999_999_998 * 1e-9 and slow[1, 1] == 1.125
    ok, _, _ = bagfields._decode(raws, bagfields.layout(reader.typestore, IMU), not ros1, [0])
    assert ok.sum() == (60 if ros1 else 59)  # the big-endian one deserialized


@pytest.mark.parametrize(
    ("spoil", "ros1", "error"),
    [
        (lambda raw: raw + b"\0\0\0\0", False, "size mismatch"),
        (lambda raw: raw + b"\0", True, "size mismatch"),
        (lambda raw: raw[:16] + b"\xff" + raw[17:], False, "invalid start byte"),
        (lambda raw: raw[:16] + b"\xff" + raw[17:], True, "invalid start byte"),
        (lambda raw: raw[:25] + b"!" + raw[26:], False, "Missing string terminator"),
        (lambda raw: raw[:12] + b"\xff\xff\xff\x7f" + raw[16:], False, "Invalid string length"),
        (lambda raw: raw[:12] + b"\xff\xff\xff\x7f" + raw[16:], True, "Invalid string length"),
    ],
)  # fmt: skip
def test_a_malformed_message_raises_the_deserializer_s_error(spoil, ros1, error):
    """The fast path does not read past what the deserializer would refuse: such a
    message goes to the deserializer, whose error the bag reader reports."""
    reader, store = _reader(ros1)
    serialize = store.serialize_ros1 if ros1 else store.serialize_cdr
    raws = [bytes(serialize(_imu(store, k, ros1=ros1), IMU)) for k in range(5)]
    raws[2] = spoil(raws[2])
    with pytest.raises(Exception, match=error):
        bagfields.topic_fields(reader, IMU, raws, IMU_FIELDS)


def test_the_layout_is_the_bag_s_own_definition():
    reader, store = _reader()
    imu = bagfields.layout(store, IMU)
    assert imu is not None and imu.floats == 37
    assert imu.ints == (("header.stamp.sec", True), ("header.stamp.nanosec", False))
    assert imu.columns["orientation.w"] == 3 and imu.columns["linear_acceleration.x"] == 25
    assert imu.columns["orientation_covariance[8]"] == 12
    ros1 = bagfields.layout(_reader(ros1=True)[1], IMU)
    assert ros1 is not None and ros1.ints[0] == ("header.seq", False)
    twist = bagfields.layout(store, "geometry_msgs/msg/TwistWithCovarianceStamped")
    assert twist is not None and twist.floats == 42
    # a second string, a byte and a 16-bit status, a sequence: not one fixed layout
    for other in ("nav_msgs/msg/Odometry", "sensor_msgs/msg/NavSatFix", "std_msgs/msg/String"):
        assert bagfields.layout(store, other) is None
    from rosbags.typesys import get_types_from_msg

    odd = "std_msgs/Header header\nfloat64 x\nuint8 n\n"  # a custom type, not all float64
    store.register(get_types_from_msg(odd, "my_msgs/msg/Odd"))
    assert bagfields.layout(store, "my_msgs/msg/Odd") is None
