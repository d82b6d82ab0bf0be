"""ROS bags as recordings: ROS 1 ``.bag`` files and ROS 2 bags (a folder holding
``metadata.yaml`` with sqlite3 ``.db3`` or ``.mcap`` storage), read with the pure-Python
`rosbags <https://gitlab.com/ternaris/rosbags>`_ library (no ROS installation), an
optional extra: ``pip install 'pronet[rosbags]'``.

Three topics, named by :class:`BagTopics` (``pronet real --format bag --imu-topic …``);
the truth is optional (``BagTopics(truth=None)``: not read, and no ``origin`` needed, a
vehicle's own recording; ``pronet real`` scores against one and needs it):

===== ======================================= =========================================
topic message type                            used
===== ======================================= =========================================
imu   ``sensor_msgs/msg/Imu``                 ``linear_acceleration`` [m/s²] (specific
                                              force), ``angular_velocity`` [rad/s]
dvl   ``geometry_msgs/msg/TwistWithCovariance ``linear`` [m/s]: the DVL's body-frame
      Stamped`` or ``…/TwistStamped``         velocity; the covariance's linear block
truth ``nav_msgs/msg/Odometry`` or            ``pose`` (position [m] in a local world
      ``geometry_msgs/msg/PoseStamped``       frame, orientation body → world),
                                              Odometry's ``twist.linear`` [m/s, body]
===== ======================================= =========================================

Three more topics are optional, read only when named (``--depth-topic``,
``--fix-topic``, ``--heading-topic``), as the generic format's ``depth``, ``fix`` and
``heading`` tables (:mod:`pronet.recorded.aiding`, :mod:`pronet.recorded.heading`):

===== ======================================= =========================================
topic message type                            used
===== ======================================= =========================================
depth ``sensor_msgs/msg/FluidPressure``       ``fluid_pressure`` [Pa] → depth
                                              ``(p − p_surface) / (ρ g)`` [m, down];
                                              ``variance`` [Pa²] → σ = √variance / (ρ g)
fix   ``sensor_msgs/msg/NavSatFix``           ``latitude``, ``longitude`` [deg],
                                              ``altitude`` [m, up; NaN: horizontal];
                                              ``position_covariance`` (ENU) → σ N, E, D
head- ``sensor_msgs/msg/Imu``,                the orientation's yaw (body → world,
ing   ``geometry_msgs/msg/QuaternionStamped``, converted as the truth's: below);
      ``…/PoseStamped`` or                    the yaw variance (Imu's
      ``…/PoseWithCovarianceStamped``         ``orientation_covariance[8]``, the
                                              pose's ``covariance[35]``) → σ
===== ======================================= =========================================

The heading topic may be the IMU's own (``heading == imu``): an AHRS's orientation in
each ``sensor_msgs/Imu`` message. An Imu message whose ``orientation_covariance[0]`` is
−1 (ROS's "no orientation") is a missing value, skipped with the reason ``"no
orientation"``; a quaternion of zero norm with ``"nan"``. The yaw is from the world
frame's north (``world_frame``): a true heading, or with ``heading_magnetic`` a magnetic
one, turned true with the declination given to
:func:`pronet.recorded.recordings.read_recording` (refused without one). Its σ is the
square root of the yaw variance when every used message sets it (> 0; 0 is "unknown",
−1 "not provided"), else σ as tuned (a vehicle file's ``heading_sigma``).

The pressure is absolute, as ``sensor_msgs/FluidPressure`` defines it: the surface
pressure ``p_surface`` (:attr:`BagTopics.surface_pressure`, default the standard
atmosphere, 101 325 Pa; 0 for a gauge sensor) is taken off and the rest divided by the
water's density ρ (:attr:`BagTopics.water_density`, default 1025 kg/m³, sea water) and
standard gravity: the hydrostatic depth of a column of constant density (the pressure
is kept, :attr:`pronet.recorded.aiding.DepthReadings.pressure`, to re-reference the
depth to a surface pressure measured from the data). The UNESCO
formula (N. P. Fofonoff and R. C. Millard, UNESCO technical papers in marine science 44,
1983), with the latitude's gravity and the water's compressibility, gives depths
0.04 % (equator) to 0.6 % (poles) smaller at 100 m and 0.3–0.8 % smaller at 1000 m; a
vehicle that needs better sets ``water_density`` to absorb it. The variance is the σ
when every message sets it (> 0), else σ as tuned. A fix with ``status.status`` below
0 (``STATUS_NO_FIX``) is a missing value (skipped and counted); its σ is the square
root of the covariance's diagonal (its ENU order turned to N, E, D: entries 4, 0, 8)
when every fix's ``position_covariance_type`` is above 0 (``COVARIANCE_TYPE_UNKNOWN``),
else σ as tuned. The altitude is taken as the height of the truth's ``origin`` is: on one datum.

Every row is stamped with its message's ``header.stamp`` (``sec + nanosec·1e-9`` [s]),
not the time the bag recorded it. :func:`pronet.recorded.recordings.read_recording` reads
a bag (through :func:`bag_streams`) as a :class:`~pronet.recorded.recordings.Recording`,
checked exactly as the generic CSV format is (one line naming the bag and topic): a bag
and the same numbers written as CSV files give the same result. The topics are read in
one pass, the IMU's messages decoded from their raw bytes where their layout allows, to
the deserializer's bits (:mod:`pronet.recorded.bagfields`; ``benches/run.py --only
bag-read`` times it against a plain rosbags loop over the same topics).

Frames. ROS follows REP-103: body frames are FLU (x forward, y left, z up) and local
world frames ENU (x east, y north, z up); pronet's are FRD and NED. With
``body_frame="flu"`` (the default) the IMU's and the DVL's vectors become
``(x, −y, −z)``; with ``"frd"`` they are taken as they are. With ``world_frame="enu"``
(the default) a truth position ``(x, y, z)`` is north ``y``, east ``x``, down ``−z``;
with ``"ned"`` it is north, east, down. The truth's orientation ``C_wb`` (body → world)
becomes ``C_nb = T_w · C_wb · D_b`` (``T_enu`` swapping x and y and negating z, ``D_flu =
diag(1, −1, −1)``; identities for NED and FRD), and roll, pitch, yaw (ZYX) follow.

Truth positions are local metres about a geodetic ``origin`` (latitude, longitude [deg],
height [m, up]) that the bag does not hold and that must be given: the world frame's
axes are taken as the local north, east (and up) at the origin, and the positions are
turned into latitude, longitude and height on WGS-84 (:func:`pronet.lla_from_ned`).
The truth's NED velocity is Odometry's ``twist.twist.linear`` (in its child frame, the
body, by nav_msgs' definition) rotated by ``C_wb`` and ``T_w``; a PoseStamped truth has
no velocity, which is the central difference of its positions (``np.gradient``).

DVL noise. A message's covariance is *set* when the diagonal of its linear block
(entries 0, 7, 14 of the row-major 6×6) is positive (ROS writes zeros for "unknown" and
−1 for "not provided"). The filter's R is the per-axis median of the set diagonals over
the topic (one value per axis, robust to a few odd messages; the sign flips of FLU → FRD
leave a diagonal as it is), kept in :attr:`Recording.dvl_variance` and used as the
R of the strategy rows and of the calibration row in place of the datasheet's or
``--filter``'s (``--dvl-noise data`` still matches R to the innovations);
``config.json`` reports it under ``dvl_variance_bag``, ``table.md`` marks it "(the
bag's)". A topic with no set covariance (or a TwistStamped) leaves R as tuned. The
median is over every message of the topic, those skipped as missing readings included.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from pronet._util.extras import missing
from pronet.recorded.bagfields import read_topics

F64 = NDArray[np.float64]


class BagError(ValueError):
    """A bag cannot be read as a recording: one line naming the bag and the topic
    (:func:`pronet.recorded.recordings.read_recording` raises it as a ``RecordingError``)."""


IMU_TYPES = ("sensor_msgs/msg/Imu",)
HEADING_TYPES = (
    "sensor_msgs/msg/Imu",
    "geometry_msgs/msg/QuaternionStamped",
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
)
DVL_TYPES = (
    "geometry_msgs/msg/TwistWithCovarianceStamped",
    "geometry_msgs/msg/TwistStamped",
)
TRUTH_TYPES = ("nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped")
DEPTH_TYPES = ("sensor_msgs/msg/FluidPressure",)
FIX_TYPES = ("sensor_msgs/msg/NavSatFix",)
#: Standard gravity [m/s²] of the pressure-to-depth conversion.
STANDARD_GRAVITY = 9.80665
#: Suffixes of a bag given as one file (ROS 1; a ROS 2 bag is a folder with metadata.yaml).
BAG_SUFFIXES = (".bag",)

_FLU = np.array([1.0, -1.0, -1.0])
_ENU_TO_NED = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]])


@dataclass(frozen=True)
class BagTopics:
    """Which topics of a bag are the IMU, the DVL and the truth, and their frames.

    Attributes:
        imu, dvl, truth: topic names (see the module docstring for their types); ``dvl``
            None: the DVL is not read (the bag then needs a depth or a fix topic);
            ``truth`` None: no ground truth is read.
        origin: the truth's local origin: latitude, longitude [deg], height [m, up]
            (required with a truth: a bag's poses are local metres).
        body_frame: ``"flu"`` (REP-103, the default) or ``"frd"``: the IMU's, the DVL's,
            the truth's and the heading's body frame.
        world_frame: ``"enu"`` (REP-103, the default) or ``"ned"``: the truth's and the
            heading's world frame.
        depth, fix: the optional depth (pressure) and position-fix topics, or None (not
            read).
        water_density: the water's density [kg/m³] of the pressure-to-depth conversion.
        surface_pressure: the pressure at the surface [Pa] taken off the readings (the
            standard atmosphere; 0 for a gauge sensor).
        heading: the optional heading topic (may be ``imu``: an AHRS's orientation), or
            None (not read).
        heading_magnetic: the heading's world frame points to magnetic north (turned
            true with the reader's ``declination``).
    """

    imu: str = "/imu/data"
    dvl: str | None = "/dvl/twist"
    truth: str | None = "/odometry"
    origin: tuple[float, float, float] | None = None
    body_frame: str = "flu"
    world_frame: str = "enu"
    depth: str | None = None
    fix: str | None = None
    water_density: float = 1025.0
    surface_pressure: float = 101_325.0
    heading: str | None = None
    heading_magnetic: bool = False

    def __post_init__(self) -> None:
        if not (np.isfinite(self.water_density) and 900.0 <= self.water_density <= 1100.0):
            raise ValueError(
                f"water_density: expected 900-1100 kg/m³ (fresh to salt water), got "
                f"{self.water_density}"
            )
        if not (np.isfinite(self.surface_pressure) and 0.0 <= self.surface_pressure <= 2e5):
            raise ValueError(
                f"surface_pressure: expected 0-200000 Pa (0: a gauge sensor), got "
                f"{self.surface_pressure}"
            )
        if self.body_frame not in ("flu", "frd"):
            raise ValueError(f"body_frame: expected flu or frd, got {self.body_frame!r}")
        if self.world_frame not in ("enu", "ned"):
            raise ValueError(f"world_frame: expected enu or ned, got {self.world_frame!r}")
        if self.origin is not None:
            lat, lon, h = (float(v) for v in self.origin)
            if not (np.isfinite([lat, lon, h]).all() and abs(lat) <= 90 and abs(lon) <= 360):
                raise ValueError(f"origin: expected lat,lon [deg],height [m], got {self.origin}")

    def __str__(self) -> str:
        return "bag"

    def record(self) -> dict[str, object]:
        """As ``config.json`` records it."""
        return {
            "format": "bag",
            "imu_topic": self.imu,
            "dvl_topic": self.dvl,
            "truth_topic": self.truth,
            "origin_deg_deg_m": None if self.origin is None else list(self.origin),
            "body_frame": self.body_frame,
            "world_frame": self.world_frame,
            "depth_topic": self.depth,
            "fix_topic": self.fix,
            "water_density_kg_m3": self.water_density,
            "surface_pressure_pa": self.surface_pressure,
            "heading_topic": self.heading,
            "heading_magnetic": self.heading_magnetic,
        }


class BagTable(NamedTuple):
    """One stream of a bag as a table: where it came from (``bag[topic]``), its rows
    (SI, body FRD, NED), the labels of its columns (``name [unit]``, the generic
    format's) and, for the heading, why each row is missing (``""``: not), else None."""

    where: str
    values: F64
    labels: list[str]
    reasons: tuple[str, ...] | None = None


def is_bag(path: Path) -> bool:
    """Whether ``path`` is a ROS bag: a ``.bag`` file, or a folder holding ``metadata.yaml``."""
    return (path.is_file() and path.suffix in BAG_SUFFIXES) or (
        path.is_dir() and (path / "metadata.yaml").is_file()
    )


def require_rosbags() -> None:
    """Raise :class:`pronet._util.extras.MissingExtra` (one line naming the extra)
    unless the ``rosbags`` library is installed."""
    try:
        import rosbags.highlevel  # noqa: F401
    except ImportError:
        raise missing("rosbags", "reading ROS bags") from None


def topic_types(path: str | Path) -> dict[str, str]:
    """The topics of the bag at ``path`` and their message types (e.g. to tell whether
    it has a truth topic before choosing :class:`BagTopics`); :class:`BagError` naming
    the bag when it is none or cannot be read."""
    require_rosbags()
    from rosbags.highlevel import AnyReader

    path = Path(path)
    if not is_bag(path):
        raise BagError(
            f"{path}: not a ROS bag (a .bag file, or a ROS 2 bag folder with metadata.yaml)"
        )
    try:
        with AnyReader([path]) as reader:
            return {c.topic: c.msgtype for c in reader.connections}
    except Exception as exc:  # noqa: BLE001 - whatever a corrupt file makes the parser raise
        raise unreadable(path, exc) from None


#: The libraries whose own errors say what is wrong with a bag (their message is kept).
_READERS = ("rosbags", "apsw", "sqlite3")


def unreadable(path: Path, exc: Exception) -> BagError:
    """The one line for a bag the reader failed on: a bag that is no bag, or corrupt or
    truncated (64 overwritten bytes made rosbags raise OverflowError, MemoryError,
    struct.error, UnicodeDecodeError, its readers' ReaderError or SQLite's
    CorruptError), naming ``path``; a :class:`BagError` passes as it is."""
    if isinstance(exc, BagError):
        return exc
    if type(exc).__module__.split(".")[0] in _READERS and str(exc):
        return BagError(f"{path}: cannot be read as a ROS bag ({exc})")
    return BagError(f"{path}: cannot be read as a ROS bag (corrupt or truncated)")


def _stamp(msg: Any) -> float:
    return float(msg.header.stamp.sec) + float(msg.header.stamp.nanosec) * 1e-9


def _xyz(v: Any) -> list[float]:
    return [float(v.x), float(v.y), float(v.z)]


def _dcm(q: Any) -> F64:
    """Body → world DCM of a unit quaternion message (x, y, z, w; normalised here)."""
    return _dcms(np.array([[q.x, q.y, q.z, q.w]], dtype=np.float64))[0]


def _dcms(xyzw: F64) -> F64:
    """Body → world DCMs ``(n, 3, 3)`` of quaternions ``(n, 4)`` (x, y, z, w;
    normalised here)."""
    x, y, z, w = xyzw.T
    n = np.sqrt(x * x + y * y + z * z + w * w)
    x, y, z, w = x / n, y / n, z / n, w / n
    rows = [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def euler_from_dcm(c: F64) -> F64:
    """Roll, pitch, yaw ``(…, 3)`` [rad] (ZYX) of body → NED DCMs ``(…, 3, 3)``, the
    inverse of :func:`pronet.recorded.alignment.dcm_from_euler`."""
    roll = np.arctan2(c[..., 2, 1], c[..., 2, 2])
    pitch = -np.arcsin(np.clip(c[..., 2, 0], -1.0, 1.0))
    yaw = np.arctan2(c[..., 1, 0], c[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def _connections(
    reader: Any, path: Path, topic: str, kind: str, types: tuple[str, ...]
) -> list[Any]:
    """The connections of ``topic``, checked: it exists (else the bag's topics are
    listed) and has one of ``types``."""
    found = [c for c in reader.connections if c.topic == topic]
    if not found:
        have = ", ".join(sorted(f"{c.topic} ({c.msgtype})" for c in reader.connections))
        hint = "; pronet navigate runs without a truth" if kind == "truth" else ""
        raise BagError(f"{path}: no topic {topic!r} for the {kind}; the bag has: {have}{hint}")
    bad = sorted({c.msgtype for c in found} - set(types))
    if bad:
        raise BagError(
            f"{path}[{topic}]: the {kind} topic holds {', '.join(bad)}; expected "
            f"{' or '.join(types)}"
        )
    return found


def _enough(path: Path, topic: str, kind: str, count: int, least: int) -> None:
    if count < least:
        raise BagError(f"{path}[{topic}]: the {kind} topic has {count} message(s)")


def _messages(
    reader: Any, path: Path, topic: str, kind: str, types: tuple[str, ...], least: int = 2
) -> list[Any]:
    """The deserialised messages of ``topic``, checked: it exists (else the bag's topics
    are listed), has one of ``types`` and at least ``least`` messages."""
    found = _connections(reader, path, topic, kind, types)
    msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=found)]
    _enough(path, topic, kind, len(msgs), least)
    return msgs


def _dvl_variance(msgs: list[Any]) -> tuple[float, float, float] | None:
    """The per-axis median of the set covariance diagonals (module docstring)."""
    diag = [
        [float(m.twist.covariance[i]) for i in (0, 7, 14)]
        for m in msgs
        if hasattr(m.twist, "covariance")
    ]
    set_ = [d for d in diag if min(d) > 0 and np.isfinite(d).all()]
    if not set_:
        return None
    r = np.median(np.array(set_), axis=0)
    return (float(r[0]), float(r[1]), float(r[2]))


def _depth_rows(msgs: list[Any], topics: BagTopics) -> tuple[F64, list[str]]:
    """``[time, depth (m, down)]`` per message, its σ [m] when every one sets a
    variance, and the pressure [Pa] (module docstring); with the columns' labels."""
    rho_g = topics.water_density * STANDARD_GRAVITY
    p = np.array([float(m.fluid_pressure) for m in msgs])
    rows = [np.array([_stamp(m) for m in msgs]), (p - topics.surface_pressure) / rho_g]
    labels = ["time [s]", "depth [m]"]
    variance = np.array([float(m.variance) for m in msgs])
    if (variance > 0).all() and np.isfinite(variance).all():
        rows.append(np.sqrt(variance) / rho_g)
        labels.append("sigma [m]")
    return np.column_stack([*rows, p]), [*labels, "pressure [Pa]"]


def _fix_rows(msgs: list[Any]) -> tuple[F64, list[str]]:
    """``[time, lat, lon (rad), height (m)]`` per NavSatFix, NaN where it has no fix,
    and σ north, east, down [m] when every one states its covariance; with the labels."""
    lla = np.array([[m.latitude, m.longitude, m.altitude] for m in msgs], dtype=np.float64)
    lla[:, :2] = np.radians(lla[:, :2])
    lla[[int(m.status.status) < 0 for m in msgs], :2] = np.nan  # STATUS_NO_FIX
    rows = [np.array([_stamp(m) for m in msgs])[:, None], lla]
    labels = ["time [s]", "lat [rad]", "lon [rad]", "height [m]"]
    diag = np.array([[float(m.position_covariance[i]) for i in (4, 0, 8)] for m in msgs])
    if all(int(m.position_covariance_type) > 0 for m in msgs) and (diag > 0).all():
        rows.append(np.sqrt(diag))
        labels += ["sigma_n [m]", "sigma_e [m]", "sigma_d [m]"]
    return np.hstack(rows), labels


def _frames(topics: BagTopics) -> tuple[F64, F64]:
    """``T_w`` (world → NED) and ``D_b`` (body FRD → the bag's body) of ``topics``."""
    t_w = _ENU_TO_NED if topics.world_frame == "enu" else np.eye(3)
    d_b = np.diag(_FLU) if topics.body_frame == "flu" else np.eye(3)
    return t_w, d_b


def _heading_inputs(msgs: list[Any]) -> tuple[F64, F64, NDArray[np.bool_], F64]:
    """Each heading message's stamp [s], orientation ``(x, y, z, w)``, whether it has
    none and its yaw variance (0 where the type has none)."""
    if hasattr(msgs[0], "orientation_covariance"):  # sensor_msgs/Imu
        quats = [m.orientation for m in msgs]
        none = np.array([float(m.orientation_covariance[0]) == -1.0 for m in msgs])
        variance = np.array([float(m.orientation_covariance[8]) for m in msgs])
    elif hasattr(msgs[0], "quaternion"):  # QuaternionStamped
        quats, none = [m.quaternion for m in msgs], np.zeros(len(msgs), bool)
        variance = np.zeros(len(msgs))
    else:  # PoseStamped or PoseWithCovarianceStamped
        covariance = hasattr(msgs[0].pose, "covariance")
        quats = [m.pose.pose.orientation if covariance else m.pose.orientation for m in msgs]
        none = np.zeros(len(msgs), bool)
        variance = np.array([float(m.pose.covariance[35]) if covariance else 0.0 for m in msgs])
    xyzw = np.array([[q.x, q.y, q.z, q.w] for q in quats], dtype=np.float64).reshape(-1, 4)
    return np.array([_stamp(m) for m in msgs]), xyzw, none, variance


#: The fields of a ``sensor_msgs/Imu`` read as a heading (last, after the IMU's).
_ORIENTATION_FIELDS = (
    *(f"orientation.{a}" for a in "xyzw"),
    "orientation_covariance[0]",
    "orientation_covariance[8]",
)


def _heading_rows(msgs: list[Any], topics: BagTopics) -> BagTable:
    """``[time, heading (rad)]`` per message, the yaw of ``C_nb = T_w C_wb D_b`` (as
    the truth's), with σ [rad] when every used message sets a yaw variance; NaN and a
    reason where a message has no orientation (module docstring)."""
    return _heading_table(*_heading_inputs(msgs), topics)


def _heading_table(
    time: F64, xyzw: F64, none: NDArray[np.bool_], variance: F64, topics: BagTopics
) -> BagTable:
    """:func:`_heading_rows` of the messages' stamps, orientations, whether they have
    none and their yaw variances (:func:`_heading_inputs`)."""
    t_w, d_b = _frames(topics)
    zero = ~(np.linalg.norm(xyzw, axis=1) > 0) & ~none
    yaw = np.full(len(time), np.nan)
    ok = ~none & ~zero
    yaw[ok] = euler_from_dcm(t_w @ _dcms(xyzw[ok]) @ d_b)[:, 2]
    reasons = np.where(none, "no orientation", np.where(zero, "nan", ""))
    rows = [time, yaw]
    name = "magnetic_heading" if topics.heading_magnetic else "heading"
    labels = ["time [s]", f"{name} [rad]"]
    used = variance[reasons == ""]
    if len(used) and (used > 0).all() and np.isfinite(used).all():
        rows.append(np.where(reasons == "", np.sqrt(np.abs(variance)), np.nan))
        labels.append("sigma [rad]")
    return BagTable("", np.column_stack(rows), labels, tuple(str(r) for r in reasons))


def _truth_rows(msgs: list[Any], topics: BagTopics, path: Path) -> list[list[float]]:
    from pronet.navigation import lla_from_ned

    if topics.origin is None:
        raise BagError(
            f"{path}[{topics.truth}]: the truth's positions are local metres; give their "
            "geodetic origin (--origin LAT,LON,HEIGHT in deg, deg, m)"
        )
    t_w, d_b = _frames(topics)
    time = np.array([_stamp(m) for m in msgs])
    odometry = hasattr(msgs[0], "twist")
    pose = [m.pose.pose if odometry else m.pose for m in msgs]
    ned = np.array([_xyz(p.position) for p in pose]) @ t_w.T
    c_wb = np.array([_dcm(p.orientation) for p in pose])
    c_nb = t_w @ c_wb @ d_b
    if odometry:  # twist in the child (body) frame, per nav_msgs/Odometry
        v_body = np.array([_xyz(m.twist.twist.linear) for m in msgs])
        vel = np.einsum("ij,njk,nk->ni", t_w, c_wb, v_body)
    else:  # a PoseStamped has no velocity: central differences of the positions
        vel = np.gradient(ned, time, axis=0) if np.all(np.diff(time) > 0) else np.zeros_like(ned)
    lat, lon, h = topics.origin
    lla = lla_from_ned(ned, np.array([np.radians(lat), np.radians(lon), h]))
    rpy = euler_from_dcm(c_nb)
    return np.column_stack([time, lla, vel, rpy]).tolist()


_IMU_LABELS = [
    "time [s]",
    *(f"acc_{a} [m/s^2]" for a in "xyz"),
    *(f"gyro_{a} [rad/s]" for a in "xyz"),
]
_DVL_LABELS = ["time [s]", *(f"vel_{a} [m/s]" for a in "xyz")]
_GT_LABELS = ["time [s]", "lat [rad]", "lon [rad]", "height [m]"]
_GT_LABELS += [*(f"vel_{a} [m/s]" for a in "ned"), "roll [rad]", "pitch [rad]", "yaw [rad]"]


_IMU_FIELDS = tuple(f"{v}.{a}" for v in ("linear_acceleration", "angular_velocity") for a in "xyz")


def _read(reader: Any, path: Path, topics: BagTopics) -> dict[str, Any]:
    """The topics ``topics`` names, checked (:func:`_connections`, then their counts)
    and read in one pass (:func:`pronet.recorded.bagfields.read_topics`), by kind: the
    IMU's and a ``sensor_msgs/Imu`` heading topic's stamps and fields as columns (the
    IMU's, then :data:`_ORIENTATION_FIELDS` where it is the heading), others' messages."""
    wanted = [
        (kind, str(topic), _connections(reader, path, str(topic), kind, types), least)
        for kind, topic, types, least in (
            ("IMU", topics.imu, IMU_TYPES, 2),
            ("DVL", topics.dvl, DVL_TYPES, 2),
            ("truth", topics.truth, TRUTH_TYPES, 2),
            ("depth", topics.depth, DEPTH_TYPES, 1),
            ("fix", topics.fix, FIX_TYPES, 1),
            ("heading", topics.heading, HEADING_TYPES, 1),
        )
        if topic is not None and not (kind == "heading" and topic == topics.imu)
    ]
    own = _ORIENTATION_FIELDS if topics.heading == topics.imu else ()
    fields = {"IMU": _IMU_FIELDS + own, "heading": _ORIENTATION_FIELDS}
    requests = [
        (topic, conns, fields.get(kind) if {c.msgtype for c in conns} == {IMU_TYPES[0]} else None)
        for kind, topic, conns, _ in wanted
    ]
    data: dict[str, Any] = {}
    for (kind, topic, _, least), got in zip(wanted, read_topics(reader, requests), strict=True):
        _enough(path, topic, kind, len(got), least)
        data[kind] = got
    return data


def bag_streams(
    path: str | Path, topics: BagTopics | None = None
) -> tuple[dict[str, BagTable], tuple[float, float, float] | None]:
    """The streams of one ROS 1 or ROS 2 bag as the generic format's tables
    (``{"imu" | "dvl" | "gt": BagTable}``, ``where`` naming bag and topic, the rows in
    :data:`pronet.recorded.recordings.COLUMNS` order, SI, body FRD, NED; ``"gt"`` only
    with ``topics.truth``; with ``topics.depth``, ``topics.fix`` and ``topics.heading``
    also ``"depth"`` (its pressure last), ``"fix"`` and ``"heading"``, their required
    columns then the optional ones present, :mod:`pronet.recorded.aiding`) and the R its
    DVL covariance states (None: not set); see the module docstring. Not yet checked:
    :func:`pronet.recorded.recordings.read_recording` reads a bag through this and checks
    it as the generic format. :class:`BagError` naming bag and topic,
    :class:`~pronet._util.extras.MissingExtra` without ``rosbags``."""
    require_rosbags()
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    topics = topics or BagTopics()
    path = Path(path)
    if topics.dvl is None and topics.depth is None and topics.fix is None:
        raise BagError(f"{path}: without a DVL topic, needs a depth or a fix topic")
    if not is_bag(path):
        raise BagError(
            f"{path}: not a ROS bag (a .bag file, or a ROS 2 bag folder with metadata.yaml)"
            + ("" if path.exists() else " (it does not exist)")
        )
    flip = _FLU if topics.body_frame == "flu" else np.ones(3)
    try:
        with AnyReader([path], default_typestore=get_typestore(Stores.LATEST)) as reader:
            data = _read(reader, path, topics)
    except Exception as exc:  # noqa: BLE001 - whatever a corrupt file makes the parser raise
        raise unreadable(path, exc) from None
    imu, dvl_msgs = data["IMU"], data.get("DVL", [])

    def velocity(m: Any) -> Any:
        return m.twist.twist.linear if hasattr(m.twist, "twist") else m.twist.linear

    def table(topic: str | None, rows: Any, labels: list[str]) -> BagTable:
        return BagTable(f"{path}[{topic}]", np.array(rows, dtype=np.float64), labels)

    rows = np.column_stack([imu[:, 0], imu[:, 1:4] * flip, imu[:, 4:7] * flip])
    streams = {"imu": table(topics.imu, rows, _IMU_LABELS)}
    if topics.dvl is not None:
        dvl = [[_stamp(m), *(np.array(_xyz(velocity(m))) * flip)] for m in dvl_msgs]
        streams["dvl"] = table(topics.dvl, dvl, _DVL_LABELS)
    if topics.truth is not None:
        streams["gt"] = table(topics.truth, _truth_rows(data["truth"], topics, path), _GT_LABELS)
    if "depth" in data:
        streams["depth"] = table(topics.depth, *_depth_rows(data["depth"], topics))
    if "fix" in data:
        streams["fix"] = table(topics.fix, *_fix_rows(data["fix"]))
    if topics.heading is not None:  # the IMU's own: an AHRS's orientation
        got = imu if topics.heading == topics.imu else data["heading"]
        if isinstance(got, np.ndarray):  # Imu columns: the stamp, …, _ORIENTATION_FIELDS
            inputs = (got[:, 0], got[:, -6:-2], got[:, -2] == -1.0, got[:, -1])
        else:
            inputs = _heading_inputs(got)
        where = f"{path}[{topics.heading}]"
        streams["heading"] = _heading_table(*inputs, topics)._replace(where=where)
    return streams, _dvl_variance(dvl_msgs)
