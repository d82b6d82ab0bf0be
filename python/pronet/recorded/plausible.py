"""Plausibility of a recording, one line each naming the file and column: checks that
catch data which would otherwise run to a silently wrong answer.

Each check returns the problem as one line (``"<file>: column '<name>': ..."``), or
None; :mod:`pronet.recorded.recordings` raises it as a ``RecordingError`` (exit 2 from
the command line). Checked, in this order, after the per-file checks (finite numbers,
increasing time, rate):

- an IMU too short to navigate (:func:`short_imu`): fewer than two rows, or ending
  before every other stream's first reading;
- magnitudes that fit their units (:func:`magnitudes`): the mean specific force near
  gravity, angular rates within :data:`MAX_RECORDED_RATE`, the DVL's speed near the
  ground truth's (without one, within :data:`MAX_DVL_SPEED`);
- a column named twice (:func:`duplicate_columns`; otherwise the first would be used);
- streams that do not share a clock (:func:`disjoint_streams`): the DVL's or the
  ground truth's stamps beside none of the IMU's (another epoch, another unit);
- values beyond physical bounds (:func:`beyond_bounds`): a ground-truth speed beyond
  :data:`MAX_SPEED` or a height beyond :data:`HEIGHT_RANGE`;
- stuck or dead channels (:func:`stuck_channels`): an IMU or DVL column whose every
  value over the section is the same (a dead gyro reads 0);
- angles whose unit disagrees with their header (:func:`attitude_units`): the ground
  truth's attitude turning :data:`ANGLE_RATIO` times more or less than the integrated
  gyro (rad under a ``[deg]`` header turns 57 times less), or its yaw turning against
  the gyro's z axis (a heading in ENU); its latitude and longitude moving so much more
  or less than its velocity, or its velocity not pointing along the track they draw
  (ENU for NED; :func:`position_units`).

Lever arms beyond 10 m are usable and only warned of
(:func:`pronet._util.plausibility.long_lever_arm`, a :class:`PlausibilityWarning`): typed
in cm or mm, they run to errors of 100 m/s; a few vehicles are that long. So is an IMU
whose stamps jitter beyond 15 % of a step (:func:`pronet._util.plausibility.imu_jitter`), and a
ground truth rolled beyond ±90° most of the time (:func:`warn_upside_down`: a body frame
read as the other).
"""

from __future__ import annotations

import warnings
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from pronet import _core
from pronet._util.plausibility import (
    HEIGHT_RANGE,
    PlausibilityWarning,
    specific_force,
)

F64 = NDArray[np.float64]

#: A rate [Hz] within this share of a nominal one is taken at it (a logger's clock
#: drift aside: the Snapir IMU's stamps step by 0.01000025 s, its rate 100 Hz): the
#: IMU's nominal step (:func:`pronet.recorded.tuning.imu_step`), and a sample rate at
#: the bounds of the plausible ones (a 10 Hz IMU 25 ppm slow is a 10 Hz IMU).
NOMINAL_RATE_TOLERANCE = 1e-3

#: The fastest a ground truth may move [m/s] (no underwater vehicle comes near it): the
#: core's bound on any solution (``pass::MAX_SPEED``), past which a pass diverged.
MAX_SPEED: float = _core.MAX_SPEED
#: The truth's attitude steps over the gyro's, by RMS, outside [1/x, x]: a unit slip.
ANGLE_RATIO = 5.0
#: Its velocity's steps against its track's (and its yaw's against the gyro's z), by
#: cosine, under this (or under its negative): a frame slip. On the Snapir sections the
#: horizontal cosine is 0.998–1.000, the vertical 0.97–1.00, the yaw's 0.89–1.00.
DIRECTION_COSINE = 0.5
#: The least vertical motion [m per truth row] its direction is checked over.
MIN_CLIMB = 0.01
#: Below this RMS gyro turn per truth row [rad] the attitude-unit check says nothing.
MIN_TURN = 1e-3
#: Plausible magnitudes. The mean specific force over a section near gravity
#: (:func:`pronet._util.plausibility.specific_force`, the API's rule too); the 99th
#: percentile of the angular rate at most this [rad/s] (as a trajectory's turn rate);
#: the DVL's median speed within this ratio of the ground truth's (when that is above
#: 0.2 m/s).
MAX_RECORDED_RATE = 10.0
DVL_SPEED_RATIO = (0.5, 2.0)
#: Without a ground truth, the DVL's median speed at most this [m/s] (no vehicle a DVL
#: tracks the bottom from moves so fast; cm/s under an m/s header does).
MAX_DVL_SPEED = 10.0


class Table(NamedTuple):
    """A table as read: values (SI, the required columns in order, then the optional
    ones present), where it came from (file, or ``file[array]``) and the column labels
    as written."""

    values: F64
    where: str
    labels: list[str]


#: The units an angle column may be given in, and their factor to radians.
ANGLE_UNITS = {"rad": 1.0, "deg": np.pi / 180}


def angle_beyond(table: Table, j: int, lo: float, hi: float, why: str) -> str | None:
    """Column ``j`` of ``table`` (an angle, its values in radians) outside ``[lo, hi]``
    [°] (a NaN, a missing value, is not): one line naming the file, row and column,
    with the value and the range in the column's unit and ``why``; None if within."""
    v = table.values[:, j]
    bad = (v < np.radians(lo)) | (v > np.radians(hi))
    if not bad.any():
        return None
    r = int(np.argmax(bad))
    unit = parse_header(table.labels[j])[1]
    if unit == "deg":
        bounds = f"{lo:g} … {hi:g} deg ({why})"
    else:
        bounds = f"{np.radians(lo):.6g} … {np.radians(hi):.6g} rad ({lo:g}° … {hi:g}°: {why})"
    value = v[r] / ANGLE_UNITS[unit]
    return f"{table.where}, row {r + 1}: {table.labels[j]!r} is {value:.10g}, beyond {bounds}"


def parse_header(cell: str) -> tuple[str, str]:
    """A column header ``name [unit]`` as its lower-case name and its unit."""
    name, _, unit = cell.strip().partition("[")
    return name.strip().lower(), unit.rstrip("] ").strip()


def magnitudes(imu: F64, dvl: F64, gt_vel: F64, source: str) -> str | None:
    """Magnitudes that fit their units, checked before anything is filtered (a unit
    mix-up otherwise runs to the end and only shows as a huge error): ``imu`` ``(n, 6)``
    SI samples, ``dvl`` ``(m, 3)`` the used DVL readings [m/s] (may be empty),
    ``gt_vel`` ``(k, 3)`` the truth's velocity [m/s] (empty: no ground truth)."""
    with np.errstate(over="ignore", invalid="ignore"):  # a corrupt file's 1e300: inf, refused
        return _magnitudes(imu, dvl, gt_vel, source)


def _magnitudes(imu: F64, dvl: F64, gt_vel: F64, source: str) -> str | None:
    if (not_gravity := specific_force(imu)) is not None:
        return f"{source} imu: {not_gravity}"
    rate = float(np.percentile(np.linalg.norm(imu[:, 3:], axis=1), 99))
    if rate > MAX_RECORDED_RATE:
        return (
            f"{source} imu: 1 % of the angular rates exceed {rate:.4g} rad/s, beyond any "
            f"vehicle (at most {MAX_RECORDED_RATE:g}); are they in deg/s under a rad/s header?"
        )
    if not len(dvl):
        return None
    if not len(gt_vel):
        dvl_speed = float(np.median(np.linalg.norm(dvl, axis=1)))
        if dvl_speed <= MAX_DVL_SPEED:
            return None
        return (
            f"{source} dvl: its median speed {dvl_speed:.4g} m/s is beyond any vehicle (at most "
            f"{MAX_DVL_SPEED:g} without a ground truth to compare); are the DVL velocities in m/s?"
        )
    truth, dvl_speed = (float(np.median(np.linalg.norm(v, axis=1))) for v in (gt_vel, dvl))
    lo, hi = DVL_SPEED_RATIO
    if truth > 0.2 and not lo <= dvl_speed / truth <= hi:
        return (
            f"{source} dvl: its median speed {dvl_speed:.4g} m/s against the ground truth's "
            f"{truth:.4g} m/s; are the DVL velocities in m/s?"
        )
    return None


def duplicate_columns(
    where: str, names: list[str], header: list[str], wanted: set[str]
) -> str | None:
    """A column of ``wanted`` named twice in ``header`` (``names``: its parsed names)."""
    for name in sorted(wanted):
        at = [i for i, n in enumerate(names) if n == name]
        if len(at) > 1:
            shown = " and ".join(f"{i + 1} ({header[i].strip()!r})" for i in at)
            return (
                f"{where}: column {name!r} appears {len(at)} times (columns {shown}); "
                "keep the one that holds the data"
            )
    return None


#: The fewest IMU rows a recording may have: a step to integrate over.
MIN_IMU_ROWS = 2


def short_imu(tables: dict[str, Table]) -> str | None:
    """The IMU table of ``tables`` with fewer than :data:`MIN_IMU_ROWS` rows, or whose
    rows all end before the first reading of every other table (nothing aids or scores
    it): named by its file and its row count."""
    imu = tables["imu"]
    n = len(imu.values)
    rows = f"{n} data row" + ("" if n == 1 else "s")
    if n < MIN_IMU_ROWS:
        return f"{imu.where}: {rows}: an IMU needs at least {MIN_IMU_ROWS} (a step to integrate)"
    others = [t for kind, t in tables.items() if kind != "imu" and len(t.values)]
    first = min(others, key=lambda t: t.values[0, 0], default=None)
    end = float(imu.values[-1, 0])
    if first is not None and end < first.values[0, 0]:
        return (
            f"{imu.where}: its {rows} end at {end:.3f} s, {first.values[0, 0] - end:.3g} s "
            f"before any other stream's first reading ({first.where}): too short to navigate"
        )
    return None


def disjoint_streams(imu: Table, other: Table, kind: str) -> str | None:
    """``other``'s stamps beside none of the IMU's: no overlap even with the clock
    search's reach (an offset of 2 s and a scale of 1 %, which acts about the section's
    start: 1 % of the streams' span, whatever the epoch of their stamps)."""
    a, b = float(imu.values[0, 0]), float(imu.values[-1, 0])
    t = other.values[:, 0]
    slack = 2.0 + 0.01 * max(b - a, float(t[-1] - t[0]))
    if t[-1] < a - slack or t[0] > b + slack:
        return (
            f"{other.where}: column {other.labels[0]!r} runs {t[0]:.10g} … {t[-1]:.10g} s, "
            f"the IMU's {a:.10g} … {b:.10g} s: the {kind} and IMU stamps do not overlap "
            "(another epoch or unit? every stream must be stamped on one clock, in seconds)"
        )
    return None


def beyond_bounds(gt: Table) -> str | None:
    """A ground-truth speed beyond :data:`MAX_SPEED` or height beyond
    :data:`HEIGHT_RANGE`, named by column."""
    for j in (4, 5, 6):
        v = np.abs(gt.values[:, j])
        if v.max() > MAX_SPEED:
            r = int(np.argmax(v))
            return (
                f"{gt.where}, row {r + 1}: column {gt.labels[j]!r} is {gt.values[r, j]:.6g} "
                f"m/s, beyond any underwater vehicle (at most {MAX_SPEED:g}); in another unit?"
            )
    h = gt.values[:, 3]
    lo, hi = HEIGHT_RANGE
    if h.min() < lo or h.max() > hi:
        r = int(np.argmax((h < lo) | (h > hi)))
        return (
            f"{gt.where}, row {r + 1}: column {gt.labels[3]!r} is {h[r]:.6g} m, beyond "
            f"{lo:g} … {hi:g} m; in another unit?"
        )
    return None


def warn_upside_down(gt: Table | None) -> None:
    """Warn (:class:`PlausibilityWarning`) of a ground truth whose roll is beyond ±90°
    at most of its rows: a vehicle upside down all along, or a body frame read as the
    other (FLU as FRD: the truth's attitude turns with the IMU's axes, so that the pass
    would run rolled by 180°, with every lever arm mirrored; where the vehicle turns,
    its yaw then turns against the gyro's z, refused by :func:`attitude_units`)."""
    if gt is not None and (flipped := _upside_down(gt)) is not None:
        warnings.warn(flipped, PlausibilityWarning, stacklevel=3)


def _upside_down(gt: Table) -> str | None:
    roll = gt.values[:, 7]
    share = float(np.mean(np.abs(roll) > np.pi / 2))
    if share <= 0.5:
        return None
    return (
        f"{gt.where}: column {gt.labels[7]!r}: the roll is beyond ±90° at "
        f"{100 * share:.0f} % of the rows (median {np.degrees(np.median(np.abs(roll))):.0f}°): "
        "upside down? a body frame read as the other (FLU as FRD) turns the truth over "
        "with the IMU, and the lever arms (given in FRD) point the wrong way"
    )


def stuck_channels(
    table: Table, columns: range, rows: NDArray[np.bool_] | None = None
) -> str | None:
    """A column of ``columns`` whose every value (of ``rows``) is the same: a stuck or
    dead channel (checked over at least 10 values)."""
    values = table.values if rows is None else table.values[rows]
    if len(values) < 10:
        return None
    for j in columns:
        if np.ptp(values[:, j]) == 0.0:
            return (
                f"{table.where}: column {table.labels[j]!r} is {values[0, j]:.6g} in every one "
                f"of its {len(values)} rows: a stuck or dead channel"
            )
    return None


def _varying_steps(angles: F64) -> float:
    """RMS of the row-to-row steps of ``angles`` ``(n, 3)`` [rad] less their median."""
    steps = np.diff(angles, axis=0)
    steps = steps - np.median(steps, axis=0)
    return float(np.sqrt(np.mean(np.sum(steps**2, axis=1))))


def attitude_units(imu: Table, gt: Table) -> str | None:
    """The truth's attitude steps between its rows against the gyro's turn over the
    same stamps (as given), each less its median step (a gyro bias, a steady turn), by
    RMS: outside [1/:data:`ANGLE_RATIO`, ANGLE_RATIO], the angles' unit disagrees with
    their header. Silent where the gyro's turn varies less than :data:`MIN_TURN` per
    row."""
    t_imu, w = imu.values[:, 0], imu.values[:, 4:7]
    dt = np.diff(t_imu, prepend=t_imu[0] - np.median(np.diff(t_imu)))
    cum = np.vstack([np.zeros(3), np.cumsum(w * dt[:, None], axis=0)])
    edges = np.concatenate([[t_imu[0] - dt[0]], t_imu])
    t = gt.values[:, 0]
    inside = (t >= edges[0]) & (t <= edges[-1])
    if inside.sum() < 10:
        return None
    turned = np.stack([np.interp(t[inside], edges, cum[:, j]) for j in range(3)], axis=1)
    euler = np.unwrap(gt.values[inside, 7:10], axis=0)
    # Steps less their median: a gyro's bias (a MEMS one turns 1e-3 rad per second on a
    # straight leg) and a steady turn cancel; the turns that come and go are compared.
    gyro, truth = (_varying_steps(a) for a in (turned, euler))
    if gyro < MIN_TURN:
        return None
    ratio = truth / gyro
    if 1 / ANGLE_RATIO <= ratio <= ANGLE_RATIO:
        return _yaw_against_gyro(turned[:, 2], euler[:, 2], gt)
    header = ", ".join(repr(gt.labels[j]) for j in (7, 8, 9))
    guess = "rad under a [deg] header" if ratio < 1 else "deg under a [rad] header"
    return (
        f"{gt.where}: columns {header} turn {ratio:.3g} times as much as the gyro between "
        f"rows; are the angles in {guess}?"
    )


def _yaw_against_gyro(turned: F64, yaw: F64, gt: Table) -> str | None:
    """The truth's yaw steps against the gyro's z turn over them (each less its median
    step): correlated below −:data:`DIRECTION_COSINE`, the yaw turns the other way: a
    heading in ENU (90° − yaw) or counted counter-clockwise, or the IMU's z axis up (a
    body frame read as the other). Silent where the z turn
    varies less than :data:`MIN_TURN` per row."""
    a, b = (np.diff(x) - np.median(np.diff(x)) for x in (turned, yaw))
    if np.sqrt(np.mean(a * a)) < MIN_TURN:
        return None
    corr = _direction(b, a)  # 1 where either does not move
    if corr >= -DIRECTION_COSINE:
        return None
    return (
        f"{gt.where}: column {gt.labels[9]!r} turns against the gyro's z axis (correlation "
        f"{corr:.2f} of their steps, about 1 for a yaw from north, clockwise seen from above): "
        "a heading in ENU (90° − yaw) or counted counter-clockwise, or a body frame read as "
        "the other (FLU as FRD)?"
    )


def _direction(steps: F64, by_velocity: F64) -> float:
    """The cosine between the position's steps and the velocity's over the same rows
    (both ``(n, k)`` [m]), 1 where they point the same way."""
    size = float(np.sqrt(np.sum(steps**2) * np.sum(by_velocity**2)))
    return float(np.sum(steps * by_velocity)) / size if size > 0 else 1.0


def position_units(gt: Table) -> str | None:
    """The truth's horizontal steps between its rows from latitude and longitude
    against the same steps from its velocity, by RMS: outside [1/:data:`ANGLE_RATIO`,
    ANGLE_RATIO], latitude and longitude disagree with their header's unit (rad under
    ``[deg]`` moves 57 times less). Silent where the velocity moves less than 0.1 m per
    row."""
    v, t = gt.values, gt.values[:, 0]
    dt = np.diff(t)
    lat = v[:, 1]
    radius = 6_371_000.0  # a sphere: enough for a ratio of 57
    north = np.diff(lat) * radius
    east = np.diff(v[:, 2]) * radius * np.cos(lat[:-1])
    moved = np.sqrt(np.mean(north**2 + east**2))
    mean_vel = (v[1:, 4:6] + v[:-1, 4:6]) / 2
    by_velocity = np.sqrt(np.mean(np.sum((mean_vel * dt[:, None]) ** 2, axis=1)))
    if len(t) < 10 or by_velocity < 0.1:
        return None
    ratio = moved / by_velocity
    if 1 / ANGLE_RATIO <= ratio <= ANGLE_RATIO:
        return _velocity_direction(gt, np.stack([north, east], axis=1), mean_vel * dt[:, None])
    guess = "rad under a [deg] header" if ratio < 1 else "deg under a [rad] header"
    return (
        f"{gt.where}: columns {gt.labels[1]!r}, {gt.labels[2]!r} move {ratio:.3g} times as "
        f"far as the velocity between rows; are they in {guess}?"
    )


def _velocity_direction(gt: Table, horizontal: F64, by_velocity: F64) -> str | None:
    """The truth's velocity against its track: the horizontal steps its latitude and
    longitude draw against the north-east velocity's (``(n, 2)`` [m]), at a cosine
    under :data:`DIRECTION_COSINE` a velocity in ENU or north and east swapped; the
    height's steps against ``−v_d Δt``, where they move :data:`MIN_CLIMB` or more per
    row, at a cosine under −:data:`DIRECTION_COSINE` a velocity whose third axis is up."""
    cos = _direction(horizontal, by_velocity)
    if cos < DIRECTION_COSINE:
        return (
            f"{gt.where}: columns {gt.labels[4]!r}, {gt.labels[5]!r} do not point along the "
            f"track {gt.labels[1]!r}, {gt.labels[2]!r} draw (cosine {cos:.2f} between their "
            "steps, about 1 in NED): a velocity in ENU, or north and east swapped?"
        )
    v, dt = gt.values, np.diff(gt.values[:, 0])
    climb = -(v[1:, 6] + v[:-1, 6]) / 2 * dt
    if np.sqrt(np.mean(climb**2)) < MIN_CLIMB:
        return None
    cos = _direction(np.diff(v[:, 3]), climb)
    if cos >= -DIRECTION_COSINE:
        return None
    return (
        f"{gt.where}: column {gt.labels[6]!r} moves {gt.labels[3]!r} the wrong way (cosine "
        f"{cos:.2f} between the height's steps and −v_d Δt, about 1 in NED): a velocity "
        "whose third axis is up (ENU)?"
    )


#: The fewest ground-truth steps (pairs of rows), or DVL rows, inside the IMU record a
#: clock is estimated from (:mod:`pronet.recorded.alignment`): fewer cost infinity at
#: every offset (the core's ``clocks::MIN_PAIRS`` for the truth's attitude steps).
CLOCK_MIN_ROWS = 10


def too_few_clock_rows(time: F64, need: int, what: str, source: str) -> None:
    """ValueError when ``what``'s stamps ``time`` are fewer than the ``need`` its clock
    is estimated from: a section too short, not streams that do not overlap."""
    n, span = len(time), float(time[-1] - time[0]) if len(time) else 0.0
    if n < need:
        raise ValueError(
            f"{source}: {what} has {n} row{'s' * (n != 1)} over {span:.3g} s; its clock is "
            f"estimated from {need} or more inside the IMU record (a longer section, or a "
            "faster stream)"
        )
