"""Summary statistics over Monte Carlo runs: means with 95 % confidence intervals.

A mean's interval is Student's t interval unless that would leave the quantity's range
(an RMS below zero, a share above one, as a t-interval over two runs can): then it is
the percentile bootstrap of the mean (:data:`BOOTSTRAP` resamples, a fixed seed), which
never leaves the range of the values themselves. ``MeanCI.method`` says which."""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np
from numpy.typing import ArrayLike

from pronet._util.validate import count, real_array

_Z975 = NormalDist().inv_cdf(0.975)

#: Resamples of a percentile-bootstrap interval.
BOOTSTRAP = 2000
#: The range of a quantity that has none.
UNBOUNDED = (-math.inf, math.inf)
#: The range of a non-negative quantity (an RMS, an error, a NEES).
NON_NEGATIVE = (0.0, math.inf)
#: The range of a share.
SHARE = (0.0, 1.0)


def t_quantile_975(df: int) -> float:
    """97.5 % quantile of Student's t with ``df`` degrees of freedom.

    Cornish-Fisher expansion around the normal quantile; within 1e-3 of the exact value
    for df >= 3 and exact in the limit (e.g. 2.262 for df = 9, 1.984 for df = 99).
    """
    if count(df, "df") < 1:
        raise ValueError(f"df: must be >= 1, got {df}")
    if df == 1:
        return 12.706204736174707
    if df == 2:
        return 4.302652729749464
    z = _Z975
    n = float(min(df, 2**53))  # beyond, the corrections are below float64 resolution
    return (
        z
        + (z**3 + z) / (4 * n)
        + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * n**2)
        + (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / (384 * n**3)
    )


def chi2_mean_band(dof: int, runs: int) -> tuple[float, float]:
    """The 95 % band of the mean over ``runs`` independent χ² values of ``dof`` degrees
    of freedom (a consistent filter's mean NEES or NIS at one epoch): the 2.5 % and
    97.5 % quantiles of χ²(runs·dof)/runs, by the Wilson–Hilferty approximation
    (within 0.1 % of the exact quantiles from 100 degrees of freedom on)."""
    if count(dof, "dof") < 1 or count(runs, "runs") < 1:
        raise ValueError(f"dof and runs: must be >= 1, got {dof} and {runs}")
    nu = dof * runs

    def quantile(z: float) -> float:
        a = 2.0 / (9.0 * nu)
        return nu * (1.0 - a + z * math.sqrt(a)) ** 3 / runs

    return quantile(-_Z975), quantile(_Z975)


#: How a table prints a statistic that is undefined (a mean NIS without an update, an
#: R² of equal labels, a mean over no finite value): never as a number.
UNDEFINED = "undefined"


def format_number(value: float, spec: str = "{:.4f}") -> str:
    """``value`` formatted by ``spec``, or :data:`UNDEFINED` if it is NaN or infinite."""
    return spec.format(value) if math.isfinite(value) else UNDEFINED


@dataclass(frozen=True)
class MeanCI:
    """Mean of the finite values with its 95 % confidence interval: ``method`` ``"t"``
    (Student's t), ``"bootstrap"`` (percentile bootstrap, where a t-interval would leave
    the quantity's range) or ``"none"`` (fewer than two values: the bounds are NaN)."""

    mean: float
    low: float
    high: float
    n: int
    method: str = "t"

    def __str__(self) -> str:
        """``mean [low, high]``; an undefined mean or interval printed as such."""
        if not math.isfinite(self.mean):
            return UNDEFINED
        if not (math.isfinite(self.low) and math.isfinite(self.high)):
            return f"{self.mean:.4f} [CI {UNDEFINED}]"
        return f"{self.mean:.4f} [{self.low:.4f}, {self.high:.4f}]"


def mean_ci(values: ArrayLike, within: tuple[float, float] = UNBOUNDED) -> MeanCI:
    """Mean and 95 % CI of ``values`` over runs (NaN, e.g. failed runs, left out), for a
    quantity whose values lie ``within`` (low, high): the t-interval, or the percentile
    bootstrap where the t-interval would leave that range (see the module)."""
    x = real_array(values, "values").astype(np.float64)
    x = x[np.isfinite(x)]
    n = int(x.size)
    if n == 0:
        return MeanCI(math.nan, math.nan, math.nan, 0, "none")
    # Scaled by a power of two (exact, so ordinary values give the same bits) to keep
    # sums and squares of values near the float64 limit from overflowing.
    e = int(np.frexp(np.abs(x).max())[1])
    y = np.ldexp(x, -e)
    m = float(np.ldexp(y.mean(), e))
    if n == 1:
        return MeanCI(m, math.nan, math.nan, 1, "none")
    with np.errstate(over="ignore"):  # a half-width beyond float64 is inf
        half = float(np.ldexp(t_quantile_975(n - 1) * float(y.std(ddof=1)) / math.sqrt(n), e))
    if within[0] <= m - half and m + half <= within[1]:
        return MeanCI(m, m - half, m + half, n)
    return _bootstrap_ci(x, m)


def _bootstrap_ci(x: np.ndarray, mean: float) -> MeanCI:
    """The percentile-bootstrap 95 % CI of the mean of ``x`` (at least two values): its
    bounds lie within ``[min(x), max(x)]``, so within any range the values respect."""
    rng = np.random.default_rng(20261204)  # fixed: a table reads the same every time
    idx = rng.integers(0, x.size, size=(BOOTSTRAP, x.size))
    # scaled as mean_ci does, so that values near the float64 limit do not overflow
    e = int(np.frexp(np.abs(x).max())[1])
    means = np.ldexp(np.ldexp(x, -e)[idx].mean(axis=1), e)
    low, high = np.percentile(means, [2.5, 97.5])
    low, high = max(float(low), float(x.min())), min(float(high), float(x.max()))
    return MeanCI(mean, min(low, mean), max(high, mean), int(x.size), "bootstrap")
