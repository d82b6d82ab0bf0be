"""The DVL calibration states with position fixes and depth: does the 19-state filter find
the DVL's scale error and misalignment, and does it then navigate better than the
15-state filter?

The setup of :func:`pronet.recorded.dvlcalibration.calibration_check` (a DVL reading
0.5 % fast and turned 0.5° in yaw, the recorded sections' tuning and IMU noise, both
filters told the true q, common random numbers) on each training trajectory, with two
aiding sensors added to the DVL: position fixes every :data:`FIX_PERIOD` s of 1σ
:data:`FIX_SIGMA` m north and east (no height), and a depth sensor of 1σ
:data:`DEPTH_SIGMA` m at 1 Hz. Reported per trajectory (:class:`AidedRow`): the share
of runs whose final scale error, yaw misalignment error and all four calibration errors
lie within 3σ of the filter's own σ, and each filter's horizontal error RMS over the
run (at every second) with the paired difference.

``python scripts/aided_calibration.py`` prints the table docs/results/calibration.md quotes;
``tests/experiments/test_aided_calibration.py`` checks the mechanism on a few runs and,
marked slow, the acceptance at 100 runs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pronet import _core
from pronet.config import sensor_kwargs
from pronet.montecarlo import MonteCarloResult, monte_carlo
from pronet.recorded import dvlcalibration
from pronet.results import markdown
from pronet.stats import mean_ci
from pronet.trajectory import builtin_trajectory

#: Position fixes: every 60 s, 1σ 2 m north and east (a USBL or GNSS fix; no height).
FIX_PERIOD = 60.0
FIX_SIGMA = 2.0
#: The depth sensor: 1σ 0.1 m at 1 Hz.
DEPTH_SIGMA = 0.1
#: History step [IMU samples] of the horizontal error RMS: 1 s at 100 Hz.
RECORD_EVERY = 100


def aided_sensors() -> _core.SensorConfig:
    """:func:`pronet.recorded.dvlcalibration.sensors` (the DVL's 0.5 % and 0.5°) with
    the fixes and the depth sensor of this experiment."""
    kwargs = sensor_kwargs(dvlcalibration.sensors())
    kwargs.update(
        depth_sigma=DEPTH_SIGMA,
        depth_period=1.0,
        fixes=[{"sigma": [FIX_SIGMA, FIX_SIGMA], "period": FIX_PERIOD}],
    )
    return _core.SensorConfig(**kwargs)


def horizontal_rms(result: MonteCarloResult) -> np.ndarray:
    """``(n_runs,)`` each run's RMS over its recorded epochs of the horizontal position
    error ``√(δp_N² + δp_E²)`` [m]."""
    if result.error is None:
        raise ValueError("result: no error history (run the Monte Carlo with record_every)")
    horizontal = result.error[:, :, 0] ** 2 + result.error[:, :, 1] ** 2
    return np.sqrt(horizontal.mean(axis=1))


@dataclass(frozen=True)
class AidedRow:
    """One trajectory of :func:`aided_calibration_check`.

    Attributes:
        scale_inside, yaw_inside, all_inside: share of runs whose final scale error,
            yaw misalignment error, and all four calibration errors lie within 3σ.
        scale, yaw: mean and standard deviation over the runs of the final estimated
            scale error and yaw misalignment [rad]; sigma_scale, sigma_yaw: mean 1σ.
        rms_15, rms_19: mean over the runs of the horizontal error RMS [m].
        difference: mean 19 − 15 of the paired per-run RMS and its 95 % CI [m].
        fix_nis: mean NIS per degree of freedom of the 19-state filter's fixes and
            depth readings (1 when consistent).
    """

    trajectory: str
    runs: int
    scale_inside: float
    yaw_inside: float
    all_inside: float
    scale: tuple[float, float]
    sigma_scale: float
    yaw: tuple[float, float]
    sigma_yaw: float
    rms_15: float
    rms_19: float
    difference: tuple[float, float, float]
    fix_nis: float


def aided_calibration_check(
    n_runs: int = 100,
    seed: int = 0,
    trajectories: tuple[str, ...] = dvlcalibration.TRAJECTORIES,
) -> list[AidedRow]:
    """Both filters on each trajectory, ``n_runs`` runs each from ``seed`` (see the
    module docstring)."""
    rows = []
    strategy = _core.Strategy.constant(dvlcalibration.IMU_Q)
    sensors = aided_sensors()
    for name in trajectories:
        traj = builtin_trajectory(name)
        plain, calibrated = [
            monte_carlo(
                traj,
                strategy,
                sensors=sensors,
                config=dvlcalibration.filter_config(calibration),
                n_runs=n_runs,
                seed=seed,
                record_every=RECORD_EVERY,
            )
            for calibration in (False, True)
        ]
        error, sigma = calibrated.calibration_error, calibrated.calibration_sigma
        if error is None or sigma is None:
            raise RuntimeError("the calibrated Monte Carlo reported no calibration states")
        inside = np.abs(error) <= 3 * sigma
        rms_15, rms_19 = horizontal_rms(plain), horizontal_rms(calibrated)
        nis = calibrated.mean_aiding_nis
        diff = mean_ci(rms_19 - rms_15)
        rows.append(
            AidedRow(
                trajectory=name,
                runs=n_runs,
                scale_inside=float(inside[:, 0].mean()),
                yaw_inside=float(inside[:, 3].mean()),
                all_inside=float(inside.all(axis=1).mean()),
                **dvlcalibration.estimate_spread(error, sigma)._asdict(),
                rms_15=float(rms_15.mean()),
                rms_19=float(rms_19.mean()),
                difference=(diff.mean, diff.low, diff.high),
                fix_nis=math.nan if nis is None else float(np.nanmean(nis)),
            )
        )
    return rows


def aided_table(rows: list[AidedRow]) -> str:
    """Markdown: one line per trajectory of :func:`aided_calibration_check`."""
    header = [
        "trajectory",
        "scale [%] (1σ)",
        "yaw [°] (1σ)",
        "within 3σ: scale / yaw / all four",
        "horiz. RMS 15 / 19 [m]",
        "19 − 15 [m] (95 % CI)",
        "fix/depth NIS per dof",
    ]
    lines: list[list[object]] = []
    for r in rows:
        d = r.difference
        lines.append(
            [
                r.trajectory,
                *dvlcalibration.spread_cells(r),
                f"{100 * r.scale_inside:.0f} % / {100 * r.yaw_inside:.0f} % / "
                f"{100 * r.all_inside:.0f} %",
                f"{r.rms_15:.2f} / {r.rms_19:.2f}",
                f"{d[0]:+.2f} [{d[1]:+.2f}, {d[2]:+.2f}]",
                f"{r.fix_nis:.2f}",
            ]
        )
    title = (
        f"{dvlcalibration.miscalibration()}, fixes every {FIX_PERIOD:g} s (σ {FIX_SIGMA:g} m) "
        f"and depth (σ {DEPTH_SIGMA:g} m), {rows[0].runs if rows else 0} runs per trajectory"
    )
    return markdown(header, lines, title)
