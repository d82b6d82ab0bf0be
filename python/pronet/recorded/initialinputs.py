"""The inputs of :func:`pronet.recorded.initial.initial_state` checked before any
computation: the IMU, the streams (finite readings, σ per reading), the lever arms, the
parts given (with their default σ), the still interval and t0; and the readings around
t0 the parts use.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet._util.plausibility import HEIGHT_RANGE, angles_beyond
from pronet._util.validate import float_array, real_array, scalar
from pronet.filter import ERROR_STATES
from pronet.recorded.levelling import StillSettings, still_intervals

F64 = NDArray[np.float64]
#: The fewest IMU samples a still interval levels over.
MIN_STILL_SAMPLES = 10
#: A stream: ``(time (k,), values (k,) or (k, c), sigma)``, σ per reading or one for all.
Stream = tuple[ArrayLike, ArrayLike, ArrayLike]

#: The largest latitude [deg] a given position may have (the navigation frame's
#: heading is undefined at a pole).
MAX_GIVEN_LATITUDE = 89.0
#: The largest heading [deg] a given heading may have, either way: a heading file's
#: bound (0–360° and ±180° conventions alike; beyond it, another unit).
MAX_GIVEN_HEADING = 360.0
#: The depths [m, down] a given depth may have: :data:`~pronet._util.plausibility.
#: HEIGHT_RANGE` negated (the deepest ocean is 11 km).
DEPTH_RANGE = (-HEIGHT_RANGE[1], -HEIGHT_RANGE[0])

#: The 1σ of a given part where it comes without one: position N, E, D [m], depth [m],
#: roll and pitch [rad] (2°), heading [rad] (5°), velocity [m/s].
GIVEN_SIGMA = {
    "lla": (5.0, 5.0, 1.0),
    "depth": 0.5,
    "rpy": (math.radians(2.0), math.radians(2.0), math.radians(5.0)),
    "heading": math.radians(5.0),
    "vel": (0.1, 0.1, 0.1),
}


@dataclass(frozen=True)
class GivenState:
    """Parts of the initial state given (``--init``, the vehicle file), each optional,
    each with an optional 1σ (else :data:`GIVEN_SIGMA`). They win over the data.

    Attributes:
        lla: ``(3,)`` the IMU's latitude, longitude [rad], height [m, up] (NaN height:
            the horizontal position alone).
        lla_sigma: ``(3,)`` its 1σ north, east, down [m].
        depth: the IMU's depth [m, down] (not with a height in ``lla``).
        depth_sigma: [m].
        rpy: ``(3,)`` roll, pitch, yaw [rad] (ZYX; not with ``heading``).
        rpy_sigma: ``(3,)`` [rad].
        heading: the yaw from true north alone [rad].
        heading_sigma: [rad].
        vel: ``(3,)`` NED velocity [m/s].
        vel_sigma: ``(3,)`` [m/s].
    """

    lla: ArrayLike | None = None
    lla_sigma: ArrayLike | None = None
    depth: float | None = None
    depth_sigma: float | None = None
    rpy: ArrayLike | None = None
    rpy_sigma: ArrayLike | None = None
    heading: float | None = None
    heading_sigma: float | None = None
    vel: ArrayLike | None = None
    vel_sigma: ArrayLike | None = None


@dataclass(frozen=True)
class InitialSettings:
    """The thresholds of :func:`pronet.recorded.initial.initial_state`.

    Attributes:
        still: how still intervals are detected.
        reading_window: how far from t0 a reading may be [s].
        max_fixes: the most fixes (and depths) averaged while still.
        gyrocompass_max_sigma: the largest heading 1σ gyrocompassing may give [rad].
        still_velocity_sigma: the velocity's 1σ while still [m/s].
    """

    still: StillSettings = field(default_factory=StillSettings)
    reading_window: float = 1.0
    max_fixes: int = 10
    gyrocompass_max_sigma: float = 0.1
    still_velocity_sigma: float = 0.02

    def __post_init__(self) -> None:
        for name in ("reading_window", "gyrocompass_max_sigma", "still_velocity_sigma"):
            value = scalar(getattr(self, name), name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"InitialSettings.{name}: expected a positive number, got {value}")
        if (
            isinstance(self.max_fixes, bool)
            or not isinstance(self.max_fixes, int)
            or self.max_fixes < 1
        ):
            raise ValueError(
                f"InitialSettings.max_fixes: expected a positive integer, got {self.max_fixes!r}"
            )


@dataclass(frozen=True)
class Readings:
    """A stream's finite readings: ``time (k,)``, ``values (k, c)``, ``sigma (k, c)``."""

    time: F64
    values: F64
    sigma: F64


@dataclass(frozen=True)
class Given:
    """A :class:`GivenState` checked, with its σ filled in."""

    lla: F64 | None
    lla_sigma: F64
    depth: float | None
    depth_sigma: float
    rpy: F64 | None
    rpy_sigma: F64
    heading: float | None
    heading_sigma: float
    vel: F64 | None
    vel_sigma: F64


@dataclass(frozen=True)
class Inputs:
    """Everything the parts read: the inputs checked, t0 and the still interval."""

    time: F64
    imu: F64
    p0: F64
    streams: dict[str, Readings]
    arms: dict[str, F64]
    given: Given
    settings: InitialSettings
    k0: int
    interval: tuple[float, float] | None
    no_still: str
    #: The DVL's median speed [m/s] over ``interval`` where it says the vehicle moves
    #: there (steady motion, which the IMU cannot tell from rest: levelled over, but
    #: neither at rest nor in one place), else None.
    moving: float | None = None

    @property
    def at_rest(self) -> bool:
        """Whether t0 ends an interval of rest (not of steady motion)."""
        return self.interval is not None and self.moving is None

    @property
    def t0(self) -> float:
        return float(self.time[self.k0])

    def pick(self, name: str, many: int = 1) -> NDArray[np.intp]:
        """Indices of stream ``name``'s readings around t0: while still, those in the
        still interval nearest t0 (up to ``many``); else, or without any, the one
        nearest t0 within the reading window; empty without any."""
        if name not in self.streams:
            return np.empty(0, dtype=np.intp)
        t = self.streams[name].time
        gap = np.abs(t - self.t0)
        if self.interval is not None and self.at_rest:
            inside = np.flatnonzero((t >= self.interval[0]) & (t <= self.interval[1]))
            if len(inside):
                return np.sort(inside[np.argsort(gap[inside], kind="stable")[:many]])
        near = np.flatnonzero(gap <= self.settings.reading_window)
        return near[np.argsort(gap[near], kind="stable")[:1]]

    def around(self, name: str) -> NDArray[np.intp]:
        """Indices of stream ``name``'s readings within the reading window of t0 (while
        still: in the still interval up to t0)."""
        if name not in self.streams:
            return np.empty(0, dtype=np.intp)
        t = self.streams[name].time
        keep = np.abs(t - self.t0) <= self.settings.reading_window
        if self.interval is not None and self.at_rest:
            keep &= (t >= self.interval[0]) & (t <= self.t0)
        return np.flatnonzero(keep)

    def absent(self, name: str, label: str) -> str:
        """Why stream ``name`` gives nothing at t0."""
        if name not in self.streams:
            return f"no {label}"
        window = self.settings.reading_window
        return f"no {label} reading within {window:g} s of t0 = {self.t0:.2f} s"

    def still_samples(self) -> F64:
        """The IMU samples of the still interval."""
        assert self.interval is not None
        a, b = self.interval
        return self.imu[(self.time >= a) & (self.time <= b)]

    def lag(self, times: F64) -> F64:
        """``t0 − times`` [s], the time a reading is moved over by the velocity: zero
        while still (the vehicle does not move)."""
        return np.zeros(len(times)) if self.at_rest else self.t0 - times

    def rate(self) -> float:
        """``|ω|`` at t0 [rad/s] (zero while still)."""
        return 0.0 if self.at_rest else float(np.linalg.norm(self.imu[self.k0, 3:]))


def _arm(value: ArrayLike | None, name: str) -> F64:
    if value is None:
        return np.zeros(3)
    a = float_array(value, name, (3,))
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name}: expected finite metres, got {a.tolist()}")
    return a


def _stream(stream: Stream | None, name: str, width: int, required: int) -> Readings | None:
    """A stream checked (times finite and non-decreasing, σ positive), its rows with a
    NaN among the first ``required`` values dropped (a fix's NaN height is kept)."""
    if stream is None:
        return None
    if not isinstance(stream, tuple | list) or len(stream) != 3:
        raise ValueError(f"{name}: expected a (time, values, sigma) tuple")
    time = real_array(stream[0], f"{name} time").astype(float)
    values = real_array(stream[1], f"{name} values").astype(float)
    k = len(time)
    if width == 1 and values.ndim == 1:
        values = values.reshape(-1, 1)
    if time.ndim != 1 or values.shape != (k, width):
        shape = "(k,)" if width == 1 else f"(k, {width})"
        raise ValueError(
            f"{name}: expected time (k,) and values {shape}, got {time.shape} and {values.shape}"
        )
    if not np.all(np.isfinite(time)) or np.any(np.diff(time) < 0):
        raise ValueError(f"{name} time: expected finite, non-decreasing seconds")
    if np.any(np.isinf(values)):
        raise ValueError(
            f"{name} values: infinite at row {int(np.argwhere(np.isinf(values))[0, 0])}"
        )
    sigma = real_array(stream[2], f"{name} sigma").astype(float)
    if sigma.ndim == 0 or (sigma.shape == (width,) and width > 1):
        sigma = np.broadcast_to(sigma, (k, width)).copy()
    elif width == 1 and sigma.shape == (k,):
        sigma = sigma.reshape(-1, 1)
    elif sigma.shape != (k, width):
        per_row = "(k,)" if width == 1 else f"({width},) or (k, {width})"
        raise ValueError(f"{name} sigma: expected one value or {per_row}, got {sigma.shape}")
    if not np.all(np.isfinite(sigma) & (sigma > 0)):
        raise ValueError(f"{name} sigma: expected positive finite values")
    keep = np.all(np.isfinite(values[:, :required]), axis=1)
    return Readings(time[keep], values[keep], sigma[keep])


def _given_vector(value: ArrayLike | None, name: str, finite: int = 3) -> F64 | None:
    if value is None:
        return None
    a = float_array(value, f"given {name}", (3,))
    if not np.all(np.isfinite(a[:finite])) or np.any(np.isinf(a)):
        raise ValueError(f"given {name}: expected finite values, got {a.tolist()}")
    return a


def _given_sigma(value: ArrayLike | float | None, name: str, default: object) -> F64:
    s = np.asarray(default if value is None else real_array(value, f"given {name}"), dtype=float)
    if not np.all(np.isfinite(s) & (s > 0)):
        raise ValueError(f"given {name}: expected positive finite values, got {s.tolist()}")
    return s


def _given(g: GivenState | None) -> Given:
    """``g`` checked, its missing σ from :data:`GIVEN_SIGMA`."""
    g = GivenState() if g is None else g
    lla = _given_vector(g.lla, "lla", finite=2)
    if lla is not None and (beyond := angles_beyond(lla, "given lla")) is not None:
        raise ValueError(beyond)
    if lla is not None and abs(lla[0]) > math.radians(MAX_GIVEN_LATITUDE):
        raise ValueError(
            f"given lla: latitude {math.degrees(lla[0]):.2f}° beyond ±{MAX_GIVEN_LATITUDE:g}°"
        )
    if g.depth is not None and lla is not None and np.isfinite(lla[2]):
        raise ValueError("given: a depth and a height in lla: give one of them")
    if g.rpy is not None and g.heading is not None:
        raise ValueError("given: rpy and heading: give one of them (rpy's yaw is the heading)")
    depth = None if g.depth is None else scalar(g.depth, "given depth")
    head = None if g.heading is None else scalar(g.heading, "given heading")
    for name, value in (("depth", depth), ("heading", head)):
        if value is not None and not math.isfinite(value):
            raise ValueError(f"given {name}: expected a finite value, got {value}")
    if depth is not None and not DEPTH_RANGE[0] <= depth <= DEPTH_RANGE[1]:
        raise ValueError(
            f"given depth: {depth:g} m is beyond {DEPTH_RANGE[0]:g} … {DEPTH_RANGE[1]:g} m "
            "(metres, positive down: the deepest ocean is 11 km); in pascals or another unit?"
        )
    if head is not None and abs(head) > math.radians(MAX_GIVEN_HEADING):
        raise ValueError(
            f"given heading: {head:.6g} rad is beyond ±{math.radians(MAX_GIVEN_HEADING):.6g} "
            f"rad (±{MAX_GIVEN_HEADING:g}°); in degrees? (radians expected)"
        )
    sigmas = {
        name: _given_sigma(getattr(g, f"{name}_sigma"), f"{name}_sigma", GIVEN_SIGMA[name])
        for name in GIVEN_SIGMA
    }
    for name, width in (("lla", 3), ("rpy", 3), ("vel", 3), ("depth", 1), ("heading", 1)):
        s = sigmas[name]
        if s.size != width:
            raise ValueError(f"given {name}_sigma: expected {width} value(s), got {s.size}")
    return Given(
        lla=lla,
        lla_sigma=sigmas["lla"].reshape(3),
        depth=depth,
        depth_sigma=float(sigmas["depth"].reshape(-1)[0]),
        rpy=_given_vector(g.rpy, "rpy"),
        rpy_sigma=sigmas["rpy"].reshape(3),
        heading=head,
        heading_sigma=float(sigmas["heading"].reshape(-1)[0]),
        vel=_given_vector(g.vel, "vel"),
        vel_sigma=sigmas["vel"].reshape(3),
    )


def _first(streams: dict[str, Readings], *names: str) -> float | None:
    """The earliest first reading of the streams ``names`` there are, or None."""
    times = [streams[n].time[0] for n in names if n in streams and len(streams[n].time)]
    return float(min(times)) if times else None


def _needed(streams: dict[str, Readings], given: Given) -> float | None:
    """The first time every stream a part needs has a reading (None: none needed)."""
    firsts = []
    if given.rpy is None:
        firsts.append(_first(streams, "orientation"))
        if given.heading is None:
            firsts.append(_first(streams, "heading", "orientation"))
    if given.vel is None:
        firsts.append(_first(streams, "dvl"))
    if given.lla is None:
        firsts.append(_first(streams, "fixes"))
    if given.depth is None and (given.lla is None or not np.isfinite(given.lla[2])):
        firsts.append(_first(streams, "depth"))
    found = [t for t in firsts if t is not None]
    return max(found) if found else None


#: A DVL's median speed [m/s] over an interval the IMU finds steady above which, and
#: above 3 of its median 1σ (per axis, times √3), the vehicle is taken as moving; over
#: at least :data:`MIN_MOVING_READINGS` readings (one spike says nothing).
STILL_DVL_SPEED = 0.2
MIN_MOVING_READINGS = 3


def _moving(streams: dict[str, Readings], a: float, b: float) -> float | None:
    """The DVL's median speed [m/s] over ``[a, b]`` where it says the vehicle moves
    there (beyond :data:`STILL_DVL_SPEED` and 3√3 of its median 1σ), else None."""
    dvl = streams.get("dvl")
    if dvl is None:
        return None
    inside = (dvl.time >= a) & (dvl.time <= b)
    if inside.sum() < MIN_MOVING_READINGS:
        return None
    speed = float(np.median(np.linalg.norm(dvl.values[inside], axis=1)))
    noise = 3.0 * math.sqrt(3.0) * float(np.median(dvl.sigma[inside]))
    return speed if speed > max(STILL_DVL_SPEED, noise) else None


def _samples(time: F64, a: float, b: float) -> int:
    """How many IMU samples lie in [a, b]."""
    return int(np.count_nonzero((time >= a) & (time <= b)))


def _when(
    time: F64,
    imu: F64,
    still: tuple[float, float] | str,
    t0: float | None,
    streams: dict[str, Readings],
    given: Given,
    settings: InitialSettings,
    gyro_bias_sigma: float,
) -> tuple[int, tuple[float, float] | None, str]:
    """The index of t0, the still interval up to it (or None) and, without one, why."""
    if isinstance(still, str):
        if still not in ("auto", "none"):
            raise ValueError(f"still: expected 'auto', 'none' or (t_start, t_end), got {still!r}")
        if still == "none":
            intervals, why = [], "no still interval asked for"
        else:
            intervals = still_intervals(time, imu, gyro_bias_sigma, settings.still)
            why = f"no still interval of {settings.still.min_duration:g} s or more in the IMU"
    else:
        if not isinstance(still, tuple | list) or len(still) != 2:
            raise ValueError(f"still: expected 'auto', 'none' or (t_start, t_end), got {still!r}")
        a, b = scalar(still[0], "still"), scalar(still[1], "still")
        if not (time[0] <= a < b <= time[-1]) or _samples(time, a, b) < MIN_STILL_SAMPLES:
            raise ValueError(
                f"still: expected t_start < t_end within the IMU's {time[0]:.3f}–{time[-1]:.3f} s"
                f" and at least {MIN_STILL_SAMPLES} samples, got ({a}, {b})"
            )
        intervals, why = [(a, b)], ""
    if t0 is not None:
        t = scalar(t0, "t0")
        if not time[0] <= t <= time[-1]:
            raise ValueError(f"t0: {t} s is outside the IMU's {time[0]:.3f}–{time[-1]:.3f} s")
        k0 = int(np.argmin(np.abs(time - t)))
        half = 0.5 * (time[-1] - time[0]) / (len(time) - 1)
        for a, b in intervals:
            end = float(time[k0])
            if a < end <= b + half and _samples(time, a, end) >= MIN_STILL_SAMPLES:
                return k0, (a, end), ""
        return k0, None, why if not intervals else "no still interval found around t0"
    if intervals:
        a, b = intervals[0]
        k0 = int(np.searchsorted(time, b, side="right")) - 1
        return k0, (a, float(time[k0])), ""
    need = _needed(streams, given)
    k0 = 0 if need is None else int(np.searchsorted(time, need))
    if k0 >= len(time):
        raise ValueError(
            f"t0: the streams' first readings ({need:.2f} s) come after the IMU's end (its "
            f"{len(time)} samples end at {time[-1]:.2f} s)"
        )
    return k0, None, why


def prepare(
    imu_time: ArrayLike,
    imu: ArrayLike,
    base_p0: ArrayLike,
    streams: dict[str, tuple[Stream | None, int, int]],
    arms: dict[str, ArrayLike | None],
    given: GivenState | None,
    still: tuple[float, float] | str,
    t0: float | None,
    settings: InitialSettings,
) -> Inputs:
    """Every input checked, then t0 and the still interval."""
    time = float_array(imu_time, "imu_time", (None,))
    samples = float_array(imu, "imu", (len(time), 6))
    if len(time) < 2 or not np.all(np.isfinite(time)) or np.any(np.diff(time) <= 0):
        raise ValueError("imu_time: expected at least 2 finite, increasing seconds")
    if not np.all(np.isfinite(samples)):
        raise ValueError(f"imu: non-finite at row {int(np.argwhere(~np.isfinite(samples))[0, 0])}")
    p0 = float_array(base_p0, "base_p0", (15,))
    if not np.all(ok := np.isfinite(p0) & (p0 > 0)):
        k = int(np.argmin(ok))
        raise ValueError(
            f"base_p0 (a vehicle file's p0_sigma): expected 15 positive finite 1σ, got "
            f"{p0[k]:g} for {ERROR_STATES[k]} (index {k})"
            + (": the initial state is never known exactly" if p0[k] == 0 else "")
        )
    read = {}
    for name, (stream, width, required) in streams.items():
        r = _stream(stream, name, width, required)
        if r is not None:
            read[name] = r
    checked_arms = {name: _arm(value, f"{name}_lever_arm") for name, value in arms.items()}
    g = _given(given)
    k0, interval, why = _when(time, samples, still, t0, read, g, settings, float(p0[12:].max()))
    moving = None if interval is None else _moving(read, *interval)
    return Inputs(time, samples, p0, read, checked_arms, g, settings, k0, interval, why, moving)
