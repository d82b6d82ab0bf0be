"""What navigating a recording produces, as plain records: a navigation solution over
time (:class:`Solution`), the initial state and how each part of it was found
(:class:`InitialState`), what the filter made of each sensor stream
(:class:`pronet.stats.StreamReport`), and the whole result of
:func:`pronet.recorded.navigate.navigate` (:class:`Navigation`), which the writers of
:mod:`pronet.recorded.export` turn into files.

Frames and units as everywhere in pronet: positions ``[lat, lon (rad), h (m, up)]``,
velocities NED [m/s], attitude roll, pitch, yaw (ZYX) [rad], σ in the classic error
coordinates (position NED [m], velocity [m/s], attitude [rad], biases).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet.recorded.alignment import moved_point
from pronet.stats import StreamReport

F64 = NDArray[np.float64]

#: The parts of an initial state whose method :attr:`InitialState.methods` names.
INITIAL_PARTS = ("position", "depth", "velocity", "attitude", "heading")


@dataclass(frozen=True)
class Solution:
    """A navigation solution of the vehicle's reference point at ``n`` epochs.

    Attributes:
        label: ``"forward"`` (the filter) or ``"smoothed"`` (the RTS smoother).
        time: ``(n,)`` times [s] on the IMU clock, counted from ``epoch``.
        epoch: the recording's first IMU stamp [s, as recorded: Unix time for a bag],
            so that ``epoch + time`` are stamps as recorded.
        lla: ``(n, 3)`` latitude, longitude [rad], height [m, up].
        vel: ``(n, 3)`` NED velocity [m/s].
        rpy: ``(n, 3)`` roll, pitch, yaw [rad] (ZYX).
        sigma: ``(n, 15)`` the filter's 1σ of position NED [m], velocity NED [m/s],
            attitude [rad] (about N, E, D), accelerometer bias [m/s²], gyro bias
            [rad/s].
    """

    label: Literal["forward", "smoothed"]
    time: F64
    epoch: float
    lla: F64
    vel: F64
    rpy: F64
    sigma: F64

    def __post_init__(self) -> None:
        n = len(self.time)
        for name, width in (("lla", 3), ("vel", 3), ("rpy", 3), ("sigma", 15)):
            shape = np.shape(getattr(self, name))
            if shape != (n, width):
                raise ValueError(f"Solution.{name}: expected shape ({n}, {width}), got {shape}")


@dataclass(frozen=True)
class InitialState:
    """Where a pass starts and how sure it is of it.

    Attributes:
        t0: time of the initial state [s] on the IMU clock (the section's).
        lla: ``(3,)`` the IMU's latitude, longitude [rad], height [m, up].
        vel: ``(3,)`` NED velocity [m/s].
        rpy: ``(3,)`` roll, pitch, yaw [rad].
        p0_sigma: ``(15,)`` the initial 1σ each method earns (the filter's P0): position
            NED [m], velocity [m/s], attitude [rad], then the biases' (from the vehicle's
            tuning).
        methods: for each of :data:`INITIAL_PARTS`, one line saying how it was found
            (``"given"``, ``"first fix (3 fixes over 2.0 s)"``, ``"levelled over 12.4 s
            still"``, ``"heading stream"``, ``"gyrocompassed over 60 s"``, …).
    """

    t0: float
    lla: F64
    vel: F64
    rpy: F64
    p0_sigma: F64
    methods: Mapping[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class Navigation:
    """A recording navigated: what :func:`pronet.recorded.navigate.navigate` returns.

    Attributes:
        name: the recording's (section's) name.
        source: where it was read from.
        forward: the filter's solution at every epoch.
        smoothed: the RTS smoother's, or None (not asked for).
        initial: the initial state and its methods.
        streams: one report per stream used, in the order applied.
        readings: the readings as applied, for figures and reports:
            ``{"fix": (time (f,), lla (f, 3)), "depth": (time, depth), "heading":
            (time, heading)}``, the ones the recording has.
        config: everything a ``config.json`` states: the vehicle's tuning, lever arms,
            streams used or switched off, surface pressure and where it came from, the
            initial-state methods, versions.
        score: the errors against a ground truth when the recording has one
            (:func:`pronet.recorded.metrics.section_metrics`' keys, per label
            ``"forward"``/``"smoothed"``), else None.
        notes: lines worth a user's attention (out-of-band NIS, a default surface
            pressure, readings skipped), in the order found.
    """

    name: str
    source: str
    forward: Solution
    smoothed: Solution | None
    initial: InitialState
    streams: tuple[StreamReport, ...]
    readings: Mapping[str, tuple[F64, F64]]
    config: Mapping[str, Any]
    score: Mapping[str, Mapping[str, float]] | None = None
    notes: tuple[str, ...] = ()

    @property
    def solutions(self) -> tuple[Solution, ...]:
        """The forward solution, then the smoothed one where there is one."""
        return (self.forward,) if self.smoothed is None else (self.forward, self.smoothed)


def solution_of(
    label: Literal["forward", "smoothed"],
    estimate: Any,
    epoch: float,
    imu: F64,
    reference_arm: ArrayLike = (0.0, 0.0, 0.0),
) -> Solution:
    """The :class:`Solution` of a pass's ``estimate`` at every epoch (a
    :class:`pronet.FilterResult`, or its :class:`pronet.SmoothedResult`: ``time``,
    ``lla``, ``vel``, ``rpy``, ``bias``, ``sigma`` of the IMU's point), moved to the
    vehicle's reference point, which lies at ``reference_arm`` [m, body FRD] from the IMU
    (the IMU's lever arm, negated). ``imu`` ``(n, 6)``: the pass's raw samples, whose
    gyro less the bias estimate turns the arm into a velocity (epoch ``k`` after sample
    ``k − 1``). The σ are the IMU point's (the arm's share of the position σ, ``|r| σ_ψ``,
    is centimetres at the most for an arm of a metre)."""
    time = np.asarray(estimate.time, dtype=np.float64)
    k = np.maximum(np.arange(len(time)) - 1, 0)
    gyro = np.asarray(imu, dtype=np.float64)[k, 3:6] - np.asarray(estimate.bias)[:, 3:6]
    lla, vel = moved_point(estimate.lla, estimate.vel, estimate.rpy, reference_arm, gyro)
    return Solution(
        label=label,
        time=time,
        epoch=float(epoch),
        lla=lla,
        vel=vel,
        rpy=np.array(estimate.rpy, dtype=np.float64),
        sigma=np.array(estimate.sigma, dtype=np.float64),
    )
