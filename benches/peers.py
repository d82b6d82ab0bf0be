"""``benches/run.py``'s rows against other filters: the NumPy reference filter of the
tests, and pyins's EKF (PyPI ``python-ins``) where it is installed.

Definitions:
- NumPy reference: ``tests/numpy_reference_ekf.py`` (the same filter equations with
  dense 15×15 matrices, here with NED-velocity aiding and sensor arrays made up front)
  on the first ``--reference-seconds`` of one run, scaled to a whole run, against the
  1-thread Monte Carlo time per run (which also simulates the sensors and aids with body
  velocity, so the ratio is conservative).
- pyins: skipped, with the reason, where ``import pyins`` fails.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from rows import PAPER_STEPS, SCRIPT, Reference, Row, best_of

import pronet
from pronet.sim import paper, scenarios

ROOT = Path(__file__).resolve().parents[1]


def paper_monte_carlo(strategy: pronet.Strategy, n_runs: int, threads: int | None) -> None:
    sc = scenarios.paper_scenario()
    pronet.monte_carlo(
        sc.trajectory,
        strategy,
        sensors=sc.sensors,
        config=paper.paper_filter_config(),
        n_runs=n_runs,
        seed=0,
        threads=threads,
    )


def bench_numpy_reference(args: argparse.Namespace, ref: Reference) -> list[Row]:
    sys.path.insert(0, str(ROOT / "tests"))
    from numpy_reference_ekf import run_reference_filter

    sc = scenarios.paper_scenario()
    cfg = paper.paper_filter_config()
    traj = sc.trajectory
    n = int(round(args.reference_seconds / traj.dt))
    rng = np.random.default_rng(0)
    imu = traj.imu[:n] + rng.normal(size=(n, 6)) * np.sqrt(paper.PAPER_Q)
    k = np.arange(100, n + 1, 100)
    dvl = traj.vel_ned[k] + rng.normal(size=(k.size, 3)) * 0.1  # nav aiding: no rotation
    t0 = time.perf_counter()
    run_reference_filter(
        imu,
        traj.time[1 : n + 1],
        dvl,
        traj.time[k],
        traj.time[0],
        traj.lla[0],
        traj.vel_ned[0],
        traj.rpy[0],
        q=paper.PAPER_Q,
        accel_bias_psd=cfg.accel_bias_psd,
        gyro_bias_psd=cfg.gyro_bias_psd,
        dvl_variance=cfg.dvl_variance,
        p0_sigma=cfg.p0_sigma,
        imu_dt=traj.dt,
        aiding="nav",
    )
    reference_per_run = (time.perf_counter() - t0) * traj.n_samples / n
    runs = 10
    wall = best_of(
        args.repeat, lambda: paper_monte_carlo(pronet.Strategy.constant(sc.q_nominal), runs, 1)
    )
    ratio = reference_per_run / (wall / runs)
    return [
        Row(
            "against the NumPy reference filter, per run, one core",
            f"{ratio:,.0f}× ({reference_per_run:.1f} s vs {wall / runs * 1e3:.1f} ms; "
            f"100 runs: {reference_per_run * 100 / 60:.0f} min vs {wall * 10:.1f} s)",
            "≥ 200×",
            ratio >= 200,
            f"{SCRIPT} --only numpy-reference --reference-seconds {args.reference_seconds:g}",
            ratio,
            "x",
            ns_per_step=reference_per_run / PAPER_STEPS * 1e9,
        )
    ]


def bench_pyins(args: argparse.Namespace, ref: Reference) -> list[Row]:
    """pyins's EKF on one recorded section: skipped, with the reason, where pyins does
    not import."""
    what, command = "pyins's EKF on one recorded section", f"{SCRIPT} --only pyins"
    try:
        import pyins  # noqa: F401
    except ImportError as exc:
        reason = f"skipped: pyins (PyPI python-ins) does not import ({exc})"
        return [Row(what, reason, "—", None, command)]
    reason = "skipped: pyins imports, but this row is not written yet"
    return [Row(what, reason, "—", None, command)]
