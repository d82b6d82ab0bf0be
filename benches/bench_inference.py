"""Inference throughput of the noise regressors, and the hybrid loop's time split.

Run:  ~/.cache/pronet-venv/bin/python benches/bench_inference.py [--repeat K]

Per shipped model: windows per second at batch 600 (100 runs × 6 channels, one tuning
instant of a 100-run ProNet Monte Carlo), best of K. Then one 100-run hybrid Monte Carlo
of the paper scenario with the detrend net, split into Rust time and model time. Not a
test: nothing asserts a time.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
import torch

import pronet
from pronet import models
from pronet.hybrid import run_hybrid

PAPER_Q = (1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20)
    args = parser.parse_args()
    print(f"# python benches/bench_inference.py --repeat {args.repeat}")
    print(
        f"# machine: {os.cpu_count()} cores, torch {torch.__version__} "
        f"({torch.get_num_threads()} threads), python {sys.version.split()[0]}"
    )
    windows = (np.random.default_rng(0).standard_normal((100, 6, 200)) * 0.1).astype(np.float32)
    print("| model | batch | best ms per call | windows/s |")
    print("|---|---:|---:|---:|")
    for name in ("detrended variance", *models.SHIPPED):
        model = models.DetrendedVariance() if name == "detrended variance" else models.load(name)
        model.predict(windows)  # warm-up
        best = np.inf
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            model.predict(windows)
            best = min(best, time.perf_counter() - t0)
        print(f"| {name} | 600 | {best * 1e3:.2f} | {600 / best:,.0f} |")
    traj = pronet.builtin_trajectory("paper")
    t0 = time.perf_counter()
    out = run_hybrid(models.load("detrend"), traj, prior_q=PAPER_Q, n_runs=100, seed=0)
    wall = time.perf_counter() - t0
    print()
    print("| hybrid detrend net, 100 runs x 330 s | wall s | Rust s | model s | tunings |")
    print("|---|---:|---:|---:|---:|")
    print(
        f"| paper scenario | {wall:.2f} | {out.rust_seconds:.2f} | {out.model_seconds:.2f} "
        f"| {out.n_tunings} |"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
