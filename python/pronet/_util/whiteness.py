"""The whiteness test of a stream's innovations, :func:`pronet.stats.whiteness` (kept
here so that :mod:`pronet.stats` stays within its size; that module re-exports it)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def whiteness(innovation: F64, cov: F64, used: NDArray[np.bool_]) -> tuple[float, float]:
    """The whiteness test of a vector stream's innovations (Bar-Shalom, Li and
    Kirubarajan 2001, §5.4.2): each used innovation ``ν_k`` ``(r, n)`` whitened by its
    covariance ``S_k = L_k L_kᵀ`` ``(r, n, n)`` (``e_k = L_k⁻¹ ν_k``, N(0, I) for a
    consistent filter), then ``ρ = Σ e_k·e_{k+1} / √(Σ |e_k|² Σ |e_{k+1}|²)`` over the
    pairs of consecutive used readings. For white innovations ``ρ`` is about
    N(0, 1/(nK)) over ``K`` pairs: the 95 % band is ``±1.96/√(nK)``. Returns ``ρ`` and
    that half-width (NaN, NaN with fewer than two pairs)."""
    ok = used & np.isfinite(innovation).all(axis=1) & np.isfinite(cov).all(axis=(1, 2))
    k = np.flatnonzero(ok)
    if len(k) < 3:
        return math.nan, math.nan
    try:
        chol = np.linalg.cholesky(cov[k])
    except np.linalg.LinAlgError:
        return math.nan, math.nan
    e = np.linalg.solve(chol, innovation[k][..., None])[..., 0]
    a, b = e[:-1], e[1:]
    rho = float(np.sum(a * b) / math.sqrt(float(np.sum(a * a)) * float(np.sum(b * b))))
    return rho, 1.96 / math.sqrt(e.shape[1] * len(a))
