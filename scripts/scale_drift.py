"""Why the DVL scale state drifts below its truth when the vehicle holds its speed.

Two experiments, printed as Markdown (docs/results/calibration.md quotes them):

1. The 19-state filter (``FilterConfig(dvl_calibration=True)``) on a 400 s straight run
   at a constant 1 m/s with an ideal DVL (scale error 0, aligned), the recorded
   sections' tuning (:mod:`pronet.recorded.dvlcalibration`), the simulated IMU matching the
   filter's q. The final scale estimate, mean over the runs, with its standard error:
   as the tuning and the scale prior are varied.
2. The same question on a one-axis model that an exact Bayesian filter can solve: the
   INS velocity error a random walk (variance ``q`` per second), the DVL reading
   ``(1 + k) v`` of a true velocity ``v`` held constant, and ``k`` with the prior
   N(0, 1 %). The EKF on ``[δv, k]`` against the exact posterior mean of ``k`` (a grid
   over ``k``, a Kalman filter on ``δv`` per grid point, weighted by its likelihood).

    python scripts/scale_drift.py [--runs N]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

from pronet import _core
from pronet.montecarlo import monte_carlo
from pronet.recorded import dvlcalibration
from pronet.results import markdown
from pronet.trajectory import trajectory_from_segments


def filter_table(runs: int) -> str:
    """Experiment 1: the 19-state filter's final scale error on a steady straight run."""
    lla0 = (math.radians(32), math.radians(34), -5.0)
    traj = trajectory_from_segments(np.array([[400.0, 0.0, 0.0, 0.0]]), lla0=lla0, speed0=1.0)
    quiet_q = tuple(v * 1e-2 for v in dvlcalibration.IMU_Q)
    real, walks = dvlcalibration.IMU_Q, (1e-9, 1e-14)
    one_deg = (math.radians(1.0),) * 3
    # label, IMU q (simulated and told), bias walks, scale prior, misalignment prior
    cases: list[tuple[str, tuple[float, ...], tuple[float, float], float | None, tuple]] = [
        ("15 states (no calibration states)", real, walks, None, one_deg),
        ("19 states: scale 1 %, misalignment 1°", real, walks, 0.01, one_deg),
        ("scale state only, 1 %", real, walks, 0.01, (0.0,) * 3),
        ("scale state only, 0.2 %", real, walks, 0.002, (0.0,) * 3),
        ("scale only 1 %, IMU noise / 100, no bias walks", quiet_q, (0.0, 0.0), 0.01, (0.0,) * 3),
    ]
    lines = []
    for label, q, (accel_psd, gyro_psd), prior, angles in cases:
        sensors = _core.SensorConfig(
            imu_variance=q,
            imu_bias_psd=(accel_psd,) * 3 + (gyro_psd,) * 3,
            dvl_variance=(dvlcalibration.DVL_VARIANCE,) * 3,
        )
        config = _core.FilterConfig(
            p0_sigma=dvlcalibration.REAL_P0_SIGMA,
            accel_bias_psd=accel_psd,
            gyro_bias_psd=gyro_psd,
            dvl_variance=(dvlcalibration.DVL_VARIANCE,) * 3,
            dvl_calibration=prior is not None,
            dvl_scale_sigma=prior,
            dvl_misalignment_sigma=None if prior is None else angles,
        )
        res = monte_carlo(
            traj, _core.Strategy.constant(q), sensors=sensors, config=config, n_runs=runs, seed=0
        )
        final = f"{np.mean(res.final_horizontal_error):.2f}"
        if res.calibration_error is None or res.calibration_sigma is None:
            lines.append([label, "", "", "", final])
            continue
        e = res.calibration_error[:, 0] * 100
        sigma = 100 * res.calibration_sigma[:, 0].mean()
        se = f"{e.mean():+.3f} ± {e.std() / math.sqrt(runs):.3f}"
        lines.append([label, se, f"{e.std():.3f}", f"{sigma:.3f}", final])
    header = ["case", "final scale error [%] (± SE)", "spread [%]", "filter 1σ [%]"]
    return markdown([*header, "final horiz. error [m]"], lines)


def one_axis(q: float, exact: bool, runs: int, rng: np.random.Generator) -> np.ndarray:
    """Experiment 2: the final estimate of k per run (truth 0), EKF or exact."""
    r, prior, p0, steps = 0.02**2, 0.01**2, 0.01**2, 400
    grid = np.linspace(-0.05, 0.05, 201)
    out = np.empty(runs)
    for i in range(runs):
        e = rng.normal() * math.sqrt(p0)  # the INS velocity error
        x, p = np.zeros(2), np.diag([p0, prior])  # EKF on [δv, k]
        m, pv = np.zeros(grid.size), np.full(grid.size, p0)  # per grid k: KF on δv
        logw = -0.5 * grid**2 / prior
        for _ in range(steps):
            e += rng.normal() * math.sqrt(q)
            v_ins, z = 1.0 + e, 1.0 + rng.normal() * math.sqrt(r)
            if exact:
                pv = pv + q
                g = 1.0 + grid
                s = g * g * pv + r
                nu = z - g * (v_ins - m)
                logw += -0.5 * (nu * nu / s + np.log(s))
                gain = -g * pv / s
                m, pv = m + gain * nu, (1.0 + gain * g) * pv
            else:
                p[0, 0] += q
                h = np.array([-(1.0 + x[1]), v_ins - x[0]])
                s_ekf = h @ p @ h + r
                gain_ekf = p @ h / s_ekf
                x = x + gain_ekf * (z - (1.0 + x[1]) * (v_ins - x[0]))
                p = (np.eye(2) - np.outer(gain_ekf, h)) @ p
        if exact:
            w = np.exp(logw - logw.max())
            out[i] = float(w @ grid / w.sum())
        else:
            out[i] = x[1]
    return out


def one_axis_table(runs: int) -> str:
    """Experiment 2: the mean final k̂ of the EKF and of the exact posterior."""
    lines = []
    for q in (3.2e-4, 3.2e-5, 3.2e-6):
        cells: list[object] = [f"{q:g}"]
        for exact in (False, True):
            k = one_axis(q, exact, runs, np.random.default_rng(1)) * 100
            cells.append(f"{k.mean():+.3f} ± {k.std() / math.sqrt(runs):.3f}")
        lines.append(cells)
    header = ["INS velocity walk q [(m/s)²/s]", "EKF: mean k̂ [%] (± SE)"]
    return markdown([*header, "exact posterior: mean k̂ [%] (± SE)"], lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=60, help="runs per case (default 60)")
    args = parser.parse_args()
    print(filter_table(args.runs))
    print(one_axis_table(3 * args.runs))


if __name__ == "__main__":
    main()
