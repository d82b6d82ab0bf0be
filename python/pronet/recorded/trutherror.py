"""The ground truth's own velocity error, estimated from data the filter under test
does not shape: the residual between the DVL and the truth.

The residual. At each DVL row inside the truth, ``r = C (z − v_b)`` [m/s, NED]: the DVL
reading ``z`` minus the truth's body velocity at the DVL ``v_b``
(:func:`pronet.recorded.dvltruth.truth_body_velocity`: the truth moved to the IMU, rotated
into the body, plus ``ω × r`` for the DVL's lever arm; clocks as
:mod:`pronet.recorded.alignment` estimated them), rotated into NED by the truth's
attitude ``C`` at the row. It holds three things: the DVL's white noise, the DVL's
slowly varying errors (bottom-track bias, scale and mounting, sound speed) and the
truth's own error (with the opposite sign).

Its two parts, per NED axis (:func:`residual_parts`):

- *fast* (``white``): the 1σ of the residual less its centred moving mean over
  :data:`SLOW_WINDOW` seconds, the part that changes from one row to the next. The
  truth is a post-processed (forward and backward) INS solution of a navigation-grade
  FOG INS; such a solution's error is smooth over seconds, so this part is the DVL's,
  not the truth's. It need not be white: on the Snapir sections it alternates from one
  reading to the next (``lag_one``, its lag-one autocorrelation, −0.2 to −0.7, with
  decaying terms of alternating sign after it, as a first-order autoregression with a
  negative coefficient gives), so ``std(Δr)/√2``, right for white noise, would
  overstate it by ``√(1 − ρ₁)``.
- *slow*: the RMS about zero of the residual's moving mean over :data:`SLOW_WINDOW`
  seconds, less the fast part's share of it: what varies slower than the window, the
  section's mean included. The fast part's share of an ``N``-row mean is that of a
  first-order autoregression with ``φ = ρ₁`` (whose ``ρ_k = φ^k`` the Snapir
  sections' fast parts follow to the second or third lag), ``(γ₀/N) [(1 + φ)/(1 − φ)
  − 2φ (1 − φᴺ) / (N (1 − φ)²)]``: ``γ₀/N`` for white noise, about a quarter of it for
  the Snapir DVL's alternating errors (``φ ≈ −0.6``). It is the truth's error and the DVL's
  correlated error together; they cannot be separated from these data alone. Were they
  independent, the slow part would be an upper bound on the truth's error.

Which number is the truth's error: the slow part, pooled over sections (the mean of
each section's square weighted by its rows, then the root). It is the largest velocity
error the data allow the truth to have, so a share "within 3σ" taken with it is
generous to the filter, and one taken without it is strict: the honest share lies
between the two, and both are reported (:class:`pronet.recorded.metrics.SectionMetrics`).
The fast part is not added: the filter models the DVL's own noise itself.

Two caveats. The post-processing may itself rest on this DVL (an INS post-processing
suite can take a DVL's bottom track as an aiding sensor; whether this one did is not
stated with the data); the truth's error then shares the DVL's correlated error, which
the residual cannot see, and the slow part is no bound.
And no published velocity accuracy of a post-processed Delph INS solution was found to
cross-check against: the numbers here come from the data alone.

Position: the DVL observes no position, and no other independent source of the truth's
position exists in these data, so no position error of the truth is stated (nothing on
recorded data scores the position against the filter's σ either).

:data:`SNAPIR_TRUTH_VELOCITY_SIGMA` holds the numbers for the Snapir truth, derived once
over sections 1–11 with :func:`truth_velocity_error`; a test re-derives them from the
data (``tests/recorded/test_trutherror.py``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet._util.validate import float_array, scalar
from pronet.recorded.alignment import Section, dcm_from_euler
from pronet.recorded.dvltruth import truth_body_velocity

F64 = NDArray[np.float64]

#: Length [s] of the centred moving mean that keeps the residual's slowly varying part.
#: The part is nearly the same over 10, 30 and 60 s on the Snapir sections (it is
#: bias-like); 30 s is long against the DVL's 1 s rows and short against a section.
SLOW_WINDOW = 30.0
#: The fast part's lag-one autocorrelation is taken within ±this (a first-order
#: autoregression with |φ| → 1 is no longer noise about a slow part).
MAX_LAG_ONE = 0.95

#: The Snapir truth's velocity error 1σ per NED axis [m/s]: the residual's slow part
#: pooled over sections 1–11 (:func:`truth_velocity_error`, :data:`SLOW_WINDOW` 30 s),
#: rounded up to 0.1 mm/s. Used by ``pronet real --format snapir``.
SNAPIR_TRUTH_VELOCITY_SIGMA = (0.0111, 0.0183, 0.0019)


@dataclass(frozen=True)
class ResidualParts:
    """The DVL–truth residual's parts per NED axis (see the module docstring).

    Attributes:
        white: ``(3,)`` the fast part's 1σ [m/s], the DVL's own noise (row to row).
        slow: ``(3,)`` the part slower than :data:`SLOW_WINDOW`, as an RMS about zero
            [m/s]: the truth's error and the DVL's correlated error together.
        mean: ``(3,)`` the residual's mean [m/s].
        rows: residual rows used.
        lag_one: ``(3,)`` the fast part's lag-one autocorrelation (0 for white noise).
    """

    white: F64
    slow: F64
    mean: F64
    rows: int
    lag_one: F64


def dvl_truth_residual(section: Section) -> tuple[F64, F64]:
    """``(time, residual)``: the DVL rows inside the truth's span [s, IMU clock] and
    ``C (z − v_b)`` there ``(rows, 3)`` [m/s, NED] (see the module docstring); a section
    without a ground truth is refused in one line."""
    rows, v_b = truth_body_velocity(section)
    t = section.dvl_time[rows]
    rpy = np.unwrap(section.truth_rpy, axis=0)
    at = np.stack([np.interp(t, section.truth_time, rpy[:, j]) for j in range(3)], axis=1)
    residual = np.einsum("kij,kj->ki", dcm_from_euler(at), section.dvl[rows] - v_b)
    return t, residual


def residual_parts(
    residual: ArrayLike, row_step: float = 1.0, window: float = SLOW_WINDOW
) -> ResidualParts:
    """The white and slow parts of one section's residual ``(rows, 3)`` [m/s] taken
    ``row_step`` [s] apart, the slow one over a centred moving mean of ``window`` [s]
    (at least two rows; see the module docstring). Raises ValueError when the residual
    has fewer rows than the window or any non-finite value."""
    r = float_array(residual, "residual", (None, 3))
    if not np.isfinite(r).all():
        raise ValueError("residual: must be finite")
    step = scalar(row_step, "row_step")
    if not step > 0:
        raise ValueError(f"row_step: must be > 0 s, got {row_step}")
    n = max(2, round(scalar(window, "window") / step))
    if len(r) < (n | 1) + 1:  # the fast part's centred mean takes n + 1 rows where n is even
        raise ValueError(f"residual: {len(r)} rows, fewer than the window's {n | 1} + 1")
    moving = _moving_mean(r, n)
    var, lag_one = _fast_part(r, n)
    phi = np.clip(lag_one, -MAX_LAG_ONE, MAX_LAG_ONE)
    share = var / n * ((1 + phi) / (1 - phi) - 2 * phi * (1 - phi**n) / (n * (1 - phi) ** 2))
    slow2 = np.mean(moving**2, axis=0) - share
    return ResidualParts(
        white=np.sqrt(var),
        slow=np.sqrt(np.maximum(slow2, 0.0)),
        mean=r.mean(axis=0),
        rows=len(r),
        lag_one=lag_one,
    )


def _moving_mean(r: F64, n: int) -> F64:
    """The ``n``-row moving means of ``r (rows, 3)``, where every row is inside."""
    kernel = np.ones(n) / n
    return np.stack([np.convolve(r[:, j], kernel, mode="valid") for j in range(3)], axis=1)


def _fast_part(r: F64, n: int) -> tuple[F64, F64]:
    """The variance ``(3,)`` and lag-one autocorrelation ``(3,)`` of the fast part of
    ``r``: each row less the moving mean centred on it (over ``n`` rows, ``n + 1`` if
    even), the variance scaled by ``m/(m − 1)`` for the ``1/m`` of a white noise's the
    mean of ``m`` rows takes with it."""
    m = n | 1
    fast = r[m // 2 : m // 2 + len(r) - m + 1] - _moving_mean(r, m)
    fast = fast - fast.mean(axis=0)
    var = np.mean(fast**2, axis=0)
    lag = np.mean(fast[1:] * fast[:-1], axis=0)
    return var * m / (m - 1), np.divide(lag, var, out=np.zeros(3), where=var > 0)


def pooled(parts: Sequence[ResidualParts]) -> ResidualParts:
    """Sections' parts pooled: each 1σ as the root of the row-weighted mean square, the
    mean and the lag-one autocorrelation row-weighted. Raises ValueError for no parts."""
    if not parts:
        raise ValueError("parts: no section to pool")
    w = np.array([p.rows for p in parts], dtype=np.float64)
    w = w / w.sum()

    def rms(name: str) -> F64:
        return np.sqrt(np.einsum("s,sj->j", w, np.array([getattr(p, name) ** 2 for p in parts])))

    mean = np.einsum("s,sj->j", w, np.array([p.mean for p in parts]))
    lag_one = np.einsum("s,sj->j", w, np.array([p.lag_one for p in parts]))
    return ResidualParts(rms("white"), rms("slow"), mean, int(sum(p.rows for p in parts)), lag_one)


def section_parts(section: Section, window: float = SLOW_WINDOW) -> ResidualParts:
    """:func:`residual_parts` of ``section``'s DVL–truth residual, its rows taken at the
    DVL's median step."""
    t, residual = dvl_truth_residual(section)
    return residual_parts(residual, float(np.median(np.diff(t))), window)


def truth_velocity_error(sections: Sequence[Section], window: float = SLOW_WINDOW) -> ResidualParts:
    """The parts of the DVL–truth residual pooled over ``sections``
    (:func:`section_parts`, :func:`pooled`): ``slow`` is the truth's velocity error 1σ
    per NED axis [m/s] as this module states it."""
    return pooled([section_parts(s, window) for s in sections])
