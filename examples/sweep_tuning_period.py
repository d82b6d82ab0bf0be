"""How often should the regressor retune Q? A sweep over the tuning period.

Run:  python examples/sweep_tuning_period.py [--runs N] [--periods 0.5 1 2 5] [--engine ray]

The shipped detrend net on the varying-noise scenario, as a pronet sweep grid (the
same grid a `pronet sweep` TOML file gives): every period sees the same noise
realizations (same seed), so the differences are paired, and `--engine ray` gives the
same numbers from Ray tasks. Prints the result as CSV that a spreadsheet or pandas
reads directly.
"""

from __future__ import annotations

import argparse

from pronet import config
from pronet.experiments import sweep


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20, help="Monte Carlo runs (default 20)")
    parser.add_argument(
        "--periods", type=float, nargs="+", default=[0.5, 1.0, 2.0, 5.0], help="seconds"
    )
    parser.add_argument("--engine", choices=sweep.ENGINES, default="local")
    args = parser.parse_args(argv)
    grid = config.sweep_grid(
        {
            "scenarios": ["varying-noise"],
            "strategies": ["learned:detrend"],
            "tuning_periods_s": args.periods,
            "runs": args.runs,
            "shard_runs": args.runs,
        },
        "example",
    )
    result = sweep.run_sweep(grid, engine=args.engine)
    table = result.to_dataframe()[["tuning_period_s", "srmse", "srmse_low", "srmse_high"]]
    table.insert(1, "tunings", [p.hybrid.n_tunings for p in result.points])
    table["model_seconds"] = [p.hybrid.model_seconds for p in result.points]
    print(table.to_csv(index=False, float_format="%.5g"), end="")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
