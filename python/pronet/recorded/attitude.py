"""A solution's attitude in the terms a user reads it: the yaw in [0, 360) degrees,
and the 1σ of roll, pitch and yaw from the filter's attitude-error σ.

The filter's attitude error ψ is a small rotation about the north, east and down axes
(``sigma[:, 6:9]`` of a solution, :data:`pronet.filter.ERROR_STATES`). Roll φ, pitch θ
and yaw γ (ZYX; γ here, ψ being the error) are rotations about other axes (the yaw
about down, the pitch about the yawed east axis, the roll about the body's x axis), so
that to first order

    ψ_N = cos γ cos θ·δφ − sin γ·δθ,   ψ_E = sin γ cos θ·δφ + cos γ·δθ,
    ψ_D = −sin θ·δφ + δγ,

whose inverse is

    δφ = (cos γ·ψ_N + sin γ·ψ_E) / cos θ,   δθ = −sin γ·ψ_N + cos γ·ψ_E,
    δγ = ψ_D + tan θ·(cos γ·ψ_N + sin γ·ψ_E).

:func:`attitude_sigma` is the σ of these with ψ_N, ψ_E, ψ_D taken as uncorrelated (a
solution holds their σ only, not their covariance). For a level vehicle σ_yaw = σ_ψD;
with ψ_N and ψ_E equally uncertain (as levelling leaves them) σ_roll = σ_ψN / cos θ and
σ_pitch = σ_ψN whatever the heading; heading north, roll and pitch are rotations about
north and east themselves, heading east about east and north.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]


def yaw_degrees(yaw: F64) -> F64:
    """Yaw [rad] as degrees in [0, 360)."""
    deg = np.mod(np.degrees(yaw), 360.0)
    return np.where(deg >= 360.0, 0.0, deg)  # a yaw of −1e-17 rad rounds to 360


def attitude_sigma(rpy: F64, sigma_psi: F64) -> F64:
    """``(n, 3)`` 1σ of roll, pitch, yaw [rad] from the attitude error ψ's 1σ about
    north, east, down ``sigma_psi`` ``(n, 3)`` [rad] at the attitudes ``rpy`` ``(n, 3)``
    [rad] (ZYX): the first-order map of the module docstring, the ψ components taken as
    uncorrelated."""
    pitch, yaw = rpy[:, 1], rpy[:, 2]
    c, s = np.cos(yaw), np.sin(yaw)
    var_n, var_e, var_d = (sigma_psi[:, j] ** 2 for j in range(3))
    level = c * c * var_n + s * s * var_e  # variance of cos γ·ψ_N + sin γ·ψ_E
    roll = np.sqrt(level) / np.cos(pitch)
    pitch_sigma = np.sqrt(s * s * var_n + c * c * var_e)
    yaw_sigma = np.sqrt(var_d + np.tan(pitch) ** 2 * level)
    return np.stack([roll, pitch_sigma, yaw_sigma], axis=1)
