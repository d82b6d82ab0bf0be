"""The surface reference of a pressure depth: a depth sensor reads the water above it
only once the atmosphere's pressure on the surface is taken off, and a weather day moves
that pressure by ±2 kPa (±0.2 m of water) from the standard 101,325 Pa a reader assumes.

When the vehicle floats at the surface with position fixes (GNSS works only there), its
depth sensor lies at its known depth below the waterline (``surface_depth``, 0 by
default: the sensor at the surface): the readings there measure the offset
(:func:`surface_offset`), which is taken off every reading. Without such readings the
reader's reference stays, and the report says so. A fix does not tell the surface by
its height (a GNSS height is ellipsoidal, tens of metres off the sea; a USBL fix has
none): a reading beside a fix is taken at the surface when it reads within
:data:`SURFACE_DEPTH` of ``surface_depth``, as no wrong surface pressure moves it
further. Depths a median :data:`MAX_ABOVE_SURFACE` above the surface are refused; a
reference left as it is whose shallowest readings lie about one atmosphere deep (an
absolute pressure) says so in its note.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pronet.recorded.solution import F64

#: A reading beside a fix is taken at the surface when it reads within this of the
#: sensor's depth there [m] (a wrong surface pressure is ±0.3 m at the most on Earth's
#: weather) and within this long [s] of a fix.
SURFACE_DEPTH = 0.5
SURFACE_WINDOW = 1.0
#: At least this many surface readings, or none is used.
MIN_SURFACE_READINGS = 5
#: Standard gravity [m/s²] of the pressure-to-depth conversion (bags').
G0 = 9.80665
#: Depths [m] above the surface (negative) beyond this in the median are refused: a
#: pressure in kPa or bar converted as pascals, or the atmosphere taken off twice.
MAX_ABOVE_SURFACE = 2.0
#: The standard atmosphere in metres of sea water (101,325 Pa over 1025 kg/m³ and
#: :data:`G0`), and how far from it a shallowest reading looks like an absolute
#: pressure whose atmosphere was never taken off [m].
ATMOSPHERE_DEPTH = 101_325.0 / (1025.0 * G0)
ATMOSPHERE_BAND = 0.6


@dataclass(frozen=True)
class SurfaceOffset:
    """The depth offset measured at the surface.

    Attributes:
        offset: to subtract from every depth reading [m] (0: none measured).
        readings: how many surface readings measured it.
        span: ``(first, last)`` time [s] of those readings, or None.
        note: one line for the report: what was used and where it came from.
    """

    offset: float
    readings: int
    span: tuple[float, float] | None
    note: str

    def pressure(self, reference: float, density: float) -> float:
        """The surface pressure [Pa] the offset implies for readings converted with
        ``reference`` [Pa] at water ``density`` [kg/m³]."""
        return reference + self.offset * density * G0


def surface_offset(
    depth_time: F64,
    depth: F64,
    fix_time: F64,
    *,
    surface_depth: float = 0.0,
    given: float | None = None,
) -> SurfaceOffset:
    """The offset of the depth readings (``depth_time`` [s], ``depth`` [m, down]) at the
    surface: the median of the readings within :data:`SURFACE_WINDOW` of a fix
    (``fix_time`` [s]) that read within :data:`SURFACE_DEPTH` of ``surface_depth`` [m,
    the sensor's depth while the vehicle floats], less ``surface_depth``. ``given`` [m]
    (a known offset) wins."""
    if given is not None:
        if not np.isfinite(given):
            raise ValueError(f"surface_offset: must be a finite number of metres, got {given}")
        return SurfaceOffset(float(given), 0, None, f"depth offset {given:+.3f} m, given")
    t = np.asarray(depth_time, dtype=np.float64)
    d = np.asarray(depth, dtype=np.float64)
    if d.size and (median := float(np.median(d))) < -MAX_ABOVE_SURFACE:
        raise ValueError(
            f"depth: the readings lie a median {median:.3g} m, above the sea surface: a "
            "height (positive up) for a depth, a pressure in kPa or bar converted as pascals, "
            "or the atmosphere taken off twice?"
        )
    ft = np.sort(np.asarray(fix_time, dtype=np.float64))
    near = np.zeros(len(t), dtype=bool)
    if ft.size and t.size:
        i = np.clip(np.searchsorted(ft, t), 1, len(ft)) - 1
        j = np.clip(i + 1, 0, len(ft) - 1)
        near = np.minimum(np.abs(t - ft[i]), np.abs(t - ft[j])) <= SURFACE_WINDOW
    use = near & (np.abs(d - surface_depth) <= SURFACE_DEPTH)
    n = int(use.sum())
    if n < MIN_SURFACE_READINGS:
        note = (
            "no reading at the surface beside a fix: the depth keeps the reader's surface "
            "reference (a wrong one is up to ±0.3 m of depth)"
        )
        shallowest = float(np.percentile(d, 1)) if d.size else np.nan
        if abs(shallowest - ATMOSPHERE_DEPTH) <= ATMOSPHERE_BAND:
            note += (
                f"; its shallowest readings are {shallowest:.2f} m deep, about one "
                f"atmosphere ({ATMOSPHERE_DEPTH:.2f} m of sea water): if the vehicle came to "
                "the surface, an absolute pressure whose atmosphere was never taken off "
                "(--surface-offset takes it off)"
            )
        return SurfaceOffset(0.0, n, None, note)
    offset = float(np.median(d[use])) - surface_depth
    span = (float(t[use][0]), float(t[use][-1]))
    return SurfaceOffset(
        offset,
        n,
        span,
        f"depth offset {offset:+.3f} m from {n} readings at the surface beside fixes "
        f"({span[0]:.1f}–{span[1]:.1f} s), the sensor {surface_depth:g} m deep there",
    )
