"""The DVL's scale-factor error and mounting angles implied by a recorded section's
ground truth, without a filter: the reference against which the filter's calibration
states (:class:`pronet.FilterConfig` ``dvl_calibration=True``) can be judged.

The DVL reads ``z = (1 + k) C_b^d v_b + n`` (:mod:`pronet.recorded.dvlcalibration`, the core's
``DvlMounting``), with ``v_b`` the body-frame velocity at the DVL and ``C_d^b =
R(roll, pitch, yaw)`` the DVL's axes in the body's. For small ``k`` and angles
``θ = [roll, pitch, yaw]`` this is ``z − v_b ≈ k v_b + v_b × θ``: linear in
``(k, θ)``. Here ``v_b`` comes from the ground truth (its NED velocity and attitude,
moved to the DVL by the lever arm with the gyro's rate), interpolated to the DVL rows,
and ``(k, θ)`` is the least-squares fit over every DVL row of the section.

What the truth can tell: an AUV moves mostly forward, so the fit sees the scale in the
forward axis, the yaw in the lateral and the pitch in the vertical axis; the roll needs
lateral or vertical motion and is weakly determined (its σ says so; with no such
motion at all it is not fitted: NaN, σ infinite). The residuals of the three axes
differ in size and in how they are correlated from row to row (the DVL's noise plus the
truth's own errors), so the fit is weighted per axis: a first unweighted pass gives each
axis its residual variance ``s²`` and lag-one autocorrelation ``ρ`` (floored at 0), and
the second pass weights the axis by ``(1 − ρ) / ((1 + ρ) s²)``, an AR(1) effective
sample size; the 1σ is that weighted fit's. It is still a lower bound when the truth
has slow errors of its own.

What the truth is: on the Snapir data a post-processed INS solution (iXblue's Delph
INS), which may itself rest on this DVL. A fit near zero then says that the DVL and the
post-processing agree, not that the DVL is right; it is still the reference the
filter's states are scored against.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pronet.recorded.alignment import Section, dcm_from_euler, no_truth

F64 = NDArray[np.float64]

#: Fewest DVL rows inside the truth's time span that a fit is made from.
MIN_ROWS = 10
#: Slowest median speed through the water [m/s] that a calibration fit is made from.
MIN_SPEED = 0.1


@dataclass(frozen=True)
class TruthCalibration:
    """The calibration a section's ground truth implies.

    Attributes:
        estimate: ``[k, roll, pitch, yaw]`` (scale error; rad), as the filter reports it
            (:attr:`pronet.FilterResult.calibration`).
        sigma: their 1σ (the per-axis weighted fit's, see the module); the roll is NaN
            with an infinite σ where the motion cannot show it.
        rms_residual: RMS of ``z − (1 + k) C_b^d v_b`` per axis after the fit [m/s].
        rows: DVL rows used.
    """

    estimate: F64
    sigma: F64
    rms_residual: float
    rows: int


def truth_body_velocity(section: Section) -> tuple[NDArray[np.intp], F64]:
    """``(rows, v_b)``: the indices of the DVL rows inside the truth's time span and the
    truth's body-frame velocity at the DVL there [m/s, FRD]: ``C_bᵀ v`` of the truth
    (at the IMU) plus ``ω × r`` for the DVL's lever arm from the IMU, ``ω`` the gyro's
    rate, everything linearly interpolated to the DVL rows (angles unwrapped). A section
    without a ground truth is refused in one line."""
    if not section.has_truth:
        raise ValueError(no_truth(section.name, "the DVL is fitted against one"))
    t = section.dvl_time
    rows = np.flatnonzero((t >= section.truth_time[0]) & (t <= section.truth_time[-1]))
    t = t[rows]

    def at(times: F64, values: F64) -> F64:
        return np.stack([np.interp(t, times, values[:, j]) for j in range(3)], axis=1)

    rpy = at(section.truth_time, np.unwrap(section.truth_rpy, axis=0))
    v_ned = at(section.truth_time, section.truth_vel)
    w = at(section.imu_time, section.imu[:, 3:6])
    r = np.asarray(section.alignment.filter_lever_arm, dtype=np.float64)
    v_b = np.einsum("kji,kj->ki", dcm_from_euler(rpy), v_ned) + np.cross(w, r)
    return rows, v_b


def truth_calibration(section: Section) -> TruthCalibration:
    """The DVL scale error and mounting angles of ``section`` fitted against its ground
    truth (see the module docstring). Raises ValueError naming the section when fewer
    than :data:`MIN_ROWS` DVL rows fall inside the truth, or its median speed is not
    above :data:`MIN_SPEED`."""
    rows, v_b = truth_body_velocity(section)
    if len(rows) < MIN_ROWS:
        raise ValueError(
            f"{section.name}: {len(rows)} DVL rows inside the ground truth; a calibration "
            f"fit needs at least {MIN_ROWS}"
        )
    d = section.dvl[rows] - v_b
    # z − v_b = k v_b + [v_b×] θ, three equations per row
    x, y, z = v_b[:, 0], v_b[:, 1], v_b[:, 2]
    zero = np.zeros_like(x)
    design = np.stack(
        [
            np.stack([x, zero, -z, y], axis=1),
            np.stack([y, z, zero, -x], axis=1),
            np.stack([z, -y, x, zero], axis=1),
        ],
        axis=1,
    )  # (rows, 3 axes, 4 unknowns)
    speed = float(np.median(np.linalg.norm(v_b, axis=1)))
    if not speed > MIN_SPEED:
        raise ValueError(
            f"{section.name}: the truth's median speed is {speed:.3g} m/s; a calibration "
            f"fit needs more than {MIN_SPEED} m/s"
        )
    # Roll is fitted only where the motion shows it (lateral or vertical velocity).
    fitted = [0, 1, 2, 3] if np.linalg.cond(_normal(design)) < 1e10 else [0, 2, 3]
    a = design[:, :, fitted]
    weights = np.ones(3)
    for _ in range(2):  # unweighted, then weighted per axis
        info = _normal(a, weights)
        coef = np.linalg.solve(info, np.einsum("kaj,ka,a->j", a, d, weights))
        resid = d - a @ coef
        weights = _axis_weights(resid)
    info = _normal(a, weights)
    estimate = np.full(4, np.nan)
    sigma = np.full(4, np.inf)
    estimate[fitted] = coef
    sigma[fitted] = np.sqrt(np.diag(np.linalg.inv(info)))
    return TruthCalibration(
        estimate=estimate,
        sigma=sigma,
        rms_residual=float(np.sqrt(np.mean(resid**2))),
        rows=len(rows),
    )


def _normal(design: F64, weights: F64 | None = None) -> F64:
    """``Σ_rows Σ_axes w_a A_aᵀ A_a`` of a ``(rows, 3, n)`` design."""
    w = np.ones(3) if weights is None else weights
    return np.einsum("kai,a,kaj->ij", design, w, design)


def _axis_weights(resid: F64) -> F64:
    """Per axis ``(1 − ρ) / ((1 + ρ) s²)`` from residuals ``(rows, 3)``: ``s²`` their
    mean square, ``ρ`` their lag-one autocorrelation floored at 0 and capped at 0.95
    (see the module docstring); a perfect fit gets the smallest positive ``s²``."""
    sq = np.sum(resid**2, axis=0)
    s2 = np.maximum(sq / max(len(resid) - 1, 1), np.finfo(np.float64).tiny)
    lag = np.sum(resid[1:] * resid[:-1], axis=0)
    rho = np.clip(np.divide(lag, sq, out=np.zeros(3), where=sq > 0), 0.0, 0.95)
    return (1.0 - rho) / ((1.0 + rho) * s2)
