"""The DVL calibration states with position fixes and depth, printed as the Markdown table
docs/results/calibration.md quotes (:mod:`pronet.experiments.aided_calibration`; about
30 s at 100 runs).

    python scripts/aided_calibration.py [--runs 100] [--seed 0]
"""

from __future__ import annotations

import argparse

from pronet.experiments.aided_calibration import aided_calibration_check, aided_table


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100, help="runs per trajectory")
    parser.add_argument("--seed", type=int, default=0, help="Monte Carlo seed")
    args = parser.parse_args()
    print(aided_table(aided_calibration_check(n_runs=args.runs, seed=args.seed)))


if __name__ == "__main__":
    main()
