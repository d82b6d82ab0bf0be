"""Statistics of raw IMU windows, in NumPy: the least-squares detrend, the unbiased
detrended variance (the statistical reference every regressor is compared with), the
Cramér–Rao floor, and the handcrafted features of the HCF ensemble.

A window is the last ``N`` samples of one IMU channel, ``(..., N)``: specific force
[m/s²] or angular rate [rad/s]; variances are per sample [(m/s²)² or (rad/s)²].
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet._util.validate import count, real_array

#: Names of :func:`features` columns, in order: seven statistics of the raw window, then
#: the same seven of the detrended window.
FEATURE_NAMES = tuple(
    f"{stat}_{kind}"
    for kind in ("raw", "detrended")
    for stat in ("var", "std", "range", "mad", "rms_diff", "skew", "kurt")
)


def as_windows(windows: ArrayLike, name: str = "windows", dtype: type = np.float64) -> NDArray[Any]:
    """``windows`` as an array of ``dtype`` ``(..., N)`` with N ≥ 3 (no copy when it
    already is one), or ``ValueError`` naming the argument."""
    arr = real_array(windows, name)
    if arr.ndim < 1 or arr.shape[-1] < 3:
        raise ValueError(f"{name}: expected shape (..., N) with N >= 3, got {arr.shape}")
    return arr.astype(dtype, copy=False)


def _unit_scaled(windows: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """``windows`` (see :func:`as_windows`) as float64, each window divided by the power
    of two ``2**e`` that brings its largest magnitude into [0.5, 1), and ``e``
    ``(..., 1)``. Exact, so statistics computed on the scaled window and scaled back
    equal the direct ones bit for bit, except where the direct ones would overflow
    (|w| ~ 1e80 raised to the 4th power) or underflow. The result is a C-ordered array
    of its own, never the caller's, so it may be worked on in place, and every layout of
    the same numbers gives the same bits."""
    src = real_array(windows, "windows")
    w = as_windows(src)
    # max |w| as max(max w, −min w): the same value (NaN where a NaN is) without a
    # window-sized array of magnitudes.
    with np.errstate(invalid="ignore"):
        peak = np.maximum(w.max(axis=-1, keepdims=True), -w.min(axis=-1, keepdims=True))
    e = np.frexp(np.where(np.isfinite(peak), peak, 0.0))[1]
    # A converted C-ordered array (float32 windows, say) is already a copy: scale it in
    # place; anything else goes to a new C-ordered array.
    own = w.dtype != src.dtype and w.flags.c_contiguous
    return np.ldexp(w, -e, out=w if own else None, order="C"), e


def detrend(windows: ArrayLike) -> NDArray[np.float64]:
    """Each window minus its least-squares line (over the sample index), ``(..., N)``."""
    y, e = _unit_scaled(windows)
    r = _detrend(y, out=y)
    return np.ldexp(r, e, out=r)


def _detrend(w: NDArray[np.float64], out: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
    """``w`` minus each window's least-squares line, written to ``out`` (which may be
    ``w``) or a new array. Apart from the line itself no window-sized temporary is made:
    each is fresh memory whose page faults cost more than its arithmetic (a batch of 600
    windows of 200 samples is ~1 MB)."""
    n = w.shape[-1]
    t = np.arange(n) - (n - 1) / 2.0
    centred = np.subtract(w, w.mean(axis=-1, keepdims=True), out=out)
    slope = centred @ t / (t @ t)
    centred -= np.multiply(slope[..., None], t)
    return centred


def detrended_variance(windows: ArrayLike) -> NDArray[np.float64]:
    """The unbiased variance of each detrended window, ``Σ r² / (N − 2)``, shape ``(...)``.

    For white Gaussian noise of variance q on a signal that is linear over the window
    this is unbiased with RMSE ``q·√(2/(N − 2))``: the one-line estimator a learned
    regressor has to beat.
    """
    y, e = _unit_scaled(windows)
    r = _detrend(y, out=y)
    return np.ldexp(np.multiply(r, r, out=r).sum(axis=-1) / (r.shape[-1] - 2), 2 * e[..., 0])


class DetrendedVariance:
    """The reference estimator as a regressor (``predict(windows) -> q``, as the learned
    models): the unbiased variance of each window after removing its least-squares line
    (N − 2 degrees of freedom). Needs no torch; the ``detvar`` strategy runs it."""

    name = "detrended variance"

    def predict(self, windows: ArrayLike) -> NDArray[np.float64]:
        return detrended_variance(windows)


def cramer_rao_rmse(q: ArrayLike, n: int) -> float:
    """The Cramér–Rao floor ``√(mean(2 q² / N))`` for the RMSE of variance estimates
    from ``n`` Gaussian samples each, over the labels ``q``."""
    q = real_array(q, "q").astype(np.float64)
    if q.size == 0 or not np.isfinite(q).all():
        raise ValueError(f"q: needs at least one finite variance, got {q.size} values")
    if count(n, "n") < 1:
        raise ValueError(f"n: must be at least 1 sample, got {n}")
    return float(np.sqrt(np.mean(2.0 * q * q / n)))


def features(windows: ArrayLike) -> NDArray[np.float64]:
    """The 14 handcrafted statistics of each window, ``(..., 14)``, named by
    :data:`FEATURE_NAMES`: variance (N − 1), standard deviation, range, mean absolute
    deviation, RMS of first differences, skewness and excess kurtosis, of the raw window
    and of the detrended one."""
    y, e = _unit_scaled(windows)
    return np.concatenate([_stats(y, e[..., 0]), _stats(_detrend(y), e[..., 0])], axis=-1)


def _stats(w: NDArray[np.float64], e: NDArray[np.int64]) -> NDArray[np.float64]:
    """The seven statistics of windows ``w`` scaled by ``2**-e`` (see
    :func:`_unit_scaled`), scaled back: skewness and kurtosis are scale-free."""
    centred = w - w.mean(axis=-1, keepdims=True)
    # Powers as products: numpy's float ** 3 and ** 4 go through pow(), ~100× slower.
    c2 = centred * centred
    m2 = c2.mean(axis=-1)
    var = m2 * w.shape[-1] / (w.shape[-1] - 1)
    # A constant window has no shape: skewness and kurtosis are 0 there, not NaN.
    safe = np.where(m2 > 0, m2, 1.0)
    skew = np.where(m2 > 0, (c2 * centred).mean(axis=-1) / safe**1.5, 0.0)
    kurt = np.where(m2 > 0, (c2 * c2).mean(axis=-1) / safe**2 - 3.0, 0.0)
    return np.stack(
        [
            np.ldexp(var, 2 * e),
            np.ldexp(np.sqrt(var), e),
            np.ldexp(w.max(axis=-1) - w.min(axis=-1), e),
            np.ldexp(np.abs(centred).mean(axis=-1), e),
            np.ldexp(np.sqrt((np.diff(w, axis=-1) ** 2).mean(axis=-1)), e),
            skew,
            kurt,
        ],
        axis=-1,
    )
