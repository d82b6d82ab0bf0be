"""A recording written as a ROS bag with the rosbags library's own writers (ROS 1
``.bag``, ROS 2 sqlite3 or mcap), in ROS's frames (REP-103: body FLU, world ENU; or the
topics' FRD and NED), as a ROS vehicle would record it: the inverse of
:mod:`pronet.recorded.bags`.

:func:`write_bag` writes a :class:`~pronet.recorded.recordings.Recording`;
:class:`BagMessages` builds the messages of each stream (IMU, DVL, truth, pressure,
fixes) for it and for other writers (``mission_recording.write_mission_bag``)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from pronet import local_ned
from pronet.recorded.alignment import dcm_from_euler
from pronet.recorded.bags import STANDARD_GRAVITY, BagTopics
from pronet.recorded.recordings import Recording

#: Added to every stamp: bags carry Unix time (and ROS 1 stamps are unsigned).
UNIX = 1_700_000_000
_FLU = np.diag([1.0, -1.0, -1.0])
_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
STORAGES = ("rosbag1", "sqlite3", "mcap")
#: The heading topics :func:`write_bag` writes, by name: their message types.
HEADING_TYPES = {
    "imu": "sensor_msgs/msg/Imu",
    "quaternion": "geometry_msgs/msg/QuaternionStamped",
    "pose": "geometry_msgs/msg/PoseStamped",
    "pose_covariance": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "own": "sensor_msgs/msg/Imu",
}


def _frames(body_frame: str = "flu", world_frame: str = "enu") -> tuple[np.ndarray, np.ndarray]:
    """The body frame from FRD and the world frame from NED, as matrices."""
    return (_FLU if body_frame == "flu" else np.eye(3)), (
        _ENU if world_frame == "enu" else np.eye(3)
    )


def ros_quaternions(
    rpy: np.ndarray, body_frame: str = "flu", world_frame: str = "enu"
) -> np.ndarray:
    """``(k, 4)`` quaternions ``x, y, z, w`` of the body → world rotation (default FLU →
    ENU) of the attitudes ``rpy`` ``(k, 3)`` [rad] (ZYX, body FRD → NED)."""
    from scipy.spatial.transform import Rotation

    d_b, t_w = _frames(body_frame, world_frame)
    c_wb = t_w @ dcm_from_euler(rpy) @ d_b
    return np.asarray(Rotation.from_matrix(c_wb).as_quat())


def heading_attitude(rec: Recording, heading: str) -> tuple[np.ndarray, np.ndarray]:
    """The stamps [s, as ``rec``'s] and roll, pitch, yaw [rad] :func:`write_bag` writes
    on a heading topic of kind ``heading``: the truth's rows, or (``"own"``: in the IMU
    messages) the truth's angles interpolated (unwrapped) at the IMU's stamps."""
    if heading != "own":
        return rec.gt_time, rec.gt_rpy
    rpy = np.unwrap(rec.gt_rpy, axis=0)
    at = np.column_stack([np.interp(rec.imu_time, rec.gt_time, rpy[:, j]) for j in range(3)])
    return rec.imu_time, at


class BagMessages:
    """The messages of one bag, built stream by stream in ROS's frames and written at
    once (:meth:`write`), sorted by stamp. ``storage``: ``rosbag1``, ``sqlite3`` or
    ``mcap``; ``unix``: added to every stamp [s] (0 for stamps already in Unix time);
    ``body_frame``, ``world_frame``: the frames written (default REP-103's)."""

    def __init__(
        self, storage: str, unix: float = UNIX, body_frame: str = "flu", world_frame: str = "enu"
    ) -> None:
        from rosbags.typesys import Stores, get_typestore

        if storage not in STORAGES:
            raise ValueError(f"storage: expected one of {', '.join(STORAGES)}, got {storage!r}")
        self.storage, self.unix = storage, unix
        self.frames = (body_frame, world_frame)
        self.d_b, self.t_w = _frames(body_frame, world_frame)
        self.ros1 = storage == "rosbag1"
        self.store = get_typestore(Stores.ROS1_NOETIC if self.ros1 else Stores.ROS2_HUMBLE)
        self.types = self.store.types
        self.msgs: list[tuple[float, str, str, object]] = []

    def header(self, stamp: float) -> Any:
        t = self.types
        sec = int(np.floor(stamp))
        ns = min(int(round((stamp - sec) * 1e9)), 999_999_999)
        time = t["builtin_interfaces/msg/Time"](sec=sec + int(self.unix), nanosec=ns)
        seq = {"seq": 0} if self.ros1 else {}
        return t["std_msgs/msg/Header"](**seq, stamp=time, frame_id="base_link")

    def vec(self, v: np.ndarray, kind: str = "geometry_msgs/msg/Vector3") -> Any:
        return self.types[kind](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def imu(
        self,
        topic: str,
        stamps: np.ndarray,
        imu: np.ndarray,
        quaternions: np.ndarray | None = None,
        orientation_covariance: np.ndarray | None = None,
    ) -> None:
        """``sensor_msgs/Imu`` per row of ``imu`` ``(n, 6)`` (body FRD, turned to the
        bag's body frame); ``quaternions`` ``(n, 4)`` (:func:`ros_quaternions`) the
        orientation, with ``orientation_covariance`` (9,) or ``(n, 9)`` [rad²]; None: no
        orientation (covariance[0] −1)."""
        t, kind = self.types, "sensor_msgs/msg/Imu"
        zeros9 = np.zeros(9)
        quat0 = t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
        unknown = np.array([-1.0, *zeros9[1:]])
        cov = unknown if orientation_covariance is None else np.asarray(orientation_covariance)
        covs = np.broadcast_to(cov, (len(stamps), 9))
        for k, (stamp, row) in enumerate(zip(stamps, imu, strict=True)):
            quat = quat0
            if quaternions is not None:
                quat = t["geometry_msgs/msg/Quaternion"](*map(float, quaternions[k]))
            msg = t[kind](
                header=self.header(stamp),
                orientation=quat,
                orientation_covariance=np.array(covs[k]),
                angular_velocity=self.vec(self.d_b @ row[3:]),
                angular_velocity_covariance=zeros9,
                linear_acceleration=self.vec(self.d_b @ row[:3]),
                linear_acceleration_covariance=zeros9,
            )
            self.msgs.append((stamp, topic, kind, msg))

    def twist(
        self,
        topic: str,
        stamps: np.ndarray,
        vel: np.ndarray,
        covariance: np.ndarray | None = None,
    ) -> None:
        """A DVL's body velocity ``vel`` ``(m, 3)`` [m/s, FRD]: a
        TwistWithCovarianceStamped with ``covariance`` ``(m, 3)`` the per-message
        diagonals, else a TwistStamped."""
        t = self.types
        kind = "geometry_msgs/msg/Twist" + ("WithCovariance" if covariance is not None else "")
        kind += "Stamped"
        for i, (stamp, v) in enumerate(zip(stamps, vel, strict=True)):
            twist = t["geometry_msgs/msg/Twist"](
                linear=self.vec(self.d_b @ v), angular=self.vec(np.zeros(3))
            )
            if covariance is not None:
                cov = np.zeros(36)
                cov[[0, 7, 14]] = covariance[i]
                twist = t["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=cov)
            self.msgs.append((stamp, topic, kind, t[kind](header=self.header(stamp), twist=twist)))

    def truth(
        self,
        topic: str,
        stamps: np.ndarray,
        lla: np.ndarray,
        vel: np.ndarray,
        rpy: np.ndarray,
        origin: np.ndarray,
        kind: str = "odometry",
    ) -> None:
        """The truth as ``nav_msgs/Odometry`` (``kind`` ``odometry``) or PoseStamped
        (``pose``): the world frame's metres about ``origin`` [rad, rad, m], the body's
        attitude."""
        t = self.types
        ned = local_ned(lla, origin)
        c_nb = dcm_from_euler(rpy)
        quats = ros_quaternions(rpy, *self.frames)
        msg_type = (
            "nav_msgs/msg/Odometry" if kind == "odometry" else "geometry_msgs/msg/PoseStamped"
        )
        for k, stamp in enumerate(stamps):
            pose = t["geometry_msgs/msg/Pose"](
                position=self.vec(self.t_w @ ned[k], "geometry_msgs/msg/Point"),
                orientation=t["geometry_msgs/msg/Quaternion"](*map(float, quats[k])),
            )
            if kind == "odometry":
                v_body = self.d_b @ c_nb[k].T @ vel[k]
                twist = t["geometry_msgs/msg/Twist"](
                    linear=self.vec(v_body), angular=self.vec(np.zeros(3))
                )
                msg = t[msg_type](
                    header=self.header(stamp),
                    child_frame_id="base_link",
                    pose=t["geometry_msgs/msg/PoseWithCovariance"](
                        pose=pose, covariance=np.zeros(36)
                    ),
                    twist=t["geometry_msgs/msg/TwistWithCovariance"](
                        twist=twist, covariance=np.zeros(36)
                    ),
                )
            else:
                msg = t[msg_type](header=self.header(stamp), pose=pose)
            self.msgs.append((stamp, topic, msg_type, msg))

    def orientation(
        self,
        topic: str,
        kind: str,
        stamps: np.ndarray,
        quaternions: np.ndarray,
        covariance: np.ndarray,
    ) -> None:
        """An attitude topic of ``kind`` (a key of :data:`HEADING_TYPES` but ``"own"``):
        ``quaternions`` ``(k, 4)`` body → world, ``covariance`` ``(k, 9)`` the orientation
        covariance (its [8], the yaw's variance, as a pose's [35])."""
        t, msg_type = self.types, HEADING_TYPES[kind]
        zeros9 = np.zeros(9)
        for k, stamp in enumerate(stamps):
            q = t["geometry_msgs/msg/Quaternion"](*map(float, quaternions[k]))
            if kind == "imu":
                msg = t[msg_type](
                    header=self.header(stamp), orientation=q,
                    orientation_covariance=np.array(covariance[k]),
                    angular_velocity=self.vec(np.zeros(3)), angular_velocity_covariance=zeros9,
                    linear_acceleration=self.vec(np.zeros(3)),
                    linear_acceleration_covariance=zeros9,
                )  # fmt: skip
            elif kind == "quaternion":
                msg = t[msg_type](header=self.header(stamp), quaternion=q)
            else:
                pose = t["geometry_msgs/msg/Pose"](
                    position=self.vec(np.zeros(3), "geometry_msgs/msg/Point"), orientation=q
                )
                if kind == "pose_covariance":
                    cov = np.zeros(36)
                    cov[35] = covariance[k][8]
                    pose = t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov)
                msg = t[msg_type](header=self.header(stamp), pose=pose)
            self.msgs.append((stamp, topic, msg_type, msg))

    def pressure(
        self, topic: str, stamps: np.ndarray, pressure: np.ndarray, variance: np.ndarray
    ) -> None:
        """``sensor_msgs/FluidPressure``: ``pressure`` [Pa] and its ``variance`` [Pa²]."""
        kind = "sensor_msgs/msg/FluidPressure"
        for stamp, p, v in zip(stamps, pressure, variance, strict=True):
            msg = self.types[kind](
                header=self.header(stamp), fluid_pressure=float(p), variance=float(v)
            )
            self.msgs.append((stamp, topic, kind, msg))

    def navsat(
        self,
        topic: str,
        stamps: np.ndarray,
        lla: np.ndarray,
        sigma: np.ndarray | None = None,
        no_fix: tuple[int, ...] = (),
    ) -> None:
        """``sensor_msgs/NavSatFix`` per row of ``lla`` ``(f, 3)`` [rad, rad, m]: σ north,
        east, down ``sigma`` ``(f, 3)`` [m] as a DIAGONAL_KNOWN covariance (UNKNOWN
        without); the fixes of index ``no_fix`` with the status NO_FIX."""
        t, kind = self.types, "sensor_msgs/msg/NavSatFix"
        for k, stamp in enumerate(stamps):
            lat, lon, h = lla[k]
            cov = np.zeros(9)
            if sigma is not None:
                cov[[4, 0, 8]] = sigma[k] ** 2  # N, E, D into ENU order
            msg = t[kind](
                header=self.header(stamp),
                status=t["sensor_msgs/msg/NavSatStatus"](
                    status=-1 if k in no_fix else 0, service=1
                ),
                latitude=float(np.degrees(lat)),
                longitude=float(np.degrees(lon)),
                altitude=float(h),
                position_covariance=cov,
                position_covariance_type=0 if sigma is None else 2,
            )
            self.msgs.append((stamp, topic, kind, msg))

    def write(self, path: Path) -> Path:
        """Write the messages (sorted by stamp) as a bag at ``path``."""
        from rosbags.rosbag1 import Writer as Writer1
        from rosbags.rosbag2 import StoragePlugin
        from rosbags.rosbag2 import Writer as Writer2

        self.msgs.sort(key=lambda m: m[0])
        if self.ros1:
            writer: Any = Writer1(path)
        else:
            plugin = StoragePlugin.MCAP if self.storage == "mcap" else StoragePlugin.SQLITE3
            writer = Writer2(path, version=9, storage_plugin=plugin)
        serialize = self.store.serialize_ros1 if self.ros1 else self.store.serialize_cdr
        with writer:
            conns = {}
            for _, topic, kind, _ in self.msgs:
                if topic not in conns:
                    conns[topic] = writer.add_connection(topic, kind, typestore=self.store)
            for stamp, topic, kind, msg in self.msgs:
                writer.write(conns[topic], int((stamp + self.unix) * 1e9), serialize(msg, kind))
        return path


def write_bag(
    path: Path,
    rec: Recording,
    storage: str = "mcap",
    *,
    topics: BagTopics | None = None,
    truth: str = "odometry",
    dvl_covariance: np.ndarray | None = None,
    no_fix: tuple[int, ...] = (),
    heading: str | None = None,
    heading_variance: np.ndarray | None = None,
    no_orientation: tuple[int, ...] = (),
    magnetic_declination: float | None = None,
) -> tuple[Path, BagTopics]:
    """Write ``rec`` as a bag at ``path`` (``storage``: ``rosbag1``, ``sqlite3`` or
    ``mcap``) and return it with the topics (origin: the truth's first row) to read it.
    ``truth``: ``odometry``, ``pose`` or ``none`` (no truth topic: the returned topics'
    ``truth`` and ``origin`` None); ``dvl_covariance``: ``(m, 3)`` per-message
    diagonals (a TwistWithCovarianceStamped; None: a TwistStamped). The frames are the
    topics' (default FLU and ENU). ``heading``: a heading topic (one of
    :data:`HEADING_TYPES`, ``topics.heading``, default ``/ahrs``; ``"own"``: the IMU
    messages carry the orientation, ``topics.heading = topics.imu``) with the attitude
    of :func:`heading_attitude`, its yaw variance ``heading_variance`` per message
    (default 0: unknown), the Imu messages of index ``no_orientation`` without an
    orientation (covariance[0] −1), and with ``magnetic_declination`` [deg] its yaw
    from magnetic north (``heading_magnetic`` set). The recording's depth and fixes,
    if any, go on ``topics.depth`` and ``topics.fix`` (default ``/depth/pressure`` and
    ``/gnss/fix`` in the returned topics) as FluidPressure (the inverse of the bag
    reader's conversion, variance 0 where the depth has no σ) and NavSatFix (σ as a
    DIAGONAL_KNOWN covariance, or UNKNOWN without; the fixes of index ``no_fix`` with
    the status NO_FIX). Stamps get :data:`UNIX` added."""
    origin = np.degrees(rec.gt_lla[0, :2]).tolist() + [float(rec.gt_lla[0, 2])]
    topics = topics or BagTopics(origin=(origin[0], origin[1], origin[2]))
    if topics.depth is None and rec.depth is not None:
        topics = replace(topics, depth="/depth/pressure")
    if topics.fix is None and rec.fixes is not None:
        topics = replace(topics, fix="/gnss/fix")
    if heading == "own":
        topics = replace(topics, heading=topics.imu)
    elif heading is not None and topics.heading is None:
        topics = replace(topics, heading="/ahrs")
    if magnetic_declination is not None:
        topics = replace(topics, heading_magnetic=True)
    bag = BagMessages(storage, body_frame=topics.body_frame, world_frame=topics.world_frame)
    own: tuple[np.ndarray, np.ndarray] | tuple[None, None] = (None, None)
    if heading is not None:
        h_time, h_rpy = heading_attitude(rec, heading)
        h_rpy = h_rpy.copy()
        h_rpy[:, 2] -= np.radians(magnetic_declination or 0.0)
        quats = ros_quaternions(h_rpy, *bag.frames)
        cov = np.zeros((len(h_time), 9))
        cov[:, 8] = 0.0 if heading_variance is None else heading_variance
        cov[list(no_orientation), 0] = -1.0
        if heading == "own":
            own = (quats, cov)
        else:
            bag.orientation(str(topics.heading), heading, h_time, quats, cov)
    bag.imu(topics.imu, rec.imu_time, rec.imu, *own)
    if topics.dvl is not None:
        bag.twist(topics.dvl, rec.dvl_time, rec.dvl, dvl_covariance)
    if truth == "none":
        topics = replace(topics, truth=None, origin=None)
    else:
        lla0 = np.array([np.radians(origin[0]), np.radians(origin[1]), origin[2]])
        bag.truth(str(topics.truth), rec.gt_time, rec.gt_lla, rec.gt_vel, rec.gt_rpy, lla0, truth)
    if rec.depth is not None and topics.depth is not None:
        rho_g = topics.water_density * STANDARD_GRAVITY
        sigma = np.zeros(len(rec.depth.time)) if rec.depth.sigma is None else rec.depth.sigma
        pressure = rec.depth.depth * rho_g + topics.surface_pressure
        bag.pressure(topics.depth, rec.depth.time, pressure, (sigma * rho_g) ** 2)
    if rec.fixes is not None and topics.fix is not None:
        bag.navsat(topics.fix, rec.fixes.time, rec.fixes.lla, rec.fixes.sigma, no_fix)
    return bag.write(path), topics
