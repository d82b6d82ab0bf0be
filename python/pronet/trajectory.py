"""Trajectories: built-in ones and custom ones from segments.

A trajectory is a list of segments during which the forward acceleration [m/s²], the
yaw rate [rad/s, positive turns right] and the pitch rate [rad/s, positive noses up]
are constant. The vehicle moves along its body x axis, roll stays at its initial value.
The native core builds the truth (time, position, NED velocity, attitude) and the ideal
100 Hz IMU consistent with it: mechanizing that IMU reproduces the truth.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from pronet import _core
from pronet._util.plausibility import angles_beyond, attitude_beyond, height_beyond
from pronet._util.validate import check_type, float_array, scalar


@dataclass(frozen=True)
class Segment:
    """One constant-rate piece of a trajectory.

    Attributes:
        duration: length [s], > 0.
        accel: forward acceleration [m/s²].
        yaw_rate: yaw rate [rad/s]; positive turns right (clockwise seen from above).
        pitch_rate: pitch rate [rad/s]; positive noses up, negative dives.
    """

    duration: float
    accel: float = 0.0
    yaw_rate: float = 0.0
    pitch_rate: float = 0.0

    def __post_init__(self) -> None:
        for name in ("duration", "accel", "yaw_rate", "pitch_rate"):
            scalar(getattr(self, name), name)

    @classmethod
    def degrees(
        cls, duration: float, accel: float = 0.0, yaw_rate: float = 0.0, pitch_rate: float = 0.0
    ) -> Segment:
        """A segment with its rates given in degrees per second."""
        yaw, pitch = scalar(yaw_rate, "yaw_rate"), scalar(pitch_rate, "pitch_rate")
        return cls(duration, accel, math.radians(yaw), math.radians(pitch))

    def as_row(self) -> tuple[float, float, float, float]:
        return (self.duration, self.accel, self.yaw_rate, self.pitch_rate)


def builtin_trajectory(name: str, dt: float = 0.01) -> _core.Trajectory:
    """A built-in trajectory sampled every ``dt`` seconds.

    Names (``pronet.builtin_trajectory_names()``): ``paper`` (the 330 s evaluation
    trajectory: straight legs, left and right turns, a dive; v0 = [1, 0, 0] m/s,
    p0 = 32°, 34°, −5 m) and the four 400 s training trajectories ``train-straight``,
    ``train-turns``, ``train-zigzag``, ``train-helix``. More samples than this process can
    still take are a ``ValueError`` naming ``dt`` (docs/results/performance.md, "Memory").
    """
    check_type(name, str, "name")
    dt = scalar(dt, "dt")
    try:
        return _core.builtin_trajectory(name, dt)
    except ValueError as exc:  # a built-in's segments are fixed: dt does not fit them
        if str(exc).startswith("segments"):
            raise ValueError(f"dt: {dt} s does not fit trajectory {name!r} ({exc})") from None
        raise


def trajectory_from_segments(
    segments: Sequence[Segment] | ArrayLike,
    *,
    lla0: ArrayLike,
    speed0: float,
    rpy0: ArrayLike = (0.0, 0.0, 0.0),
    dt: float = 0.01,
    name: str = "custom",
) -> _core.Trajectory:
    """A trajectory from segments.

    Args:
        segments: :class:`Segment` objects, or an array ``(k, 4)`` of
            ``[duration s, accel m/s², yaw_rate rad/s, pitch_rate rad/s]`` rows.
        lla0: initial ``[lat rad, lon rad, h m]`` (height positive up); a longitude
            beyond −180° … 360° or a height beyond ``HEIGHT_RANGE`` of
            :mod:`pronet._util.plausibility` (−12 … 10 km) is a ``ValueError``.
        speed0: initial forward speed [m/s].
        rpy0: initial roll, pitch, yaw [rad]; roll is held. A roll or pitch beyond ±π,
            or a yaw beyond ±2π, is a ``ValueError`` (degrees given).
        dt: sample period [s]; more samples than this process can still take are a
            ``ValueError`` naming it (docs/results/performance.md, "Memory").
        name: label carried by the trajectory.
    """
    if isinstance(segments, Sequence) and any(isinstance(s, Segment) for s in segments):
        segments = [s.as_row() if isinstance(s, Segment) else s for s in segments]
    rows = float_array(segments, "segments", (None, 4))  # type: ignore[arg-type]
    check_type(name, str, "name")
    lla, rpy = float_array(lla0, "lla0", (3,)), float_array(rpy0, "rpy0", (3,))
    if np.isfinite(lla).all() and np.isfinite(rpy).all():  # else the core names them
        # degrees or a depth given here ran: a roll of 10 rad is 213°, upside down
        problem = (
            angles_beyond(lla, "lla0")
            or height_beyond(float(lla[2]), "lla0")
            or attitude_beyond(rpy, "rpy0")
        )
        if problem is not None:
            raise ValueError(problem)
    return _core.trajectory_from_segments(
        rows,
        lla0=lla,
        speed0=scalar(speed0, "speed0"),
        rpy0=rpy,
        dt=scalar(dt, "dt"),
        name=name,
    )
