"""The DVL calibration states in simulation: what the 19-state filter buys against the
15-state one when the DVL has a scale-factor error and a yaw misalignment.

One experiment per training trajectory (:data:`TRAJECTORIES`): a DVL reading 0.5 %
fast and turned 0.5° in yaw (:data:`TRUE_SCALE`, :data:`TRUE_MISALIGNMENT`), the IMU
and the filter's tuning those of the recorded sections (a navigation-grade FOG INS,
:func:`pronet.recorded.tuning.real_filter_config`'s P0 and bias walks; IMU noise
:data:`IMU_Q`), both filters told the true q. All runs of both filters see the same
noise (common random numbers). Reported per trajectory (:class:`CalibrationRow`): mean
final horizontal error and SRMSE of each filter, the share of runs whose four
calibration errors all lie within 3σ, and the share of DVL epochs whose mean NIS and
mean calibration NEES over the runs lie inside their 95 % bands
(:func:`pronet.stats.chi2_mean_band`).

A caution on the NEES: the truth is fixed, not drawn from the filter's prior, so the
directions the data cannot see (roll and pitch of the DVL here, both truly 0) add
almost nothing to it and the mean stays below 4 even for a consistent filter.
:func:`drawn_consistency` draws each run's DVL from the prior instead, which is what a
NEES test of the calibration states assumes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple, Protocol

import numpy as np

from pronet import _core
from pronet.montecarlo import monte_carlo
from pronet.recorded.tuning import REAL_ACCEL_BIAS_PSD, REAL_GYRO_BIAS_PSD, REAL_P0_SIGMA
from pronet.results import markdown
from pronet.stats import chi2_mean_band
from pronet.trajectory import builtin_trajectory

#: The four training trajectories (``pronet.builtin_trajectory_names()``).
TRAJECTORIES = ("train-straight", "train-turns", "train-zigzag", "train-helix")
#: The simulated DVL's scale-factor error: it reads 0.5 % fast.
TRUE_SCALE = 0.005
#: The simulated DVL's mounting roll, pitch, yaw in the body frame [rad]: 0.5° in yaw.
TRUE_MISALIGNMENT = (0.0, 0.0, math.radians(0.5))
#: Per-sample IMU noise variances [(m/s²)², (rad/s)²]: the geometric middle of the
#: "thrusters" regime of :data:`pronet.sim.scenarios.REGIMES`, i.e. the Snapir AUV's.
IMU_Q = (10**-3.5,) * 3 + (10**-6.5,) * 3
#: DVL noise [(m/s)²]: (0.02 m/s)², the datasheet's.
DVL_VARIANCE = 0.02**2


def sensors(
    scale: float = TRUE_SCALE,
    misalignment: tuple[float, float, float] = TRUE_MISALIGNMENT,
) -> _core.SensorConfig:
    """The simulated sensors: :data:`IMU_Q` with the recorded sections' bias walks, the
    DVL with the scale error ``scale`` and mounting roll, pitch, yaw ``misalignment``
    [rad] (default: :data:`TRUE_SCALE`, :data:`TRUE_MISALIGNMENT`; zeros: ideal)."""
    return _core.SensorConfig(
        imu_variance=IMU_Q,
        imu_bias_psd=(REAL_ACCEL_BIAS_PSD,) * 3 + (REAL_GYRO_BIAS_PSD,) * 3,
        dvl_variance=(DVL_VARIANCE,) * 3,
        dvl_scale=scale,
        dvl_misalignment=misalignment,
    )


def filter_config(
    calibration: bool, prior: tuple[float, float] | None = None
) -> _core.FilterConfig:
    """The recorded sections' tuning, with or without the calibration states; their
    prior ``(scale σ, angle σ [rad])`` per axis, constants (default: the core's 1 % and
    1°)."""
    scale, angle = (None, None) if prior is None or not calibration else prior
    return _core.FilterConfig(
        p0_sigma=REAL_P0_SIGMA,
        accel_bias_psd=REAL_ACCEL_BIAS_PSD,
        gyro_bias_psd=REAL_GYRO_BIAS_PSD,
        dvl_variance=(DVL_VARIANCE,) * 3,
        dvl_calibration=calibration,
        dvl_scale_sigma=scale,
        dvl_misalignment_sigma=None if angle is None else (angle,) * 3,
    )


class Spread(NamedTuple):
    """The final estimated scale error and yaw misalignment over the runs: mean and
    standard deviation (``scale``, ``yaw`` [rad]) and the mean of the filter's 1σ."""

    scale: tuple[float, float]
    sigma_scale: float
    yaw: tuple[float, float]
    sigma_yaw: float


def estimate_spread(error: np.ndarray, sigma: np.ndarray) -> Spread:
    """:class:`Spread` of the runs' final calibration errors ``error`` and 1σ ``sigma``
    (``(n_runs, 4)``: scale error, roll, pitch, yaw), the estimates being the truth
    (:data:`TRUE_SCALE`, :data:`TRUE_MISALIGNMENT`) plus the errors."""
    estimate = error + np.array([TRUE_SCALE, *TRUE_MISALIGNMENT])
    return Spread(
        scale=(float(np.mean(estimate[:, 0])), float(np.std(estimate[:, 0]))),
        sigma_scale=float(np.mean(sigma[:, 0])),
        yaw=(float(np.mean(estimate[:, 3])), float(np.std(estimate[:, 3]))),
        sigma_yaw=float(np.mean(sigma[:, 3])),
    )


class HasSpread(Protocol):
    """A table row with a :class:`Spread`'s fields."""

    @property
    def scale(self) -> tuple[float, float]: ...
    @property
    def sigma_scale(self) -> float: ...
    @property
    def yaw(self) -> tuple[float, float]: ...
    @property
    def sigma_yaw(self) -> float: ...


def spread_cells(row: HasSpread) -> list[str]:
    """The table cells of a row's spread: ``"scale [%] (1σ)"`` and ``"yaw [°] (1σ)"``,
    each ``mean ± std (mean 1σ)``."""
    return [
        f"{100 * row.scale[0]:.2f} ± {100 * row.scale[1]:.2f} ({100 * row.sigma_scale:.2f})",
        f"{math.degrees(row.yaw[0]):.2f} ± {math.degrees(row.yaw[1]):.2f} "
        f"({math.degrees(row.sigma_yaw):.2f})",
    ]


def miscalibration() -> str:
    """The simulated DVL's errors, for a table's title."""
    yaw = math.degrees(TRUE_MISALIGNMENT[2])
    return f"DVL with a {100 * TRUE_SCALE:g} % scale error and {yaw:g}° yaw misalignment"


@dataclass(frozen=True)
class CalibrationRow:
    """One trajectory of :func:`calibration_check`.

    Attributes:
        final_15, final_19: mean final horizontal error [m] of each filter.
        final_ideal: the 15-state filter's with an ideal DVL (the floor).
        srmse_15, srmse_19: mean velocity SRMSE [m/s].
        inside_3sigma: share of runs whose four calibration errors are all within 3σ.
        nis_in_band, nees_in_band: share of DVL epochs whose mean NIS (3 dof) and mean
            calibration NEES (4 dof) over the runs lie in their 95 % bands.
        scale, yaw: mean and standard deviation over the runs of the final estimated
            scale error and yaw misalignment [rad]; sigma_scale, sigma_yaw: mean 1σ.
    """

    trajectory: str
    runs: int
    final_15: float
    final_19: float
    final_ideal: float
    srmse_15: float
    srmse_19: float
    inside_3sigma: float
    nis_in_band: float
    nees_in_band: float
    scale: tuple[float, float]
    sigma_scale: float
    yaw: tuple[float, float]
    sigma_yaw: float

    @property
    def ratio(self) -> float:
        """The 19-state filter's mean final error over the 15-state one's."""
        return self.final_19 / self.final_15


def _in_band(values: np.ndarray, dof: int, runs: int) -> float:
    lo, hi = chi2_mean_band(dof, runs)
    mean = np.nanmean(values, axis=0)
    return float(np.mean((mean >= lo) & (mean <= hi)))


def calibration_check(
    n_runs: int = 100,
    seed: int = 0,
    trajectories: tuple[str, ...] = TRAJECTORIES,
    prior: tuple[float, float] | None = None,
) -> list[CalibrationRow]:
    """Both filters on each trajectory, ``n_runs`` runs each from ``seed``, and the
    15-state filter with an ideal DVL (see the module docstring); ``prior``: the
    calibration states' ``(scale σ, angle σ [rad])`` (default 1 %, 1°)."""
    rows = []
    strategy = _core.Strategy.constant(IMU_Q)
    for name in trajectories:
        traj = builtin_trajectory(name)
        plain, calibrated, ideal = [
            monte_carlo(
                traj,
                strategy,
                sensors=sensors(0.0, (0.0, 0.0, 0.0)) if ideal_dvl else sensors(),
                config=filter_config(calibration, prior),
                n_runs=n_runs,
                seed=seed,
            )
            for ideal_dvl, calibration in ((False, False), (False, True), (True, False))
        ]
        error, sigma = calibrated.calibration_error, calibrated.calibration_sigma
        nees = calibrated.calibration_nees
        if error is None or sigma is None or nees is None:
            raise RuntimeError("the calibrated Monte Carlo reported no calibration states")
        spread = estimate_spread(error, sigma)
        rows.append(
            CalibrationRow(
                trajectory=name,
                runs=n_runs,
                final_15=float(np.mean(plain.final_horizontal_error)),
                final_19=float(np.mean(calibrated.final_horizontal_error)),
                final_ideal=float(np.mean(ideal.final_horizontal_error)),
                srmse_15=float(np.mean(plain.srmse)),
                srmse_19=float(np.mean(calibrated.srmse)),
                inside_3sigma=float(np.mean(np.all(np.abs(error) <= 3 * sigma, axis=1))),
                nis_in_band=_in_band(calibrated.nis, 3, n_runs),
                nees_in_band=_in_band(nees, 4, n_runs),
                **spread._asdict(),
            )
        )
    return rows


def calibration_table(rows: list[CalibrationRow]) -> str:
    """Markdown: one line per trajectory of :func:`calibration_check`."""
    header = [
        "trajectory",
        "final error 15 / 19 states (ideal DVL) [m]",
        "19 / 15",
        "SRMSE 15 / 19 [m/s]",
        "scale [%] (1σ)",
        "yaw [°] (1σ)",
        "runs within 3σ",
        "epochs: NIS / NEES in 95 % band",
    ]
    lines: list[list[object]] = []
    for r in rows:
        lines.append(
            [
                r.trajectory,
                f"{r.final_15:.2f} / {r.final_19:.2f} ({r.final_ideal:.2f})",
                f"{r.ratio:.2f}",
                f"{r.srmse_15:.4f} / {r.srmse_19:.4f}",
                *spread_cells(r),
                f"{100 * r.inside_3sigma:.0f} %",
                f"{100 * r.nis_in_band:.0f} % / {100 * r.nees_in_band:.0f} %",
            ]
        )
    title = f"{miscalibration()}, {rows[0].runs if rows else 0} runs per trajectory"
    return markdown(header, lines, title)


@dataclass(frozen=True)
class DrawnConsistency:
    """The calibrated filter's consistency when each run's DVL scale and mounting are
    drawn from the filter's own prior (:func:`drawn_consistency`).

    Attributes:
        nees_in_band, nis_in_band: share of DVL epochs whose mean calibration NEES
            (4 dof) and mean NIS (3 dof) over the runs lie in their 95 % bands.
        inside_3sigma: share of runs whose four final calibration errors are all within 3σ.
        mean_nees: the mean calibration NEES over runs and epochs (4 when consistent).
    """

    trajectory: str
    runs: int
    nees_in_band: float
    nis_in_band: float
    inside_3sigma: float
    mean_nees: float


def drawn_consistency(
    trajectory: str = "train-zigzag", n_runs: int = 100, seed: int = 0
) -> DrawnConsistency:
    """The 19-state filter on ``trajectory``, each of ``n_runs`` runs with its own DVL:
    scale error and mounting angles drawn from the filter's prior (N(0, 1 %) and
    N(0, 1°) per axis, from ``seed``), its own noise (run index ``i``). One Monte Carlo
    call per run, so about 20 times slower per run than :func:`calibration_check`."""
    cfg = filter_config(True)
    scale_sigma = cfg.dvl_scale_sigma or 0.0
    angle_sigma = np.asarray(cfg.dvl_misalignment_sigma or [0.0] * 3)
    rng = np.random.default_rng([seed, 22])
    traj = builtin_trajectory(trajectory)
    strategy = _core.Strategy.constant(IMU_Q)
    nees, nis, inside = [], [], []
    for i in range(n_runs):
        scale = float(scale_sigma * rng.normal())
        a = angle_sigma * rng.normal(size=3)
        dvl = sensors(scale, (float(a[0]), float(a[1]), float(a[2])))
        run = monte_carlo(traj, strategy, sensors=dvl, config=cfg, n_runs=1, seed=seed, first_run=i)
        error, sigma = run.calibration_error, run.calibration_sigma
        if run.calibration_nees is None or error is None or sigma is None:
            raise RuntimeError("the calibrated Monte Carlo reported no calibration states")
        nees.append(run.calibration_nees[0])
        nis.append(run.nis[0])
        inside.append(bool(np.all(np.abs(error[0]) <= 3 * sigma[0])))
    return DrawnConsistency(
        trajectory=trajectory,
        runs=n_runs,
        nees_in_band=_in_band(np.array(nees), 4, n_runs),
        nis_in_band=_in_band(np.array(nis), 3, n_runs),
        inside_3sigma=float(np.mean(inside)),
        mean_nees=float(np.nanmean(nees)),
    )
