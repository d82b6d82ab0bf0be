"""The surface reference of a pressure depth: a depth sensor reads the water above it
only once the atmosphere's pressure on the surface is taken off, and a weather day moves
that pressure by ±2 kPa (±0.2 m of water) from the standard 101,325 Pa a reader assumes.

When the vehicle is at the surface with a position fix (GNSS works only there; a fix
whose height is near the surface), the depth sensor is at the surface too, within its
lever arm: the readings there measure the offset (:func:`surface_offset`), which is
taken off every reading. Without such readings the reader's reference stays, and the
report says so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pronet.recorded.solution import F64

#: A fix is taken at the surface when its height is within this of 0 m [m].
SURFACE_HEIGHT = 1.0
#: A depth reading is taken at the surface when it is within this of 0 m [m] (a wrong
#: surface pressure is ±0.3 m at the most on Earth's weather) and within this long
#: [s] of a surface fix.
SURFACE_DEPTH = 1.0
SURFACE_WINDOW = 1.0
#: At least this many surface readings, or none is used.
MIN_SURFACE_READINGS = 5
#: Standard gravity [m/s²] of the pressure-to-depth conversion (bags').
G0 = 9.80665


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
    fix_height: F64,
    *,
    given: float | None = None,
) -> SurfaceOffset:
    """The offset of the depth readings (``depth_time`` [s], ``depth`` [m, down]) at the
    surface: the median of the readings within :data:`SURFACE_WINDOW` of a fix whose
    height (``fix_height`` [m, up]; NaN: a horizontal fix, not used) lies within
    :data:`SURFACE_HEIGHT` of 0, where the reading itself is within
    :data:`SURFACE_DEPTH` of 0. ``given`` [m] (a known offset) wins."""
    if given is not None:
        if not np.isfinite(given):
            raise ValueError(f"surface offset: must be a finite number of metres, got {given}")
        return SurfaceOffset(float(given), 0, None, f"depth offset {given:+.3f} m, given")
    t = np.asarray(depth_time, dtype=np.float64)
    d = np.asarray(depth, dtype=np.float64)
    ft = np.asarray(fix_time, dtype=np.float64)
    fh = np.asarray(fix_height, dtype=np.float64)
    surface_fixes = ft[np.abs(np.nan_to_num(fh, nan=np.inf)) <= SURFACE_HEIGHT]
    near = np.zeros(len(t), dtype=bool)
    if surface_fixes.size and t.size:
        i = np.clip(np.searchsorted(surface_fixes, t), 1, len(surface_fixes)) - 1
        j = np.clip(i + 1, 0, len(surface_fixes) - 1)
        gap = np.minimum(np.abs(t - surface_fixes[i]), np.abs(t - surface_fixes[j]))
        near = gap <= SURFACE_WINDOW
    use = near & (np.abs(d) <= SURFACE_DEPTH)
    n = int(use.sum())
    if n < MIN_SURFACE_READINGS:
        return SurfaceOffset(
            0.0,
            n,
            None,
            "no surface reading beside a fix at the surface: the depth keeps the reader's "
            "surface reference (a wrong one is up to ±0.3 m of depth)",
        )
    offset = float(np.median(d[use]))
    span = (float(t[use][0]), float(t[use][-1]))
    return SurfaceOffset(
        offset,
        n,
        span,
        f"depth offset {offset:+.3f} m from {n} readings at the surface beside fixes "
        f"({span[0]:.1f}–{span[1]:.1f} s)",
    )
