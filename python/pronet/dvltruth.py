"""The DVL's scale-factor error and mounting angles implied by a recorded section's
ground truth, without a filter: the reference against which the filter's calibration
states (:class:`pronet.FilterConfig` ``dvl_calibration=True``) can be judged.

The DVL reads ``z = (1 + k) C_b^d v_b + n`` (:mod:`pronet.dvlcalibration`, the core's
``DvlMounting``), with ``v_b`` the body-frame velocity at the DVL and ``C_d^b =
R(roll, pitch, yaw)`` the DVL's axes in the body's. For small ``k`` and angles
``θ = [roll, pitch, yaw]`` this is ``z − v_b ≈ k v_b + v_b × θ``: linear in
``(k, θ)``. Here ``v_b`` comes from the ground truth (its NED velocity and attitude,
moved to the DVL by the lever arm with the gyro's rate), interpolated to the DVL rows,
and ``(k, θ)`` is the least-squares fit over every DVL row of the section.

What the truth can tell: an AUV moves mostly forward, so the fit sees the scale in the
forward axis, the yaw in the lateral and the pitch in the vertical axis; the roll needs
lateral or vertical motion and is weakly determined (its σ says so). The residuals are
the DVL's noise plus the truth's own errors, which are correlated from row to row; the
1σ is the least-squares one widened by ``√((1 + ρ) / (1 − ρ))`` for the residuals'
lag-one autocorrelation ``ρ`` (an AR(1) effective sample size), and is still a lower
bound when the truth has slow errors of its own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from pronet.alignment import Section, dcm_from_euler

F64 = NDArray[np.float64]

#: Fewest DVL rows inside the truth's time span that a fit is made from.
MIN_ROWS = 10


@dataclass(frozen=True)
class TruthCalibration:
    """The calibration a section's ground truth implies.

    Attributes:
        estimate: ``[k, roll, pitch, yaw]`` (scale error; rad), as the filter reports it
            (:attr:`pronet.FilterResult.calibration`).
        sigma: their 1σ (least squares widened for correlated residuals, see the module).
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
    rate, everything linearly interpolated to the DVL rows (angles unwrapped)."""
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
    than :data:`MIN_ROWS` DVL rows fall inside the truth, or the motion cannot
    separate the four (for example a vehicle at rest)."""
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
    a = design.reshape(-1, 4)
    normal = a.T @ a
    if np.linalg.cond(normal) > 1e12:
        raise ValueError(
            f"{section.name}: the truth's motion cannot separate the DVL's scale and "
            "mounting angles (too little speed)"
        )
    coef = np.linalg.solve(normal, a.T @ d.reshape(-1))
    resid = (d - design @ coef).reshape(len(rows), 3)
    dof = resid.size - 4
    s2 = float(np.sum(resid**2) / dof)
    lag = float(np.sum(resid[1:] * resid[:-1]) / np.sum(resid**2)) if len(rows) > 1 else 0.0
    rho = min(max(lag, 0.0), 0.95)
    widen = (1.0 + rho) / (1.0 - rho)
    sigma = np.sqrt(np.diag(np.linalg.inv(normal)) * s2 * widen)
    return TruthCalibration(
        estimate=coef.astype(np.float64),
        sigma=sigma,
        rms_residual=float(np.sqrt(np.mean(resid**2))),
        rows=len(rows),
    )
