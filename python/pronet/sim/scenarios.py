"""Simulated evaluation scenarios: a trajectory, its sensors, the filter's tuning and
the true IMU noise schedule.

Built-ins (:data:`SCENARIOS`), all but ``mission`` on the paper's 330 s trajectory:

- the paper's reproduction (``pronet reproduce``, :data:`PAPER_SCENARIOS`): ``paper``
  (Table I, :func:`paper_scenario`) and ``varying-noise`` (each IMU channel's variance
  changing every 30–60 s inside the paper's training range,
  :func:`varying_noise_scenario`), both with the paper's filter (bias walk ε = 0.001);
- the study (``pronet study``, :data:`STUDY_SCENARIOS`), each with the filter's bias
  random walk matched to the simulated IMU's (:data:`MATCHED_BIAS_PSD`): ``matched``
  (the paper's sensors), ``varying-matched`` (``varying-noise``'s schedule), ``regimes``
  (a realistic marine IMU switching between a quiet survey and vibration regimes,
  :func:`regimes_scenario`), ``outage`` (``regimes`` with three 60 s DVL outages) and
  ``mission`` (an AUV survey of 1036 s with all its sensors: GNSS at the surface, a dive,
  a lawnmower at 30 m with USBL fixes every 60 s, a depth sensor throughout, the
  ascent and a GNSS fix again; ``regimes``' IMU and DVL, :func:`mission_scenario`).

A drawn noise schedule comes from the scenario's ``schedule_seed``: the Monte Carlo
seed unless a scenario file sets its own. A user's scenario comes from a TOML file
(:func:`pronet.config.load_scenario`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from pronet import _core
from pronet.sim.paper import PAPER_Q, paper_filter_config
from pronet.trajectory import builtin_trajectory, trajectory_from_segments


@dataclass(frozen=True)
class Scenario:
    """A simulated evaluation scenario.

    Attributes:
        name: a built-in's name (:data:`SCENARIOS`) or a user's.
        trajectory: truth and ideal IMU.
        sensors: simulated IMU and DVL.
        config: filter tuning (bias walk, DVL R, P0).
        q_nominal: 6 per-sample variances the constant rows are told (and every
            adaptive row starts from): the true q, or its time average when it varies.
        schedule_time: ``(k,)`` [s] start of each piece of the true noise schedule.
        schedule_q: ``(k, 6)`` true per-sample variances of each piece.
        schedule_seed: the seed the schedule was drawn from (None: not drawn).
    """

    name: str
    trajectory: _core.Trajectory
    sensors: _core.SensorConfig
    config: _core.FilterConfig
    q_nominal: tuple[float, ...]
    schedule_time: np.ndarray
    schedule_q: np.ndarray
    schedule_seed: int | None = None

    @property
    def dvl_outages(self) -> np.ndarray:
        """``(k, 2)`` DVL outages ``[start, end)`` [s] of the simulated DVL."""
        return np.asarray(self.sensors.dvl_outages, dtype=np.float64).reshape(-1, 2)


def paper_scenario(seed: int = 0) -> Scenario:
    """The paper's Table I: constant accelerometer 0.01², gyro 0.001² variances
    (``seed`` is unused: nothing is drawn)."""
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
    every 30–60 s inside the training range [0.001, 0.05] (:func:`noise_schedule`, drawn
    from ``seed``). The constant rows are told each channel's time-averaged variance."""
    trajectory = builtin_trajectory("paper")
    times, q = noise_schedule(trajectory.duration, seed)
    return scheduled_scenario("varying-noise", trajectory, times, q, paper_filter_config(), seed)


def scheduled_scenario(
    name: str,
    trajectory: _core.Trajectory,
    times: np.ndarray,
    q: np.ndarray,
    config: _core.FilterConfig,
    seed: int | None,
    bias_psd: tuple[float, ...] = (0.0,) * 6,
    dvl_variance: tuple[float, float, float] = (0.01, 0.01, 0.01),
    dvl_outages: np.ndarray | None = None,
    **aiding: Any,
) -> Scenario:
    """A scenario named ``name`` on ``trajectory`` whose simulated IMU follows the noise
    schedule ``times`` ``(k,)`` [s], ``q`` ``(k, 6)`` (per-sample variances, accelerometer
    [(m/s²)²] then gyro [(rad/s)²], body FRD; e.g. :func:`noise_schedule`'s), filtered
    with ``config``; the constant rows are told the schedule's time average.
    ``seed``: the seed the schedule was drawn from, recorded (None: not drawn).
    ``bias_psd``: the simulated IMU's bias random walks (``SensorConfig.imu_bias_psd``),
    ``dvl_variance`` [(m/s)²] and ``dvl_outages`` ``(n, 2)`` [s] its DVL's; ``aiding``:
    the aiding sensors' arguments of ``SensorConfig`` (``depth_sigma``, ``fixes`` ...)."""
    sensors = _core.SensorConfig(
        imu_variance=q,
        imu_variance_times=times,
        imu_bias_psd=bias_psd,
        dvl_variance=dvl_variance,
        dvl_outages=dvl_outages,
        **aiding,
    )
    return Scenario(
        name=name,
        trajectory=trajectory,
        sensors=sensors,
        config=config,
        q_nominal=time_average_q(times, q, trajectory.duration),
        schedule_time=times,
        schedule_q=q,
        schedule_seed=seed,
    )


#: The matched bias random walk of the study scenarios, in the simulated IMU and the
#: filter alike: accelerometer 1e-10 (m/s²)²/s, gyro 1e-14 (rad/s)²/s, i.e. 1e-5 m/s²
#: and 1e-7 rad/s (0.02 °/h) per √s, tactical grade.
MATCHED_BIAS_PSD = (1e-10,) * 3 + (1e-14,) * 3


def matched_filter_config(dvl_variance: float = 0.01) -> _core.FilterConfig:
    """The paper's filter with the bias random walk matched to the simulated IMU
    (:data:`MATCHED_BIAS_PSD`) and DVL variance ``dvl_variance`` [(m/s)²]."""
    return _core.FilterConfig(
        accel_bias_psd=MATCHED_BIAS_PSD[0],
        gyro_bias_psd=MATCHED_BIAS_PSD[3],
        dvl_variance=(dvl_variance,) * 3,
    )


def matched_scenario(seed: int = 0) -> Scenario:
    """``paper`` with the bias random walk matched (:data:`MATCHED_BIAS_PSD`, in the
    IMU and the filter): the paper's constant IMU noise, nothing drawn."""
    return Scenario(
        name="matched",
        trajectory=builtin_trajectory("paper"),
        sensors=_core.SensorConfig(imu_variance=PAPER_Q, imu_bias_psd=MATCHED_BIAS_PSD),
        config=matched_filter_config(),
        q_nominal=PAPER_Q,
        schedule_time=np.zeros(1),
        schedule_q=np.array([PAPER_Q]),
    )


def varying_matched_scenario(seed: int = 0) -> Scenario:
    """``varying-noise``'s schedule (drawn from ``seed``) with the bias walk matched."""
    trajectory = builtin_trajectory("paper")
    times, q = noise_schedule(trajectory.duration, seed)
    return scheduled_scenario(
        "varying-matched",
        trajectory,
        times,
        q,
        matched_filter_config(),
        seed,
        MATCHED_BIAS_PSD,
    )


#: Noise regimes of a marine tactical-grade IMU at 100 Hz: per-sample variance bands
#: ``(accelerometer (m/s²)², gyro (rad/s)²)``, each ``(low, high)``. Sources:
#: - quiet survey: tactical-grade datasheets, velocity random walk 0.02–0.04 m/s/√h and
#:   angle random walk 0.03–0.1 °/√h, i.e. at 100 Hz (σ² = RW²·f): 1e-5–5e-5 (m/s²)²
#:   and 1e-8–1e-7 (rad/s)²;
#: - thrusters: the Snapir AUV's sections (``docs/results/snapir.md``; per-sample σ 0.01–0.04
#:   m/s² and 2e-4–1e-3 rad/s, mostly vibration): 1e-4–1e-3, 1e-7–1e-6;
#: - sea state: the vibration of a hull in waves, up to about 3× Snapir's worst
#:   accelerometer and 10× its worst gyro: 1e-3–3e-3, 1e-6–1e-5.
REGIMES: dict[str, tuple[tuple[float, float], tuple[float, float]]] = {
    "quiet": ((1e-5, 5e-5), (1e-8, 1e-7)),
    "thrusters": ((1e-4, 1e-3), (1e-7, 1e-6)),
    "sea state": ((1e-3, 3e-3), (1e-6, 1e-5)),
}
#: DVL noise of the realistic scenarios: (0.02 m/s)², the Workhorse Navigator's 1σ.
REALISTIC_DVL_VARIANCE = 0.02**2
#: DVL outages of the ``outage`` scenario [s]: three 60 s gaps.
OUTAGES = ((60.0, 120.0), (150.0, 210.0), (240.0, 300.0))


def regime_schedule(duration: float, seed: int) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """A regime-switching variance schedule ``(times (k,), q (k, 6), regimes)``: the
    vehicle starts quiet and holds each regime of :data:`REGIMES` for 30–90 s (drawn
    uniformly), then switches to one of the other two (equally likely); within a regime
    each channel's variance is drawn log-uniformly from the regime's band."""
    rng = np.random.default_rng([seed, 78])
    names = list(REGIMES)
    times, rows, regimes = [], [], []
    t, current = 0.0, "quiet"
    while t < duration:
        (a_lo, a_hi), (g_lo, g_hi) = REGIMES[current]
        acc = np.exp(rng.uniform(np.log(a_lo), np.log(a_hi), 3))
        gyro = np.exp(rng.uniform(np.log(g_lo), np.log(g_hi), 3))
        times.append(t)
        rows.append(np.concatenate([acc, gyro]))
        regimes.append(current)
        t += rng.uniform(30.0, 90.0)
        current = str(rng.choice([n for n in names if n != current]))
    return np.array(times), np.array(rows), regimes


def regimes_scenario(seed: int = 0) -> Scenario:
    """A realistic marine IMU on the paper's trajectory: its noise switches between a
    quiet survey and vibration regimes (:func:`regime_schedule`, drawn from ``seed``),
    the bias walk matched, DVL noise :data:`REALISTIC_DVL_VARIANCE`."""
    return _realistic("regimes", seed)


def outage_scenario(seed: int = 0) -> Scenario:
    """``regimes`` with the DVL silent during :data:`OUTAGES`: there Q alone sets how
    fast the covariance grows while nothing corrects it."""
    return _realistic("outage", seed, np.array(OUTAGES))


def _realistic(
    name: str,
    seed: int,
    dvl_outages: np.ndarray | None = None,
    trajectory: _core.Trajectory | None = None,
    **aiding: Any,
) -> Scenario:
    trajectory = trajectory if trajectory is not None else builtin_trajectory("paper")
    times, q, _ = regime_schedule(trajectory.duration, seed)
    return scheduled_scenario(
        name,
        trajectory,
        times,
        q,
        matched_filter_config(REALISTIC_DVL_VARIANCE),
        seed,
        MATCHED_BIAS_PSD,
        (REALISTIC_DVL_VARIANCE,) * 3,
        dvl_outages,
        **aiding,
    )


#: The ``mission`` scenario's aiding sensors. GNSS at the surface: 1σ 2.5 m north and
#: east (a consumer/marine receiver's horizontal accuracy, no height: the depth sensor
#: has it), 1 Hz while the true depth is at most 0.5 m (the antenna above water). USBL
#: acoustic fixes every 60 s, 1σ 3 m per axis (about 1 % of a few hundred metres of
#: slant range with the ship's own GNSS and attitude errors). A pressure depth sensor,
#: 1σ 0.1 m at 1 Hz (0.01-0.1 % of a 100-300 m full scale).
MISSION_GNSS = {"sigma": [2.5, 2.5], "period": 1.0, "max_depth": 0.5}
MISSION_USBL = {"sigma": [3.0, 3.0, 3.0], "period": 60.0}
MISSION_DEPTH_SIGMA = 0.1


def mission_trajectory(dt: float = 0.01) -> _core.Trajectory:
    """An AUV survey at 1.5 m/s, 1036 s, heading north from 32° N, 34° E at the surface:
    60 s at the surface, a dive (pitch down at 2°/s to −20°, held 48 s, levelled: 29.8 m
    deep), a lawnmower of four 150 s legs (225 m) joined by 180° turns at 3°/s (57 m
    apart, right then left), the ascent (the dive mirrored) and 60 s at the surface."""
    deg = math.radians
    rows = [[60.0, 0, 0, 0], [10.0, 0, 0, deg(-2)], [48.0, 0, 0, 0], [10.0, 0, 0, deg(2)]]
    for leg in range(4):
        rows.append([150.0, 0, 0, 0])
        if leg < 3:
            rows.append([60.0, 0, deg(3) if leg % 2 == 0 else deg(-3), 0])
    rows += [[10.0, 0, 0, deg(2)], [48.0, 0, 0, 0], [10.0, 0, 0, deg(-2)], [60.0, 0, 0, 0]]
    return trajectory_from_segments(
        np.array(rows), lla0=(deg(32.0), deg(34.0), 0.0), speed0=1.5, dt=dt, name="mission"
    )


def mission_scenario(seed: int = 0) -> Scenario:
    """An AUV mission (:func:`mission_trajectory`) with all its sensors: the DVL, IMU and
    filter of ``regimes`` (its noise schedule drawn from ``seed`` over the mission), a
    depth sensor throughout and position fixes: GNSS at the surface, USBL every 60 s
    (:data:`MISSION_GNSS`, :data:`MISSION_USBL`, :data:`MISSION_DEPTH_SIGMA`)."""
    return _realistic(
        "mission",
        seed,
        trajectory=mission_trajectory(),
        depth_sigma=MISSION_DEPTH_SIGMA,
        fixes=[MISSION_GNSS, MISSION_USBL],
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


#: Built-in scenarios by name; each builder takes the schedule seed.
SCENARIOS: dict[str, Callable[[int], Scenario]] = {
    "paper": paper_scenario,
    "varying-noise": varying_noise_scenario,
    "matched": matched_scenario,
    "varying-matched": varying_matched_scenario,
    "regimes": regimes_scenario,
    "outage": outage_scenario,
    "mission": mission_scenario,
}
#: The scenarios of the paper's reproduction (``pronet reproduce``).
PAPER_SCENARIOS = ("paper", "varying-noise")
#: The scenarios of the study (``pronet study``).
STUDY_SCENARIOS = ("matched", "varying-matched", "regimes", "outage", "mission")
