"""The consistency suite: is the filter's σ honest, block by block, for every IMU grade?

Each cell is a Monte Carlo of one IMU grade (:data:`GRADES`) on one motion
(:data:`MOTIONS`) with a DVL at 1 or 5 Hz, 1200 s long, the filter told the exact
noise model. Per error block (position, velocity, attitude, accelerometer and gyro
bias) it reports the share of DVL epochs whose run-averaged NEES lies inside its 95 %
band, and the heading error RMS at the end against the filter's mean 1σ there. Each
block's NEES is taken in the coordinates where its error is linear (the velocity as
the body-frame velocity error rotated to NED; see ``docs/reference/filter.md``, "Metrics").

Initial errors: ``draw=True`` draws every initial error, the biases' too, from P0 (the
filter starts at its prior mean, so its errors are P0-distributed); ``draw=False``
starts the filter at the truth with zero biases, where a consistent filter is
conservative (its error stays below its σ).

``python scripts/consistency.py`` runs the whole grid and writes the tables of
``docs/results/consistency.md``; the cheap cells are tests
(``tests/experiments/test_consistency.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from pronet import _core
from pronet.montecarlo import STATE_BLOCKS, MonteCarloResult, monte_carlo

#: The filter's velocity-error coordinates (:class:`pronet.FilterConfig`).
Formulation = Literal["invariant", "classic", "se23"]

#: IMU grades: per-sample white-noise variance at 100 Hz of the accelerometers
#: [(m/s²)²] and gyros [(rad/s)²], turn-on bias 1σ [m/s², rad/s] and bias random-walk
#: PSDs [(m/s²)²/s, (rad/s)²/s]. MEMS is the grade whose heading the classic
#: formulation got wrong (gyro ARW ≈ 1.5 °/√h, bias 41 °/h); tactical is ≈ 0.11 °/√h
#: and 1 °/h; FOG (navigation grade) ≈ 0.011 °/√h and 0.01 °/h.
GRADES: dict[str, dict[str, float]] = {
    "mems": {"q_a": 2e-3, "q_g": 2e-5, "b_a": 1e-3, "b_g": 2e-4, "w_a": 1e-9, "w_g": 2.35e-12},
    "tactical": {"q_a": 2.5e-5, "q_g": 1e-7, "b_a": 1e-3, "b_g": 5e-6, "w_a": 1e-11, "w_g": 1e-15},
    "fog": {"q_a": 2.5e-6, "q_g": 1e-9, "b_a": 2e-4, "b_g": 5e-8, "w_a": 1e-13, "w_g": 1e-17},
}

_DEG = math.pi / 180.0
#: Motions, 1200 s at 1.5 m/s: rows ``[duration s, accel m/s², yaw rate rad/s, pitch
#: rate rad/s]`` of :func:`pronet.trajectory_from_segments`.
MOTIONS: dict[str, list[list[float]]] = {
    "straight": [[1200.0, 0.0, 0.0, 0.0]],
    "turns": [
        [100.0, 0.0, 0.0, 0.0],
        [90.0, 0.0, 2 * _DEG, 0.0],
        [500.0, 0.0, 0.0, 0.0],
        [90.0, 0.0, -2 * _DEG, 0.0],
        [420.0, 0.0, 0.0, 0.0],
    ],
    "helix": [
        [10.0, 0.0, 0.0, -1 * _DEG],
        [10.0, 0.0, 0.0, 1 * _DEG],
        [1180.0, 0.0, 3 * _DEG, 0.0],
    ],
    "zigzag": [[60.0, 0.0, 0.0, 0.0]]
    + [[30.0, 0.0, s * 3 * _DEG, 0.0] for s in (1, -1, -1, 1) * 9]
    + [[60.0, 0.0, 0.0, 0.0]],
}
#: DVL noise 1σ [m/s] per axis.
DVL_SIGMA = 0.02


@dataclass(frozen=True)
class Cell:
    """One cell of the suite.

    Attributes:
        grade, motion, formulation, dvl_hz, draw: what was run.
        runs: Monte Carlo runs.
        heading_rms, heading_sigma: heading error RMS over the runs and the filter's
            mean 1σ at the end [rad].
        gyro_z_sigma_ratio: the vertical gyro bias's final mean 1σ over its prior.
        inside: per block (:data:`pronet.montecarlo.STATE_BLOCKS`), the share of DVL
            epochs whose NEES averaged over the runs lies inside its 95 % band.
        mean_nees: per block, the NEES averaged over runs and epochs (3 if consistent).
        mean_nis: NIS over every update (3 if consistent).
    """

    grade: str
    motion: str
    formulation: str
    dvl_hz: float
    draw: bool
    runs: int
    heading_rms: float
    heading_sigma: float
    gyro_z_sigma_ratio: float
    inside: tuple[float, ...]
    mean_nees: tuple[float, ...]
    mean_nis: float

    @property
    def heading_ratio(self) -> float:
        """Heading error RMS over its mean 1σ (1 when consistent, < 1 conservative)."""
        return self.heading_rms / self.heading_sigma


def filter_config(
    grade: str, formulation: Formulation, *, second_order: bool = False
) -> _core.FilterConfig:
    """The filter told ``grade``'s exact model: its bias priors and walks, position
    1 m, velocity 0.02 m/s, roll and pitch 1 mrad, heading 1° (1σ); ``second_order``:
    with the second-order heading term (``FilterConfig.heading_second_order``)."""
    g = GRADES[grade]
    p0 = [1.0] * 3 + [0.02] * 3 + [1e-3, 1e-3, _DEG] + [g["b_a"]] * 3 + [g["b_g"]] * 3
    return _core.FilterConfig(
        p0_sigma=p0,
        accel_bias_psd=g["w_a"],
        gyro_bias_psd=g["w_g"],
        dvl_variance=[DVL_SIGMA**2] * 3,
        formulation=formulation,
        heading_second_order=second_order,
    )


def _monte_carlo(
    what: tuple[str, Formulation, list, str],
    how: tuple[int, int, int, bool, bool],
    *,
    second_order: bool = False,
    **aiding: Any,
) -> MonteCarloResult:
    """The constant-Q Monte Carlo of ``what`` = (``grade``'s IMU, the filter's
    formulation, trajectory segments and their name) from the cells' start (32° N,
    34° E, 20 m deep, 1.5 m/s), its white noise and bias walks simulated and the filter
    told them (:func:`filter_config`), a DVL of σ :data:`DVL_SIGMA` and ``aiding``'s
    other sensor keys; ``how`` = (runs, seed, record_every, sample_initial_error,
    smooth); ``second_order`` as :func:`filter_config`'s."""
    grade, formulation, segments, name = what
    runs, seed, record_every, draw, smooth = how
    g = GRADES[grade]
    q = [g["q_a"]] * 3 + [g["q_g"]] * 3
    trajectory = _core.trajectory_from_segments(
        np.array(segments), lla0=[32.0 * _DEG, 34.0 * _DEG, -20.0], speed0=1.5, dt=0.01,
        name=name,
    )  # fmt: skip
    sensors = _core.SensorConfig(
        imu_variance=q, imu_bias_psd=[g["w_a"]] * 3 + [g["w_g"]] * 3,
        dvl_variance=[DVL_SIGMA**2] * 3, **aiding,
    )  # fmt: skip
    return monte_carlo(
        trajectory, _core.Strategy.constant(q), sensors=sensors,
        config=filter_config(grade, formulation, second_order=second_order), n_runs=runs, seed=seed,
        record_every=record_every, sample_initial_error=draw, smooth=smooth,
    )  # fmt: skip


def run_cell(
    grade: str,
    motion: str,
    formulation: Formulation,
    *,
    dvl_hz: float = 5.0,
    draw: bool = True,
    runs: int = 20,
    seed: int = 0,
    second_order: bool = False,
) -> Cell:
    """Run one cell (see the module's docstring); ``second_order``: with the
    second-order heading term (:func:`filter_config`)."""
    g = GRADES[grade]
    every = int(round(100 / dvl_hz))
    out = _monte_carlo(
        (grade, formulation, MOTIONS[motion], motion),
        (runs, seed, every * 50, draw, False),
        dvl_period=1.0 / dvl_hz,
        second_order=second_order,
    )
    error, sigma = out.error, out.sigma
    assert error is not None and sigma is not None  # record_every > 0
    return Cell(
        grade=grade,
        motion=motion,
        formulation=formulation + (" + second order" if second_order else ""),
        dvl_hz=dvl_hz,
        draw=draw,
        runs=runs,
        heading_rms=float(np.sqrt(np.mean(error[:, -1, 8] ** 2))),
        heading_sigma=float(np.mean(sigma[:, -1, 8])),
        gyro_z_sigma_ratio=float(np.mean(sigma[:, -1, 14]) / g["b_g"]),
        inside=tuple(out.nees_in_band(block) for block in STATE_BLOCKS),
        mean_nees=tuple(float(np.mean(out.block_nees(block))) for block in STATE_BLOCKS),
        mean_nis=float(np.mean(out.nis)),
    )


#: The long MEMS mission without fixes: a lawnmower at 1.5 m/s, legs of 60 s joined by
#: 180° turns at 6 °/s (30 s), alternately to starboard and to port, for 1 h.
LAWNMOWER_HOURS = 1.0
#: DVL bottom-lock losses (mean interval, mean length) [s] and the depth sensor
#: (1σ [m], period [s]) of the lawnmower.
LAWNMOWER_DROPOUT = (300.0, 10.0)
LAWNMOWER_DEPTH = (0.1, 1.0)


def lawnmower_segments(hours: float = LAWNMOWER_HOURS) -> list[list[float]]:
    """The lawnmower's segments, rows of :func:`pronet.trajectory_from_segments`."""
    rows: list[list[float]] = []
    turn = 6 * _DEG
    side = 1.0
    while sum(r[0] for r in rows) < hours * 3600.0:
        rows += [[60.0, 0.0, 0.0, 0.0], [30.0, 0.0, side * turn, 0.0]]
        side = -side
    return rows


@dataclass(frozen=True)
class Mission:
    """The lawnmower Monte Carlo of one formulation (:func:`run_lawnmower`).

    Attributes:
        formulation, runs: what was run.
        inside, smoothed_inside: per block (:data:`pronet.montecarlo.STATE_BLOCKS`),
            the share of DVL epochs whose run-averaged NEES lies in its 95 % band,
            forward and smoothed.
        mean_nees, smoothed_mean_nees: per block, the NEES averaged over runs and
            epochs.
        heading_error_deg: the largest heading error of any run at the end [deg].
    """

    formulation: str
    runs: int
    inside: tuple[float, ...]
    smoothed_inside: tuple[float, ...]
    mean_nees: tuple[float, ...]
    smoothed_mean_nees: tuple[float, ...]
    heading_error_deg: float


def run_lawnmower(
    formulation: Formulation,
    *,
    grade: str = "mems",
    hours: float = LAWNMOWER_HOURS,
    runs: int = 20,
    seed: int = 0,
    second_order: bool = False,
) -> Mission:
    """A long mission without fixes: ``grade``'s IMU on :func:`lawnmower_segments`
    at 1.5 m/s, 20 m deep, a 5 Hz DVL with random bottom-lock losses
    (:data:`LAWNMOWER_DROPOUT`), a depth sensor (:data:`LAWNMOWER_DEPTH`), the filter
    told the exact model (:func:`filter_config`), every initial error drawn from P0,
    smoothed too. The position block's NEES is taken in the filter's own coordinates
    (in SE₂(3), ``δP = p̂ − Ĉ Cᵀ p`` about the first position); ``second_order``: the
    filter carries the second-order heading term (:func:`filter_config`)."""
    out = _monte_carlo(
        (grade, formulation, lawnmower_segments(hours), "lawnmower"),
        (runs, seed, 100 * 60, True, True),
        dvl_period=0.2,
        dvl_dropout=LAWNMOWER_DROPOUT,
        depth_sigma=LAWNMOWER_DEPTH[0],
        depth_period=LAWNMOWER_DEPTH[1],
        second_order=second_order,
    )
    smoothed = out.smoothed
    assert smoothed is not None and out.error is not None  # smooth=True, recorded
    return Mission(
        formulation=formulation + (" + second order" if second_order else ""),
        runs=runs,
        inside=tuple(out.nees_in_band(b) for b in STATE_BLOCKS),
        smoothed_inside=tuple(smoothed.nees_in_band(b) for b in STATE_BLOCKS),
        mean_nees=tuple(float(np.nanmean(out.block_nees(b))) for b in STATE_BLOCKS),
        smoothed_mean_nees=tuple(float(np.nanmean(smoothed.block_nees(b))) for b in STATE_BLOCKS),
        heading_error_deg=float(np.max(np.abs(out.error[:, -1, 8])) / _DEG),
    )
