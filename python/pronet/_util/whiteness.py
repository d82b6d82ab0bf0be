"""The whiteness test of a stream's innovations, :func:`pronet.stats.whiteness` (kept
here so that :mod:`pronet.stats` stays within its size; that module re-exports it), the
same test per axis (:func:`axis_whiteness`), and the clauses a stream's health line
says of them (:func:`whiteness_clause`)."""

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


#: A stream is flagged when its whiteness statistic is beyond this many σ of white
#: innovations, reported against its 95 % band: 4, so that a consistent stream is
#: flagged in about one pass in 6,000 by chance (the whitened vector's test two-sided,
#: one pass in 16,000, and each of three axes' one-sided, positive only).
WHITENESS_FLAG = 4.0
#: The names of a vector stream's axes in its health line.
AXES = ("x", "y", "z")


def axis_whiteness(innovation: F64, cov: F64, used: NDArray[np.bool_]) -> tuple[F64, float]:
    """The whiteness test per axis: each component of the used innovations ``(r, n)``
    over its predicted 1σ ``√S_aa`` (``cov`` ``(r, n, n)``), its lag-one autocorrelation
    over the pairs of consecutive used readings, ``(n,)``; and the half-width of its
    95 % band for white innovations, ``1.96/√pairs``. A slow error on one axis reads
    positive there even where the other axes alternate and the whitened vector's test
    (:func:`whiteness`) reads negative. NaN with fewer than two pairs."""
    ok = used & np.isfinite(innovation).all(axis=1) & np.isfinite(cov).all(axis=(1, 2))
    ok &= (np.diagonal(cov, axis1=1, axis2=2) > 0).all(axis=1)  # a σ to divide by
    e = innovation[ok] / np.sqrt(np.diagonal(cov[ok], axis1=1, axis2=2))
    if len(e) < 3:
        return np.full(innovation.shape[1], math.nan), math.nan
    a, b = e[:-1], e[1:]
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = np.sum(a * b, axis=0) / np.sqrt(np.sum(a * a, axis=0) * np.sum(b * b, axis=0))
    return np.asarray(rho, dtype=np.float64), 1.96 / math.sqrt(len(a))


def flagged(rho: float, half: float) -> bool:
    """Whether a lag-one autocorrelation is beyond :data:`WHITENESS_FLAG` σ of white
    innovations (``half``: its 95 % band's half-width)."""
    return abs(rho) > WHITENESS_FLAG / 1.96 * half


def whiteness_clause(rho: float, half: float, axes: F64, axes_half: float) -> str:
    """What a stream's health line says of its innovations' whiteness (empty where
    nothing is flagged): the whitened vector's lag-one autocorrelation ``rho`` (band
    ``±half``, :func:`whiteness`), then each axis of ``axes`` (band ``±axes_half``,
    :func:`axis_whiteness`) correlated beyond the flag where the vector does not
    already say so."""
    said = []
    if flagged(rho, half):
        why = (
            "a slowly varying error (a DVL's bottom-track bias, sound speed, alignment, or "
            "an IMU error the filter does not model) that a white R takes as averaging "
            "out, so that the σ are too small"
            if rho > 0
            else "each update over-corrects (the filter trusts the readings more than "
            "their errors warrant: R too small against Q) or the readings' errors "
            "alternate (stamps jittering against the IMU's)"
        )
        sign = "correlated" if rho > 0 else "anti-correlated"
        said.append(
            f"its whitened innovations are {sign} from one reading to the next (lag-one "
            f"autocorrelation {rho:.3g}, white within ±{half:.2g}): {why}"
        )
    if len(axes) > 1 and not (flagged(rho, half) and rho > 0):
        vector = f"the whitened vector ({rho:+.2f})" if math.isfinite(rho) else "its vector"
        slow = [
            f"{AXES[a]} ({r:+.2f})" for a, r in enumerate(axes) if r > 0 and flagged(r, axes_half)
        ]
        if slow:
            where = "that axis" if len(slow) == 1 else "those axes"
            said.append(
                f"its innovations along {' and '.join(slow)} (each over its σ, white within "
                f"±{axes_half:.2g}) are correlated from one reading to the next, which "
                f"{vector} hides: a slowly varying error along {where} "
                "that the filter does not model (for a DVL in the body frame, x is forward): "
                "the sensor's scale or bias, the INS's drift there, or an R too large there "
                "against Q, so that the filter follows the INS and its slow error shows; "
                "the σ there are too small"
            )
    return "; ".join(said)
