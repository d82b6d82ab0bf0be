"""Your own noise regressor in the ProNet loop.

Run:  python examples/own_regressor.py [--runs N]

Anything with ``predict(windows) -> q`` plugs in: ``windows`` is ``(n_runs, 6, N)``
float32 raw IMU samples (the last N = 200 of each channel), ``q`` is ``(n_runs, 6)`` the
per-sample noise variance [(m/s²)², (rad/s)²]. Here a robust one: the variance from the
median absolute deviation of first differences (a white noise of variance q has
differences of variance 2q; a smooth signal barely moves them), against the shipped
detrend net, on the scenario whose noise changes halfway.
"""

from __future__ import annotations

import argparse

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet.learn import models
from pronet.run import run
from pronet.sim import scenarios
from pronet.strategies import Learned


class DifferenceMAD:
    """q = (1.4826 · MAD(Δw))² / 2 per window: robust to a few outliers."""

    def predict(self, windows: ArrayLike) -> NDArray[np.float64]:
        d = np.diff(np.asarray(windows, dtype=np.float64), axis=-1)
        mad = np.median(np.abs(d - np.median(d, axis=-1, keepdims=True)), axis=-1)
        return (1.4826 * mad) ** 2 / 2.0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20, help="Monte Carlo runs (default 20)")
    args = parser.parse_args(argv)
    sc = scenarios.SCENARIOS["varying-noise"]()
    for label, regressor in [
        ("difference MAD", DifferenceMAD()),
        ("detrend net", models.load("detrend")),
    ]:
        done = run(Learned(regressor, sc.q_nominal), sc, n_runs=args.runs, seed=0)
        out, s = done.hybrid, done.result.summary()
        assert out is not None  # a learned strategy's run records the loop
        print(
            f"{label:15s} SRMSE {s['srmse']} m/s; {out.n_tunings} tunings, "
            f"model {out.model_seconds:.1f} s, {int(out.clipped.sum())} clipped"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
