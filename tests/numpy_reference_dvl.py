"""The DVL error states of the NumPy reference filter (``numpy_reference_ekf.py``),
written from docs/reference/filter.md, "DVL calibration states (opt-in, 19 states)" and
"The DVL's correlated velocity error (opt-in, 22 states)".

The DVL reads ``z = (1 + k) M v_b + b + n`` in its own axes: ``k`` the scale-factor
error, ``M`` the rotation from the body axes to the DVL's, ``b`` a first-order
Gauss–Markov error per DVL axis (``ḃ = −b/τ + w``, stationary 1σ ``σ_b``). The error
states after the 15 are ``δk = k̂ − k`` (15), ``δμ`` with ``M̂ = M (I + [δμ×])``
(16..18) and, with the correlated error, ``δb = b̂ − b`` (19..21).
"""

from __future__ import annotations

import math

import numpy as np

from numpy_reference_ekf import euler_from_dcm, exp_so3, skew


class DvlErrors:
    """The estimates ``k̂``, ``M̂``, ``b̂`` and the blocks of the DVL error states.

    ``calibration``: None, or ``(scale_sigma, misalignment_sigma (3,), scale_psd,
    misalignment_psd)``; ``bias``: None, or ``(sigma (3,), tau)``. With ``bias`` alone
    the scale and misalignment states exist with σ 0 and no walk (held at nominal)."""

    def __init__(self, calibration, bias):
        self.bias = bias
        if calibration is None:
            calibration = (0.0, (0.0, 0.0, 0.0), 0.0, 0.0)
        scale_sigma, mis_sigma, scale_psd, mis_psd = calibration
        self.variances = [scale_sigma**2, *(np.asarray(mis_sigma, dtype=float) ** 2)]
        self.walks = np.array([scale_psd, mis_psd, mis_psd, mis_psd])
        if bias is not None:
            self.sigma_b = np.asarray(bias[0], dtype=float)
            self.tau = float(bias[1])
            self.variances += list(self.sigma_b**2)  # initial P_bb = diag(σ_b²)
        self.n = len(self.variances)
        self.k = 0.0  # k̂
        self.m = np.eye(3)  # M̂, body -> DVL
        self.b = np.zeros(3)  # b̂ [m/s, DVL axes]

    def p0(self) -> np.ndarray:
        """The initial variances of the DVL error states."""
        return np.array(self.variances)

    def transition(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """The diagonals of ``Φ_cc`` and of the noise over ``dt`` seconds: 1 and the
        walks ``ε Δt`` for ``δk``, ``δμ``; ``e = exp(−Δt/τ)`` and ``σ_b² (1 − e²)`` for
        ``δb`` (so ``P_xb ← Φ P_xb e``, ``P_cb ← P_cb e``, ``P_bb ← e² P_bb + σ_b² (1 −
        e²)``)."""
        phi, noise = np.ones(4), self.walks * dt
        if self.bias is None:
            return phi, noise
        e = math.exp(-dt / self.tau)
        gauss_markov = self.sigma_b**2 * (1 - e * e)
        return np.concatenate([phi, [e] * 3]), np.concatenate([noise, gauss_markov])

    def measurement(self, v_b: np.ndarray, h_body: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``h = (1 + k̂) M̂ v̂_b + b̂`` and ``H = [(1 + k̂) M̂ H_b, M̂ v̂_b, −(1 + k̂) M̂
        [v̂_b×], I]`` (the ``I`` on ``δb`` only with the correlated error)."""
        g = 1.0 + self.k
        blocks = [g * self.m @ h_body, (self.m @ v_b)[:, None], -g * self.m @ skew(v_b)]
        pred = g * self.m @ v_b
        if self.bias is not None:
            blocks.append(np.eye(3))
            pred = pred + self.b
        return pred, np.hstack(blocks)

    def noise_as_read(self, sigma: np.ndarray) -> np.ndarray:
        """A noise covariance on ``v_b`` as the reading's: ``(1 + k̂)² M̂ Σ M̂ᵀ``."""
        g = 1.0 + self.k
        return g * g * self.m @ sigma @ self.m.T

    def feed(self, dc: np.ndarray) -> None:
        """``k̂ ← k̂ − δk̂``, ``M̂ ← M̂ Exp(−δμ̂)``, ``b̂ ← b̂ − δb̂``."""
        self.k = self.k - dc[0]
        self.m = self.m @ exp_so3(-dc[1:4])
        if self.bias is not None:
            self.b = self.b - dc[4:7]

    def reported(self) -> np.ndarray:
        """``[k̂, roll, pitch, yaw]`` of the DVL in the body, then ``b̂`` with the
        correlated error."""
        out = [[self.k], euler_from_dcm(self.m.T)]
        return np.concatenate(out if self.bias is None else [*out, self.b])
