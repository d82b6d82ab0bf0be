"""The files of a simulated survey (``mission_recording``): the generic CSV format
(:func:`write_generic`) and a ROS bag (:func:`write_mission_bag`), the truth left out
unless a test asks for it (the readers' round trip while they still need a truth)."""

from __future__ import annotations

import gzip
import io
import math
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import NDArray

from pronet.recorded.bags import STANDARD_GRAVITY, BagTopics

if TYPE_CHECKING:
    from mission_recording import Mission

F64 = NDArray[np.float64]

#: The standard atmosphere [Pa]: the surface pressure a logger assumes by default.
STANDARD_ATMOSPHERE = 101_325.0

DvlMissing = Literal["empty", "sentinel", "valid"]


def _write_table(path: Path, header: list[str], columns: list[F64], gz: bool) -> Path:
    buf = io.StringIO()
    buf.write(",".join(header) + "\n")
    np.savetxt(buf, np.column_stack(columns), delimiter=",", fmt="%.17g")
    text = buf.getvalue().replace("nan", "")  # a missing value: an empty cell
    if gz:
        path = path.with_name(path.name + ".gz")
        path.write_bytes(gzip.compress(text.encode(), compresslevel=1))
    else:
        path.write_text(text)
    return path


def _truth_rows(mission: Mission, rate: float) -> NDArray[np.intp]:
    every = max(1, round(mission.sensors.imu_rate / rate))
    return np.arange(0, len(mission.truth.time), every)


def write_generic(
    mission: Mission,
    folder: str | Path,
    *,
    truth: bool = False,
    truth_rate: float = 10.0,
    dvl_missing: DvlMissing = "empty",
    sigma: bool = True,
    surface_pressure: float = STANDARD_ATMOSPHERE,
    gz: bool = False,
) -> Path:
    """Write ``mission`` as the generic CSV format (:mod:`pronet.recorded.recordings`)
    into ``folder``: ``imu.csv`` (rad/s), ``dvl.csv`` (the rows without bottom lock as
    ``dvl_missing``: ``empty`` cells, RDI's ``sentinel`` −32.768 m/s, or zeros with a
    ``valid`` column of 0), ``depth.csv`` (the depth over ``surface_pressure`` [Pa], as
    a logger converts it, and the raw ``pressure [Pa]``), ``fix.csv`` (latitude and
    longitude in degrees, no height: horizontal) unless there are none, ``heading.csv``
    (``time [s]``, ``heading [deg]``, ``sigma [deg]``) with a compass; every number at
    full precision. ``sigma``: the depth's and the fixes' σ columns. ``truth``: also a
    ``gt.csv`` at ``truth_rate`` [Hz] (a test's round trip; a mission has none);
    ``gz``: gzip every file."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    s = mission.sensors
    imu_header = [
        "time [s]",
        *(f"acc_{a} [m/s^2]" for a in "xyz"),
        *(f"gyro_{a} [rad/s]" for a in "xyz"),
    ]
    _write_table(folder / "imu.csv", imu_header, [mission.imu_time, mission.imu], gz)
    dvl = mission.dvl.copy()
    dvl_header = ["time [s]", *(f"vel_{a} [m/s]" for a in "xyz")]
    dvl_columns = [mission.dvl_time, dvl]
    lost = ~mission.dvl_valid
    if dvl_missing == "sentinel":
        dvl[lost] = -32.768
    elif dvl_missing == "valid":
        dvl[lost] = 0.0
        dvl_header.append("valid")
        dvl_columns.append((~lost).astype(np.float64))
    elif dvl_missing != "empty":
        raise ValueError(f"dvl_missing: expected empty, sentinel or valid, got {dvl_missing!r}")
    _write_table(folder / "dvl.csv", dvl_header, dvl_columns, gz)
    n_depth = len(mission.depth_time)
    depth_header = ["time [s]", "depth [m]"] + (["sigma [m]"] if sigma else []) + ["pressure [Pa]"]
    depth_columns = [mission.depth_time, mission.depth(surface_pressure)]
    depth_columns += [np.full(n_depth, s.depth_sigma)] if sigma else []
    _write_table(folder / "depth.csv", depth_header, [*depth_columns, mission.pressure], gz)
    if len(mission.fix_time):
        fix_header = ["time [s]", "lat [deg]", "lon [deg]"]
        fix_columns = [mission.fix_time, np.degrees(mission.fix_lla[:, :2])]
        if sigma:
            fix_header += [f"sigma_{a} [m]" for a in "ned"]
            fix_columns.append(np.tile(fix_sigma(mission), (len(mission.fix_time), 1)))
        _write_table(folder / "fix.csv", fix_header, fix_columns, gz)
    if len(mission.heading_time):
        sigma_deg = np.full(len(mission.heading_time), math.degrees(s.heading_sigma))
        heading_header = ["time [s]", "heading [deg]", "sigma [deg]"]
        heading_columns = [mission.heading_time, np.degrees(mission.heading), sigma_deg]
        _write_table(folder / "heading.csv", heading_header, heading_columns, gz)
    if truth:
        k = _truth_rows(mission, truth_rate)
        t = mission.truth
        gt_header = ["time [s]", "lat [rad]", "lon [rad]", "height [m]"]
        gt_header += [f"vel_{a} [m/s]" for a in "ned"] + ["roll [rad]", "pitch [rad]", "yaw [rad]"]
        _write_table(folder / "gt.csv", gt_header, [t.time[k], t.lla[k], t.vel[k], t.rpy[k]], gz)
    return folder


def fix_sigma(mission: Mission) -> F64:
    """The fixes' 1σ north, east, down [m] as written (down: twice the horizontal,
    unused by horizontal fixes)."""
    h = mission.sensors.fix_sigma
    return np.array([h, h, 2.0 * h])


#: The bag's topics (the issue's example names; the fixes of ``fixes="surface"``, GNSS,
#: on ``/gnss/fix``).
BAG_TOPICS = {
    "imu": "/imu/data",
    "dvl": "/dvl/twist",
    "depth": "/bar30/pressure",
    "fix": "/usbl/fix",
    "gnss": "/gnss/fix",
    "truth": "/odometry",
}


def write_mission_bag(
    mission: Mission,
    path: str | Path,
    storage: str = "mcap",
    *,
    truth: bool = False,
    truth_rate: float = 10.0,
) -> tuple[Path, BagTopics]:
    """Write ``mission`` as a ROS bag at ``path`` (``storage``: ``rosbag1``, ``sqlite3``
    or ``mcap``) in REP-103's frames through ``ros_bag.BagMessages``: ``sensor_msgs/Imu``
    with the AHRS orientation (its covariance ``ahrs_sigma²``), the DVL as
    TwistWithCovarianceStamped (σ² set; the rows without bottom lock absent),
    FluidPressure (absolute [Pa], variance set), NavSatFix (horizontal: altitude NaN,
    σ diagonal known) unless there are no fixes, and no truth topic unless ``truth``
    (``nav_msgs/Odometry`` at ``truth_rate`` [Hz], a test's round trip). Returns the path
    and the :class:`~pronet.recorded.bags.BagTopics` that read it: :data:`BAG_TOPICS`
    (with ``truth``, the truth's topic and its first position as origin; without, none),
    the TRUE surface pressure and density (a user who does not know them reads with the
    default ``surface_pressure``)."""
    from ros_bag import BagMessages, ros_quaternions

    path = Path(path)
    t, s = mission.truth, mission.sensors
    origin = (math.degrees(t.lla[0, 0]), math.degrees(t.lla[0, 1]), float(t.lla[0, 2]))
    has_fix = len(mission.fix_time) > 0
    fix_topic = BAG_TOPICS["gnss" if mission.fixes == "surface" else "fix"]
    topics = BagTopics(
        imu=BAG_TOPICS["imu"],
        dvl=BAG_TOPICS["dvl"],
        truth=BAG_TOPICS["truth"] if truth else None,
        origin=origin if truth else None,
        depth=BAG_TOPICS["depth"],
        fix=fix_topic if has_fix else None,
        water_density=mission.water_density,
        surface_pressure=mission.surface_pressure,
    )
    bag = BagMessages(storage, unix=0)
    orientation_cov = np.diag(np.square(s.ahrs_sigma)).ravel()
    bag.imu(
        topics.imu,
        mission.imu_time,
        mission.imu,
        ros_quaternions(mission.ahrs_rpy),
        orientation_cov,
    )
    valid = mission.dvl_valid
    cov = np.full((int(valid.sum()), 3), s.dvl_sigma**2)
    bag.twist(BAG_TOPICS["dvl"], mission.dvl_time[valid], mission.dvl[valid], cov)
    rho_g = mission.water_density * STANDARD_GRAVITY
    variance = np.full(len(mission.depth_time), (s.depth_sigma * rho_g) ** 2)
    bag.pressure(BAG_TOPICS["depth"], mission.depth_time, mission.pressure, variance)
    if has_fix:
        sigma = np.tile(fix_sigma(mission), (len(mission.fix_time), 1))
        bag.navsat(fix_topic, mission.fix_time, mission.fix_lla, sigma)
    if truth:
        k = _truth_rows(mission, truth_rate)
        lla0 = t.lla[0]
        bag.truth(str(topics.truth), t.time[k], t.lla[k], t.vel[k], t.rpy[k], lla0)
    return bag.write(path), topics


def write_vehicle_file(tmp_path: Path, m: Mission, *, arms: bool = True) -> Path:
    """A vehicle file as the mission's team would write it: the MEMS grade, the DVL's σ,
    the lever arms (with ``arms``), the compass's σ and the sensor's depth afloat."""
    la = m.lever_arms
    lines = [
        'grade = "mems"',
        f"dvl_variance = {[m.sensors.dvl_sigma**2] * 3}",
        f"dvl_lever_arm = {list(map(float, la.dvl))}",
        f"heading_sigma = {np.degrees(m.sensors.heading_sigma)}",
        # the survey floats with its IMU 0.3 m deep, level
        f"surface_depth = {0.3 + la.depth[2]}",
    ]
    if arms:
        lines += [
            f"depth_lever_arm = {list(map(float, la.depth))}",
            f"fix_lever_arm = {list(map(float, la.fix))}",
        ]
    path = tmp_path / "vehicle.toml"
    path.write_text("\n".join(lines) + "\n")
    return path
