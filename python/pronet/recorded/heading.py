"""Heading readings in recorded data: a compass's, an AHRS's or a gyrocompass's yaw,
the generic format's optional ``heading`` table and a ROS bag's heading topic
(:mod:`pronet.recorded.bags`), true or magnetic, with their σ and missing values.

One optional table beside ``imu``, ``dvl``, ``gt``, ``depth`` and ``fix`` (a folder's
``heading.csv``, optionally ``.gz``; an ``.npz``'s arrays ``heading`` and
``heading_columns``), on its own stamps and rate:

======= ===========================================================================
table   columns (accepted units; converted to the first)
======= ===========================================================================
heading ``time [s]`` and either ``heading [rad | deg]``, the yaw of the body (ZYX,
        as the filter's ``rpy``) from TRUE north, or ``magnetic_heading [rad |
        deg]``, the same from magnetic north; optional ``sigma [rad | deg]``, its 1σ
======= ===========================================================================

A magnetic heading becomes a true one with the magnetic declination [deg, east
positive] given to the reader (``declination`` of
:func:`pronet.recorded.recordings.read_recording` and
:func:`pronet.recorded.alignment.load_section`; the vehicle file's key ``declination``,
or ``--declination DEG``): ``true = magnetic + declination``. A magnetic column without
a declination is refused in one line (a heading some degrees off would be taken as
true); a declination beside a true ``heading`` is not used. The values are wrapped into
(−π, π] (those inside it kept to the bit); a value beyond ±360° (degrees under a
``[rad]`` header) is refused naming its row.

Missing values are skipped, never fatal, as the depth's and the fixes'
(:mod:`pronet.recorded.aiding`): a row with a NaN or empty heading or σ is left out of
the filter and kept with the reason ``"nan"``; a bag's ``sensor_msgs/Imu`` message
without an orientation (its ``orientation_covariance[0]`` is −1, ROS's convention)
with the reason ``"no orientation"`` (:attr:`HeadingReadings.skipped_reason`). A σ of 0
or below, or beyond π (180°), is an error naming its row. Against a ground truth (at
each row's stamp, as given; :func:`against_truth`): the median of the heading's wrapped
difference from the truth's yaw within :data:`MAX_HEADING_OFFSET` (a magnetic heading
read as true in a region of large declination, an ENU yaw (90° − heading), or
degrees are not).

σ: the file's per row, else the tuned one (``heading_sigma`` of a vehicle file,
:class:`pronet.recorded.aiding.AidingTuning`); with neither the stream is refused in one
line naming that key (:func:`pronet.recorded.aiding.tuned_heading`): no default, as a
compass's error (0.5–5°, more near iron) and a gyrocompass's (0.01–0.1°) differ too
much for one. The heading refers to the body: it has no lever arm.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from pronet.recorded.plausible import ANGLE_UNITS, Table, angle_beyond, parse_header

F64 = NDArray[np.float64]

#: The heading table's required columns (one of its heading columns is required too).
COLUMNS: dict[str, dict[str, dict[str, float]]] = {"heading": {"time": {"s": 1.0}}}
#: Its optional columns: one of the two heading columns, and the σ.
OPTIONAL: dict[str, dict[str, dict[str, float]]] = {
    "heading": {"heading": ANGLE_UNITS, "magnetic_heading": ANGLE_UNITS, "sigma": ANGLE_UNITS}
}
#: Plausible sample rates [Hz]: a compass at 0.1 Hz to an AHRS at the IMU's rate.
RATE_RANGE = {"heading": (0.01, 1000.0)}
#: The median heading may differ from the ground truth's yaw by at most this [rad] (30°).
MAX_HEADING_OFFSET = float(np.radians(30.0))
#: The reasons a heading row is skipped.
REASONS = ("nan", "no orientation")


@dataclass(frozen=True)
class HeadingReadings:
    """A heading stream as read (SI, true north).

    Attributes:
        time: ``(h,)`` stamps [s] of the rows the filter uses.
        heading: ``(h,)`` the yaw of the body from true north [rad] (ZYX), in (−π, π].
        sigma: ``(h,)`` the recording's 1σ [rad], or None (σ as tuned).
        skipped_time: ``(j,)`` stamps of the rows skipped as missing values.
        skipped_reason: why each was skipped (one of :data:`REASONS`).
        source: where it was read from.
        declination: the magnetic declination [rad, east positive] added to a magnetic
            heading, or None (the heading was true as recorded).
    """

    time: F64
    heading: F64
    sigma: F64 | None
    skipped_time: F64 = field(default_factory=lambda: np.empty(0))
    skipped_reason: tuple[str, ...] = ()
    source: str = ""
    declination: float | None = None

    def on_clock(self, clock: Callable[[F64], F64]) -> HeadingReadings:
        """The same stream with every stamp mapped by ``clock``."""
        return replace(self, time=clock(self.time), skipped_time=clock(self.skipped_time))


def wrap(angle: F64) -> F64:
    """``angle`` [rad] wrapped into (−π, π]; a value inside it is kept to the bit."""
    a = np.asarray(angle, dtype=np.float64)
    inside = (a > -np.pi) & (a <= np.pi)
    return np.where(inside, a, np.pi - np.mod(np.pi - a, 2 * np.pi))


def check_declination(value: float | None, where: str) -> float | None:
    """A magnetic declination [deg, east positive] within ±180°, or None; ValueError
    naming ``where`` otherwise."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{where}: a number of degrees (east positive), got {value!r}")
    if not (np.isfinite(value) and -180.0 <= value <= 180.0):
        raise ValueError(f"{where}: expected -180 … 180 deg (east positive), got {value}")
    return float(value)


def _check_sigma(table: Table, j: int) -> None:
    v = table.values[:, j]
    bad = (v <= 0) | (v > np.pi)  # NaN compares False: a missing value
    if bad.any():
        r = int(np.argmax(bad))
        shown = v[r] / ANGLE_UNITS.get(parse_header(table.labels[j])[1], 1.0)
        raise ValueError(
            f"{table.where}, row {r + 1}: {table.labels[j]!r} is {shown:g}; a heading's 1σ "
            "must be > 0 and at most 180° (π rad)"
        )


def heading_readings(
    table: Table,
    names: list[str],
    declination: float | None = None,
    reasons: tuple[str, ...] | None = None,
) -> HeadingReadings:
    """The heading stream of a finished ``heading`` table (``names``: its parsed column
    names), a magnetic one turned true with ``declination`` [deg, east positive];
    ``reasons``: per row, why it is missing (``""``: not; a bag's), beside its NaN
    cells. ValueError, one line naming file, row and column, for a problem."""
    true, magnetic = "heading" in names, "magnetic_heading" in names
    if true and magnetic:
        raise ValueError(
            f"{table.where}: has both 'heading' (true north) and 'magnetic_heading'; keep one"
        )
    if not true and not magnetic:
        raise ValueError(
            f"{table.where}: missing column 'heading [rad | deg]' (from true north) or "
            f"'magnetic_heading [rad | deg]'; has: {', '.join(table.labels)}"
        )
    j = names.index("heading" if true else "magnetic_heading")
    if (beyond := angle_beyond(table, j, -360.0, 360.0, "a heading")) is not None:
        raise ValueError(beyond)
    values = table.values[:, j]
    east = check_declination(declination, "declination")
    if magnetic:
        if east is None:
            raise ValueError(
                f"{table.where}: column {table.labels[j]!r} is a magnetic heading: give the "
                "magnetic declination [deg, east positive] (declination in the vehicle file, "
                "or --declination DEG)"
            )
        values = values + np.radians(east)
    sigma = None
    if "sigma" in names:
        _check_sigma(table, names.index("sigma"))
        sigma = table.values[:, names.index("sigma")]
    t = table.values[:, 0]
    why = np.array(reasons if reasons is not None else [""] * len(t), dtype=object)
    why[(why == "") & (np.isnan(values) | (np.isnan(sigma) if sigma is not None else False))] = (
        "nan"
    )
    missing = why != ""
    if missing.all():
        seen = ", ".join(sorted({str(w) for w in why}))
        raise ValueError(f"{table.where}: no usable heading in its {len(t)} rows ({seen})")
    keep = ~missing
    return HeadingReadings(
        time=t[keep].copy(),
        heading=wrap(values[keep]),
        sigma=None if sigma is None else sigma[keep].copy(),
        skipped_time=t[missing].copy(),
        skipped_reason=tuple(str(w) for w in why[missing]),
        source=table.where,
        declination=float(np.radians(east)) if magnetic and east is not None else None,
    )


def as_table(heading: HeadingReadings) -> tuple[list[str], F64]:
    """The stream as the generic format's ``heading`` table, header and SI values (the
    rows the filter uses, true north)."""
    columns = [heading.time, heading.heading]
    if heading.sigma is not None:
        columns.append(heading.sigma)
    header = ["time [s]", "heading [rad]", "sigma [rad]"][: len(columns)]
    return header, np.column_stack(columns)


def against_truth(heading: HeadingReadings | None, gt: Table) -> str | None:
    """The heading against the ground truth ``gt`` (its table: time, …, yaw in column
    9; stamps as given): the median absolute wrapped difference beyond
    :data:`MAX_HEADING_OFFSET`. One line naming the file, or None."""
    if heading is None or len(gt.values) == 0:
        return None
    t_gt, yaw = gt.values[:, 0], np.unwrap(gt.values[:, 9])
    difference = wrap(heading.heading - np.interp(heading.time, t_gt, yaw))
    offset = float(np.degrees(np.median(np.abs(difference))))
    most = float(np.degrees(MAX_HEADING_OFFSET))
    if offset > most:
        median, bound = f"{offset:.3g}°", f"{most:g}°"
        # a median rounded to the bound said "30° (at most 30°)": the figure once
        lies = f"just over {bound} (the most accepted)" if median == bound else median
        limit = "" if median == bound else f" (at most {bound})"
        return (
            f"{heading.source}: the heading lies a median {lies} from the ground truth's "
            f"yaw{limit}; magnetic without its declination, a yaw from east (ENU: 90° − "
            "heading), or in another unit?"
        )
    return None
