"""Your own q estimator, run in lockstep over a Monte Carlo with pronet.Ensemble.

Run:  python examples/own_estimator.py [--runs N]

An Ensemble holds the Monte Carlo's runs paused at every tuning instant: ``advance()``
hands over each run's last ``window`` raw IMU samples, ``(n_runs, 6, window)``, and
``set_q`` takes your estimate of the per-sample IMU noise variance, ``(n_runs, 6)``
[(m/s²)², (rad/s)²], which the filter uses as its Q until the next instant. Here the
estimate is the variance of first differences over two (a white noise of variance q
has differences of variance 2q; the slow motion barely moves them), on the scenario
whose IMU noise changes halfway, against the filter told the nominal q throughout.
Both see the same noise realizations (the same seed), so the difference is paired.
"""

from __future__ import annotations

import argparse

import numpy as np

import pronet
from pronet.sim import scenarios
from pronet.stats import mean_ci


def difference_variance(windows: np.ndarray) -> np.ndarray:
    """q per run and channel: half the variance of the window's first differences."""
    return np.diff(windows.astype(np.float64), axis=2).var(axis=2) / 2.0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20, help="Monte Carlo runs (default 20)")
    args = parser.parse_args(argv)
    sc = scenarios.SCENARIOS["varying-noise"]()
    common = dict(sensors=sc.sensors, config=sc.config, n_runs=args.runs, seed=3)
    ens = pronet.Ensemble(sc.trajectory, sc.q_nominal, **common, window=200, tuning_period=1.0)
    tunings = 0
    while (windows := ens.advance()) is not None:
        ens.set_q(difference_variance(windows))
        tunings += 1
    mine = ens.finish()  # a MonteCarloResult, as monte_carlo returns
    nominal = pronet.monte_carlo(sc.trajectory, pronet.Strategy.constant(sc.q_nominal), **common)
    diff = mean_ci(mine.srmse - nominal.srmse)
    print(f"difference variance: SRMSE {mine.summary()['srmse']} m/s, {tunings} tunings")
    print(f"constant nominal q:  SRMSE {nominal.summary()['srmse']} m/s")
    print(f"paired difference:   {diff} m/s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
