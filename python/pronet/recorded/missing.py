"""Missing DVL readings: the rows a DVL writes when it has no bottom lock, recognised
and skipped as updates (a missed update, as in an outage), never fatal.

A DVL that loses the bottom keeps writing rows, marked in one of these ways; each such
row is a *skipped* reading, counted by reason (:data:`REASONS`):

- ``nan``: a NaN (or an empty cell) in any velocity component;
- ``sentinel``: a component at or beyond :data:`DVL_SENTINEL` in magnitude (or
  infinite). Recognised markers: Teledyne RDI's bad velocity, −32768 mm/s, written as
  −32.768 m/s by its PD0/PD6 decoders (Nortek's DVLs use the same −32.768), the raw
  −32768 when left in mm/s, and placeholders such as ±99.99 or 9999; no vehicle moves
  at 32 m/s. A marker repeats its value: ten or more such rows taking over three
  different values there are readings in another unit (cm/s, mm/s), refused
  (:func:`varied_markers`);
- ``zero``: all three components exactly 0 while the ground truth (stamps as given,
  interpolated) moves faster than :data:`MOVING_SPEED`: several loggers write zeros for
  a ping without lock; a vehicle at rest may read exact zeros and keeps them. Without a
  ground truth the vehicle's speed there is the DVL's own, interpolated between its
  nearest usable rows that are not all zero (:func:`own_speed`): zeros amid readings of
  a moving vehicle are a dropout, zeros amid readings near rest are kept;
- ``invalid``: the optional ``valid`` column of the generic format (``valid``, no unit
  or ``[-]``, 1 valid and 0 not) is 0.

The filter sees only the remaining rows; the skipped ones are kept (stamps and reasons)
so that ``pronet real`` reports them per section (``table.md``, ``missed_updates`` in
``metrics.csv``, ``config.json``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

#: Magnitude [m/s] at or beyond which a DVL velocity component is a no-lock marker.
DVL_SENTINEL = 32.768
#: Rows beyond :data:`DVL_SENTINEL` from which their values are looked at, and the most
#: different values they may take and still be markers (:func:`varied_markers`).
MARKER_ROWS = 10
MARKER_VALUES = 3
#: Ground-truth speed [m/s] above which an all-zero DVL row is a missing reading.
MOVING_SPEED = 0.2
#: Why a DVL row is skipped, in the order a row is classified (the first that applies).
REASONS = ("invalid", "nan", "sentinel", "zero")


def classify(
    vel: F64,
    valid: F64 | None,
    truth_speed: F64,
) -> NDArray[np.str_]:
    """The reason each DVL row ``vel (m, 3)`` [m/s] is skipped (one of :data:`REASONS`),
    ``""`` for a reading the filter uses. ``valid`` ``(m,)``: the ``valid`` column (0 or
    1) or None; ``truth_speed`` ``(m,)``: the ground truth's speed at each row [m/s]."""
    why = np.full(len(vel), "", dtype="<U8")
    with np.errstate(invalid="ignore"):
        zero = np.all(vel == 0.0, axis=1) & (truth_speed > MOVING_SPEED)
        sentinel = np.any(np.abs(vel) >= DVL_SENTINEL, axis=1)
    for reason, rows in reversed(
        [
            ("invalid", np.zeros(len(vel), bool) if valid is None else valid == 0.0),
            ("nan", np.any(np.isnan(vel), axis=1)),
            ("sentinel", sentinel),
            ("zero", zero),
        ]
    ):
        why[rows] = reason
    return why


def varied_markers(vel: F64, sentinel: NDArray[np.bool_]) -> str | None:
    """What is wrong when the rows ``sentinel`` of the DVL velocities ``vel (m, 3)``
    [m/s] are not no-lock markers (None when they may be): at least
    :data:`MARKER_ROWS` of them, over :data:`MARKER_VALUES` different values beyond
    :data:`DVL_SENTINEL`. A DVL's marker repeats one value (RDI's −32.768); readings in
    cm/s or mm/s read as m/s vary row by row."""
    beyond = vel[sentinel]
    beyond = beyond[np.isfinite(beyond) & (np.abs(beyond) >= DVL_SENTINEL)]
    values = np.unique(beyond)
    if sentinel.sum() < MARKER_ROWS or len(values) <= MARKER_VALUES:
        return None
    share = 100.0 * sentinel.sum() / len(vel)
    return (
        f"{int(sentinel.sum())} rows ({share:.0f} %) read beyond the no-lock marker "
        f"±{DVL_SENTINEL} m/s, with {len(values)} different values there (a marker "
        f"repeats one: {values[0]:.6g} … {values[-1]:.6g})"
    )


def counts(reasons: tuple[str, ...] | NDArray[np.str_]) -> dict[str, int]:
    """Skipped rows per reason of :data:`REASONS` (every reason present, 0 if none)."""
    found = list(reasons)
    return {r: found.count(r) for r in REASONS}


def longest_gap(kept_time: F64, skipped_time: F64) -> float:
    """The longest stretch [s] between two used DVL rows that holds skipped ones (0
    without skipped rows): the longest dropout the filter bridged on the IMU alone."""
    if skipped_time.size == 0 or kept_time.size == 0:
        return 0.0
    edges = np.concatenate([[-np.inf], kept_time, [np.inf]])
    slot = np.searchsorted(kept_time, skipped_time)
    gaps = [edges[s + 1] - edges[s] for s in np.unique(slot)]
    finite = [g for g in gaps if np.isfinite(g)]
    if len(finite) < len(gaps):  # before the first or after the last used row
        ends = [skipped_time.max() - kept_time[-1], kept_time[0] - skipped_time.min()]
        finite.append(float(max(e for e in ends)))
    return float(max(finite))


def own_speed(time: F64, vel: F64, valid: F64 | None) -> F64:
    """The DVL's speed [m/s] at each row's ``time``, interpolated between the rows of
    ``vel (m, 3)`` that are none of :data:`REASONS` nor all zero (0 without any): the
    speed :func:`classify` takes for an all-zero row without a ground truth."""
    with np.errstate(invalid="ignore"):
        usable = ~np.any(np.isnan(vel) | (np.abs(vel) >= DVL_SENTINEL), axis=1)
        usable &= ~np.all(vel == 0.0, axis=1)
    if valid is not None:
        usable &= valid != 0.0
    if not usable.any():
        return np.zeros(len(time))
    return np.interp(time, time[usable], np.linalg.norm(vel[usable], axis=1))


def usable_rows(
    dvl: F64, truth: tuple[F64, F64] | None, source: str
) -> tuple[F64, NDArray[np.str_]]:
    """The DVL rows ``dvl`` (``(m, 4)`` time and velocity, or ``(m, 5)`` with the
    ``valid`` column) the filter uses, and the reason each row is skipped (``""``:
    used; :func:`classify`). ``truth``: the ground truth's stamps and speed [m/s], or
    None (the DVL's own speed, :func:`own_speed`). A DVL with no usable row is a
    ValueError naming ``source``."""
    valid = dvl[:, 4] if dvl.shape[1] > 4 else None
    if truth is not None:
        speed = truth[1]
        moving = np.interp(dvl[:, 0], truth[0], speed)
    else:
        moving = own_speed(dvl[:, 0], dvl[:, 1:4], valid)
    why = classify(dvl[:, 1:4], valid, moving)
    if (why == "sentinel").all():  # every row beyond any vehicle: a unit, not a dropout
        speed_dvl = float(np.median(np.linalg.norm(dvl[:, 1:4], axis=1)))
        against = "" if truth is None else f" against the ground truth's {np.median(speed):.4g} m/s"
        raise ValueError(
            f"{source} dvl: its median speed {speed_dvl:.4g} m/s{against}, every row at or "
            f"beyond the no-lock marker ±{DVL_SENTINEL} m/s; are the DVL velocities in m/s?"
        )
    if varied := varied_markers(dvl[:, 1:4], why == "sentinel"):
        raise ValueError(f"{source} dvl: {varied}; are the DVL velocities in m/s?")
    if (why != "").all():
        seen = ", ".join(f"{n} {r}" for r, n in counts(tuple(why)).items() if n)
        raise ValueError(
            f"{source} dvl: no usable reading in its {len(dvl)} rows ({seen}); see "
            "pronet.recorded.missing for the markers recognised"
        )
    return dvl[why == "", :4], why
