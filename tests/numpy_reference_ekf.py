"""An independent, pure-NumPy implementation of the filter in ``docs/reference/filter.md``.

It shares no code with the Rust core: dense 15x15 matrices (19x19 with the DVL
calibration states, 22x22 with the DVL's correlated error: ``numpy_reference_dvl.py``),
``Phi = I + F dt`` built as a full matrix, ``P = Phi P Phi^T + Qd``, the Joseph update
with full matrices. It is slow and plain on purpose; the test suite
runs both filters on the same arrays.
Frames: NED navigation, FRD body; positions [lat rad, lon rad, h m].
"""

from __future__ import annotations

import math

import numpy as np

A = 6378137.0
F_FLAT = 1.0 / 298.257223563
E2 = F_FLAT * (2.0 - F_FLAT)
B = A * (1.0 - F_FLAT)
OMEGA = 7.292115e-5
GM = 3.986004418e14
GAMMA_E = 9.7803253359
GAMMA_P = 9.8321849378


def radii(lat: float) -> tuple[float, float]:
    """Meridian and prime-vertical radii of curvature [m]."""
    d = 1.0 - E2 * math.sin(lat) ** 2
    return A * (1.0 - E2) / d**1.5, A / math.sqrt(d)


def gravity(lat: float, h: float) -> float:
    """WGS-84 normal gravity with the second-order height correction [m/s²]."""
    s2 = math.sin(lat) ** 2
    k = (1.0 - F_FLAT) * GAMMA_P / GAMMA_E - 1.0
    g0 = GAMMA_E * (1.0 + k * s2) / math.sqrt(1.0 - E2 * s2)
    m = OMEGA**2 * A**2 * B / GM
    return g0 * (1.0 - 2.0 * h / A * (1.0 + F_FLAT + m - 2.0 * F_FLAT * s2) + 3.0 * h**2 / A**2)


def _wrap(d: float) -> float:
    """An angle difference [rad] wrapped into (−π, π], as given within it."""
    return d if -math.pi < d <= math.pi else math.pi - (math.pi - d) % (2 * math.pi)


def _lon_difference(lon: float, lon_hat: float) -> float:
    """``lon - lon_hat`` [rad] wrapped into (−π, π] (longitude is periodic), as given
    within it."""
    return _wrap(lon - lon_hat)


def skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def exp_so3(rv: np.ndarray) -> np.ndarray:
    """Rodrigues' formula."""
    t = float(np.linalg.norm(rv))
    k = skew(rv)
    if t < 1e-12:
        return np.eye(3) + k + 0.5 * k @ k
    return np.eye(3) + math.sin(t) / t * k + (1.0 - math.cos(t)) / t**2 * k @ k


def dcm_from_euler(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """C_b^n = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return rz @ ry @ rx


def euler_from_dcm(c: np.ndarray) -> np.ndarray:
    return np.array(
        [math.atan2(c[2, 1], c[2, 2]), math.asin(-c[2, 0]), math.atan2(c[1, 0], c[0, 0])]
    )


def rates(lla: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Earth rate, transport rate [rad/s] and gravity [m/s²], NED."""
    lat, h = lla[0], lla[2]
    rn, re = radii(lat)
    w_ie = OMEGA * np.array([math.cos(lat), 0.0, -math.sin(lat)])
    w_en = np.array([v[1] / (re + h), -v[0] / (rn + h), -v[1] * math.tan(lat) / (re + h)])
    return w_ie, w_en, np.array([0.0, 0.0, gravity(lat, h)])


def strapdown_step(lla, v, c, f, w, dt):
    """One step of docs/reference/filter.md "Strapdown step"."""
    w_ie, w_en, g = rates(lla, v)
    w_in = w_ie + w_en
    c_mid = exp_so3(-w_in * dt / 2) @ c @ exp_so3(w * dt / 2)
    c_new = exp_so3(-w_in * dt) @ c @ exp_so3(w * dt)
    v_new = v + c_mid @ f * dt + (g - np.cross(2 * w_ie + w_en, v)) * dt
    h_new = lla[2] - (v[2] + v_new[2]) * dt / 2
    h_bar = (lla[2] + h_new) / 2
    rn, _ = radii(lla[0])
    lat_new = lla[0] + (v[0] + v_new[0]) * dt / (2 * (rn + h_bar))
    lat_bar = (lla[0] + lat_new) / 2
    _, re = radii(lat_bar)
    lon_new = lla[1] + (v[1] + v_new[1]) * dt / (2 * (re + h_bar) * math.cos(lat_bar))
    return np.array([lat_new, lon_new, h_new]), v_new, c_new


def error_dynamics(lla, v, c, f_ned, invariant):
    """F (15×15) and Γ (15×12, noise ``[accel, gyro, accel bias, gyro bias]``) at the
    state ``lla, v, c`` with the NED specific force ``f_ned`` (docs/reference/filter.md)."""
    w_ie, w_en, g = rates(lla, v)
    rn, re = radii(lla[0])
    big_r = math.sqrt(rn * re) + lla[2]
    fm = np.zeros((15, 15))
    fm[0:3, 0:3] = -skew(w_en)
    fm[0:3, 3:6] = np.eye(3)
    fm[3:6, 0:3] = g[2] / big_r * np.diag([-1.0, -1.0, 2.0])
    fm[3:6, 3:6] = -skew(2 * w_ie + w_en)
    fm[3:6, 6:9] = skew(f_ned)
    fm[3:6, 9:12] = -c
    fm[6:9, 6:9] = -skew(w_ie + w_en)
    fm[6:9, 12:15] = c
    gam = np.zeros((15, 12))
    gam[3:6, 0:3] = c
    gam[6:9, 3:6] = -c
    if invariant:  # docs/reference/filter.md, "The invariant formulation"
        fm[0:3, 6:9] = skew(v)
        fm[3:6, 6:9] = -skew(g) - skew(v) @ skew(w_ie)
        fm[3:6, 12:15] = -skew(v) @ c
        gam[3:6, 3:6] = skew(v) @ c
    gam[9:12, 6:9] = np.eye(3)
    gam[12:15, 9:12] = np.eye(3)
    return fm, gam


# Measurement models of docs/reference/aiding.md, "Lever arms and heading": each predicted
# measurement h(x) and its H row(s) over the error state (n_x columns, zero past the
# 15). ``c`` is the body-to-NED DCM, ``r`` a lever arm [m, body FRD] from the IMU.


def _arm(r) -> np.ndarray:
    return np.asarray(r, dtype=float)


def position_h_row(axis: int, c: np.ndarray, r, n_x: int = 15) -> np.ndarray:
    """H of the NED component ``axis`` (0 N, 1 E, 2 D) of the point ``p + C r``:
    ``e_axis`` on δp and row ``axis`` of ``[(C r)×]`` on ψ."""
    h = np.zeros(n_x)
    h[axis] = 1.0
    h[6:9] = skew(c @ _arm(r))[axis]
    return h


def depth_prediction(lla: np.ndarray, c: np.ndarray, r=(0.0, 0.0, 0.0)) -> float:
    """The depth [m, positive down] a pressure sensor at ``r`` reads: ``−h + (C r)_D``."""
    return -lla[2] + (c @ _arm(r))[2]


def depth_h_row(c: np.ndarray, r=(0.0, 0.0, 0.0), n_x: int = 15) -> np.ndarray:
    """H of ``depth_prediction``: ``e_D`` on δp, ``[−(Cr)_E, (Cr)_N, 0]`` on ψ."""
    return position_h_row(2, c, r, n_x)


def fix_prediction(lla: np.ndarray, c: np.ndarray, r=(0.0, 0.0, 0.0)) -> np.ndarray:
    """``[lat, lon, h]`` of an antenna at ``r``: the IMU's position moved by ``C r`` NED
    metres with the radii at ``lla`` (the map ``fix_innovation`` inverts; first order in
    |r|/R, 1e-7 m at 1 m)."""
    a = c @ _arm(r)
    rn, re = radii(lla[0])
    return np.array(
        [
            lla[0] + a[0] / (rn + lla[2]),
            lla[1] + a[1] / ((re + lla[2]) * math.cos(lla[0])),
            lla[2] - a[2],
        ]
    )


def fix_innovation(z, lla: np.ndarray, c: np.ndarray, r, axis: int) -> float:
    """``ν_axis`` [m] of a fix ``z = [lat, lon, h]`` of an antenna at ``r`` against the
    estimate ``lla, c``: the fix minus the predicted antenna, NED metres at ``lla``."""
    rn, re = radii(lla[0])
    a = c @ _arm(r)
    if axis == 0:
        return (z[0] - lla[0]) * (rn + lla[2]) - a[0]
    if axis == 1:
        return _lon_difference(z[1], lla[1]) * (re + lla[2]) * math.cos(lla[0]) - a[1]
    return lla[2] - z[2] - a[2]


def heading_prediction(c: np.ndarray) -> float:
    """Yaw [rad] of the body from true north (ZYX, as ``euler_from_dcm``)."""
    return math.atan2(c[1, 0], c[0, 0])


def heading_innovation(z: float, c: np.ndarray) -> float:
    """``wrap(z − ŷ)`` into (−π, π]."""
    return _wrap(z - heading_prediction(c))


def heading_h_row(c: np.ndarray, n_x: int = 15) -> np.ndarray:
    """H of ``heading_prediction`` on ψ, ``[C20 C00/d, C20 C10/d, −1]`` with
    ``d = C00² + C10²`` (either formulation): from ``Ĉ − C = −[ψ×]C``,
    ``δyaw = (C00 δC10 − C10 δC00)/d = −ψ_z + C20 (C00 ψ_x + C10 ψ_y)/d``."""
    d = c[0, 0] ** 2 + c[1, 0] ** 2
    h = np.zeros(n_x)
    h[6:9] = [c[2, 0] * c[0, 0] / d, c[2, 0] * c[1, 0] / d, -1.0]
    return h


def nav_velocity_prediction(v: np.ndarray, c: np.ndarray, w: np.ndarray, r) -> np.ndarray:
    """NED velocity [m/s] of the point ``r`` with the body rate ``w`` (corrected gyro):
    ``v + C (w × r)``; ``v`` itself (a copy) when ``r`` is zero."""
    r = _arm(r)
    return v + c @ np.cross(w, r) if np.any(r != 0.0) else v.copy()


def nav_velocity_h(v: np.ndarray, c: np.ndarray, w: np.ndarray, r, invariant: bool) -> np.ndarray:
    """H (3×15) of ``nav_velocity_prediction``: ``I`` on δv (δV), on ψ
    ``[(C (w×r))×]`` (+ ``[v×]`` invariant), ``C [r×]`` on δb_g; the terms of ``r``
    only when it is not zero."""
    r = _arm(r)
    h = np.zeros((3, 15))
    h[:, 3:6] = np.eye(3)
    h[:, 6:9] = skew(v) if invariant else 0.0
    if np.any(r != 0.0):
        h[:, 6:9] += skew(c @ np.cross(w, r))
        h[:, 12:15] = c @ skew(r)
    return h


def run_reference_filter(
    imu,
    imu_time,
    dvl,
    dvl_time,
    t0,
    lla0,
    vel0,
    rpy0,
    *,
    q,
    accel_bias_psd,
    gyro_bias_psd,
    dvl_variance,
    p0_sigma,
    imu_dt,
    lever_arm=(0.0, 0.0, 0.0),
    aiding="body",
    calibration=None,
    dvl_bias=None,
    formulation="classic",
    covariance_step=0.0,
    log=None,
    depth=(),
    depth_time=(),
    depth_sigma=None,
    fix=(),
    fix_time=(),
    fix_sigma=(),
    depth_lever_arm=(0.0, 0.0, 0.0),
    fix_lever_arm=(0.0, 0.0, 0.0),
    heading=(),
    heading_time=(),
    heading_sigma=None,
    anchor=None,
    heading_second_order=False,
):
    """Run the filter; returns dict of time, lla, vel, rpy, bias, sigma (n+1 rows) and
    innovation, nis (one row per DVL measurement applied, in order).

    ``calibration``: None, or ``(scale_sigma, misalignment_sigma (3,), scale_psd,
    misalignment_psd)`` for the DVL scale-factor and misalignment states 15..19; the
    output then also has ``calibration`` (k, roll, pitch, yaw of the DVL in the body)
    and ``calibration_sigma`` per epoch, ``sigma`` keeping the first 15.
    ``dvl_bias``: None, or ``(sigma (3,), tau)`` for the DVL's correlated velocity
    error (states 19..21; the calibration states then exist, with σ 0 without
    ``calibration``); ``calibration`` then has ``b̂`` in columns 4..6.

    ``formulation``: ``"classic"`` (velocity error ``dv``) or ``"invariant"`` (``dV = dv
    - [v x] psi``): P lives in its coordinates, ``x_inv = T x_classic`` with ``T`` the
    identity but ``-[v x]`` at (velocity, attitude); ``sigma`` is always classic.
    ``"se23"``: ``dV`` and ``dP = dp - [p x] psi``, ``p`` the displacement from
    ``anchor`` (default ``lla0``; ``numpy_reference_se23.py``).

    ``covariance_step`` [s]: P propagated once per interval of that many seconds
    (rounded to whole IMU samples; under 1.5 samples: every sample), with F and Γ at
    the interval's start and the mean NED specific force, ``Phi = I + F T + (F T)²/2``
    and ``P = Phi (P + Q/2) Phiᵀ + Q/2``; closed early before a DVL update and at the
    last sample. Between closes ``sigma`` repeats the last closed covariance.

    ``log``: a list that receives, per epoch, ``(phi, p_prior, p_post, dx, v_prior,
    lla_prior)`` (the transition of the covariance step that closed at the epoch, None
    where none did, the covariance before and after its updates, the sum of the error
    estimates fed back there, the velocity [m/s, NED] and position before them) for the smoother in
    ``numpy_reference_smoother.py``; epoch 0 has no transition (None). Without a
    covariance step every epoch has its step's Φ.

    ``depth`` [m, down] at ``depth_time`` with 1σ ``depth_sigma`` (a scalar or one per
    row) from a sensor at ``depth_lever_arm`` [m, body], and ``fix`` rows ``[lat, lon, h
    (NaN: none)]`` at ``fix_time`` with 1σ rows ``fix_sigma`` [m, N E D] of an antenna
    at ``fix_lever_arm``: after an epoch's DVL rows, each available component a scalar
    update (``H = e_i`` on the position error, ``[(Ĉr)×]`` row i on ψ; Joseph form) fed
    back before the next; then ``heading`` [rad, yaw from true north] at
    ``heading_time`` with 1σ ``heading_sigma`` (scalar or per row), a scalar update each
    (``heading_h_row``). Rows before the run are skipped. The output has ``depth_nis``,
    ``fix_nis`` and ``heading_nis`` (one per row applied). ``lever_arm`` with
    ``aiding="nav"``: ``h = v̂ + Ĉ (ω̂ × r)`` (``nav_velocity_h``).

    ``heading_second_order``: with the second-order heading term
    (``numpy_reference_second_order.py``)."""
    from numpy_reference_second_order import SecondOrder

    from numpy_reference_dvl import DvlErrors
    from numpy_reference_se23 import (
        anchor_metres,
        corrected_lla,
        displacement,
        position_h_psi,
        t_matrix,
        to_se23,
    )

    invariant, se23 = formulation in ("invariant", "se23"), formulation == "se23"
    anchor = np.array(lla0 if anchor is None else anchor, dtype=float)

    def disp_at(lla):
        """``p̂`` in SE₂(3), else None (no position shear)."""
        return displacement(lla, anchor) if se23 else None

    def dynamics(lla, v, c, f_ned):
        fm, gam = error_dynamics(lla, v, c, f_ned, invariant)
        return to_se23(fm, gam, lla, v, c, disp_at(lla)) if se23 else (fm, gam)

    every_sample = covariance_step < 1.5 * imu_dt
    interval = None

    def dvl_transition(phi, dt):
        """``Φ_cc`` (docs: 1 on δk, δμ; ``exp(−Δt/τ)`` on δb) into ``phi``, and the DVL
        error states' noise over ``dt``, added whole after ``Φ P Φᵀ`` (exact for δb)."""
        noise = np.zeros((n_x, n_x))
        if dvl_errors is not None:
            phi_c, noise_c = dvl_errors.transition(dt)
            phi[15:, 15:] = np.diag(phi_c)
            noise[15:, 15:] = np.diag(noise_c)
        return noise

    def close(p, interval):
        """P over the covariance step ``interval``, and the step's Φ."""
        big_t = interval["dt"]
        start_lla, start_v, start_c = interval["nav"]
        fm, gam = dynamics(start_lla, start_v, start_c, interval["force"] / big_t)
        phi = np.eye(n_x)
        phi[:15, :15] += fm * big_t + (fm * big_t) @ (fm * big_t) / 2
        qd = np.zeros((n_x, n_x))
        qd[:15, :15] = gam @ np.diag(interval["q"]) @ gam.T
        noise = dvl_transition(phi, big_t)
        p = phi @ (p + qd / 2) @ phi.T + qd / 2 + noise
        return (p + p.T) / 2, phi

    lla = np.array(lla0, dtype=float)
    v = np.array(vel0, dtype=float)
    c = dcm_from_euler(*rpy0)
    ba = np.zeros(3)
    bg = np.zeros(3)
    dvl_errors = None
    if calibration is not None or dvl_bias is not None:
        dvl_errors = DvlErrors(calibration, dvl_bias)
        if aiding != "body":
            raise ValueError("the DVL error states lie in its own axes: aiding='body' only")
    n_x = 15 if dvl_errors is None else 15 + dvl_errors.n
    p0 = np.asarray(p0_sigma, dtype=float) ** 2
    if dvl_errors is not None:
        p0 = np.concatenate([p0, dvl_errors.p0()])
    p = np.diag(p0)
    if invariant:
        t0_ = t_matrix(np.asarray(vel0, dtype=float), disp_at(lla), n_x)
        p = t0_ @ p @ t0_.T
    r_arm = np.asarray(lever_arm, dtype=float)
    rmat = np.diag(dvl_variance)
    q = np.asarray(q, dtype=float)
    keys = ("time", "lla", "vel", "rpy", "bias", "sigma", "innovation", "nis")
    extra = ("calibration", "calibration_sigma", "depth_nis", "fix_nis", "heading_nis")
    out = {k: [] for k in (*keys, *extra)}

    def feed(dx):
        """The filter's feedback of the error estimate ``dx``."""
        nonlocal lla, v, c, ba, bg
        rn, re = radii(lla[0])
        lla = corrected_lla(lla, dx, anchor) if se23 else lla - np.array(
            [dx[0] / (rn + lla[2]), dx[1] / ((re + lla[2]) * math.cos(lla[0])), -dx[2]]
        )  # fmt: skip
        # invariant: v = C Ĉᵀ (v̂ − δV), with C = Exp(ψ) Ĉ (exact; first order δV + [v̂×]ψ)
        v = exp_so3(dx[6:9]) @ (v - dx[3:6]) if invariant else v - dx[3:6]
        c = exp_so3(dx[6:9]) @ c
        ba = ba - dx[9:12]
        bg = bg - dx[12:15]
        if dvl_errors is not None:
            dvl_errors.feed(dx[15:])

    def scalar(h_row, nu, r):
        """A scalar update with the H row ``h_row`` (n_x), innovation ``nu`` and
        variance ``r``; its dx and NIS. With ``h_row = e_i`` the numbers are those of
        ``P[:, i]`` and ``P[i, i]`` exactly (the products with zeros add nothing)."""
        nonlocal p
        ph = p @ h_row
        s_i = h_row @ ph + r
        gain = ph / s_i
        ikh = np.eye(n_x) - np.outer(gain, h_row)
        p = ikh @ p @ ikh.T + r * np.outer(gain, gain)
        p = (p + p.T) / 2
        if second is not None:
            second.update(ikh)
        dx = -gain * nu
        feed(dx)
        return dx, nu * nu / s_i

    def per_row(sigma, i):
        """Row i's σ of a scalar or per-row ``sigma``."""
        return sigma if np.ndim(sigma) == 0 else sigma[i]

    def aiding_rows(t, dt, first):
        """The depth readings, fixes and headings due at the epoch of time t, in that
        order; their dx summed."""
        nonlocal jd, jf, jh
        total = np.zeros(n_x)
        while jd < len(depth) and depth_time[jd] <= t + dt / 2:
            if depth_time[jd] >= first:
                nu = depth[jd] - depth_prediction(lla, c, depth_arm)
                h_row = depth_h_row(c, depth_arm, n_x)
                if se23:
                    h_row[6:9] += position_h_psi(disp_at(lla), 2)
                dx, nis = scalar(h_row, nu, per_row(depth_sigma, jd) ** 2)
                total += dx
                out["depth_nis"].append(nis)
            jd += 1
        while jf < len(fix) and fix_time[jf] <= t + dt / 2:
            if fix_time[jf] >= first:
                z, sig, nis = fix[jf], fix_sigma[jf], 0.0
                for axis in range(2 if math.isnan(z[2]) else 3):
                    # re-linearized at the estimate the last component corrected
                    nu = fix_innovation(z, lla, c, fix_arm, axis)
                    h_row = position_h_row(axis, c, fix_arm, n_x)
                    k = anchor_metres(lla, anchor, axis) if se23 else 1.0
                    if se23:  # the reading in the anchor's metres, those of δP
                        nu, h_row[6:9] = k * nu, k * h_row[6:9]
                        h_row[6:9] += position_h_psi(disp_at(lla), axis)
                    dx, one = scalar(h_row, nu, (k * sig[axis]) ** 2)
                    total += dx
                    nis += one
                out["fix_nis"].append(nis)
            jf += 1
        while jh < len(heading) and heading_time[jh] <= t + dt / 2:
            if heading_time[jh] >= first:
                nu = heading_innovation(heading[jh], c)
                dx, nis = scalar(heading_h_row(c, n_x), nu, per_row(heading_sigma, jh) ** 2)
                total += dx
                out["heading_nis"].append(nis)
            jh += 1
        return total

    jd = jf = jh = 0
    depth_arm, fix_arm = _arm(depth_lever_arm), _arm(fix_lever_arm)
    second = SecondOrder(n_x) if heading_second_order else None

    def sigmas():
        """The 15 states' σ (classic coordinates) and the calibration's, from P now."""
        t_inv = t_matrix(v, disp_at(lla), n_x, +1.0)
        classic = t_inv @ p @ t_inv.T if invariant else p
        return np.sqrt(np.diag(classic))[:15], np.sqrt(np.diag(p))[15:]

    def record(t):
        out["time"].append(t)
        out["lla"].append(lla.copy())
        out["vel"].append(v.copy())
        out["rpy"].append(euler_from_dcm(c))
        out["bias"].append(np.concatenate([ba, bg]))
        sigma, cal_sigma = sigmas()
        out["sigma"].append(sigma)
        if dvl_errors is not None:
            out["calibration"].append(dvl_errors.reported())
            out["calibration_sigma"].append(cal_sigma)

    def interpolate_stale(closed):
        """Inside a covariance step P stands at its start: once it closes (σ ``closed``
        before the epoch's updates), the variances of the epochs since the last
        up-to-date one are interpolated linearly in time (docs/reference/filter.md)."""
        nonlocal last_current
        now = len(out["time"]) - 1
        if closed is not None:
            t_a, t_b = out["time"][last_current], out["time"][now]
            for e in pending:
                w = (out["time"][e] - t_a) / (t_b - t_a)
                for key, to in (("sigma", closed[0]), ("calibration_sigma", closed[1])):
                    if out[key]:
                        frm = out[key][last_current]
                        out[key][e] = np.sqrt(frm**2 + w * (to**2 - frm**2))
            pending.clear()
        if interval is None:
            last_current = now
            pending.clear()
        else:
            pending.append(now)

    last_current, pending = 0, []

    record(t0)
    if log is not None:
        log.append((None, p.copy(), p.copy(), np.zeros(n_x), v.copy(), lla.copy()))
    t_prev = t0
    first = t0 - (imu_time[0] - t0) / 2  # readings stamped before it are skipped
    j = 0
    w_hat = np.zeros(3)
    for k in range(len(imu)):
        t = imu_time[k]
        dt = t - t_prev
        f_hat = imu[k, :3] - ba
        w_hat = imu[k, 3:] - bg
        phi = None
        if every_sample:
            fm, gam = dynamics(lla, v, c, c @ f_hat)
            qc = np.diag(np.concatenate([q * imu_dt, [accel_bias_psd] * 3, [gyro_bias_psd] * 3]))
            phi = np.eye(n_x)
            phi[:15, :15] += fm * dt
            qd = np.zeros((n_x, n_x))
            qd[:15, :15] = gam @ qc @ gam.T * dt
            noise = dvl_transition(phi, dt)
            heading_variance = p[8, 8] if second is None else second.linear_heading_variance(p)
            p = phi @ p @ phi.T + qd + noise
            p = (p + p.T) / 2
            if second is not None:
                second.moved(v, dt)
                p = second.grow(p, phi, heading_variance)
        else:  # docs/reference/filter.md, "Covariance step"
            if interval is None:
                interval = {"nav": (lla, v, c), "dt": 0.0, "force": np.zeros(3), "q": 0.0}
            interval["dt"] += dt
            interval["force"] = interval["force"] + c @ f_hat * dt
            walks = np.array([accel_bias_psd] * 3 + [gyro_bias_psd] * 3) * dt
            interval["q"] = interval["q"] + np.concatenate([q * imu_dt * dt, walks])
            if second is not None:
                second.moved(v, dt)
        lla, v, c = strapdown_step(lla, v, c, f_hat, w_hat, dt)
        # A reading stamped before the run is skipped (aiding_rows) and closes no step.
        updating = (j < len(dvl_time) and dvl_time[j] <= t + dt / 2) or any(
            first <= times[i] <= t + dt / 2
            for start, times in ((jd, depth_time), (jf, fix_time), (jh, heading_time))
            for i in range(start, int(np.searchsorted(times, t + dt / 2, side="right")))
        )
        closed = None
        if interval is not None and (
            interval["dt"] + imu_dt / 2 >= covariance_step or updating or k == len(imu) - 1
        ):
            heading_variance = p[8, 8] if second is None else second.linear_heading_variance(p)
            p, phi = close(p, interval)
            if second is not None:
                p = second.grow(p, phi, heading_variance)
            interval = None
            closed = sigmas()
        p_prior, dx_sum, v_prior, lla_prior = p.copy(), np.zeros(n_x), v.copy(), lla.copy()
        while j < len(dvl) and dvl_time[j] <= t + dt / 2:
            h = np.zeros((3, 15))
            if aiding == "body":
                pred = c.T @ v + np.cross(w_hat, r_arm)
                h[:, 3:6] = c.T
                h[:, 6:9] = 0.0 if invariant else -c.T @ skew(v)
                h[:, 12:15] = skew(r_arm)
            else:  # the terms of the lever arm only when it is not zero
                pred = nav_velocity_prediction(v, c, w_hat, r_arm)
                h = nav_velocity_h(v, c, w_hat, r_arm, invariant)
            # The gyro's white noise n on ω̂ × r: the prediction's error [r×] n.
            arm = skew(r_arm) if aiding == "body" else c @ skew(r_arm)
            r_j = rmat + arm @ np.diag(q[3:] * imu_dt / dt) @ arm.T
            if dvl_errors is not None:  # z = (1 + k) M v_b + b
                pred, h = dvl_errors.measurement(pred, h)
                r_j = rmat + dvl_errors.noise_as_read(r_j - rmat)
            nu = dvl[j] - pred
            s = h @ p @ h.T + r_j
            gain = p @ h.T @ np.linalg.inv(s)
            ikh = np.eye(n_x) - gain @ h
            p = ikh @ p @ ikh.T + gain @ r_j @ gain.T
            p = (p + p.T) / 2
            if second is not None:
                second.update(ikh)
            dx = -gain @ nu
            feed(dx)
            dx_sum += dx
            out["innovation"].append(nu)
            out["nis"].append(float(nu @ np.linalg.solve(s, nu)))
            j += 1
        dx_sum += aiding_rows(t, dt, first)
        record(t)
        interpolate_stale(closed)
        if log is not None:
            log.append((phi, p_prior, p.copy(), dx_sum, v_prior, lla_prior))
        t_prev = t
    return {k: np.array(val) for k, val in out.items()}
