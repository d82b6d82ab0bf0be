"""Simulated evaluation scenarios: a trajectory, its sensors, the filter's tuning and
the true IMU noise schedule.

Built-ins: ``paper`` (the paper's Table I, :func:`paper_scenario`) and
``varying-noise`` (each IMU channel's variance changing every 30–60 s,
:func:`varying_noise_scenario`). A user's scenario comes from a TOML file
(:func:`pronet.config.load_scenario`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from pronet import _core
from pronet.paper import PAPER_Q, paper_filter_config
from pronet.trajectory import builtin_trajectory


@dataclass(frozen=True)
class Scenario:
    """A simulated evaluation scenario.

    Attributes:
        name: ``"paper"`` or ``"varying-noise"`` (or a user's).
        trajectory: truth and ideal IMU.
        sensors: simulated IMU and DVL.
        config: filter tuning (bias walk, DVL R, P0).
        q_nominal: 6 per-sample variances the constant rows are told (and every
            adaptive row starts from): the true q, or its time average when it varies.
        schedule_time: ``(k,)`` [s] start of each piece of the true noise schedule.
        schedule_q: ``(k, 6)`` true per-sample variances of each piece.
    """

    name: str
    trajectory: _core.Trajectory
    sensors: _core.SensorConfig
    config: _core.FilterConfig
    q_nominal: tuple[float, ...]
    schedule_time: np.ndarray
    schedule_q: np.ndarray


def paper_scenario() -> Scenario:
    """The paper's Table I: constant accelerometer 0.01², gyro 0.001² variances."""
    return Scenario(
        name="paper",
        trajectory=builtin_trajectory("paper"),
        sensors=_core.SensorConfig(imu_variance=PAPER_Q),
        config=paper_filter_config(),
        q_nominal=PAPER_Q,
        schedule_time=np.zeros(1),
        schedule_q=np.array([PAPER_Q]),
    )


def noise_schedule(
    duration: float, seed: int, q_range: tuple[float, float] = (0.001, 0.05)
) -> tuple[np.ndarray, np.ndarray]:
    """A piecewise-constant variance schedule ``(times (k,), q (k, 6))``: each channel
    independently holds a value drawn uniformly from ``q_range`` for 30–60 s (drawn
    uniformly), then changes. ``times`` merges every channel's change instants."""
    rng = np.random.default_rng([seed, 77])
    changes, values = [], []
    for _ in range(6):
        t = [0.0]
        while t[-1] + 30.0 < duration:
            t.append(t[-1] + rng.uniform(30.0, 60.0))
        t = [x for x in t if x < duration]
        changes.append(np.array(t))
        values.append(rng.uniform(*q_range, size=len(t)))
    times = np.unique(np.concatenate(changes))
    q = np.stack(
        [
            v[np.searchsorted(c, times, side="right") - 1]
            for c, v in zip(changes, values, strict=True)
        ],
        axis=1,
    )
    return times, q


def varying_noise_scenario(seed: int = 0) -> Scenario:
    """The paper's trajectory and filter, with each IMU channel's noise variance changing
    every 30–60 s inside the training range [0.001, 0.05] (:func:`noise_schedule`). The
    constant rows are told each channel's time-averaged variance."""
    trajectory = builtin_trajectory("paper")
    times, q = noise_schedule(trajectory.duration, seed)
    mean_q = time_average_q(times, q, trajectory.duration)
    return Scenario(
        name="varying-noise",
        trajectory=trajectory,
        sensors=_core.SensorConfig(imu_variance=q, imu_variance_times=times),
        config=paper_filter_config(),
        q_nominal=mean_q,
        schedule_time=times,
        schedule_q=q,
    )


def time_average_q(
    times: np.ndarray, q: np.ndarray, duration: float
) -> tuple[float, float, float, float, float, float]:
    """Each channel's time-averaged variance over ``[0, duration]`` s of the
    piecewise-constant schedule ``times (k,)`` [s, from 0], ``q (k, 6)``."""
    times = np.asarray(times, dtype=np.float64)
    inside = times < duration
    held = np.diff(np.append(times[inside], duration))
    mean = (np.asarray(q, dtype=np.float64)[inside] * held[:, None]).sum(axis=0) / held.sum()
    return tuple(float(v) for v in mean)  # type: ignore[return-value]


SCENARIOS: dict[str, Callable[[], Scenario]] = {
    "paper": paper_scenario,
    "varying-noise": varying_noise_scenario,
}
