"""A simulated BlueROV2-class survey written as the recordings pronet reads, its truth
kept apart: the data that navigating without ground truth is measured on.

The vehicle (:class:`Sensors`, :class:`LeverArms`): a MEMS IMU at 200 Hz (white noise,
a turn-on bias drawn from the ``mems`` grade of :data:`pronet.recorded.vehicle.GRADES`
plus a bias random walk), an AHRS orientation with each IMU row, an A50-class DVL at
8 Hz with bottom-lock losses (runs of missing readings), a Bar30-class pressure sensor
at 10 Hz over a surface pressure that is not the standard atmosphere, USBL or GNSS
position fixes at 1 Hz and a compass heading at 10 Hz. The DVL, the pressure sensor and
the fix antenna each sit away from the IMU and read their own point (DVL ``Cᵀv + ω×r``,
depth ``−h + (C r)_D``, fix ``p + C r``).

The motion (:func:`survey_segments`, built by :func:`pronet.trajectory_from_segments`,
so that the ideal IMU integrates to the truth): still at the surface for levelling, a
dive to ~10 m, a lawnmower of straight legs joined by 180° turns, the ascent, still at
the surface again.

:func:`simulate_mission` returns a :class:`Mission`: the recording's arrays, each on its
own Unix-time stamps, and apart from them the truth (:class:`Truth`, the IMU's point),
the true biases and every parameter. :func:`write_generic` writes the generic CSV
format (no ``gt.csv`` unless asked for, a test's round trip), :func:`write_mission_bag`
a ROS bag (no truth topic unless asked for); both live in ``mission_files`` and are
imported here. :func:`filter_streams`, :func:`run_from_truth` and :func:`score` run
:func:`pronet.run_filter` on it and score the result against the truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from mission_files import (  # noqa: F401 - the files of a mission, with it
    BAG_TOPICS,
    STANDARD_ATMOSPHERE,
    fix_sigma,
    write_generic,
    write_mission_bag,
    write_vehicle_file,
)
from numpy.typing import NDArray

import pronet
from pronet.recorded.alignment import dcm_from_euler
from pronet.recorded.bags import STANDARD_GRAVITY
from pronet.recorded.vehicle import GRADES

F64 = NDArray[np.float64]
_DEG = math.pi / 180.0

#: Unix time [s] of the mission's start (every stamp is this plus seconds into it).
EPOCH = 1_700_000_000.0
#: Seconds still at the surface at the start and (at least) at the end.
STILL = 30.0
#: The survey's turns [rad/s] (180° in 30 s: lanes 2 v / rate apart) and the legs'
#: target length [s]; dive and ascent pitch to 20° at 2°/s.
TURN_RATE = 6.0 * _DEG
LEG = 170.0
DIVE_PITCH, PITCH_RATE = 20.0 * _DEG, 2.0 * _DEG
ACCEL = 0.1  # [m/s²] to and from the survey speed
FIX_KINDS = ("usbl", "surface", "none")

_MEMS = GRADES["mems"]["p0_sigma"]


@dataclass(frozen=True)
class Sensors:
    """The sensors' rates [Hz] and errors (1σ; 0 makes a sensor exact).

    IMU: white noise PSDs ``accel_noise_psd`` [(m/s²)²/Hz] and ``gyro_noise_psd``
    [(rad/s)²/Hz] (the consistency suite's MEMS, :mod:`pronet.experiments.consistency`:
    0.27 m/s/√h, 1.5 °/√h; a per-sample variance of PSD × rate); a turn-on bias
    ``imu_bias`` (6) [m/s², rad/s], or drawn with 1σ ``accel_bias_sigma``,
    ``gyro_bias_sigma`` (the ``mems`` grade's: 1 mg, 0.1 °/s); a bias random walk of
    PSDs ``accel_bias_psd``, ``gyro_bias_psd`` [(m/s²)²/s, (rad/s)²/s] (the suite's
    MEMS). DVL: ``dvl_sigma`` [m/s] per body axis; bottom-lock losses at
    ``dvl_losses_per_minute`` (Poisson), each lasting uniformly ``dvl_loss_seconds``.
    Depth ``depth_sigma`` [m]; fixes ``fix_sigma`` [m] north and east (horizontal
    fixes); compass ``heading_sigma`` [rad], white. AHRS orientation in the IMU rows:
    a first-order Gauss–Markov error of 1σ ``ahrs_sigma`` (roll, pitch, yaw) [rad]
    and correlation time ``ahrs_tau`` [s] (an AHRS's error is slow, not white).
    """

    imu_rate: float = 200.0
    accel_noise_psd: float = 2e-5
    gyro_noise_psd: float = 2e-7
    imu_bias: tuple[float, float, float, float, float, float] | None = None
    accel_bias_sigma: float = _MEMS[9]
    gyro_bias_sigma: float = _MEMS[12]
    accel_bias_psd: float = 1e-9
    gyro_bias_psd: float = 2.35e-12
    dvl_rate: float = 8.0
    dvl_sigma: float = 0.015
    dvl_losses_per_minute: float = 0.5
    dvl_loss_seconds: tuple[float, float] = (2.0, 20.0)
    depth_rate: float = 10.0
    depth_sigma: float = 0.02
    fix_rate: float = 1.0
    fix_sigma: float = 1.5
    heading_rate: float = 10.0
    heading_sigma: float = 1.0 * _DEG
    ahrs_sigma: tuple[float, float, float] = (0.5 * _DEG, 0.5 * _DEG, 1.0 * _DEG)
    ahrs_tau: float = 30.0

    def __post_init__(self) -> None:
        for name in ("imu_rate", "dvl_rate", "depth_rate", "fix_rate", "heading_rate"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name}: must be > 0 Hz, got {getattr(self, name)}")
        if not self.ahrs_tau > 0:
            raise ValueError(f"ahrs_tau: must be > 0 s, got {self.ahrs_tau}")


#: Every sensor exact: no noise, no bias, no bottom-lock loss (the geometry alone).
EXACT = Sensors(
    accel_noise_psd=0.0,
    gyro_noise_psd=0.0,
    imu_bias=(0.0,) * 6,
    accel_bias_psd=0.0,
    gyro_bias_psd=0.0,
    dvl_sigma=0.0,
    dvl_losses_per_minute=0.0,
    depth_sigma=0.0,
    fix_sigma=0.0,
    heading_sigma=0.0,
    ahrs_sigma=(0.0, 0.0, 0.0),
)


@dataclass(frozen=True)
class LeverArms:
    """Each sensor's point from the IMU [m, body FRD]: the DVL, the pressure sensor and
    the fix antenna or USBL transponder (above the IMU: out of the water at the
    surface)."""

    dvl: tuple[float, float, float] = (-0.6, 0.1, 0.3)
    depth: tuple[float, float, float] = (-0.6, 0.2, -0.2)
    fix: tuple[float, float, float] = (-0.4, 0.0, -0.7)


@dataclass(frozen=True)
class Truth:
    """The truth at the IMU's point at every IMU epoch (the start, then each row's end).

    Attributes:
        time: ``(n+1,)`` Unix stamps [s].
        lla: ``(n+1, 3)`` latitude, longitude [rad], height [m, up].
        vel: ``(n+1, 3)`` NED velocity [m/s].
        rpy: ``(n+1, 3)`` roll, pitch, yaw [rad] (ZYX, yaw in (−π, π]).
        imu: ``(n, 6)`` the ideal IMU (row k the mean over ``(time[k], time[k+1]]``).
        bias: ``(n, 6)`` the IMU's true bias in each row [m/s², rad/s].
    """

    time: F64
    lla: F64
    vel: F64
    rpy: F64
    imu: F64
    bias: F64


@dataclass(frozen=True)
class Mission:
    """A simulated recording and, apart, its truth. Stamps are Unix time [s]; angles
    rad; body FRD, NED.

    Attributes:
        imu_time, imu: ``(n,)``, ``(n, 6)`` the IMU rows ``[f, ω]``.
        ahrs_rpy: ``(n, 3)`` the AHRS orientation with each IMU row (magnetic yaw if
            ``magnetic``).
        dvl_time, dvl: ``(m,)``, ``(m, 3)`` body velocity at the DVL, NaN rows where
            the bottom lock was lost (:attr:`dvl_outages`).
        depth_time, pressure: ``(d,)`` the pressure sensor's absolute pressure [Pa]
            (:meth:`depth` converts it).
        fix_time, fix_lla: ``(f,)``, ``(f, 3)`` horizontal fixes of the antenna (height
            NaN); none for ``fixes="none"``.
        heading_time, heading: ``(h,)`` the compass's yaw [rad, in [0, 2π)], magnetic
            if ``magnetic``; none without a heading.
        truth: the truth at the IMU (:class:`Truth`), not part of the recording.
        sensors, lever_arms: the parameters the data were drawn with.
        surface_pressure: the true pressure at the surface [Pa].
        water_density: [kg/m³] of the pressure's conversion (with standard gravity).
        declination: the magnetic declination [rad, east positive]; ``magnetic``
            whether the heading and the AHRS yaw are magnetic (true − declination).
        fixes: ``"usbl"`` (every second), ``"surface"`` (GNSS while the antenna is above
            water) or ``"none"``.
        dvl_outages: ``(k, 2)`` the bottom-lock losses ``[start, end)`` [s].
        still: ``(2, 2)`` the still intervals at the surface ``[start, end]`` [s].
        seed, name: what it was drawn from, and its name.
    """

    imu_time: F64
    imu: F64
    ahrs_rpy: F64
    dvl_time: F64
    dvl: F64
    depth_time: F64
    pressure: F64
    fix_time: F64
    fix_lla: F64
    heading_time: F64
    heading: F64
    truth: Truth
    sensors: Sensors
    lever_arms: LeverArms
    surface_pressure: float
    water_density: float
    declination: float
    magnetic: bool
    fixes: str
    dvl_outages: F64
    still: F64
    seed: int
    name: str = "mission"

    @property
    def dvl_valid(self) -> NDArray[np.bool_]:
        """``(m,)`` whether each DVL row holds a reading (bottom lock)."""
        return np.asarray(~np.isnan(self.dvl).any(axis=1))

    def depth(self, surface_pressure: float | None = None) -> F64:
        """``(d,)`` the pressure as a depth [m, down] over ``surface_pressure`` [Pa]
        (None: the true one; :data:`STANDARD_ATMOSPHERE` is what a logger assumes)."""
        reference = self.surface_pressure if surface_pressure is None else surface_pressure
        return (self.pressure - reference) / (self.water_density * STANDARD_GRAVITY)

    def true_heading(self) -> F64:
        """The compass readings from true north [rad] (declination added if magnetic)."""
        return self.heading + (self.declination if self.magnetic else 0.0)

    @property
    def t0(self) -> float:
        """The stamp of the first IMU row's start (the truth's first row) [s]."""
        return float(self.truth.time[0])


def survey_segments(
    minutes: float, speed: float = 1.0, depth: float = 10.0, surface: float = 0.3
) -> F64:
    """The rows ``[duration s, accel m/s², yaw rate rad/s, pitch rate rad/s]`` of a
    ``minutes`` long survey: :data:`STILL` s still, up to ``speed`` [m/s], a dive from
    ``surface`` to ``depth`` [m] (pitching to 20° at 2°/s), legs of about :data:`LEG` s
    joined by 180° turns alternately right and left, the mirrored ascent, slowing down
    and still at the surface to the end."""
    total = 60.0 * minutes
    ramp = DIVE_PITCH / PITCH_RATE
    gain = speed * (1.0 - math.cos(DIVE_PITCH)) / PITCH_RATE  # depth of one ramp [m]
    hold = (depth - surface - 2.0 * gain) / (speed * math.sin(DIVE_PITCH))
    if not (speed > 0 and hold > 0):
        raise ValueError(
            f"depth: {depth} m is too shallow to dive to from {surface} m at {speed} m/s "
            f"(at least {surface + 2 * gain:.2f} m)"
        )
    speed_up = speed / ACCEL
    dive = [[ramp, 0, 0, -PITCH_RATE], [hold, 0, 0, 0], [ramp, 0, 0, PITCH_RATE]]
    ascent = [[ramp, 0, 0, PITCH_RATE], [hold, 0, 0, 0], [ramp, 0, 0, -PITCH_RATE]]
    turn = math.pi / TURN_RATE
    fixed = 2 * STILL + 2 * speed_up + 2 * (2 * ramp + hold)
    remaining = total - fixed
    n = max(1, round((remaining + turn) / (LEG + turn)))
    leg = math.floor((remaining - (n - 1) * turn) / n * 10.0) / 10.0
    if leg < 10.0:
        shortest = (fixed + 10.0) / 60.0
        raise ValueError(f"minutes: {minutes} is too short for a survey (at least {shortest:.2f})")
    rows: list[list[float]] = [[STILL, 0, 0, 0], [speed_up, ACCEL, 0, 0], *dive]
    for k in range(n):
        rows.append([leg, 0, 0, 0])
        if k < n - 1:
            rows.append([turn, 0, TURN_RATE if k % 2 == 0 else -TURN_RATE, 0])
    rows += [*ascent, [speed_up, -ACCEL, 0, 0]]
    rows.append([total - sum(r[0] for r in rows), 0, 0, 0])
    return np.array(rows, dtype=np.float64)


class _TruthAt:
    """The truth of a trajectory at any time inside it (linear interpolation of the
    200 Hz epochs; the rate of the IMU row covering the time)."""

    def __init__(self, traj: pronet.Trajectory) -> None:
        self.t = traj.time
        self.lla, self.vel, self.imu = traj.lla, traj.vel_ned, traj.imu
        self.rpy = np.unwrap(traj.rpy, axis=0)

    def __call__(self, t: F64) -> tuple[F64, F64, F64, F64]:
        """``lla``, ``vel``, ``rpy`` (yaw unwrapped) and ``ω`` [rad/s] at ``t`` [s]."""

        def at(values: F64) -> F64:
            return np.stack([np.interp(t, self.t, values[:, j]) for j in range(3)], axis=1)

        row = np.clip(np.searchsorted(self.t, t, side="left") - 1, 0, len(self.imu) - 1)
        return at(self.lla), at(self.vel), at(self.rpy), self.imu[row, 3:6]


def _stamps(rate: float, duration: float, rng: np.random.Generator) -> F64:
    """Regular stamps [s from the start] at ``rate`` from a random phase, inside
    ``(0, duration]``."""
    step = 1.0 / rate
    first = rng.uniform(0.0, step) or step
    count = int(math.floor((duration - first) / step)) + 1
    return np.asarray(first + step * np.arange(count), dtype=np.float64)


def _wrap(angle: F64) -> F64:
    return np.angle(np.exp(1j * angle))


def _imu_errors(sensors: Sensors, ideal: F64, rng: np.random.Generator) -> tuple[F64, F64]:
    """The IMU rows with noise and bias, and the true bias of each row."""
    dt = 1.0 / sensors.imu_rate
    if sensors.imu_bias is not None:
        turn_on = np.asarray(sensors.imu_bias, dtype=np.float64)
    else:
        sigma = [sensors.accel_bias_sigma] * 3 + [sensors.gyro_bias_sigma] * 3
        turn_on = rng.normal(size=6) * sigma
    walk_psd = np.array([sensors.accel_bias_psd] * 3 + [sensors.gyro_bias_psd] * 3)
    walk = np.cumsum(rng.normal(size=ideal.shape) * np.sqrt(walk_psd * dt), axis=0)
    bias = turn_on + walk
    noise_psd = np.array([sensors.accel_noise_psd] * 3 + [sensors.gyro_noise_psd] * 3)
    noise = rng.normal(size=ideal.shape) * np.sqrt(noise_psd / dt)
    return ideal + bias + noise, bias


def _ahrs_error(sensors: Sensors, time: F64, rng: np.random.Generator) -> F64:
    """``(n, 3)`` a Gauss–Markov error (1σ ``ahrs_sigma``, ``ahrs_tau``) drawn at 10 Hz
    and interpolated to ``time`` [s from the start]."""
    grid = np.arange(0.0, time[-1] + 0.2, 0.1)
    a = math.exp(-0.1 / sensors.ahrs_tau)
    sigma = np.asarray(sensors.ahrs_sigma, dtype=np.float64)
    w = rng.normal(size=(len(grid), 3))
    e = np.empty_like(w)
    e[0] = w[0] * sigma
    scale = math.sqrt(1.0 - a * a) * sigma
    for k in range(1, len(grid)):
        e[k] = a * e[k - 1] + scale * w[k]
    return np.stack([np.interp(time, grid, e[:, j]) for j in range(3)], axis=1)


def _dvl_outages(sensors: Sensors, duration: float, rng: np.random.Generator) -> F64:
    """``(k, 2)`` bottom-lock losses ``[start, end)`` [s from the start]."""
    count = rng.poisson(sensors.dvl_losses_per_minute * duration / 60.0)
    start = np.sort(rng.uniform(0.0, duration, count))
    length = rng.uniform(*sensors.dvl_loss_seconds, count)
    return np.column_stack([start, np.minimum(start + length, duration)])


def simulate_mission(
    seed: int = 0,
    minutes: float = 22.0,
    *,
    heading: bool = True,
    fixes: Literal["usbl", "surface", "none"] = "usbl",
    magnetic: bool = False,
    declination: float = 5.0 * _DEG,
    lever_arms: LeverArms = LeverArms(),  # noqa: B008 - frozen
    sensors: Sensors = Sensors(),  # noqa: B008 - frozen
    surface_pressure: float = 101_900.0,
    water_density: float = 1025.0,
    speed: float = 1.0,
    depth: float = 10.0,
    surface: float = 0.3,
    origin: tuple[float, float] = (32.0 * _DEG, 34.0 * _DEG),
    yaw0: float = 30.0 * _DEG,
    epoch: float = EPOCH,
    name: str = "mission",
) -> Mission:
    """A ``minutes`` long survey (:func:`survey_segments`) at ``speed`` [m/s] and
    ``depth`` [m], the IMU ``surface`` [m] deep when floating, starting at ``origin``
    (latitude, longitude [rad]) heading ``yaw0`` [rad], its stamps ``epoch`` + seconds;
    every error drawn from ``seed`` (each sensor from its own stream). ``heading``: with
    a compass; ``fixes``: ``"usbl"`` (1 Hz all along), ``"surface"`` (GNSS while the
    antenna is above water), ``"none"``; ``magnetic``: the compass and the AHRS yaw read
    from magnetic north (true − ``declination`` [rad, east positive])."""
    if fixes not in FIX_KINDS:
        raise ValueError(f"fixes: expected one of {', '.join(FIX_KINDS)}, got {fixes!r}")
    rows = survey_segments(minutes, speed, depth, surface)
    traj = pronet.trajectory_from_segments(
        rows,
        lla0=(origin[0], origin[1], -surface),
        speed0=0.0,
        rpy0=(0.0, 0.0, yaw0),
        dt=1.0 / sensors.imu_rate,
        name=name,
    )

    def rng(stream: int) -> np.random.Generator:
        return np.random.default_rng([seed, stream])

    duration = float(traj.time[-1])
    imu, bias = _imu_errors(sensors, traj.imu, rng(1))
    truth_at = _TruthAt(traj)
    arms = {
        k: np.asarray(getattr(lever_arms, k), dtype=np.float64) for k in ("dvl", "depth", "fix")
    }
    offset = -(1.0 if magnetic else 0.0) * declination

    ahrs = np.unwrap(traj.rpy, axis=0)[1:] + _ahrs_error(sensors, traj.time[1:], rng(2))
    ahrs[:, 2] = _wrap(ahrs[:, 2] + offset)

    t_dvl = _stamps(sensors.dvl_rate, duration, rng(3))
    _, vel, rpy, omega = truth_at(t_dvl)
    c = dcm_from_euler(rpy)
    dvl = np.einsum("kji,kj->ki", c, vel) + np.cross(omega, arms["dvl"])
    dvl += rng(4).normal(size=dvl.shape) * sensors.dvl_sigma
    outages = _dvl_outages(sensors, duration, rng(5))
    lost = ((t_dvl[:, None] >= outages[:, 0]) & (t_dvl[:, None] < outages[:, 1])).any(axis=1)
    dvl[lost] = np.nan

    t_depth = _stamps(sensors.depth_rate, duration, rng(6))
    lla, _, rpy, _ = truth_at(t_depth)
    sensor_depth = -lla[:, 2] + (dcm_from_euler(rpy) @ arms["depth"])[:, 2]
    sensor_depth += rng(7).normal(size=len(t_depth)) * sensors.depth_sigma
    pressure = surface_pressure + water_density * STANDARD_GRAVITY * sensor_depth

    t_fix, fix_lla = _fixes(fixes, sensors, duration, truth_at, arms["fix"], rng(8))

    t_heading = _stamps(sensors.heading_rate, duration, rng(9)) if heading else np.empty(0)
    _, _, rpy, _ = truth_at(t_heading)
    compass = rpy[:, 2] + rng(10).normal(size=len(t_heading)) * sensors.heading_sigma
    compass = np.mod(compass + offset, 2.0 * np.pi)

    truth = Truth(
        time=epoch + traj.time,
        lla=traj.lla,
        vel=traj.vel_ned,
        rpy=traj.rpy,
        imu=traj.imu,
        bias=bias,
    )
    return Mission(
        imu_time=epoch + traj.time[1:],
        imu=imu,
        ahrs_rpy=ahrs,
        dvl_time=epoch + t_dvl,
        dvl=dvl,
        depth_time=epoch + t_depth,
        pressure=pressure,
        fix_time=epoch + t_fix,
        fix_lla=fix_lla,
        heading_time=epoch + t_heading,
        heading=compass,
        truth=truth,
        sensors=sensors,
        lever_arms=lever_arms,
        surface_pressure=surface_pressure,
        water_density=water_density,
        declination=declination,
        magnetic=magnetic,
        fixes=fixes,
        dvl_outages=epoch + outages,
        still=epoch + np.array([[0.0, STILL], [duration - float(rows[-1, 0]), duration]]),
        seed=seed,
        name=name,
    )


def _fixes(
    kind: str,
    sensors: Sensors,
    duration: float,
    truth_at: _TruthAt,
    arm: F64,
    rng: np.random.Generator,
) -> tuple[F64, F64]:
    """Horizontal fixes of the antenna at ``arm``: every ``1 / fix_rate`` s
    (``usbl``), while the antenna is above water (``surface``), or none."""
    if kind == "none":
        return np.empty(0), np.empty((0, 3))
    t = _stamps(sensors.fix_rate, duration, rng)
    lla, _, rpy, _ = truth_at(t)
    offset = dcm_from_euler(rpy) @ arm
    if kind == "surface":  # the antenna above water: its depth below 0
        above = -lla[:, 2] + offset[:, 2] < 0.0
        t, lla, offset = t[above], lla[above], offset[above]
    offset[:, :2] += rng.normal(size=(len(t), 2)) * sensors.fix_sigma
    out = np.array([pronet.lla_from_ned(offset[k], lla[k]) for k in range(len(t))])
    out = out.reshape(-1, 3)
    out[:, 2] = np.nan  # horizontal fixes: the depth sensor gives the height
    return t, out


# --- the filter on it ------------------------------------------------------------------


def filter_streams(
    mission: Mission,
    *,
    lever_arms: bool = True,
    surface_pressure: float | None = None,
    fixes: bool = True,
    heading: bool = True,
) -> list[Any]:
    """The mission's streams for :func:`pronet.run_filter`, σ as simulated: the DVL's
    readings (bottom lock only), the depth over ``surface_pressure`` [Pa] (None: the
    true one), the fixes and the compass (declination corrected) where there are any
    and asked for; with ``lever_arms`` each at its lever arm, else all at the IMU."""
    s = mission.sensors
    arms = mission.lever_arms if lever_arms else LeverArms((0.0,) * 3, (0.0,) * 3, (0.0,) * 3)
    valid = mission.dvl_valid
    depth = mission.depth(surface_pressure)
    streams: list[Any] = [
        pronet.Dvl(
            mission.dvl_time[valid],
            mission.dvl[valid],
            sigma=s.dvl_sigma,
            frame="body",
            lever_arm=arms.dvl,
        ),
        pronet.Depth(mission.depth_time, depth, sigma=s.depth_sigma, lever_arm=arms.depth),
    ]
    if fixes and len(mission.fix_time):
        sigma = fix_sigma(mission)
        streams.append(
            pronet.Fix(mission.fix_time, mission.fix_lla, sigma=sigma, lever_arm=arms.fix)
        )
    if heading and len(mission.heading_time):
        yaw = _wrap(mission.true_heading())
        streams.append(pronet.Heading(mission.heading_time, yaw, sigma=s.heading_sigma))
    return streams


def mems_config(mission: Mission) -> pronet.FilterConfig:
    """The ``mems`` grade's tuning (``--filter mems``, :mod:`pronet.recorded.vehicle`)
    at the IMU's rate, the DVL's R and lever arm as simulated."""
    from pronet.recorded.tuning import real_filter_config
    from pronet.recorded.vehicle import load_vehicle

    variance = mission.sensors.dvl_sigma**2
    return real_filter_config(
        lever_arm=mission.lever_arms.dvl,
        dvl_variance=(variance, variance, variance),
        imu_dt=1.0 / mission.sensors.imu_rate,
        base=load_vehicle("mems").base,
    )


def run_from_truth(mission: Mission, streams: list[Any], *, smooth: bool = False) -> Any:
    """:func:`pronet.run_filter` started at the truth's first row with
    :func:`mems_config` and the constant q estimated from the IMU rows
    (:func:`pronet.recorded.tuning.white_noise_q`, as ``pronet real`` does)."""
    from pronet.recorded.tuning import white_noise_q

    t = mission.truth
    return pronet.run_filter(
        mission.imu,
        mission.imu_time,
        streams,
        t0=mission.t0,
        lla0=t.lla[0],
        vel0=t.vel[0],
        rpy0=t.rpy[0],
        config=mems_config(mission),
        strategy=pronet.Strategy.constant(white_noise_q(mission.imu)),
        smooth=smooth,
    )


@dataclass(frozen=True)
class Score:
    """A solution against the mission's truth, over every epoch.

    Attributes:
        horizontal_rms, final_horizontal, max_horizontal: horizontal error [m].
        horizontal_within_3sigma: share of epochs with the north and the east error
            each within 3σ.
        vertical_mean, vertical_rms: the depth error (estimate − truth, down) [m]: a
            wrong surface pressure is a mean.
        heading_rms: heading error RMS [rad].
        heading_within_3sigma: share of epochs with the heading error within 3σ.
    """

    horizontal_rms: float
    final_horizontal: float
    max_horizontal: float
    horizontal_within_3sigma: float
    vertical_mean: float
    vertical_rms: float
    heading_rms: float
    heading_within_3sigma: float


def score(mission: Mission, lla: F64, rpy: F64, sigma: F64) -> Score:
    """``lla``, ``rpy`` and ``sigma`` (15 1σ) at every truth epoch (a filter's or a
    smoother's, every epoch kept) against the truth."""
    t = mission.truth
    if len(lla) != len(t.time):
        raise ValueError(f"lla: {len(lla)} rows, the truth {len(t.time)} (keep every epoch)")
    err = pronet.local_ned(lla, t.lla[0]) - pronet.local_ned(t.lla, t.lla[0])
    horizontal = np.hypot(err[:, 0], err[:, 1])
    inside = (np.abs(err[:, :2]) <= 3.0 * sigma[:, :2]).all(axis=1)
    yaw = _wrap(rpy[:, 2] - t.rpy[:, 2])
    return Score(
        horizontal_rms=float(np.sqrt(np.mean(horizontal**2))),
        final_horizontal=float(horizontal[-1]),
        max_horizontal=float(horizontal.max()),
        horizontal_within_3sigma=float(inside.mean()),
        vertical_mean=float(err[:, 2].mean()),
        vertical_rms=float(np.sqrt(np.mean(err[:, 2] ** 2))),
        heading_rms=float(np.sqrt(np.mean(yaw**2))),
        heading_within_3sigma=float(np.mean(np.abs(yaw) <= 3.0 * sigma[:, 8])),
    )
