"""The SE₂(3) formulation of the NumPy reference filter (``numpy_reference_ekf.py``),
from docs/reference/heading.md, "The SE₂(3) formulation".

The position error is taken about an anchor, ``δP = δp − [p̂×]ψ`` (beside the invariant
velocity error ``δV = δv − [v̂×]ψ``), with ``p̂`` the estimate's NED displacement from the
anchor in metres, the radii at the anchor. Dense matrices again; nothing is shared with
the Rust core.
"""

from __future__ import annotations

import math

import numpy as np

from numpy_reference_ekf import exp_so3, radii, rates, skew


def displacement(lla: np.ndarray, anchor: np.ndarray) -> np.ndarray:
    """``p̂`` [m, NED] of ``lla`` from ``anchor``: ``[(φ−φ₀)(R_N₀+h₀),
    (λ−λ₀)(R_E₀+h₀) cos φ₀, −(h−h₀)]``, radii at the anchor."""
    rn, re = radii(anchor[0])
    return np.array(
        [
            (lla[0] - anchor[0]) * (rn + anchor[2]),
            (lla[1] - anchor[1]) * (re + anchor[2]) * math.cos(anchor[0]),
            -(lla[2] - anchor[2]),
        ]
    )


def anchor_metres(lla: np.ndarray, anchor: np.ndarray, axis: int) -> float:
    """Metres at ``anchor`` per metre at ``lla`` along NED ``axis`` (1 down): the scale
    a fix read at the estimate takes to be in δP's metres."""
    if axis == 2:
        return 1.0
    here, there = radii(lla[0]), radii(anchor[0])
    if axis == 0:
        return (there[0] + anchor[2]) / (here[0] + lla[2])
    return (there[1] + anchor[2]) * math.cos(anchor[0]) / ((here[1] + lla[2]) * math.cos(lla[0]))


def position(disp: np.ndarray, anchor: np.ndarray) -> np.ndarray:
    """The geodetic ``[lat, lon, h]`` whose ``displacement`` from ``anchor`` is ``disp``."""
    rn, re = radii(anchor[0])
    return np.array(
        [
            anchor[0] + disp[0] / (rn + anchor[2]),
            anchor[1] + disp[1] / ((re + anchor[2]) * math.cos(anchor[0])),
            anchor[2] - disp[2],
        ]
    )


#: Multiplies the position–attitude block of F: 1, or −1 in a test that breaks the
#: reference on purpose to show that the equality with the core can fail.
POS_ATT_SIGN = 1.0


def to_se23(fm: np.ndarray, gam: np.ndarray, lla, v, c, disp):
    """The invariant formulation's F (15×15) and Γ (15×12) at ``lla, v, c`` (from
    ``error_dynamics(..., invariant=True)``) rewritten in SE₂(3)'s position error at the
    displacement ``disp`` (new arrays):

    - ``δṖ = −[ω_en×]δP + δV + ([p̂×][ω_in×] − [ω_en×][p̂×])ψ − [p̂×]C δb_g``: the
      invariant ``[v̂×]`` on ψ replaced, ``−[p̂×]C`` on δb_g;
    - the velocity rows gain ``(γ/R)·diag(−1, −1, 2) [p̂×]`` on ψ (their δp column read
      at ``δp = δP + [p̂×]ψ``);
    - the gyro noise, ``ψ ← −C w_g``, drives ``δP = δp − [p̂×]ψ`` by ``[p̂×]C``."""
    fm, gam = fm.copy(), gam.copy()
    w_ie, w_en, g = rates(lla, v)
    rn, re = radii(lla[0])
    big_r = math.sqrt(rn * re) + lla[2]
    d = skew(disp)
    fm[0:3, 6:9] = POS_ATT_SIGN * (d @ skew(w_ie + w_en) - skew(w_en) @ d)
    fm[0:3, 12:15] = -d @ c
    fm[3:6, 6:9] += g[2] / big_r * np.diag([-1.0, -1.0, 2.0]) @ d
    gam[0:3, 3:6] = d @ c
    return fm, gam


def t_matrix(v: np.ndarray, disp: np.ndarray | None, n_x: int, sign: float = -1.0) -> np.ndarray:
    """``T`` (``sign`` −1) or ``T⁻¹`` (+1): ``x_f = T x_classic`` with ``sign·[v̂×]`` at
    (velocity rows, attitude columns) and, in SE₂(3) (``disp`` given), ``sign·[p̂×]`` at
    (position rows, attitude columns)."""
    t = np.eye(n_x)
    t[3:6, 6:9] = sign * skew(v)
    if disp is not None:
        t[0:3, 6:9] = sign * skew(disp)
    return t


def position_h_psi(disp: np.ndarray, axis: int) -> np.ndarray:
    """What SE₂(3) adds on ψ to a row with ``e_axis`` on the position error: row
    ``axis`` of ``[p̂×]`` (``δp = δP + [p̂×]ψ``)."""
    return skew(disp)[axis]


def corrected_lla(lla: np.ndarray, dx: np.ndarray, anchor: np.ndarray) -> np.ndarray:
    """SE₂(3)'s exact position feedback ``p̂ ← Exp(ψ̂)(p̂ − δP̂)`` about the anchor
    (from ``δP = p̂ − Ĉ Cᵀ p`` and ``C = Exp(ψ) Ĉ``)."""
    return position(exp_so3(dx[6:9]) @ (displacement(lla, anchor) - dx[0:3]), anchor)
