"""The initial state of a pass from the data alone (or given), each part with the 1σ its
method earns: :func:`initial_state` returns a
:class:`~pronet.recorded.solution.InitialState` whose ``methods`` say what was used.

Frames and units as everywhere in pronet: body FRD, NED, ``C = Rz(yaw) Ry(pitch) Rx(roll)``
body to NED; positions ``[lat, lon (rad), h (m, up)]``; lever arms [m, body FRD] from
the IMU; the 1σ in the filter's error coordinates (position NED [m], velocity [m/s],
attitude ψ about N, E, D [rad]). The parts, in the order they are found (each one
``given`` wins over the data for the parts it gives, with its σ or the defaults below):

- **roll and pitch** (``attitude``): levelled over a still interval (given, or detected
  as in :mod:`pronet.recorded.levelling`; a roll beyond ±90° is refused: an IMU in FLU).
  The IMU cannot tell steady motion from rest: where the DVL reads a median speed over
  the interval beyond 0.2 m/s and its noise, it is levelled over as "steady" (an
  unaccelerated vehicle's specific force is gravity's too), but the velocity and the
  position are found as when moving, the DVL's and the fix nearest t0. At rest ``f = −Cᵀ
  g^n``, so the mean specific force gives ``roll = atan2(−f̄_y, −f̄_z)``, ``pitch =
  atan2(f̄_x, √(f̄_y² + f̄_z²))``; a bias ``σ_ba`` (the accelerometer bias 1σ of
  ``base_p0``) and the mean's noise ``σ_f̄``
  (:func:`~pronet.recorded.levelling.mean_noise`) tilt it by ``σ_t = √(σ_ba² +
  σ_f̄²)/g`` (``σ_pitch = σ_t``, ``σ_roll = σ_t / cos θ``, θ the
  pitch). Or an
  AHRS orientation stream's readings around t0 (wrapped mean, σ the stream's); of the
  two, the one of smaller σ.
- **heading**: a heading stream's readings around t0 (wrapped mean, σ the stream's, not
  divided by their number: a compass's error is slow), an AHRS orientation's yaw, or
  gyrocompassing while still: the mean body rate turned level,
  ``ω^L = Ry(pitch) Rx(roll) ω̄ = [Ω cos φ cos y, −Ω cos φ sin y, −Ω sin φ]`` (y the
  heading), gives ``y = atan2(−ω^L_y, ω^L_x)`` with
  ``σ_y² = (σ_bg² + σ_ω̄²)/(Ω cos φ)² + (σ_t tan φ)²`` (Ω = 7.292115e-5 rad/s, φ the
  latitude of the position, ``σ_bg`` the gyro bias 1σ of ``base_p0``): it works only
  while ``σ_bg ≪ Ω cos φ`` (a navigation-grade gyro) and is refused beyond
  ``gyrocompass_max_sigma``. Of the sources there are, the one of smallest σ. Read away
  from rest, a reading Δt from t0 adds ``|ω| Δt`` to its σ.
- **velocity**: zero while still (σ ``still_velocity_sigma``), else the DVL reading
  nearest t0 rotated to NED, ``v = C (z − ω × r_dvl)``, with
  ``cov v = C diag(σ_dvl²) Cᵀ + [v×] diag(σ_ψ²) [v×]ᵀ`` (the attitude's error turns
  the velocity: the heading's σ times the speed) plus ``(|a| Δt)²`` for a reading Δt
  from t0 (``a = C f + g^n``).
- **position** (``position``): the fixes while still (up to ``max_fixes``, those
  nearest t0), else the fix nearest t0, each moved from the antenna to the IMU,
  ``p_imu = p_fix − C r_fix + v (t0 − t_fix)`` (NED metres about the first,
  :func:`pronet.local_ned` and :func:`pronet.lla_from_ned`), averaged: ``σ² = Σ σ_i²/k²``
  (independent fixes, as the filter takes them), plus the lever arm turned by the
  attitude error, ``diag([a×] diag(σ_ψ²) [a×]ᵀ)`` with ``a = C r``, plus ``(σ_v Δt)²``.
- **height** (``depth``): from the pressure depth when there is one, the IMU's depth
  being the sensor's less the arm's down component, ``h = −(d − (C r_depth)_D)``
  (readings chosen and averaged as the fixes', ``σ² = Σ σ_i²/k² + a_E² σ_ψN² +
  a_N² σ_ψE²``); else the fixes' height; a horizontal fix (NaN height) without a depth
  leaves the height to ``given``.
- the biases' 1σ are ``base_p0``'s (the vehicle's tuning).

Readings "around t0" are those within ``reading_window`` of it (while still: in the
still interval up to t0). ``t0``, unless given, is the end of the still interval, else
the first IMU time at which every stream a part needs has a reading (the first IMU
sample when nothing is needed). A part that cannot be found raises ``ValueError`` with
one line naming what to provide.

Sources: P. D. Groves, *Principles of GNSS, Inertial, and Multisensor Integrated
Navigation Systems*, 2nd ed., Artech House 2013, ch. 5.6 (initialisation: levelling and
gyrocompassing, their accuracy) and ch. 14.2 (the integrated filter's states and
their initial uncertainties); D. H. Titterton
and J. L. Weston, *Strapdown Inertial Navigation Technology*, 2nd ed., IEE 2004, ch. 10
(alignment on a stationary base).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet import _core
from pronet._util.plausibility import STANDARD_GRAVITY as G0
from pronet.navigation import lla_from_ned, local_ned
from pronet.recorded.alignment import dcm_from_euler
from pronet.recorded.initialinputs import (
    GIVEN_SIGMA,
    GivenState,
    InitialSettings,
    Inputs,
    Stream,
    prepare,
)
from pronet.recorded.levelling import EARTH_RATE, gyrocompass, level, psi_sigma, wrapped_mean
from pronet.recorded.solution import InitialState

F64 = NDArray[np.float64]

__all__ = ["GIVEN_SIGMA", "GivenState", "InitialSettings", "Stream", "initial_state"]


def _skew(a: F64) -> F64:
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _turned(a: F64, psi: F64) -> F64:
    """The variance ``(3,)`` of ``[a×] ψ``: a vector of the body turned by the attitude
    error (``(Ĉ − C) r = [a×] ψ`` with ``a = C r``)."""
    s = _skew(a)
    return np.diag(s @ np.diag(psi**2) @ s.T)


def _read_angle(p: Inputs, name: str, col: int) -> tuple[float, float, int] | None:
    """The wrapped mean of column ``col`` of stream ``name`` around t0, its 1σ (the
    stream's, plus ``|ω| Δt`` away from rest) and the readings' count, or None."""
    idx = p.around(name)
    if not len(idx):
        return None
    r = p.streams[name]
    sigma = math.sqrt(float(np.mean(r.sigma[idx, col] ** 2)))
    lag = float(np.max(np.abs(r.time[idx] - p.t0)))
    return wrapped_mean(r.values[idx, col]), math.hypot(sigma, p.rate() * lag), len(idx)


def _read(label: str, n: int) -> str:
    """The method of an angle read from ``n`` readings of a stream named ``label``."""
    return f"{label} (1 reading)" if n == 1 else f"{label} ({n} readings, wrapped mean)"


def _resting(p: Inputs) -> str:
    """How the vehicle spent the still interval: still, or steady by the DVL's speed."""
    return "still" if p.moving is None else f"steady (the DVL reads {p.moving:.3g} m/s)"


def _attitude(p: Inputs) -> tuple[F64, F64, str]:
    """Roll and pitch ``(2,)`` [rad], their 1σ ``(2,)`` and the method."""
    if p.given.rpy is not None:
        note = f" ({p.no_still})" if p.interval is None else ""
        return p.given.rpy[:2], p.given.rpy_sigma[:2], "given" + note
    found: list[tuple[F64, F64, str]] = []
    if p.interval is not None:
        a, b = p.interval
        roll, pitch, tilt, _ = level(p.still_samples(), float(p.p0[9:12].max()))
        # Upside down: f̄_z well above 0 (−g at rest, level), not noise about 0 at a pitch
        # near ±90°.
        if abs(roll) > 0.5 * math.pi and float(np.mean(p.still_samples()[:, 2])) > 0.5 * G0:
            raise ValueError(
                f"initial roll and pitch: levelled over {a:.2f}–{b:.2f} s, the vehicle is upside "
                f"down (roll {math.degrees(roll):.1f}°): the IMU's z axis points up (an IMU in "
                "FLU, or one mounted upside down); pronet takes body FRD (x forward, y "
                "starboard, z down): rotate the samples"
            )
        sigma = np.array([tilt / math.cos(pitch), tilt])
        found.append(
            (
                np.array([roll, pitch]),
                sigma,
                f"levelled over {b - a:.1f} s {_resting(p)} ({a:.2f}–{b:.2f} s)",
            )
        )
    angles = [_read_angle(p, "orientation", col) for col in (0, 1)]
    if angles[0] is not None and angles[1] is not None:
        value = np.array([angles[0][0], angles[1][0]])
        sigma = np.array([angles[0][1], angles[1][1]])
        found.append((value, sigma, _read("AHRS orientation", angles[0][2])))
    if not found:
        raise ValueError(
            f"initial roll and pitch: {p.no_still}, {p.absent('orientation', 'AHRS orientation')}"
            " and no given attitude: give a still interval, an AHRS orientation or the initial"
            " roll, pitch and yaw"
        )
    return min(found, key=lambda c: float(c[1].max()))


def _latitude(p: Inputs) -> float | None:
    """The latitude [rad] gyrocompassing needs: the given position's or a fix's."""
    if p.given.lla is not None:
        return float(p.given.lla[0])
    idx = p.pick("fixes")
    return float(p.streams["fixes"].values[idx[0], 0]) if len(idx) else None


def _gyrocompassed(
    p: Inputs, rp: F64, rp_sigma: F64, latitude: float | None
) -> tuple[float, float, str] | str:
    """The heading by gyrocompassing, its 1σ and method, or why it is refused."""
    if p.interval is None:
        return "no still interval to gyrocompass over"
    if latitude is None:
        return "no fix or given position for the latitude gyrocompassing needs"
    a, b = p.interval
    bias = float(p.p0[12:].max())
    tilt = max(float(rp_sigma[0]) * math.cos(rp[1]), float(rp_sigma[1]))
    yaw, sigma = gyrocompass(p.still_samples(), rp[0], rp[1], tilt, latitude, bias)
    limit = p.settings.gyrocompass_max_sigma
    if sigma > limit:
        horizontal = EARTH_RATE * math.cos(latitude)
        where = f"{abs(math.degrees(latitude)):.1f}° {'N' if latitude >= 0 else 'S'}"
        return (
            f"this gyro (bias σ {bias:.1e} rad/s) cannot gyrocompass at {where} (σ {sigma:.2g}"
            f" rad > {limit:g} rad; it needs a bias ≪ Ω cos φ = {horizontal:.1e} rad/s)"
        )
    return (
        yaw,
        sigma,
        (f"gyrocompassed over {b - a:.1f} s {_resting(p)} (σ {math.degrees(sigma):.2f}°)"),
    )


def _heading(p: Inputs, rp: F64, rp_sigma: F64, latitude: float | None) -> tuple[float, float, str]:
    """The heading [rad], its 1σ and the method."""
    g = p.given
    if g.heading is not None:
        return g.heading, g.heading_sigma, "given"
    if g.rpy is not None:
        return float(g.rpy[2]), float(g.rpy_sigma[2]), "given"
    found: list[tuple[float, float, str]] = []
    absent = []
    for name, col, label in (
        ("heading", 0, "heading stream"),
        ("orientation", 2, "AHRS orientation"),
    ):
        read = _read_angle(p, name, col)
        if read is None:
            absent.append(p.absent(name, label))
        else:
            found.append((read[0], read[1], _read(label, read[2])))
    compass = _gyrocompassed(p, rp, rp_sigma, latitude)
    if isinstance(compass, str):
        if not found:
            raise ValueError(
                f"initial heading: {', '.join(absent)} and no given heading; {compass}:"
                " give one of them"
            )
    else:
        found.append(compass)
    return min(found, key=lambda c: c[1])


def _velocity(p: Inputs, c: F64, psi: F64, latitude: float | None) -> tuple[F64, F64, str]:
    """The NED velocity [m/s], its 1σ ``(3,)`` and the method."""
    if p.given.vel is not None:
        return p.given.vel, p.given.vel_sigma, "given"
    if p.at_rest:
        return np.zeros(3), np.full(3, p.settings.still_velocity_sigma), "zero (still)"
    idx = p.pick("dvl")
    if not len(idx):
        raise ValueError(
            f"initial velocity: {p.no_still} at t0 = {p.t0:.2f} s and {p.absent('dvl', 'DVL')}:"
            " give the initial velocity or a still interval"
        )
    d = p.streams["dvl"]
    i = int(idx[0])
    k = int(np.argmin(np.abs(p.time - d.time[i])))
    rate = p.imu[k, 3:]
    v = c @ (d.values[i] - np.cross(rate, p.arms["dvl"]))
    cov = c @ np.diag(d.sigma[i] ** 2) @ c.T
    gravity = _core.normal_gravity(latitude if latitude is not None else math.pi / 4, 0.0)
    accel = float(np.linalg.norm(c @ p.imu[p.k0, :3] + np.array([0.0, 0.0, gravity])))
    lag = abs(float(d.time[i]) - p.t0)
    drift = accel * lag + float(np.linalg.norm(v)) * p.rate() * lag
    sigma = np.sqrt(np.diag(cov) + _turned(v, psi) + drift**2)
    arm = ", lever arm removed" if np.any(p.arms["dvl"]) else ""
    first = "first DVL reading" if i == 0 else "DVL reading nearest t0"
    return v, sigma, f"{first} rotated to NED ({lag:.2f} s from t0{arm})"


@dataclass(frozen=True)
class _Found:
    """A position part found from readings: its value, 1σ and method."""

    value: F64
    sigma: F64
    method: str


def _fixes(
    p: Inputs, c: F64, v: F64, v_sigma: F64, psi: F64
) -> tuple[_Found, _Found | None] | None:
    """Latitude and longitude from the fixes around t0 and, where they have one, the
    height; None without a fix there."""
    idx = p.pick("fixes", p.settings.max_fixes)
    if not len(idx):
        return None
    fx = p.streams["fixes"]
    a = c @ p.arms["fix"]
    origin = np.array([fx.values[idx[0], 0], fx.values[idx[0], 1], 0.0])
    flat = fx.values[idx].copy()
    flat[:, 2] = 0.0
    lag = p.lag(fx.time[idx])
    moved = local_ned(flat, origin) - a + lag[:, None] * v
    horizontal = lla_from_ned(np.array([*moved.mean(axis=0)[:2], 0.0]), origin)[:2]
    k = len(idx)
    spread = (v_sigma * float(np.max(np.abs(lag)))) ** 2
    var = np.sum(fx.sigma[idx] ** 2, axis=0) / k**2 + _turned(a, psi) + spread
    arm = ", moved by the antenna's lever arm" if np.any(p.arms["fix"]) else ""
    if k == 1:
        what = (
            "first fix" if idx[0] == 0 else "fix nearest t0"
        ) + f" ({abs(p.t0 - fx.time[idx[0]]):.2f} s from t0"
        what += f"{arm})"
    else:
        what = (
            f"mean of {k} fixes while still ({fx.time[idx[0]]:.2f}–{fx.time[idx[-1]]:.2f} s{arm})"
        )
    place = _Found(np.asarray(horizontal), np.sqrt(var[:2]), what)
    up = np.isfinite(fx.values[idx, 2])
    if not np.any(up):
        return place, None
    heights = fx.values[idx, 2][up] + a[2] - v[2] * lag[up]
    k_up = int(up.sum())
    var_up = float(np.sum(fx.sigma[idx, 2][up] ** 2)) / k_up**2 + _turned(a, psi)[2] + spread[2]
    return place, _Found(np.array([heights.mean()]), np.array([math.sqrt(var_up)]), "fix height")


def _height(p: Inputs, c: F64, v: F64, v_sigma: F64, psi: F64, fix_height: _Found | None) -> _Found:
    """The IMU's height [m, up], its 1σ and the method."""
    g = p.given
    if g.depth is not None:
        return _Found(np.array([-g.depth]), np.array([g.depth_sigma]), "given")
    if g.lla is not None and np.isfinite(g.lla[2]):
        return _Found(g.lla[2:], g.lla_sigma[2:], "given")
    idx = p.pick("depth", p.settings.max_fixes)
    if len(idx):
        d = p.streams["depth"]
        a = c @ p.arms["depth"]
        lag = p.lag(d.time[idx])
        depth = d.values[idx, 0] + v[2] * lag - a[2]
        k = len(idx)
        var = (
            float(np.sum(d.sigma[idx, 0] ** 2)) / k**2
            + float(_turned(a, psi)[2])
            + (float(v_sigma[2]) * float(np.max(np.abs(lag)))) ** 2
        )
        what = "pressure depth" + (f" (mean of {k} readings)" if k > 1 else "")
        what += ", moved by the sensor's lever arm" if np.any(p.arms["depth"]) else ""
        return _Found(np.array([-depth.mean()]), np.array([math.sqrt(var)]), what)
    if fix_height is not None:
        return fix_height
    why = p.absent("depth", "depth sensor")
    fixes = "no fix with a height around t0" if "fixes" in p.streams else "no fixes"
    raise ValueError(
        f"initial depth: {why}, {fixes} and no given depth or height: give a depth sensor,"
        " fixes with a height or the initial depth"
    )


def initial_state(
    imu_time: ArrayLike,
    imu: ArrayLike,
    base_p0: ArrayLike,
    *,
    fixes: Stream | None = None,
    depth: Stream | None = None,
    heading: Stream | None = None,
    orientation: Stream | None = None,
    dvl: Stream | None = None,
    fix_lever_arm: ArrayLike | None = None,
    depth_lever_arm: ArrayLike | None = None,
    dvl_lever_arm: ArrayLike | None = None,
    given: GivenState | None = None,
    still: tuple[float, float] | Literal["auto", "none"] = "auto",
    t0: float | None = None,
    settings: InitialSettings | None = None,
) -> InitialState:
    """The initial state of a pass from its data (the methods and their 1σ are in the
    module docstring), the parts ``given`` gives winning.

    Args:
        imu_time: ``(n,)`` increasing IMU times [s].
        imu: ``(n, 6)`` samples ``[f (m/s²), ω (rad/s)]``, body FRD.
        base_p0: ``(15,)`` the vehicle tuning's P0 1σ; its bias parts are kept, and its
            accelerometer and gyro bias 1σ set the levelling's and gyrocompassing's.
        fixes: ``(time (f,), lla (f, 3) [rad, rad, m up; NaN height: horizontal], σ (f,
            3) or (3,) N, E, D [m])``.
        depth: ``(time (d,), depth (d,) [m, down], σ (d,) or one [m])``.
        heading: ``(time (h,), yaw from true north (h,) [rad], σ (h,) or one [rad])``.
        orientation: an AHRS's ``(time (o,), rpy (o, 3) [rad], σ (o, 3) or (3,) [rad])``.
        dvl: ``(time (m,), body velocity (m, 3) [m/s] at the DVL, σ (3,) or (m, 3))``;
            NaN rows (no bottom lock) are left out, as in every stream.
        fix_lever_arm: ``(3,)`` the fix receiver from the IMU [m, body FRD] (zero
            when None).
        depth_lever_arm: ``(3,)`` the depth sensor from the IMU, the same way.
        dvl_lever_arm: ``(3,)`` the DVL from the IMU, the same way.
        given: parts given, with their σ.
        still: the still interval ``(t_start, t_end)`` [s], ``"auto"`` (detected, the
            first one) or ``"none"`` (the vehicle never rests).
        t0: the initial time [s] (snapped to the nearest IMU sample); by default the
            end of the still interval, else the first time every needed stream has a
            reading.
        settings: the thresholds (:class:`InitialSettings`).

    Returns:
        The state at t0 of the IMU, its P0 1σ and one line per part on how it was found.

    Raises:
        ValueError: an input unusable (naming it), or a part that cannot be found (one
            line naming what to provide).
    """
    s = InitialSettings() if settings is None else settings
    p = prepare(
        imu_time,
        imu,
        base_p0,
        {
            "fixes": (fixes, 3, 2),
            "depth": (depth, 1, 1),
            "heading": (heading, 1, 1),
            "orientation": (orientation, 3, 3),
            "dvl": (dvl, 3, 3),
        },
        {"fix": fix_lever_arm, "depth": depth_lever_arm, "dvl": dvl_lever_arm},
        given,
        still,
        t0,
        s,
    )
    rp, rp_sigma, attitude = _attitude(p)
    latitude = _latitude(p)
    yaw, yaw_sigma, heading_method = _heading(p, rp, rp_sigma, latitude)
    rpy = np.array([rp[0], rp[1], math.remainder(yaw, 2 * math.pi)])
    psi = psi_sigma(rpy, np.array([rp_sigma[0], rp_sigma[1], yaw_sigma]))
    c = dcm_from_euler(rpy)
    vel, vel_sigma, velocity = _velocity(p, c, psi, latitude)
    found = _fixes(p, c, vel, vel_sigma, psi)
    if p.given.lla is not None:
        place = _Found(p.given.lla[:2], p.given.lla_sigma[:2], "given")
    elif found is not None:
        place = found[0]
    else:
        raise ValueError(
            f"initial position: {p.absent('fixes', 'fix')} and no given position: give"
            " fixes or the initial position"
        )
    height = _height(p, c, vel, vel_sigma, psi, None if found is None else found[1])
    p0 = np.concatenate([place.sigma, height.sigma, vel_sigma, psi, p.p0[9:]])
    methods = {
        "position": place.method,
        "depth": height.method,
        "velocity": velocity,
        "attitude": attitude,
        "heading": heading_method,
    }
    lla = np.array([place.value[0], place.value[1], height.value[0]])
    return InitialState(t0=p.t0, lla=lla, vel=vel, rpy=rpy, p0_sigma=p0, methods=methods)
