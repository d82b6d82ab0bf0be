"""Sections to learn q from: recorded missions with ground truth, and simulated
recordings of the study's ``regimes`` scenario, both held as the same
:class:`TrainingSection` (a :class:`~pronet.recorded.alignment.Section`, the filter
tuning it runs with, the constant row's q and, in simulation, the true q schedule).

- Recorded (:func:`recorded_sections`): read and aligned exactly as ``pronet real``
  reads them (clocks estimated, lever arms applied; Snapir's arms for its format, the
  generic format needs them given), filtered with
  :func:`pronet.recorded.tuning.real_filter_config`; the constant row's q is
  ``pronet real``'s, the section's own white-noise estimate
  (:func:`pronet.recorded.tuning.white_noise_q`).
- Simulated (:func:`simulated_sections`): the ``regimes`` scenario's trajectory
  (the paper's 330 s), IMU noise switching regimes
  (:func:`pronet.sim.scenarios.regime_schedule`, a schedule per section), the matched
  bias random walk, a 1 Hz DVL with (0.02 m/s)² noise, the truth at 1 Hz; the filter
  is the scenario's; the constant row's q is the schedule's time average (the study's
  "constant told the truth" row) and the oracle's q is the schedule itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pronet import _core
from pronet.recorded.alignment import (
    Alignment,
    Format,
    Section,
    dcm_from_euler,
    load_section,
    select_sections,
)
from pronet.recorded.tuning import imu_step, real_filter_config, white_noise_q
from pronet.recorded.vehicle import lever_arms
from pronet.sim.scenarios import (
    MATCHED_BIAS_PSD,
    REALISTIC_DVL_VARIANCE,
    matched_filter_config,
    regime_schedule,
    time_average_q,
)
from pronet.trajectory import builtin_trajectory

F64 = NDArray[np.float64]

#: Ground-truth rows per simulated second (the DVL's rate; Snapir's truth is 1 Hz too).
SIM_TRUTH_RATE = 1.0
#: Memory [bytes] a simulated recording holds per IMU sample (its IMU and clock, 56,
#: and the DVL and truth at 1 Hz; measured 57-58 with tracemalloc: 1.9 MB per 330 s).
SIM_BYTES_PER_SAMPLE = 64


@dataclass(frozen=True)
class TrainingSection:
    """One section to train on or to score.

    Attributes:
        section: the sensors and the truth at the IMU, on the IMU clock.
        config: the filter tuning every row runs with.
        q_nominal: the constant row's 6 per-sample variances [(m/s²)², (rad/s)²].
        oracle_time, oracle_q: simulation only: the true schedule ``(k,)`` [s] and
            ``(k, 6)``, in force from each time on; None for recorded data.
    """

    section: Section
    config: _core.FilterConfig
    q_nominal: tuple[float, ...]
    oracle_time: F64 | None = None
    oracle_q: F64 | None = None

    @property
    def name(self) -> str:
        return self.section.name


def recorded_sections(
    data: str | Path,
    fmt: Format = "snapir",
    names: list[str] | tuple[str, ...] | None = None,
    *,
    imu_lever_arm: tuple[float, float, float] | None = None,
    dvl_lever_arm: tuple[float, float, float] | None = None,
    covariance_step: float | None = None,
) -> list[TrainingSection]:
    """The sections under ``data`` (only ``names`` when given), aligned as ``pronet
    real`` aligns them; ``ValueError`` naming the section when one cannot be read or
    has fewer than two ground-truth rows inside its IMU record."""
    imu_arm, dvl_arm = lever_arms(fmt, imu_lever_arm, dvl_lever_arm, None)
    paths = select_sections(data, names)
    if not paths:
        raise ValueError(f"--recorded: no section found under {data}")
    out = []
    for path in paths:
        try:
            aligned, _ = load_section(path, fmt, imu_lever_arm=imu_arm, dvl_lever_arm=dvl_arm)
        except (OSError, ValueError) as exc:
            raise ValueError(f"--recorded: {path}: {exc}") from None
        inside = (aligned.truth_time >= aligned.imu_time[0]) & (
            aligned.truth_time <= aligned.imu_time[-1]
        )
        if inside.sum() < 2:
            raise ValueError(f"--recorded: {path}: no ground truth inside the IMU record")
        config = real_filter_config(
            aligned.alignment.filter_lever_arm,
            aligned.dvl_variance,
            imu_dt=imu_step(aligned.imu_time),
            covariance_step=covariance_step,
        )
        out.append(TrainingSection(aligned, config, white_noise_q(aligned.imu)))
    return out


def simulated_section(seed: int, duration: float | None = None) -> TrainingSection:
    """One simulated ``regimes`` recording (see the module), its noise schedule and
    sensor noise drawn from ``seed``; ``duration`` [s] cuts the paper's 330 s
    trajectory shorter (tests)."""
    trajectory = builtin_trajectory("paper")
    n = trajectory.n_samples
    if duration is not None:
        _check_duration(duration, trajectory)
        n = int(round(duration / trajectory.dt))
    span = n * trajectory.dt
    times, q, _ = regime_schedule(span, seed)
    rng = np.random.default_rng([seed, 39])
    t = trajectory.time[: n + 1]
    piece = np.searchsorted(times, t[:-1], side="right") - 1  # sample k: (t_k, t_k+1]
    dt = trajectory.dt
    walk = rng.standard_normal((n, 6)) * np.sqrt(np.array(MATCHED_BIAS_PSD) * dt)
    bias = np.cumsum(walk, axis=0)
    imu = trajectory.imu[:n] + bias + rng.standard_normal((n, 6)) * np.sqrt(q[piece])
    every = int(round(1.0 / (SIM_TRUTH_RATE * dt)))
    truth = np.arange(0, n + 1, every)
    dvl_rows = truth[1:]
    c = dcm_from_euler(trajectory.rpy[dvl_rows])
    body = np.einsum("kji,kj->ki", c, trajectory.vel_ned[dvl_rows])
    dvl = body + rng.standard_normal(body.shape) * np.sqrt(REALISTIC_DVL_VARIANCE)
    section = Section(
        name=f"regimes-{seed}",
        imu_time=t[1:].copy(),
        imu=imu,
        dvl_time=t[dvl_rows].copy(),
        dvl=dvl,
        truth_time=t[truth].copy(),
        truth_lla=trajectory.lla[truth].copy(),
        truth_vel=trajectory.vel_ned[truth].copy(),
        truth_rpy=trajectory.rpy[truth].copy(),
        alignment=Alignment(how="given"),
    )
    return TrainingSection(
        section,
        matched_filter_config(REALISTIC_DVL_VARIANCE),
        time_average_q(times, q, span),
        times.astype(np.float64),
        q.astype(np.float64),
    )


def simulated_sections(
    n: int, seed: int = 0, duration: float | None = None
) -> list[TrainingSection]:
    """``n`` simulated ``regimes`` recordings, seeds ``seed .. seed + n − 1``. Raises
    ValueError before building any when they would hold more than
    :data:`pronet.learn.dataset.MAX_DATASET_BYTES` (4 GiB: about 2,000 of 330 s)."""
    if n < 1:
        raise ValueError(f"n: must be at least 1, got {n}")
    if seed < 0:
        raise ValueError(f"seed: must be >= 0, got {seed}")
    check_simulated_memory(n, duration)
    return [simulated_section(seed + i, duration) for i in range(n)]


def _check_duration(duration: float, trajectory: _core.Trajectory) -> None:
    """ValueError naming ``duration`` [s] unless it lies within [2 s, the trajectory's]."""
    if not 2.0 <= duration <= trajectory.duration:  # NaN too
        raise ValueError(f"duration: must be within [2, {trajectory.duration:g}] s")


def check_simulated_memory(n: int, duration: float | None = None, name: str = "n") -> None:
    """Raises ValueError, naming the argument ``name``, when ``n`` simulated recordings
    of ``duration`` [s] (default the paper's 330 s) would hold more memory than
    :data:`pronet.learn.dataset.MAX_DATASET_BYTES`."""
    from pronet.learn.dataset import MAX_DATASET_BYTES

    trajectory = builtin_trajectory("paper")
    if duration is not None:
        _check_duration(duration, trajectory)
    span = trajectory.duration if duration is None else duration
    each = int(span / trajectory.dt) * SIM_BYTES_PER_SAMPLE
    if n * each > MAX_DATASET_BYTES:
        raise ValueError(
            f"{name}: {n} simulated recordings of {span:g} s would hold "
            f"{n * each / 2**30:.1f} GiB; at most {MAX_DATASET_BYTES / 2**30:.0f} GiB "
            f"({MAX_DATASET_BYTES // each} recordings)"
        )
