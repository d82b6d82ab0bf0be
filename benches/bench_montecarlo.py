"""Wall time of 100 Monte Carlo runs of the paper's evaluation scenario (constant Q).

Run:  ~/.cache/pronet-venv/bin/python benches/bench_montecarlo.py [--runs N] [--repeat K]

Prints the figures with the command that reproduces them. Not a test: nothing asserts a
time. The performance issue's target is <= 1.0 s wall on 2 cores for 100 runs.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import pronet

PAPER_Q = (1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    traj = pronet.builtin_trajectory("paper")
    steps = args.runs * traj.n_samples
    command = f"python benches/bench_montecarlo.py --runs {args.runs} --repeat {args.repeat}"
    print(f"# {command}")
    print(f"# machine: {os.cpu_count()} cores, python {sys.version.split()[0]}")
    print("| strategy | threads | best wall [s] | filter steps/s |")
    print("|---|---|---|---|")
    for label, strategy in [
        ("constant", pronet.Strategy.constant(PAPER_Q)),
        ("mehra(5)", pronet.Strategy.mehra(5, PAPER_Q)),
    ]:
        for threads in (1, os.cpu_count() or 1):
            best = float("inf")
            for _ in range(args.repeat):
                t0 = time.perf_counter()
                pronet.monte_carlo(traj, strategy, n_runs=args.runs, seed=0, threads=threads)
                best = min(best, time.perf_counter() - t0)
            print(f"| {label} | {threads} | {best:.3f} | {steps / best:,.0f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
