"""A navigated recording as a ROS bag of ``nav_msgs/msg/Odometry`` messages, for RViz
and Foxglove users: ROS 1 ``.bag``, or a ROS 2 bag folder (sqlite3 or mcap storage),
written with the `rosbags <https://gitlab.com/ternaris/rosbags>`_ library (the
``rosbags`` extra: ``pip install 'pronet[rosbags]'``). The inverse of what
:mod:`pronet.recorded.bags` reads as a truth topic: read back with ``BagTopics(truth=
topic, origin=bag_origin(...))``, the positions and attitudes come back as written.

Topics (:class:`OdometryOptions`): the forward solution on ``/pronet/odometry``, the
smoothed one on ``/pronet/odometry_smoothed``, each message stamped ``epoch + time`` (as
recorded: Unix time for a bag), at most ``rate`` messages a second (the first epoch of
each 1/rate interval; default 10 Hz; an epoch whose position, velocity or attitude is not
finite is left out); and one ``sensor_msgs/msg/NavSatFix`` on
``/pronet/origin`` holding the local frame's geodetic origin (latitude, longitude [deg],
height [m, up]).

Frames (REP-103 by default). The pose is the vehicle's position in a local world frame
about the origin (by default the forward solution's first position): ``world_frame``
``"enu"`` (x east, y north, z up; the default) or ``"ned"``, its axes the local north,
east (and up) at the origin (:func:`pronet.local_ned`); its orientation is body →
world, the body ``"flu"`` (x forward, y left, z up; the default) or ``"frd"``: ``C_wb =
T_w · C_nb · D_b`` with ``T_enu`` swapping x and y and negating z and ``D_flu = diag(1,
−1, −1)``, the very matrices :mod:`pronet.recorded.bags` undoes. The twist is the
velocity in the body frame (``child_frame_id``), as ``nav_msgs/Odometry`` defines it,
``D_b · C_nbᵀ · v_NED``; its angular part is not in a solution (zeros).

Covariances (6×6, row-major). The pose's: the position's variances ``σ_N², σ_E², σ_D²``
and the attitude error ψ's (a small rotation about north, east, down) put on the world
axes (for ENU: x ← east, y ← north, z ← down), the rest zero (a solution holds only the
σ). The twist's linear block: the NED velocity's diagonal covariance turned into the
body frame, ``R · diag(σ_v²) · Rᵀ`` with ``R = D_b · C_nbᵀ`` (a full 3×3); its angular
diagonal is −1 (not provided, as ``sensor_msgs`` marks a quantity it lacks).
"""

from __future__ import annotations

import heapq
import math
import os
import shutil
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from pronet._util.extras import missing
from pronet._util.files import check_writable

if TYPE_CHECKING:
    from pronet.recorded.solution import Navigation, Solution

F64 = NDArray[np.float64]

#: The storages a bag is written in: ROS 1, ROS 2 sqlite3, ROS 2 mcap.
STORAGES = ("rosbag1", "sqlite3", "mcap")
_FLU = np.diag([1.0, -1.0, -1.0])
_ENU = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


@dataclass(frozen=True)
class OdometryOptions:
    """How an odometry bag is written (module docstring).

    Attributes:
        rate: most messages a second per topic [Hz]; None: every epoch.
        frame_id: ``header.frame_id``, the world frame's name.
        child_frame_id: the body frame's name.
        topic, smoothed_topic: the forward and the smoothed solution's topics.
        origin_topic: the topic of the origin's ``NavSatFix``; None: not written.
        world_frame: ``"enu"`` (REP-103) or ``"ned"``.
        body_frame: ``"flu"`` (REP-103) or ``"frd"``.
        origin: the world frame's origin: latitude, longitude [deg], height [m, up];
            None: the forward solution's first position.
    """

    rate: float | None = 10.0
    frame_id: str = "map"
    child_frame_id: str = "base_link"
    topic: str = "/pronet/odometry"
    smoothed_topic: str = "/pronet/odometry_smoothed"
    origin_topic: str | None = "/pronet/origin"
    world_frame: str = "enu"
    body_frame: str = "flu"
    origin: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if self.rate is not None and not (math.isfinite(self.rate) and self.rate > 0):
            raise ValueError(f"rate: expected a positive number [Hz] or None, got {self.rate}")
        if self.world_frame not in ("enu", "ned"):
            raise ValueError(f"world_frame: expected enu or ned, got {self.world_frame!r}")
        if self.body_frame not in ("flu", "frd"):
            raise ValueError(f"body_frame: expected flu or frd, got {self.body_frame!r}")
        topics = [self.topic, self.smoothed_topic, self.origin_topic]
        named = [t for t in topics if t is not None]
        if any(not t.startswith("/") for t in named) or len(set(named)) < len(named):
            raise ValueError(f"topics: expected distinct names starting with '/', got {named}")
        if not (self.frame_id and self.child_frame_id):
            raise ValueError("frame_id, child_frame_id: expected names, got an empty one")
        if self.origin is not None:
            lat, lon, h = (float(v) for v in self.origin)
            if not (np.isfinite([lat, lon, h]).all() and abs(lat) <= 90 and abs(lon) <= 360):
                raise ValueError(f"origin: expected lat,lon [deg],height [m], got {self.origin}")


def bag_name(storage: str) -> str:
    """The name :func:`pronet.recorded.export.write_all` gives a bag of ``storage``:
    ``odometry.bag`` (ROS 1) or the folder ``odometry`` (ROS 2)."""
    return "odometry.bag" if storage == "rosbag1" else "odometry"


def bag_origin(navigation: Navigation, options: OdometryOptions) -> tuple[float, float, float]:
    """The world frame's origin: latitude, longitude [deg], height [m, up]
    (``options.origin``, else the forward solution's first position)."""
    if options.origin is not None:
        lat, lon, h = (float(v) for v in options.origin)
        return lat, lon, h
    lla = np.asarray(navigation.forward.lla[0], dtype=np.float64)
    if not np.isfinite(lla).all():
        raise ValueError("navigation.forward.lla: the first position is not finite")
    return math.degrees(lla[0]), math.degrees(lla[1]), float(lla[2])


def _require_rosbags() -> None:
    """:class:`~pronet._util.extras.MissingExtra` unless ``rosbags`` is installed."""
    try:
        import rosbags.rosbag1  # noqa: F401
        import rosbags.rosbag2  # noqa: F401
    except ImportError:
        raise missing("rosbags", "writing an odometry bag") from None


def check_bag(path: Path, navigation: Navigation, storage: str, options: OdometryOptions) -> None:
    """What :func:`write_odometry_bag` checks before writing: the storage, the
    ``rosbags`` extra, a new and writable ``path``, stamps after 1970 (ROS times are
    unsigned), and the origin. ``ValueError`` naming the argument."""
    if storage not in STORAGES:
        raise ValueError(f"storage: expected one of {', '.join(STORAGES)}, got {storage!r}")
    _require_rosbags()
    if path.exists() or path.is_symlink():
        raise ValueError(f"path: {path} exists; a bag is never overwritten")
    check_writable(path, "path")
    for sol in navigation.solutions:
        if sol.epoch + float(np.min(sol.time)) < 0:
            raise ValueError(f"navigation.{sol.label}: stamps before 0 s; a ROS time cannot be")
    bag_origin(navigation, options)


def decimate(time: F64, rate: float | None) -> NDArray[np.intp]:
    """The epochs kept at ``rate`` [Hz]: the first of each 1/rate interval from the
    first epoch (every epoch for None)."""
    if rate is None:
        return np.arange(len(time))
    slot = np.floor((time - time[0]) * rate + 1e-9)
    return np.unique(slot, return_index=True)[1]


def quaternion_from_dcm(c: F64) -> F64:
    """Unit quaternions ``(n, 4)`` (x, y, z, w; w ≥ 0) of rotation matrices ``(n, 3, 3)``,
    from the largest of the four squared components (Shepperd's method): with ``p[i, j]
    = 4 q_i q_j`` read off the matrix, ``q_j = p[k, j] / (2 √p[k, k])`` for the largest
    ``p[k, k]``."""
    c00, c11, c22 = c[:, 0, 0], c[:, 1, 1], c[:, 2, 2]
    w_x, w_y, w_z = c[:, 2, 1] - c[:, 1, 2], c[:, 0, 2] - c[:, 2, 0], c[:, 1, 0] - c[:, 0, 1]
    x_y, x_z, y_z = c[:, 0, 1] + c[:, 1, 0], c[:, 0, 2] + c[:, 2, 0], c[:, 1, 2] + c[:, 2, 1]
    p = np.array(  # (4, 4, n), components in the order w, x, y, z
        [
            [1 + c00 + c11 + c22, w_x, w_y, w_z],
            [w_x, 1 + c00 - c11 - c22, x_y, x_z],
            [w_y, x_y, 1 - c00 + c11 - c22, y_z],
            [w_z, x_z, y_z, 1 - c00 - c11 + c22],
        ]
    )
    n = np.arange(len(c))
    k = np.argmax(np.stack([p[i, i] for i in range(4)]), axis=0)
    wxyz = p[k, :, n] / (2.0 * np.sqrt(p[k, k, n]))[:, None]  # (n, 4)
    q = wxyz[:, [1, 2, 3, 0]]
    return q * np.where(q[:, 3:] < 0, -1.0, 1.0)


@dataclass(frozen=True)
class _Frames:
    """The solution's rows as ROS poses and twists (module docstring)."""

    position: F64  # (m, 3) world [m]
    quaternion: F64  # (m, 4) x, y, z, w body → world
    pose_variance: F64  # (m, 6) position then rotation about the world axes
    twist: F64  # (m, 3) body [m/s]
    twist_covariance: F64  # (m, 3, 3) body [(m/s)²]


def _frames(
    sol: Solution, rows: NDArray[np.intp], options: OdometryOptions, origin: F64
) -> _Frames:
    from pronet.navigation import local_ned
    from pronet.recorded.alignment import dcm_from_euler

    t_w = _ENU if options.world_frame == "enu" else np.eye(3)
    d_b = _FLU if options.body_frame == "flu" else np.eye(3)
    lla = np.asarray(sol.lla, dtype=np.float64)[rows]
    sigma = np.asarray(sol.sigma, dtype=np.float64)[rows]
    c_nb = dcm_from_euler(np.asarray(sol.rpy, dtype=np.float64)[rows])
    to_body = d_b @ np.swapaxes(c_nb, 1, 2)  # R = D_b C_nbᵀ, (m, 3, 3)
    vel = np.asarray(sol.vel, dtype=np.float64)[rows]
    var_v = sigma[:, 3:6] ** 2
    perm = t_w**2  # a variance's axes: T_w only permutes and negates
    return _Frames(
        position=local_ned(lla, origin) @ t_w.T,
        quaternion=quaternion_from_dcm(t_w @ c_nb @ d_b),
        pose_variance=np.hstack([sigma[:, 0:3] ** 2 @ perm.T, sigma[:, 6:9] ** 2 @ perm.T]),
        twist=np.einsum("nij,nj->ni", to_body, vel),
        twist_covariance=np.einsum("nij,nj,nkj->nik", to_body, var_v, to_body),
    )


def _stamp(epoch: float, time: float) -> tuple[int, int]:
    """``epoch + time`` [s] as whole seconds and nanoseconds, the sum split so that a
    Unix epoch does not round the time to its float spacing (0.24 µs)."""
    whole = math.floor(epoch)
    rest = (epoch - whole) + time
    sec = math.floor(rest)
    ns = round((rest - sec) * 1e9)
    if ns >= 1_000_000_000:
        sec, ns = sec + 1, ns - 1_000_000_000
    return whole + sec, ns


class _Messages:
    """The message types of one typestore, and its serialiser."""

    def __init__(self, ros1: bool) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.ros1 = ros1
        self.store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        self.t = self.store.types
        self.serialize = self.store.serialize_ros1 if ros1 else self.store.serialize_cdr

    def header(self, stamp: tuple[int, int], frame: str, seq: int) -> Any:
        time = self.t["builtin_interfaces/msg/Time"](sec=stamp[0], nanosec=stamp[1])
        extra = {"seq": seq} if self.ros1 else {}
        return self.t["std_msgs/msg/Header"](**extra, stamp=time, frame_id=frame)

    def vector(self, v: Any, kind: str = "geometry_msgs/msg/Vector3") -> Any:
        return self.t[kind](x=float(v[0]), y=float(v[1]), z=float(v[2]))

    def odometry(self, f: _Frames, k: int, header: Any, child: str) -> Any:
        t = self.t
        x, y, z, w = (float(v) for v in f.quaternion[k])
        pose = t["geometry_msgs/msg/Pose"](
            position=self.vector(f.position[k], "geometry_msgs/msg/Point"),
            orientation=t["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
        )
        pose_cov = np.diag(f.pose_variance[k]).ravel()
        twist_cov = np.zeros((6, 6))
        twist_cov[:3, :3] = f.twist_covariance[k]
        twist_cov[[3, 4, 5], [3, 4, 5]] = -1.0  # the angular rate: not provided
        twist = t["geometry_msgs/msg/Twist"](
            linear=self.vector(f.twist[k]), angular=self.vector(np.zeros(3))
        )
        return t["nav_msgs/msg/Odometry"](
            header=header,
            child_frame_id=child,
            pose=t["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=pose_cov),
            twist=t["geometry_msgs/msg/TwistWithCovariance"](
                twist=twist, covariance=twist_cov.ravel()
            ),
        )

    def origin(self, origin: tuple[float, float, float], header: Any) -> Any:
        t = self.t
        return t["sensor_msgs/msg/NavSatFix"](
            header=header,
            status=t["sensor_msgs/msg/NavSatStatus"](status=0, service=0),
            latitude=origin[0],
            longitude=origin[1],
            altitude=origin[2],
            position_covariance=np.zeros(9),
            position_covariance_type=0,
        )


def _odometry_messages(
    sol: Solution, topic: str, msgs: _Messages, options: OdometryOptions, origin: F64
) -> Iterator[tuple[int, str, str, Any]]:
    """``(stamp [ns], topic, type, serialised message)`` of one solution, in time order."""
    kind = "nav_msgs/msg/Odometry"
    rows = decimate(np.asarray(sol.time, dtype=np.float64), options.rate)
    state = np.hstack([sol.lla, sol.vel, sol.rpy])[rows]
    rows = rows[np.isfinite(state).all(axis=1)]  # a diverged epoch has no pose
    frames = _frames(sol, rows, options, origin)
    for k, row in enumerate(rows.tolist()):
        stamp = _stamp(sol.epoch, float(sol.time[row]))
        msg = msgs.odometry(
            frames, k, msgs.header(stamp, options.frame_id, k), options.child_frame_id
        )
        yield stamp[0] * 1_000_000_000 + stamp[1], topic, kind, msgs.serialize(msg, kind)


def write_odometry_bag(
    path: str | Path,
    navigation: Navigation,
    storage: str = "rosbag1",
    options: OdometryOptions | None = None,
) -> Path:
    """Write ``navigation``'s solutions as ``nav_msgs/msg/Odometry`` into a new bag.

    Args:
        path: the bag: a ``.bag`` file (``rosbag1``) or a ROS 2 bag folder; it must not
            exist (written beside it under a temporary name, then renamed into place).
        navigation: the navigated recording.
        storage: ``"rosbag1"``, ``"sqlite3"`` or ``"mcap"``.
        options: topics, frames, rate and origin (:class:`OdometryOptions`).

    Returns:
        ``path``. ``ValueError`` naming the argument (:func:`check_bag`) before
        anything is written; :class:`~pronet._util.extras.MissingExtra` without
        ``rosbags``.
    """
    path, options = Path(path), options or OdometryOptions()
    check_bag(path, navigation, storage, options)
    origin = bag_origin(navigation, options)
    origin_rad = np.array([math.radians(origin[0]), math.radians(origin[1]), origin[2]])
    msgs = _Messages(storage == "rosbag1")
    streams = [
        _odometry_messages(sol, topic, msgs, options, origin_rad)
        for sol, topic in zip(
            navigation.solutions, (options.topic, options.smoothed_topic), strict=False
        )
    ]
    if options.origin_topic is not None:
        first = _stamp(navigation.forward.epoch, float(navigation.forward.time[0]))
        fix = msgs.origin(origin, msgs.header(first, options.frame_id, 0))
        kind = "sensor_msgs/msg/NavSatFix"
        head = (first[0] * 1_000_000_000 + first[1], options.origin_topic, kind)
        streams.insert(0, iter([(*head, msgs.serialize(fix, kind))]))
    _write_bag(path, storage, msgs, heapq.merge(*streams, key=lambda m: m[0]))
    return path


def _write_bag(
    path: Path, storage: str, msgs: _Messages, messages: Iterator[tuple[int, str, str, Any]]
) -> None:
    """Write ``messages`` into a bag made under a temporary folder beside ``path`` (so
    that a ROS 2 bag's files carry its final name), then rename it into place."""
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2

    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{path.name}.", dir=path.parent))
    try:
        inner = tmp / path.name
        if msgs.ros1:
            writer: Any = Writer1(inner)
        else:
            plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
            writer = Writer2(inner, version=9, storage_plugin=plugin)
        with writer:
            connections: dict[str, Any] = {}
            for stamp, topic, kind, raw in messages:
                if topic not in connections:
                    connections[topic] = writer.add_connection(topic, kind, typestore=msgs.store)
                writer.write(connections[topic], stamp, raw)
        if inner.is_dir():
            os.chmod(inner, 0o755)
        os.replace(inner, path)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
