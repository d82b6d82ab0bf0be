"""Every performance figure of pronet as a ratio to a reference measured in the same run.

Run:  ~/.cache/pronet-venv/bin/python benches/run.py [--quick] [--only NAME ...] [--json FILE]

The reference is the constant-Q Monte Carlo of ``paper`` at one IMU step (100 runs,
2 threads), timed in a fresh process before the rows (and after them, to show the
drift; ``benches/rows.py``). Each timed row is given as its ratio to the reference and, where
it counts its filter steps, in ns per filter step; rows that compare two settings or two
filters in the same run (threads, the covariance step, the NumPy reference, pyins) are
ratios themselves. Targets are ratios; absolute seconds stay in the ``measured`` column
as information. Each row is printed with the command that reproduces it alone
(``--only NAME``).

``--json FILE`` also writes every row, the reference and the machine to FILE;
``--compare OLD.json NEW.json`` prints two such files side by side
(``benches/compare_runs.py``): the same command on the previous build and on this one.
The Rust micro-benchmarks also run alone: ``cargo bench --features bench --bench core``.
Benchmarks are not tests: nothing here fails on a slow machine; a missed target is
printed as missed. ``--quick`` scales the long rows down (fewer runs, no reproduce) to
check that the script works, not to measure. The rows are defined in
``benches/filter_rows.py``, ``benches/peers.py`` and ``benches/program_rows.py``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import resource
import sys
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from compare_runs import compare
from filter_rows import (
    bench_covariance_step,
    bench_mechanization,
    bench_monte_carlo,
    bench_online,
    bench_rust,
    bench_second_order,
    bench_smoother,
    bench_soak,
)
from peers import bench_numpy_reference, bench_pyins
from program_rows import (
    bench_bag_read,
    bench_dataset,
    bench_hybrid,
    bench_inference,
    bench_real,
    bench_real_memory,
    bench_reproduce,
    bench_study,
    bench_sweep,
)
from rows import HEADER, SCRIPT, Reference, Row, cells, measure_reference

from pronet._util.cores import usable_cores
from pronet._util.files import atomic_write

BENCHES: dict[str, Callable[[argparse.Namespace, Reference], list[Row]]] = {
    "rust": bench_rust,
    "mechanization": bench_mechanization,
    "monte-carlo": bench_monte_carlo,
    "covariance-step": bench_covariance_step,
    "second-order": bench_second_order,
    "smoother": bench_smoother,
    "online": bench_online,
    "hybrid": bench_hybrid,
    "dataset": bench_dataset,
    "inference": bench_inference,
    "numpy-reference": bench_numpy_reference,
    "pyins": bench_pyins,
    "soak": bench_soak,
    "sweep": bench_sweep,
    "real": bench_real,
    "bag-read": bench_bag_read,
    "real-memory": bench_real_memory,
    "reproduce": bench_reproduce,
    "study": bench_study,
}
#: Rows ``--quick`` leaves out unless named.
SLOW = ("reproduce", "real", "study")


def parse(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", choices=list(BENCHES), help="run these rows only")
    parser.add_argument("--quick", action="store_true", help="a fast smoke run, not a measurement")
    parser.add_argument("--runs", type=int, default=100, help="Monte Carlo runs (default 100)")
    parser.add_argument("--repeat", type=int, default=3, help="best of this many (default 3)")
    parser.add_argument(
        "--reference-seconds",
        type=float,
        default=20.0,
        help="seconds of a run the NumPy reference filters (default 20)",
    )
    parser.add_argument("--json", metavar="FILE", help="also write every row to FILE")
    parser.add_argument(
        "--compare", nargs=2, metavar=("OLD", "NEW"), help="print two --json files side by side"
    )
    args = parser.parse_args(argv)
    if args.quick:
        args.runs, args.repeat, args.reference_seconds = 10, 1, 2.0
    return args


def machine() -> str:
    """The machine, one line."""
    import torch

    return (
        f"{usable_cores()} cores, python {sys.version.split()[0]}, "
        f"numpy {np.__version__}, torch {torch.__version__} ({torch.get_num_threads()} threads)"
    )


def run_rows(args: argparse.Namespace, chosen: list[str], ref: Reference) -> list[Row]:
    """Every chosen bench's rows, each printed as it comes."""
    rows: list[Row] = []
    for name in chosen:
        for row in BENCHES[name](args, ref):
            rows.append(row)
            print("| " + " | ".join(cells(row)) + " |")
            sys.stdout.flush()
    return rows


def main() -> int:
    args = parse()
    if args.compare:
        return compare(*args.compare)
    chosen = args.only or [k for k in BENCHES if not (args.quick and k in SLOW)]
    command = f"{SCRIPT} {' '.join(sys.argv[1:])}".rstrip()
    print(f"# {command}")
    print(f"# machine: {machine()}")
    before = measure_reference(args.repeat)
    print(HEADER)
    print("|---|---|---|---|---|---|---|")
    rows = run_rows(args, chosen, Reference(before))
    ref = Reference(before, measure_reference(args.repeat))
    print(ref.describe())
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"# this process's peak memory: {peak:.0f} MiB")
    if args.json:
        record = {
            "command": command,
            "machine": machine(),
            "date": time.strftime("%Y-%m-%d %H:%M:%S"),
            "runs": args.runs,
            "reference_s": [ref.wall, ref.after],
            "rows": [dataclasses.asdict(r) for r in rows],
        }
        atomic_write(Path(args.json), (json.dumps(record, indent=1) + "\n").encode())
        print(f"# wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
