"""An independent, pure-NumPy Rauch–Tung–Striebel smoother over the reference filter.

The plain fixed-interval recursion at every IMU step, dense matrices throughout, with
the closed-loop filter's resets: after each epoch's updates the forward error estimate
is zero, and the error of the solution before them is the one after plus the estimate
fed back (``docs/reference/smoother.md``, "The RTS smoother"). It shares no code with the Rust core
(whose backward pass chains the steps between updates instead) and is slow on purpose.
"""

from __future__ import annotations

import math

import numpy as np

from numpy_reference_ekf import dcm_from_euler, euler_from_dcm, exp_so3, radii
from numpy_reference_se23 import corrected_lla, displacement, t_matrix


def rts_smooth(forward: dict, log: list, formulation: str = "classic", anchor=None) -> dict:
    """The smoothed ``lla``, ``vel``, ``rpy``, ``bias`` and classic ``sigma`` at every
    epoch (with the DVL calibration states, ``calibration`` and ``calibration_sigma``
    too: all 19 states smoothed), from the reference filter's output ``forward`` and
    its ``log``.

    The recursion runs from close to close of the covariance (every epoch without a
    covariance step); between two closes the smoothed error of the forward solution is
    interpolated linearly in time, from the one after the earlier close's updates to the
    one before the later close's. So is the change the smoother makes to each classic
    variance (smoothed minus forward, both at the forward velocity the forward σ there
    was read at): from the earlier close's after its updates (at the velocity after
    them) to the later close's before them (at the velocity before them; the smoothed
    covariance is the same before and after an epoch's updates), added to the forward
    variance at the epoch (``forward["sigma"]``, itself interpolated so). In SE₂(3) the
    map to the classic coordinates is taken at the velocity and position together (the
    position's displacement from ``anchor``, by default the first epoch's), and the
    smoothed error is fed back as the filter feeds back an update."""
    se23 = formulation == "se23"
    anchor = (forward["lla"][0] if anchor is None else anchor) if se23 else None
    form = (formulation != "classic", None if anchor is None else np.asarray(anchor, float))
    n = len(log)
    keys = ("lla", "vel", "rpy", "bias", "calibration")
    out = {k: np.array(forward[k], dtype=float, copy=True) for k in keys}
    out["sigma"] = np.zeros((n, 15))
    out["calibration_sigma"] = np.zeros((n, 4))
    time = np.asarray(forward["time"], dtype=float)
    closes = [0] + [i for i in range(1, n) if log[i][0] is not None]
    assert closes[-1] == n - 1, "the last epoch closes the covariance step"
    later = n - 1
    ds = np.zeros(len(log[-1][3]))
    ps = log[-1][2]
    _fill(out, forward, log, (later, later + 1), (ds, ds), (ps, ps), time, form)
    for c in reversed(closes[:-1]):
        phi, p_prior, _, dx = log[later][:4]
        p_post = log[c][2]
        ds_prior = ds + dx  # the error before the later close's updates
        # C = P⁺ Φᵀ (P⁻)⁻¹ = ((P⁻)⁻¹ Φ P⁺)ᵀ (both symmetric), by a solve: with an explicit
        # inverse, SE₂(3) 4.8 km from its anchor lost 3e-8 of a classic σ to rounding.
        gain = np.linalg.solve(p_prior, phi @ p_post).T
        ds = gain @ ds_prior
        ps_end = ps
        ps = p_post + gain @ (ps - p_prior) @ gain.T
        ps = (ps + ps.T) / 2
        _fill(out, forward, log, (c, later), (ds, ds_prior), (ps, ps_end), time, form)
        later = c
    return out


def _fill(out, forward, log, closes, errors, covariances, time, form) -> None:
    """The smoothed error and σ at the close ``c`` and, interpolated linearly in time
    towards the close ``end``, at the epochs between (``closes = (c, end)``; ``errors``
    and ``covariances`` the smoothed ones at the two, ``δs`` at ``end`` before its
    updates)."""
    (c, end), (ds, ds_end), (ps, ps_end) = closes, errors, covariances
    vel, lla = forward["vel"], forward["lla"]
    at = (vel[c], lla[c])
    near = _variances(ps, at, form) - _variances(log[c][2], at, form)
    far = near
    if end < len(log):  # the forward covariance, velocity, position at end before updates
        p_prior, at = log[end][1], log[end][4:6]
        far = _variances(ps_end, at, form) - _variances(p_prior, at, form)
    calibrated = len(ps) > 15
    for i in range(c, end):
        w = 0.0 if i == c else (time[i] - time[c]) / (time[end] - time[c])
        if i == c:
            out["sigma"][i] = _classic_sigma(ps[:15, :15], (vel[i], lla[i]), form)
            if calibrated:
                out["calibration_sigma"][i] = np.sqrt(np.maximum(np.diag(ps)[15:], 0.0))
        else:
            sigma = np.asarray(forward["sigma"][i], dtype=float)
            if calibrated:
                sigma = np.concatenate([sigma, forward["calibration_sigma"][i]])
            smoothed = np.sqrt(np.maximum(sigma**2 + (1 - w) * near + w * far, 0.0))
            out["sigma"][i] = smoothed[:15]
            if calibrated:
                out["calibration_sigma"][i] = smoothed[15:]
        _correct(out, i, (1 - w) * ds + w * ds_end, form)


def _variances(p: np.ndarray, at, form) -> np.ndarray:
    """The classic variances of the covariance ``p`` (15 or 19 states) at the point
    ``at = (velocity, lla)``."""
    v = np.diag(p).copy()
    v[:15] = _classic_sigma(p[:15, :15], at, form, squared=True)
    return v


def _classic_sigma(p: np.ndarray, at, form, squared: bool = False) -> np.ndarray:
    """σ (variances: ``squared``) in the classic coordinates of ``p`` in those of
    ``form = (invariant, SE₂(3)'s anchor or None)`` at ``at = (velocity, lla)``:
    ``dv = dV + [v x] psi`` (and ``dp = dP + [p x] psi``)."""
    invariant, anchor = form
    if invariant:
        disp = None if anchor is None else displacement(at[1], anchor)
        t = t_matrix(at[0], disp, 15, +1.0)
        p = t @ p @ t.T
    return np.diag(p).copy() if squared else np.sqrt(np.maximum(np.diag(p), 0.0))


def _correct(out: dict, i: int, dx: np.ndarray, form) -> None:
    """The filter's feedback of ``dx`` applied to the solution at epoch ``i``."""
    (invariant, anchor), lla, v = form, out["lla"][i], out["vel"][i]
    c = dcm_from_euler(*out["rpy"][i])
    rn, re = radii(lla[0])
    out["lla"][i] = corrected_lla(lla, dx, anchor) if anchor is not None else lla - np.array(
        [dx[0] / (rn + lla[2]), dx[1] / ((re + lla[2]) * math.cos(lla[0])), -dx[2]]
    )  # fmt: skip
    rot = exp_so3(dx[6:9])
    out["vel"][i] = rot @ (v - dx[3:6]) if invariant else v - dx[3:6]
    out["rpy"][i] = euler_from_dcm(rot @ c)
    out["bias"][i] = out["bias"][i] - dx[9:15]
    if len(dx) > 15:  # the DVL calibration: k -= dk, M = M exp(-[dmu x])
        k, roll, pitch, yaw = out["calibration"][i]
        m_dvl = dcm_from_euler(roll, pitch, yaw).T @ exp_so3(-dx[16:19])
        out["calibration"][i] = np.concatenate([[k - dx[15]], euler_from_dcm(m_dvl.T)])
