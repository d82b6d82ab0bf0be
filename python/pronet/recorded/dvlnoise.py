"""The DVL's noise variance R estimated from a recording.

Two estimators, per body axis [(m/s)²]:

- :func:`second_difference_variance`, filter-free: ``var(Δ²v)/6`` of the DVL's own
  readings. White noise of variance σ² has second differences of variance 6σ², while
  the vehicle's velocity changes little over two 1 s steps. It measures the sensor.
- :func:`match_innovations`, through the filter: repeated passes over the recording,
  each axis's R scaled by the ratio of the innovations' mean square to the filter's own
  prediction of it (the mean of ``S_aa``), until R changes by less than a tolerance.
  At its fixed point every axis's innovations have the variance the filter predicts,
  so the mean NIS is near 3. It measures what the *filter* needs: where P is too large
  or too small (Q, the bias walks), R absorbs the difference, so it can differ from
  the sensor's noise. Both are reported by ``pronet real``.

Where the innovations of that fit are correlated from one reading to the next beyond
4σ of white innovations on an axis (a slow error the white R leaves unmodelled),
:func:`match_correlated` fits R and the 1σ of a first-order Gauss–Markov DVL error
together, at a given correlation time: the innovations identify the slow error's power
in the filter's passband, not its correlation time (measured in
``tests/recorded/test_dvlnoise.py``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet._util.validate import count, float_array, scalar
from pronet._util.whiteness import axis_whiteness, flagged
from pronet.filter import FilterResult

F64 = NDArray[np.float64]
Variance = tuple[float, float, float]

#: Where the DVL noise R of a recorded run's strategy rows comes from (``pronet real
#: --dvl-noise``): the datasheet, or the recording itself (the innovation-matched R).
DVL_NOISE_SOURCES = ("datasheet", "data")
#: Smallest R per axis [(m/s)²]: the quantization noise of a 1 mm/s velocity
#: resolution (the Workhorse Navigator's), (1 mm/s)²/12.
DVL_VARIANCE_FLOOR = 1e-6 / 12
#: Default stop of :func:`match_innovations`: R changed by under 1 % on every axis.
MATCH_TOLERANCE = 0.01
#: Default most passes of :func:`match_innovations`.
MATCH_PASSES = 30
#: Longest secant step of :func:`match_correlated`'s variance, in plain steps: the
#: filter takes most of a slow error into its velocity, so the lag-one covariance the
#: plain step reads moves by a few percent of each step (measured on Snapir: 4 %).
LONGEST_STEP = 100.0


def second_difference_variance(dvl: ArrayLike) -> Variance:
    """``var(Δ²v)/6`` per axis of body-frame DVL readings ``(m, 3)`` [m/s], over the
    runs of three consecutive finite rows; at least :data:`DVL_VARIANCE_FLOOR`.

    Raises ValueError when fewer than ten second differences can be formed.
    """
    v = float_array(dvl, "dvl", (None, 3))
    d2 = v[2:] - 2 * v[1:-1] + v[:-2]
    d2 = d2[np.isfinite(d2).all(axis=1)]
    if len(d2) < 10:
        raise ValueError(
            f"dvl: needs at least ten runs of three consecutive finite rows, got {len(d2)}"
        )
    var = np.maximum(np.var(d2, axis=0) / 6, DVL_VARIANCE_FLOOR)
    return (float(var[0]), float(var[1]), float(var[2]))


@dataclass(frozen=True)
class MatchedVariance:
    """The outcome of :func:`match_innovations`.

    Attributes:
        variance: R per body axis [(m/s)²].
        start: the R the first pass used.
        passes: filter passes made.
        converged: whether the last pass changed R by less than the tolerance.
        mean_nis: mean NIS of the last pass (made with the R before its update: within
            the tolerance of ``variance`` when converged).
        correlated: the DVL's correlated error fitted with R (:func:`match_correlated`):
            its stationary 1σ per body axis [m/s], or None where the innovations show
            none (white R only).
        time_constant: its correlation time [s] (None without it).
    """

    variance: Variance
    start: Variance
    passes: int
    converged: bool
    mean_nis: float
    correlated: Variance | None = None
    time_constant: float | None = None


def innovation_ratio(result: FilterResult) -> F64:
    """Per axis, the mean square of the applied innovations over the mean of the
    filter's predicted ``S_aa`` (1 for a filter that predicts its innovations right).

    Raises ValueError when no update was applied."""
    applied = result.accepted & np.isfinite(result.innovation).all(axis=1)
    if not applied.any():
        raise ValueError("no DVL update was applied: the innovations say nothing about R")
    nu2 = np.mean(result.innovation[applied] ** 2, axis=0)
    s = np.mean(np.diagonal(result.innovation_cov[applied], axis1=1, axis2=2), axis=0)
    return np.asarray(nu2 / s, dtype=np.float64)


def match_innovations(
    run_pass: Callable[[Variance], FilterResult],
    start: ArrayLike,
    *,
    tolerance: float = MATCH_TOLERANCE,
    max_passes: int = MATCH_PASSES,
    floor: float = DVL_VARIANCE_FLOOR,
) -> MatchedVariance:
    """R such that each axis's innovations have the variance the filter predicts.

    Args:
        run_pass: one filter pass over the recording with the given R [(m/s)²].
        start: R of the first pass (e.g. :func:`second_difference_variance`).
        tolerance: stop when R changes by less than this fraction on every axis.
        max_passes: most passes (≥ 1).
        floor: smallest R per axis [(m/s)²].

    The fixed point is ``mean ν_a² = mean S_aa``: per axis, the root of
    ``f(x) = log ratio`` in ``x = log R_a`` (:func:`innovation_ratio`). It exists and
    is unique because P grows with R more slowly than R does, so a too-small R gives a
    ratio above 1 and a too-large one below 1. The first step multiplies R_a by its
    ratio; later steps take the secant through the last two passes, which converges
    in a few passes where the plain step crawls (where the filter's own share of S
    dominates, f is flat), falling back to the plain step whenever the secant would
    step the other way or more than 10 times as far. The result is the last R times
    its ratio (within the tolerance of the last R when converged).
    """
    r = float_array(start, "start", (3,))
    if not (np.all(np.isfinite(r)) and np.all(r > 0)):
        raise ValueError(f"start: must be finite and > 0 on every axis, got {r.tolist()}")
    passes = _check_matching(tolerance, max_passes, floor)
    first = _variance(r)
    made, converged, mean_nis = 0, False, float("nan")
    x, previous = np.log(r), None
    while made < passes and not converged:
        result = run_pass(_variance(np.maximum(np.exp(x), floor)))
        made += 1
        nis = result.nis[result.accepted]
        mean_nis = float(np.mean(nis)) if nis.size else float("nan")
        f = np.log(innovation_ratio(result))
        plain = np.maximum(x + f, math.log(floor))
        converged = bool(np.all(np.abs(np.exp(plain - x) - 1) < tolerance))
        step = _secant(x, f, previous) if previous is not None else f
        previous = (x, f)
        x = plain if converged else np.maximum(x + step, math.log(floor))
    return MatchedVariance(
        _variance(np.maximum(np.exp(x), floor)), first, made, converged, mean_nis
    )


def lag_one(result: FilterResult) -> tuple[F64, F64, float]:
    """Over the pairs of consecutive applied updates, per axis: the innovations'
    lag-one autocovariance [(m/s)²], then the whiteness test per axis
    (:func:`pronet._util.whiteness.axis_whiteness`: the lag-one autocorrelation of the
    innovations each over its predicted 1σ, and its 95 % band's half-width).

    Raises ValueError with fewer than ten pairs."""
    applied = result.accepted & np.isfinite(result.innovation).all(axis=1)
    nu = result.innovation[applied]
    if len(nu) < 11:
        raise ValueError(f"needs at least ten pairs of applied updates, got {max(len(nu) - 1, 0)}")
    rho, band = axis_whiteness(result.innovation, result.innovation_cov, applied)
    return np.asarray(np.mean(nu[:-1] * nu[1:], axis=0), np.float64), rho, band


def match_correlated(
    run_pass: Callable[[Variance, Variance | None], FilterResult],
    white: MatchedVariance,
    time_constant: float,
    dvl_step: float,
    *,
    tolerance: float = MATCH_TOLERANCE,
    max_passes: int = MATCH_PASSES,
    floor: float = DVL_VARIANCE_FLOOR,
) -> MatchedVariance:
    """R and the DVL's correlated error fitted together, from the white fit ``white``
    (:func:`match_innovations`).

    Args:
        run_pass: one filter pass with the given R [(m/s)²] and the correlated error's
            1σ per body axis [m/s] (None: without its states).
        white: R matched with ``run_pass(R, None)``.
        time_constant: the correlated error's correlation time τ [s] (a vehicle file's
            ``dvl_bias_time_constant``, else the filter's default).
        dvl_step: the DVL's step [s] (lag one).
        tolerance: as :func:`match_innovations`'s (and of ``R + b`` for ``b``).
        max_passes: most passes, the lag-one pass included (≥ 1).
        floor: smallest R per axis [(m/s)²].

    One pass with ``white``'s R reads the innovations' lag-one autocorrelation
    (:func:`lag_one`). Where no axis's is positive beyond 4σ of white innovations (the
    health line's flag, :func:`pronet._util.whiteness.flagged`: a 95 % one-sided gate
    would fit a σ to one white axis in 40, as the fit drives the sample's lag-one
    covariance to zero whatever its cause), the innovations show no slow error and
    ``white`` is returned, that pass counted. Otherwise, on those axes, the variance
    ``b`` of a first-order
    Gauss–Markov error with τ is fitted beside R: ``b`` takes the lag-one
    autocovariance ``c₁`` over ``φ = exp(−dvl_step/τ)`` (the error's own lag-one
    covariance is ``b φ``), then secant steps towards ``c₁ = 0``, as R takes
    :func:`match_innovations`'s towards its ratio 1, in the same passes, until both
    change by less than ``tolerance`` (of ``R + b`` for ``b``; an R held at ``floor``
    does not change). ``passes`` of the result counts ``white``'s with these. At the fixed point
    the innovations are uncorrelated at lag one and have the variance the filter
    predicts. ``b`` reaching 0 on every axis ends with no correlated part.
    """
    if not (math.isfinite(time_constant) and time_constant > 0):
        raise ValueError(f"time_constant: must be > 0 s, got {time_constant}")
    if not (math.isfinite(dvl_step) and dvl_step > 0):
        raise ValueError(f"dvl_step: must be > 0 s, got {dvl_step}")
    passes = _check_matching(tolerance, max_passes, floor)
    c1, rho, band = lag_one(run_pass(white.variance, None))
    phi = math.exp(-dvl_step / time_constant)
    fitted = (rho > 0) & np.array([flagged(r, band) for r in rho])
    if not fitted.any():
        return replace(white, passes=white.passes + 1)
    b = np.where(fitted, np.maximum(c1 / phi, 0.0), 0.0)
    # the white R held the slow part's variance too
    r = np.maximum(np.asarray(white.variance, dtype=np.float64) - b, floor)
    made, converged, mean_nis, previous = 1, False, white.mean_nis, None
    while made < passes and not converged and b.any():
        result = run_pass(_variance(r), _variance(np.sqrt(b)))
        made += 1
        nis = result.nis[result.accepted]
        mean_nis = float(np.mean(nis)) if nis.size else float("nan")
        ratio = innovation_ratio(result)
        f = np.where(fitted, lag_one(result)[0] / phi, 0.0)
        step = _secant(b, f, previous, LONGEST_STEP) if previous is not None else f
        previous = (b, f)
        new_b = np.where(fitted, np.maximum(b + step, 0.0), 0.0)
        new_r = np.maximum(r * ratio, floor)
        converged = bool(  # R at its floor and still too large counts as settled
            np.all(np.abs(new_r / r - 1) < tolerance)
            and np.all(np.abs(new_b - b) <= tolerance * (new_r + new_b))
        )
        r, b = new_r, new_b
    if not b.any():
        return MatchedVariance(_variance(r), white.start, white.passes + made, converged, mean_nis)
    sigma = _variance(np.sqrt(b))
    return MatchedVariance(
        _variance(r), white.start, white.passes + made, converged, mean_nis, sigma, time_constant
    )


def _check_matching(tolerance: float, max_passes: int, floor: float) -> int:
    """The number of passes, once the matching's ``tolerance`` (> 0), ``max_passes``
    (≥ 1) and ``floor`` (> 0) are checked (``ValueError`` naming the argument)."""
    if not scalar(tolerance, "tolerance") > 0:
        raise ValueError(f"tolerance: must be > 0, got {tolerance}")
    passes = count(max_passes, "max_passes", 1000)
    if passes < 1:
        raise ValueError(f"max_passes: must be at least 1, got {passes}")
    if not scalar(floor, "floor") > 0:
        raise ValueError(f"floor: must be > 0 (m/s)², got {floor}")
    return passes


def _secant(x: F64, f: F64, previous: tuple[F64, F64], longest: float = 10.0) -> F64:
    """Per axis, the secant step towards the root of f through ``previous`` and
    ``(x, f)``; the plain step ``f`` where the secant is undefined, points the other
    way or is more than ``longest`` times as long."""
    x0, f0 = previous
    with np.errstate(divide="ignore", invalid="ignore"):
        secant = -f * (x - x0) / (f - f0)
    good = np.isfinite(secant) & (secant * f > 0) & (np.abs(secant) <= longest * np.abs(f))
    return np.where(good, secant, f)


def _variance(r: F64) -> Variance:
    return (float(r[0]), float(r[1]), float(r[2]))
