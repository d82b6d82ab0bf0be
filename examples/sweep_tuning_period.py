"""How often should the regressor retune Q? A sweep over the tuning period.

Run:  python examples/sweep_tuning_period.py [--runs N] [--periods 0.5 1 2 5]

The shipped detrend net on the varying-noise scenario, the same noise realizations for
every period (same seed), so the differences are paired. Prints one row per period and
the result as CSV rows a spreadsheet or pandas reads directly.
"""

from __future__ import annotations

import argparse

from pronet import experiment, models
from pronet.hybrid import run_hybrid


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20, help="Monte Carlo runs (default 20)")
    parser.add_argument(
        "--periods", type=float, nargs="+", default=[0.5, 1.0, 2.0, 5.0], help="seconds"
    )
    args = parser.parse_args(argv)
    sc = experiment.SCENARIOS["varying-noise"]()
    net = models.load("detrend")
    print("tuning_period_s,tunings,srmse_mean,srmse_low,srmse_high,model_seconds")
    for period in args.periods:
        out = run_hybrid(
            net,
            sc.trajectory,
            prior_q=sc.q_nominal,
            sensors=sc.sensors,
            config=sc.config,
            n_runs=args.runs,
            seed=0,
            tuning_period=period,
        )
        s = out.result.summary()["srmse"]
        print(
            f"{period:g},{out.n_tunings},{s.mean:.5f},{s.low:.5f},{s.high:.5f},"
            f"{out.model_seconds:.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
