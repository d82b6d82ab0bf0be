"""A recording written as a ROS bag with the rosbags library's own writers (ROS 1
``.bag``, ROS 2 sqlite3 or mcap), in ROS's frames (REP-103: body FLU, world ENU; or the
topics' FRD and NED), as a ROS vehicle would record it: the inverse of
:mod:`pronet.recorded.bags`."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from pronet import local_ned
from pronet.recorded.alignment import dcm_from_euler
from pronet.recorded.bags import STANDARD_GRAVITY, BagTopics
from pronet.recorded.recordings import Recording

#: Added to every stamp: bags carry Unix time (and ROS 1 stamps are unsigned).
UNIX = 1_700_000_000
_FLU = np.diag([1.0, -1.0, -1.0])
_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])
#: The heading topics :func:`write_bag` writes, by name: their message types.
HEADING_TYPES = {
    "imu": "sensor_msgs/msg/Imu",
    "quaternion": "geometry_msgs/msg/QuaternionStamped",
    "pose": "geometry_msgs/msg/PoseStamped",
    "pose_covariance": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "own": "sensor_msgs/msg/Imu",
}


def heading_attitude(rec: Recording, heading: str) -> tuple[np.ndarray, np.ndarray]:
    """The stamps [s, as ``rec``'s] and roll, pitch, yaw [rad] :func:`write_bag` writes
    on a heading topic of kind ``heading``: the truth's rows, or (``"own"``: in the IMU
    messages) the truth's angles interpolated (unwrapped) at the IMU's stamps."""
    if heading != "own":
        return rec.gt_time, rec.gt_rpy
    rpy = np.unwrap(rec.gt_rpy, axis=0)
    at = np.column_stack([np.interp(rec.imu_time, rec.gt_time, rpy[:, j]) for j in range(3)])
    return rec.imu_time, at


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
    from magnetic north (``heading_magnetic`` set). The recording's
    depth and fixes, if any, go on ``topics.depth`` and ``topics.fix`` (default
    ``/depth/pressure`` and ``/gnss/fix`` in the returned topics) as FluidPressure (the
    inverse of the bag reader's conversion, variance 0 where the depth has no σ) and
    NavSatFix (σ as a DIAGONAL_KNOWN covariance, or UNKNOWN without; the fixes of
    index ``no_fix`` with the status NO_FIX)."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore
    from scipy.spatial.transform import Rotation

    ros1 = storage == "rosbag1"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    t = ts.types
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
    d_b = _FLU if topics.body_frame == "flu" else np.eye(3)
    t_w = _ENU if topics.world_frame == "enu" else np.eye(3)

    def header(stamp: float):  # noqa: ANN202
        sec = int(np.floor(stamp))
        ns = min(int(round((stamp - sec) * 1e9)), 999_999_999)
        time = t["builtin_interfaces/msg/Time"](sec=sec + UNIX, nanosec=ns)
        seq = {"seq": 0} if ros1 else {}
        return t["std_msgs/msg/Header"](**seq, stamp=time, frame_id="base_link")

    def vec(v: np.ndarray, kind: str = "geometry_msgs/msg/Vector3"):  # noqa: ANN202
        return t[kind](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    zeros9 = np.zeros(9)
    quat0 = t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
    msgs: list[tuple[float, str, str, object]] = []

    def quaternion(c_nb: np.ndarray):  # noqa: ANN202
        x, y, z, w = Rotation.from_matrix(t_w @ c_nb @ d_b).as_quat()
        return t["geometry_msgs/msg/Quaternion"](x=float(x), y=float(y), z=float(z), w=float(w))

    orientations: list[object] = []
    if heading is not None:
        h_time, h_rpy = heading_attitude(rec, heading)
        h_rpy = h_rpy.copy()
        h_rpy[:, 2] -= np.radians(magnetic_declination or 0.0)
        orientations = [quaternion(c) for c in dcm_from_euler(h_rpy)]
        variance = np.zeros(len(h_time)) if heading_variance is None else heading_variance

    def orientation_covariance(k: int) -> np.ndarray:
        cov = np.zeros(9)
        cov[8] = variance[k]
        if k in no_orientation:
            cov[0] = -1.0
        return cov

    imu_type = "sensor_msgs/msg/Imu"
    for k, (stamp, row) in enumerate(zip(rec.imu_time, rec.imu, strict=True)):
        flu = np.concatenate([d_b @ row[:3], d_b @ row[3:]])
        own = heading == "own"
        msg = t[imu_type](
            header=header(stamp),
            orientation=orientations[k] if own else quat0,
            orientation_covariance=(
                orientation_covariance(k) if own else np.array([-1.0, *zeros9[1:]])
            ),
            angular_velocity=vec(flu[3:]),
            angular_velocity_covariance=zeros9,
            linear_acceleration=vec(flu[:3]),
            linear_acceleration_covariance=zeros9,
        )
        msgs.append((stamp, topics.imu, imu_type, msg))
    if heading is not None and heading != "own":
        kind = HEADING_TYPES[heading]
        for k, stamp in enumerate(h_time):
            q = orientations[k]
            if heading == "imu":
                msg = t[kind](
                    header=header(stamp),
                    orientation=q,
                    orientation_covariance=orientation_covariance(k),
                    angular_velocity=vec(np.zeros(3)),
                    angular_velocity_covariance=zeros9,
                    linear_acceleration=vec(np.zeros(3)),
                    linear_acceleration_covariance=zeros9,
                )
            elif heading == "quaternion":
                msg = t[kind](header=header(stamp), quaternion=q)
            else:
                pose = t["geometry_msgs/msg/Pose"](
                    position=vec(np.zeros(3), "geometry_msgs/msg/Point"), orientation=q
                )
                if heading == "pose_covariance":
                    cov = np.zeros(36)
                    cov[35] = variance[k]
                    pose = t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=cov)
                msg = t[kind](header=header(stamp), pose=pose)
            msgs.append((stamp, str(topics.heading), kind, msg))
    dvl_type = "geometry_msgs/msg/Twist" + ("WithCovariance" if dvl_covariance is not None else "")
    dvl_type += "Stamped"
    for i, (stamp, v) in enumerate(zip(rec.dvl_time, rec.dvl, strict=True)):
        twist = t["geometry_msgs/msg/Twist"](linear=vec(d_b @ v), angular=vec(np.zeros(3)))
        if dvl_covariance is not None:
            cov = np.zeros(36)
            cov[[0, 7, 14]] = dvl_covariance[i]
            twist = t["geometry_msgs/msg/TwistWithCovariance"](twist=twist, covariance=cov)
        msgs.append((stamp, topics.dvl, dvl_type, t[dvl_type](header=header(stamp), twist=twist)))
    ned = local_ned(rec.gt_lla, np.array([np.radians(origin[0]), np.radians(origin[1]), origin[2]]))
    c_nb = dcm_from_euler(rec.gt_rpy)
    c_wb = t_w @ c_nb @ d_b  # body (FLU) → world (ENU)
    quats = Rotation.from_matrix(c_wb).as_quat()  # x, y, z, w
    truth_type = "nav_msgs/msg/Odometry" if truth == "odometry" else "geometry_msgs/msg/PoseStamped"
    if truth == "none":
        topics = replace(topics, truth=None, origin=None)
    for k, stamp in enumerate(rec.gt_time if truth != "none" else ()):
        pose = t["geometry_msgs/msg/Pose"](
            position=vec(t_w @ ned[k], "geometry_msgs/msg/Point"),
            orientation=t["geometry_msgs/msg/Quaternion"](*map(float, quats[k])),
        )
        if truth == "odometry":
            v_body = d_b @ c_nb[k].T @ rec.gt_vel[k]
            twist = t["geometry_msgs/msg/Twist"](linear=vec(v_body), angular=vec(np.zeros(3)))
            msg = t[truth_type](
                header=header(stamp),
                child_frame_id="base_link",
                pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
                twist=t["geometry_msgs/msg/TwistWithCovariance"](
                    twist=twist, covariance=np.zeros(36)
                ),
            )
        else:
            msg = t[truth_type](header=header(stamp), pose=pose)
        msgs.append((stamp, str(topics.truth), truth_type, msg))
    if rec.depth is not None and topics.depth is not None:
        kind = "sensor_msgs/msg/FluidPressure"
        rho_g = topics.water_density * STANDARD_GRAVITY
        sigma = np.zeros(len(rec.depth.time)) if rec.depth.sigma is None else rec.depth.sigma
        for stamp, depth, s in zip(rec.depth.time, rec.depth.depth, sigma, strict=True):
            p = float(depth * rho_g + topics.surface_pressure)
            msg = t[kind](header=header(stamp), fluid_pressure=p, variance=float((s * rho_g) ** 2))
            msgs.append((stamp, topics.depth, kind, msg))
    if rec.fixes is not None and topics.fix is not None:
        kind = "sensor_msgs/msg/NavSatFix"
        for k, stamp in enumerate(rec.fixes.time):
            lat, lon, h = rec.fixes.lla[k]
            cov = np.zeros(9)
            if rec.fixes.sigma is not None:
                cov[[4, 0, 8]] = rec.fixes.sigma[k] ** 2  # N, E, D into ENU order
            msg = t[kind](
                header=header(stamp),
                status=t["sensor_msgs/msg/NavSatStatus"](
                    status=-1 if k in no_fix else 0, service=1
                ),
                latitude=float(np.degrees(lat)),
                longitude=float(np.degrees(lon)),
                altitude=float(h),
                position_covariance=cov,
                position_covariance_type=0 if rec.fixes.sigma is None else 2,
            )
            msgs.append((stamp, topics.fix, kind, msg))
    msgs.sort(key=lambda m: m[0])
    if ros1:
        writer = Writer1(path)
    else:
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        writer = Writer2(path, version=9, storage_plugin=plugin)
    serialize = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    with writer:
        conns = {}
        for _, topic, kind, _ in msgs:
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, kind, typestore=ts)
        for stamp, topic, kind, msg in msgs:
            writer.write(conns[topic], int((stamp + UNIX) * 1e9), serialize(msg, kind))
    return path, topics
