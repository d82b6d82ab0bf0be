"""The NumPy reference's second-order heading term (``heading_second_order``; the
core's ``ekf::second_order``, docs/reference/heading.md): P carries ``¾ u uᵀ``, ``u``
through every Φ and ``I − K H``, grown at each propagation of P by the linear part's
heading variance before it times the horizontal displacement since the last, in its
position rows."""

from __future__ import annotations

import numpy as np

KAPPA = 0.75


class SecondOrder:
    def __init__(self, n_x: int) -> None:
        self.u = np.zeros(n_x)
        self.run = np.zeros(2)

    def linear_heading_variance(self, p: np.ndarray) -> float:
        """``P[8, 8] − κ u₈²``: the heading variance of ``P − κ u uᵀ``."""
        return float(p[8, 8] - KAPPA * self.u[8] ** 2)

    def moved(self, v: np.ndarray, dt: float) -> None:
        """One IMU sample at the NED velocity ``v`` for ``dt`` [s]."""
        self.run += v[:2] * dt

    def grow(self, p: np.ndarray, phi: np.ndarray, heading_variance: float) -> np.ndarray:
        """``u`` through ``phi`` and grown; P with the term's change added."""
        before = phi @ self.u
        after = before.copy()
        after[:2] += max(heading_variance, 0.0) * self.run
        self.run[:] = 0.0
        self.u = after
        return p + KAPPA * (np.outer(after, after) - np.outer(before, before))

    def update(self, ikh: np.ndarray) -> None:
        """``u ← (I − K H) u``."""
        self.u = ikh @ self.u
