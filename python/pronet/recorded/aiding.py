"""Depth readings and position fixes in recorded data: the generic format's optional
``depth`` and ``fix`` streams, their missing values, their checks against the ground
truth, and the σ the filter gives them; with the heading readings of
:mod:`pronet.recorded.heading`, the streams that aid a recorded pass after the DVL.

Two optional tables beside ``imu``, ``dvl`` and ``gt`` (a folder's ``depth.csv`` and
``fix.csv``, each optionally ``.gz``; an ``.npz``'s arrays ``depth``/``depth_columns``
and ``fix``/``fix_columns``), each on its own stamps and at its own rate:

===== =============================================================================
table columns (accepted units; converted to the first)
===== =============================================================================
depth ``time [s]``, ``depth [m]`` (pressure depth, positive down); optional
      ``sigma [m]``, its 1σ, and ``pressure [Pa | hPa | mbar | kPa | bar]``, the
      absolute pressure the depth was computed from (a bag's, below)
fix   ``time [s]``, ``lat``, ``lon [rad | deg]``; optional ``height [m]`` (up: a fix
      without it, or with an empty height cell, is horizontal), ``sigma_n``,
      ``sigma_e``, ``sigma_d [m]`` (1σ north, east, down; the three together)
===== =============================================================================

The raw pressure. A ROS bag's depth is computed from absolute pressure at read time
(:mod:`pronet.recorded.bags`: ``(p − p_surface) / (ρ g)`` with the topics'
``surface_pressure`` and ``water_density``); the pressure is kept
(:attr:`DepthReadings.pressure`, with :attr:`DepthReadings.water_density`), so that a
surface pressure measured from the data (the pressure while a fix says the vehicle is
at the surface) can replace the assumed one: :meth:`DepthReadings.rereferenced`. A
generic table may carry the same ``pressure`` column (it is then written back by
:func:`pronet.recorded.recordings.write_recording`); a row with a missing pressure is
skipped as one with a missing depth.

Both refer to the IMU's point (their streams, :func:`filter_aiding`'s
:class:`pronet.Depth` and :class:`pronet.Fix`, have no lever arm): a depth sensor or an
antenna away from it is not moved. Their stamps are taken on the
IMU's clock, counted from the section's epoch as every stream's, or on the DVL's or the
ground truth's as estimated (:func:`pronet.recorded.alignment.load_section`'s
``aiding_clock``, :class:`~pronet.recorded.alignment.Alignment`'s): no clock is
estimated from the depth or the fixes themselves.

Extra columns are ignored, as in every table, but for one whose name starts with
``sigma`` and is none of the σ columns above (``sigma [m]`` in a fix table, ``sigma_d
[m]`` in a depth table): refused (:func:`unknown_sigma`), as it would leave the default σ
in use. A fix's latitude must lie within ±89° (``_core.MAX_LATITUDE_DEG``, the filter's
rule) and its longitude within −180° … 360° (``_core.LONGITUDE_RANGE_DEG``: the ±180°
and the 0–360° conventions; the filter wraps the longitude difference), each error
naming file, row and column, in the column's unit.

Missing values are skipped, never fatal, as the DVL's
(:mod:`pronet.recorded.missing`): a depth row with a NaN or empty depth or σ cell, a
fix row with a NaN or empty latitude, longitude or σ, is left out of the filter and
kept with the reason ``"nan"`` (:attr:`DepthReadings.skipped_time`). Rows stamped
before the run's start or after its end are applied at no epoch (``depth_epoch``,
``fix_epoch`` −1) and ``pronet real`` counts them apart (``outside_run``). A σ of 0 or
below is an error naming its row, as is a fix's below :data:`MIN_FIX_SIGMA`. Checks
against the ground truth (at each row's stamp, as given; :func:`against_truth`): the
median depth within :data:`MAX_DEPTH_OFFSET` of the truth's (a depth from absolute
pressure, feet, or a height, are not), the median horizontal distance of the fixes within
:data:`MAX_FIX_OFFSET` of it (degrees under a ``[rad]`` header are not).

σ (:func:`filter_aiding`): the filter takes each row's σ where the file gives one (a
``sigma`` column: an outlier marked with a large σ weighs as little as it says), else
one for all. Without a σ in the file, a vehicle file's ``depth_sigma`` / ``fix_sigma``
(:mod:`pronet.recorded.vehicle`), else :data:`DEFAULT_DEPTH_SIGMA` and
:data:`DEFAULT_FIX_SIGMA`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray

from pronet import _core
from pronet._util.plausibility import HEIGHT_RANGE, STANDARD_GRAVITY
from pronet.recorded import heading as _heading
from pronet.recorded.heading import HeadingReadings
from pronet.recorded.plausible import ANGLE_UNITS, Table, angle_beyond, parse_header

F64 = NDArray[np.float64]

_METRE = {"m": 1.0}
#: The units a pressure may be given in, and their factor to pascals.
PRESSURE_UNITS = {"Pa": 1.0, "hPa": 100.0, "mbar": 100.0, "kPa": 1000.0, "bar": 1e5}
#: Required columns of the aiding tables (the heading's:
#: :mod:`pronet.recorded.heading`): name → accepted units and their SI factor.
COLUMNS: dict[str, dict[str, dict[str, float]]] = {
    "depth": {"time": {"s": 1.0}, "depth": _METRE},
    "fix": {"time": {"s": 1.0}, "lat": ANGLE_UNITS, "lon": ANGLE_UNITS},
    **_heading.COLUMNS,
}
#: Optional columns of the aiding tables.
OPTIONAL: dict[str, dict[str, dict[str, float]]] = {
    "depth": {"sigma": _METRE, "pressure": PRESSURE_UNITS},
    "fix": {"height": _METRE, "sigma_n": _METRE, "sigma_e": _METRE, "sigma_d": _METRE},
    **_heading.OPTIONAL,
}
#: Plausible sample rates [Hz]: a pressure sensor; fixes on any schedule (a GNSS fix
#: at 10 Hz at the surface, a USBL fix every few minutes); a heading.
RATE_RANGE = {"depth": (0.01, 1000.0), "fix": (1e-4, 100.0), **_heading.RATE_RANGE}
#: The median depth may differ from the ground truth's by at most this [m]: a depth
#: from absolute pressure (the atmosphere's 10 m), in feet, or a height, differs more.
MAX_DEPTH_OFFSET = 5.0
#: The median horizontal distance [m] of the fixes from the ground truth at most this.
MAX_FIX_OFFSET = 1000.0
#: The filter's depth σ [m] when neither the file nor the vehicle gives one: a
#: pressure sensor's 0.01–0.1 % of a 100–300 m full scale, rounded up.
DEFAULT_DEPTH_SIGMA = 0.1
#: The fixes' σ north, east, down [m] when neither the file nor the vehicle gives
#: one: a standalone GNSS fix's 2 m horizontally, twice that vertically.
DEFAULT_FIX_SIGMA = (2.0, 2.0, 4.0)
#: The smallest 1σ [m] of a fix: no position fix is better than a millimetre (RTK
#: GNSS's is about 1 cm), and far below it the update leaves the filter's position
#: covariance numerically singular (σ 1e-9 m: a "numerical failure" of the pass).
MIN_FIX_SIGMA = 1e-3


_S = TypeVar("_S", bound="_Stream")


class _Stream:
    """What a depth and a fix stream share: their stamps, on a clock."""

    time: F64
    skipped_time: F64

    def on_clock(self: _S, clock: Callable[[F64], F64]) -> _S:
        """The same stream with every stamp mapped by ``clock``."""
        mapped = {"time": clock(self.time), "skipped_time": clock(self.skipped_time)}
        return replace(self, **mapped)  # type: ignore[type-var]  # each subclass: a dataclass


@dataclass(frozen=True)
class DepthReadings(_Stream):
    """A depth stream as read (SI).

    Attributes:
        time: ``(d,)`` stamps [s] of the rows the filter uses.
        depth: ``(d,)`` depth [m, positive down].
        sigma: ``(d,)`` the file's 1σ [m], or None (σ as tuned).
        skipped_time: ``(j,)`` stamps of the rows skipped as missing values.
        skipped_reason: why each was skipped (``"nan"``).
        source: where it was read from.
        pressure: ``(d,)`` the absolute pressure [Pa] each depth was computed from (a
            bag's, or a table's ``pressure`` column), or None.
        water_density: the water's density [kg/m³] the depth was computed with (a
            bag's), or None.
    """

    time: F64
    depth: F64
    sigma: F64 | None
    skipped_time: F64 = field(default_factory=lambda: np.empty(0))
    skipped_reason: tuple[str, ...] = ()
    source: str = ""
    pressure: F64 | None = None
    water_density: float | None = None

    def rereferenced(
        self, surface_pressure: float, water_density: float | None = None
    ) -> DepthReadings:
        """The depth recomputed from :attr:`pressure` against ``surface_pressure`` [Pa]
        (e.g. measured from the data): ``(p − p_surface) / (ρ g)``, ρ ``water_density``
        [kg/m³], else :attr:`water_density`, g standard gravity; σ as read. ValueError
        naming the source without a pressure or a density."""
        if self.pressure is None:
            raise ValueError(f"{self.source}: the depth holds no pressure to re-reference")
        rho = self.water_density if water_density is None else float(water_density)
        if rho is None or not (np.isfinite(rho) and rho > 0):
            raise ValueError(
                f"{self.source}: re-referencing the depth needs the water's density, got {rho}"
            )
        if not (np.isfinite(surface_pressure) and surface_pressure >= 0):
            raise ValueError(
                f"surface_pressure: must be finite and >= 0 Pa, got {surface_pressure}"
            )
        depth = (self.pressure - float(surface_pressure)) / (rho * STANDARD_GRAVITY)
        return replace(self, depth=depth, water_density=rho)


@dataclass(frozen=True)
class PositionFixes(_Stream):
    """A position-fix stream as read (SI).

    Attributes:
        time: ``(f,)`` stamps [s] of the fixes the filter uses.
        lla: ``(f, 3)`` latitude, longitude [rad], height [m, up] (NaN: horizontal).
        sigma: ``(f, 3)`` the file's 1σ north, east, down [m], or None (σ as tuned).
        skipped_time, skipped_reason, source: as :class:`DepthReadings`'.
    """

    time: F64
    lla: F64
    sigma: F64 | None
    skipped_time: F64 = field(default_factory=lambda: np.empty(0))
    skipped_reason: tuple[str, ...] = ()
    source: str = ""


def may_be_missing(kind: str, names: list[str]) -> list[int]:
    """The columns of ``kind``'s table (by parsed ``names``, in the table's order) whose
    NaN or empty cell is a missing value rather than an error."""
    if kind not in COLUMNS:
        return []
    return [j for j, n in enumerate(names) if n != "time"]


def _column(table: Table, names: list[str], name: str) -> F64 | None:
    return table.values[:, names.index(name)] if name in names else None


def _check_sigma(table: Table, names: list[str], wanted: list[str], least: float = 0.0) -> None:
    """Each σ column of ``wanted`` > 0 and at least ``least`` [m] (a fix's)."""
    for name in wanted:
        j = names.index(name)
        v = table.values[:, j]
        bad = (v <= 0) | (v < least)  # NaN compares False: a missing value
        if bad.any():
            r = int(np.argmax(bad))
            rule = (
                f"a fix's 1σ must be at least {least:g} m (no fix is that exact; the filter's "
                "covariance would be singular)"
                if v[r] > 0
                else "a 1σ must be > 0 m"
            )
            raise ValueError(f"{table.where}, row {r + 1}: {table.labels[j]!r} is {v[r]:g}; {rule}")


def unknown_sigma(where: str, kind: str, names: list[str], header: list[str]) -> str | None:
    """A column of the ``depth`` or ``fix`` table (``names``: the parsed names of its
    ``header``) whose name starts with ``sigma`` but is none of the σ columns: a σ that
    would otherwise be ignored (extra columns are) and the default used. One line
    naming the file, the column and the accepted σ columns, or None."""
    if kind not in OPTIONAL:
        return None
    accepted = [n for n in OPTIONAL[kind] if n.startswith("sigma")]
    shown = ", ".join(f"{n} [{' | '.join(OPTIONAL[kind][n])}]" for n in accepted)
    for name, label in zip(names, header, strict=True):
        if name.startswith("sigma") and name not in accepted:
            return (
                f"{where}: column {label.strip()!r} is not a σ column of the {kind} table; "
                f"its σ columns are {shown}"
            )
    return None


def depth_readings(table: Table, names: list[str]) -> DepthReadings:
    """The depth stream of a finished ``depth`` table (``names``: its parsed column
    names); ValueError, one line naming file, row and column, for a problem."""
    with_sigma = "sigma" in names
    if with_sigma:
        _check_sigma(table, names, ["sigma"])
    t, depth = table.values[:, 0], table.values[:, 1]
    sigma = _column(table, names, "sigma")
    pressure = _column(table, names, "pressure")
    missing = np.isnan(depth) | (np.isnan(sigma) if sigma is not None else False)
    missing |= np.isnan(pressure) if pressure is not None else False
    if missing.all():
        raise ValueError(
            f"{table.where}: no usable depth in its {len(t)} rows (every one NaN or empty)"
        )
    lo, hi = -HEIGHT_RANGE[1], -HEIGHT_RANGE[0]
    if (bad := np.flatnonzero((depth < lo) | (depth > hi))).size:
        r = int(bad[0])
        raise ValueError(
            f"{table.where}, row {r + 1}: {table.labels[1]!r} is {depth[r]:.6g} m, beyond "
            f"{lo:g} … {hi:g} m (metres, positive down: the deepest ocean is 11 km); in "
            "pascals or another unit?"
        )
    keep = ~missing
    return DepthReadings(
        time=t[keep].copy(),
        depth=depth[keep].copy(),
        sigma=None if sigma is None else sigma[keep].copy(),
        skipped_time=t[missing].copy(),
        skipped_reason=("nan",) * int(missing.sum()),
        source=table.where,
        pressure=None if pressure is None else pressure[keep].copy(),
    )


def position_fixes(table: Table, names: list[str]) -> PositionFixes:
    """The fixes of a finished ``fix`` table (``names``: its parsed column names);
    ValueError, one line naming file, row and column, for a problem."""
    sigma_names = ["sigma_n", "sigma_e", "sigma_d"]
    given = [n for n in sigma_names if n in names]
    if given and len(given) < 3:
        lacking = ", ".join(n for n in sigma_names if n not in names)
        raise ValueError(
            f"{table.where}: has {', '.join(given)} but not {lacking}; give all three or none"
        )
    if given:
        _check_sigma(table, names, sigma_names, MIN_FIX_SIGMA)
    t = table.values[:, 0]
    lat, lon = table.values[:, 1], table.values[:, 2]
    height = _column(table, names, "height")
    h = np.full(len(t), np.nan) if height is None else height
    limit, (lo, hi) = _core.MAX_LATITUDE_DEG, _core.LONGITUDE_RANGE_DEG
    poles = "the filter's latitudes: NED is singular at the poles"
    for beyond in (
        angle_beyond(table, 1, -limit, limit, poles),
        angle_beyond(table, 2, lo, hi, "a longitude in the ±180° or the 0–360° convention"),
    ):
        if beyond is not None:
            raise ValueError(beyond)
    missing = np.isnan(lat) | np.isnan(lon)
    sigma: F64 | None = None
    if given:
        sigma = np.column_stack([table.values[:, names.index(n)] for n in sigma_names])
        missing |= np.isnan(sigma[:, :2]).any(axis=1) | (np.isfinite(h) & np.isnan(sigma[:, 2]))
    if missing.all():
        raise ValueError(
            f"{table.where}: no usable fix in its {len(t)} rows (every one NaN or empty)"
        )
    keep = ~missing
    return PositionFixes(
        time=t[keep].copy(),
        lla=np.column_stack([lat, lon, h])[keep],
        sigma=None if sigma is None else sigma[keep].copy(),
        skipped_time=t[missing].copy(),
        skipped_reason=("nan",) * int(missing.sum()),
        source=table.where,
    )


def streams(tables: Mapping[str, Table]) -> tuple[DepthReadings | None, PositionFixes | None]:
    """The depth and fix streams of a recording's finished ``tables`` (None where
    absent), checked; ValueError naming file, row and column for a problem."""

    def names(kind: str) -> list[str]:
        return [parse_header(label)[0] for label in tables[kind].labels]

    depth = depth_readings(tables["depth"], names("depth")) if "depth" in tables else None
    fixes = position_fixes(tables["fix"], names("fix")) if "fix" in tables else None
    return depth, fixes


def as_tables(
    depth: DepthReadings | None,
    fixes: PositionFixes | None,
    heading: HeadingReadings | None = None,
) -> dict[str, tuple[list[str], F64]]:
    """The streams as the generic format's tables, header and SI values (the rows the
    filter uses; the heading true), for :func:`pronet.recorded.recordings.write_recording`."""
    out = {}
    if depth is not None:
        header, columns = ["time [s]", "depth [m]"], [depth.time, depth.depth]
        for label, values in (("sigma [m]", depth.sigma), ("pressure [Pa]", depth.pressure)):
            if values is not None:
                header.append(label)
                columns.append(values)
        out["depth"] = (header, np.column_stack(columns))
    if fixes is not None:
        header = ["time [s]", "lat [rad]", "lon [rad]", "height [m]"]
        parts = [fixes.time[:, None], fixes.lla]
        if fixes.sigma is not None:
            header += [f"sigma_{a} [m]" for a in "ned"]
            parts.append(fixes.sigma)
        out["fix"] = (header, np.hstack(parts))
    if heading is not None:
        out["heading"] = _heading.as_table(heading)
    return out


def against_truth(
    depth: DepthReadings | None, fixes: PositionFixes | None, gt: Table
) -> str | None:
    """The depth and fixes against the ground truth ``gt`` (its table: time, lat, lon,
    height, ...; stamps as given): the median depth offset beyond
    :data:`MAX_DEPTH_OFFSET`, the median horizontal distance of the fixes beyond
    :data:`MAX_FIX_OFFSET`. One line naming the file, or None (also for an empty
    ``gt``: no ground truth to check against)."""
    if len(gt.values) == 0:
        return None
    t_gt, lla = gt.values[:, 0], gt.values[:, 1:4]
    if depth is not None:
        offset = float(np.median(depth.depth + np.interp(depth.time, t_gt, lla[:, 2])))
        if abs(offset) > MAX_DEPTH_OFFSET:
            return (
                f"{depth.source}: column 'depth' lies a median {offset:+.4g} m from the ground "
                f"truth's depth (at most {MAX_DEPTH_OFFSET:g}); is it positive down, in metres, "
                "from gauge pressure (less the atmosphere's ~10 m)?"
            )
    if fixes is not None:
        radius = 6_371_000.0  # a sphere: enough to tell a unit from an error of metres
        lat = np.interp(fixes.time, t_gt, lla[:, 0])
        lon = np.interp(fixes.time, t_gt, lla[:, 1])
        north = (fixes.lla[:, 0] - lat) * radius
        wrapped = np.angle(np.exp(1j * (fixes.lla[:, 1] - lon)))  # a 0–360° fix, ±180° truth
        east = wrapped * radius * np.cos(lat)
        distance = float(np.median(np.hypot(north, east)))
        if distance > MAX_FIX_OFFSET:
            return (
                f"{fixes.source}: columns 'lat', 'lon' lie a median {distance:.4g} m from the "
                f"ground truth (at most {MAX_FIX_OFFSET:g}); in another unit or datum?"
            )
    return None


@dataclass(frozen=True)
class AidingTuning:
    """What ``pronet real`` does with a section's aiding sensors: DVL, depth, fixes,
    heading.

    Attributes:
        depth_sigma: the depth's 1σ [m] where the file has none.
        fix_sigma: the fixes' 1σ north, east, down [m] where the file has none.
        use_depth, use_fixes, use_dvl: False ignores the stream (``--no-depth``,
            ``--no-fixes``, ``--no-dvl``).
        heading_sigma: the heading's 1σ [rad] where the recording has none, or None
            (no default: such a heading stream is refused, :func:`tuned_heading`).
        use_heading: False ignores the heading stream (``--no-heading``).
    """

    depth_sigma: float = DEFAULT_DEPTH_SIGMA
    fix_sigma: tuple[float, float, float] = DEFAULT_FIX_SIGMA
    use_depth: bool = True
    use_fixes: bool = True
    use_dvl: bool = True
    heading_sigma: float | None = None
    use_heading: bool = True

    def __post_init__(self) -> None:
        sigma = (self.depth_sigma, *self.fix_sigma)
        if (
            len(self.fix_sigma) != 3
            or not all(np.isfinite(s) and s > 0 for s in sigma)
            or min(self.fix_sigma) < MIN_FIX_SIGMA
        ):
            raise ValueError(
                f"depth_sigma, fix_sigma: must be finite numbers of metres > 0 (fix_sigma "
                f"three: north, east, down, each at least {MIN_FIX_SIGMA:g} m), got "
                f"{self.depth_sigma}, {self.fix_sigma}"
            )
        h = self.heading_sigma
        if h is not None and not (np.isfinite(h) and 0 < h <= np.pi):
            raise ValueError(f"heading_sigma: must be > 0 and at most π rad, got {h}")


def tuned(
    depth: DepthReadings | None, fixes: PositionFixes | None, tuning: AidingTuning
) -> tuple[DepthReadings | None, PositionFixes | None]:
    """The streams with ``tuning``'s σ where the file has none (the file's kept), and
    None for a stream ``tuning`` ignores."""
    if depth is not None and depth.sigma is None:
        depth = replace(depth, sigma=np.full(len(depth.time), float(tuning.depth_sigma)))
    if fixes is not None and fixes.sigma is None:
        sigma = np.tile(np.asarray(tuning.fix_sigma, dtype=np.float64), (len(fixes.time), 1))
        fixes = replace(fixes, sigma=sigma)
    return (depth if tuning.use_depth else None), (fixes if tuning.use_fixes else None)


def tuned_heading(heading: HeadingReadings | None, tuning: AidingTuning) -> HeadingReadings | None:
    """The heading with ``tuning``'s σ where the recording has none (its own kept), None
    without one or when ``tuning`` ignores it; a heading without σ when ``tuning`` has
    none either is a ValueError naming its source and the vehicle key ``heading_sigma``."""
    if heading is None or not tuning.use_heading:
        return None
    if heading.sigma is None:
        if tuning.heading_sigma is None:
            raise ValueError(
                f"{heading.source}: the heading has no σ (no sigma column, or a covariance "
                "not set in every message): give heading_sigma [deg] in the vehicle file"
            )
        heading = replace(heading, sigma=np.full(len(heading.time), float(tuning.heading_sigma)))
    return heading


def filter_aiding(
    depth: DepthReadings | None,
    fixes: PositionFixes | None,
    heading: HeadingReadings | None = None,
) -> tuple[_core.Depth | _core.Fix | _core.Heading, ...]:
    """The streams a pass takes after the DVL (:func:`pronet.run_filter`): a section's
    depth readings (:class:`pronet.Depth`), position fixes (:class:`pronet.Fix`), both
    at the IMU's point, and heading readings (:class:`pronet.Heading`), their σ the
    file's, else the defaults (:func:`tuned` and :func:`tuned_heading` put a vehicle's
    in first; a heading has no default σ: without one it is refused); empty for none.
    Each stream takes its rows' σ."""
    depth, fixes = tuned(depth, fixes, AidingTuning())
    out: list[_core.Depth | _core.Fix | _core.Heading] = []
    if depth is not None and depth.sigma is not None:
        out.append(_core.Depth(depth.time, depth.depth, sigma=depth.sigma))
    if fixes is not None:
        out.append(_core.Fix(fixes.time, fixes.lla, sigma=fixes.sigma))
    heading = tuned_heading(heading, AidingTuning())
    if heading is not None:
        out.append(_core.Heading(heading.time, heading.heading, sigma=heading.sigma))
    return tuple(out)
