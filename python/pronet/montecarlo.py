"""Monte Carlo runs of a simulated scenario with one process-noise strategy.

Run i of a Monte Carlo with seed s draws all its noise from random streams keyed by
(s, i), so results do not depend on the thread count, and every strategy run with the
same seed sees the same noise realizations (common random numbers): differences between
strategies are paired.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from pronet import _core
from pronet._validate import check_type, count
from pronet.stats import MeanCI, mean_ci

#: Names of the five 3-blocks of the error state, in order.
STATE_BLOCKS = ("position", "velocity", "attitude", "accel_bias", "gyro_bias")


@dataclass(frozen=True)
class MonteCarloResult:
    """Per-run metrics and per-epoch consistency statistics.

    Attributes:
        srmse: ``(n_runs,)`` velocity SRMSE ``sqrt(mean_k Σ_NED δv²)`` [m/s].
        smae: ``(n_runs,)`` velocity SMAE ``mean_k Σ_NED |δv|`` [m/s].
        final_horizontal_error: ``(n_runs,)`` horizontal position error at the end [m].
        max_horizontal_error: ``(n_runs,)`` largest horizontal position error [m].
        mean_nis: ``(n_runs,)`` mean NIS over the DVL epochs.
        failure: per run, None or the message of the numerical failure that stopped it
            (its metrics are then NaN).
        dvl_time: ``(m,)`` DVL epoch times [s].
        nis: ``(n_runs, m)`` NIS at each DVL epoch (3 dof).
        nees: ``(n_runs, m, 5)`` NEES after each update of the blocks in
            :data:`STATE_BLOCKS` (3 dof each).
        record_time: ``(r,)`` history epochs [s] (empty without ``record_every``).
        error: ``(n_runs, r, 15)`` true error ``[δp (NED m), δv (m/s), ψ (rad), δb_a, δb_g]``.
        sigma: ``(n_runs, r, 15)`` filter 1σ of the same.
        q: ``(n_runs, r, 6)`` IMU variances the strategy used (NaN where it has none).
    """

    srmse: NDArray[np.float64]
    smae: NDArray[np.float64]
    final_horizontal_error: NDArray[np.float64]
    max_horizontal_error: NDArray[np.float64]
    mean_nis: NDArray[np.float64]
    failure: list[str | None]
    dvl_time: NDArray[np.float64]
    nis: NDArray[np.float64]
    nees: NDArray[np.float64]
    record_time: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    error: NDArray[np.float64] | None = None
    sigma: NDArray[np.float64] | None = None
    q: NDArray[np.float64] | None = None

    @property
    def n_runs(self) -> int:
        return int(self.srmse.shape[0])

    @property
    def n_failed(self) -> int:
        return sum(f is not None for f in self.failure)

    def summary(self) -> dict[str, MeanCI]:
        """Mean and 95 % CI over runs of every per-run metric."""
        return {
            name: mean_ci(getattr(self, name))
            for name in (
                "srmse",
                "smae",
                "final_horizontal_error",
                "max_horizontal_error",
                "mean_nis",
            )
        }


def monte_carlo(
    trajectory: _core.Trajectory,
    strategy: _core.Strategy,
    *,
    sensors: _core.SensorConfig | None = None,
    config: _core.FilterConfig | None = None,
    n_runs: int = 100,
    seed: int = 0,
    record_every: int = 0,
    sample_initial_error: bool = True,
    threads: int | None = None,
) -> MonteCarloResult:
    """Simulate ``n_runs`` noisy runs along ``trajectory`` and filter each one.

    Args:
        trajectory: truth and ideal IMU (e.g. ``builtin_trajectory("paper")``).
        strategy: process-noise strategy.
        sensors: sensor models (default ``SensorConfig()``: the paper's IMU and DVL).
        config: filter tuning (default ``FilterConfig()``).
        n_runs: number of runs.
        seed: Monte Carlo seed (run i uses the streams of (seed, i)).
        record_every: keep the error and 1σ history every this many IMU steps (0: none).
        sample_initial_error: start each run from the truth plus an error drawn from
            the filter's P0 (True) or exactly at the truth (False).
        threads: worker threads (default: all cores).
    """
    check_type(trajectory, _core.Trajectory, "trajectory")
    check_type(strategy, _core.Strategy, "strategy")
    sensors = sensors if sensors is not None else _core.SensorConfig()
    config = config if config is not None else _core.FilterConfig()
    check_type(sensors, _core.SensorConfig, "sensors")
    check_type(config, _core.FilterConfig, "config")
    seed = count(seed, "seed")
    if seed < 0:
        raise ValueError(f"seed: must be >= 0, got {seed}")
    out = _core.monte_carlo(
        trajectory,
        sensors,
        config,
        strategy,
        n_runs=count(n_runs, "n_runs"),
        seed=seed,
        record_every=count(record_every, "record_every"),
        sample_initial_error=bool(sample_initial_error),
        threads=None if threads is None else count(threads, "threads"),
    )
    return MonteCarloResult(**out)
