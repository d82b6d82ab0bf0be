"""An independent, pure-NumPy Rauch–Tung–Striebel smoother over the reference filter.

The plain fixed-interval recursion at every IMU step, dense matrices throughout, with
the closed-loop filter's resets: after each epoch's updates the forward error estimate
is zero, and the error of the solution before them is the one after plus the estimate
fed back (``docs/filter.md``, "The RTS smoother"). It shares no code with the Rust core
(whose backward pass chains the steps between updates instead) and is slow on purpose.
"""

from __future__ import annotations

import math

import numpy as np

from numpy_reference_ekf import dcm_from_euler, euler_from_dcm, exp_so3, radii, skew


def rts_smooth(forward: dict, log: list, formulation: str = "classic") -> dict:
    """The smoothed ``lla``, ``vel``, ``rpy``, ``bias`` and classic ``sigma`` at every
    epoch (with the DVL calibration states, ``calibration`` and ``calibration_sigma``
    too: all 19 states smoothed), from the reference filter's output ``forward`` and
    its ``log``.

    The recursion runs from close to close of the covariance (every epoch without a
    covariance step); between two closes the smoothed error of the forward solution is
    interpolated linearly in time, from the one after the earlier close's updates to the
    one before the later close's, and the smoothed covariance linearly in time between
    the two closes' (the same before and after an epoch's updates), σ read from it at
    each epoch's forward velocity."""
    invariant = formulation == "invariant"
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
    _fill(out, forward, later, later + 1, ds, ds, ps, ps, time, invariant)
    for c in reversed(closes[:-1]):
        phi, p_prior, _, dx = log[later]
        p_post = log[c][2]
        ds_prior = ds + dx  # the error before the later close's updates
        gain = p_post @ phi.T @ np.linalg.inv(p_prior)
        ds = gain @ ds_prior
        ps_end = ps
        ps = p_post + gain @ (ps - p_prior) @ gain.T
        ps = (ps + ps.T) / 2
        _fill(out, forward, c, later, ds, ds_prior, ps, ps_end, time, invariant)
        later = c
    return out


def _fill(out, forward, c, end, ds, ds_end, ps, ps_end, time, invariant) -> None:
    """The smoothed error and covariance at the close ``c`` and, interpolated linearly in
    time towards ``ds_end`` and ``ps_end`` at the close ``end``, at the epochs between;
    σ from the covariance at each epoch's forward velocity."""
    for i in range(c, end):
        w = 0.0 if i == c else (time[i] - time[c]) / (time[end] - time[c])
        p = ps if i == c else (1 - w) * ps + w * ps_end
        out["sigma"][i] = _classic_sigma(p[:15, :15], forward["vel"][i], invariant)
        if len(p) > 15:
            out["calibration_sigma"][i] = np.sqrt(np.maximum(np.diag(p)[15:], 0.0))
        _correct(out, i, (1 - w) * ds + w * ds_end, invariant)


def _classic_sigma(p: np.ndarray, vel: np.ndarray, invariant: bool) -> np.ndarray:
    if invariant:  # dv = dV + [v x] psi
        t = np.eye(15)
        t[3:6, 6:9] = skew(vel)
        p = t @ p @ t.T
    return np.sqrt(np.maximum(np.diag(p), 0.0))


def _correct(out: dict, i: int, dx: np.ndarray, invariant: bool) -> None:
    """The filter's feedback of ``dx`` applied to the solution at epoch ``i``."""
    lla, v = out["lla"][i], out["vel"][i]
    c = dcm_from_euler(*out["rpy"][i])
    rn, re = radii(lla[0])
    out["lla"][i] = lla - np.array(
        [dx[0] / (rn + lla[2]), dx[1] / ((re + lla[2]) * math.cos(lla[0])), -dx[2]]
    )
    rot = exp_so3(dx[6:9])
    out["vel"][i] = rot @ (v - dx[3:6]) if invariant else v - dx[3:6]
    out["rpy"][i] = euler_from_dcm(rot @ c)
    out["bias"][i] = out["bias"][i] - dx[9:15]
    if len(dx) > 15:  # the DVL calibration: k -= dk, M = M exp(-[dmu x])
        k, roll, pitch, yaw = out["calibration"][i]
        m_dvl = dcm_from_euler(roll, pitch, yaw).T @ exp_so3(-dx[16:19])
        out["calibration"][i] = np.concatenate([[k - dx[15]], euler_from_dcm(m_dvl.T)])
