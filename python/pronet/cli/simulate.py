"""``pronet simulate``: chosen strategies on one scenario (:mod:`pronet.experiments.simulation`)."""

from __future__ import annotations

import argparse
import sys
import time

from pronet.cli._common import (
    Bars,
    Output,
    Subparsers,
    add_monte_carlo_args,
    add_no_plots,
    add_output_flags,
    add_result_folder,
    add_tuning_period,
    experiment_result,
)
from pronet.sim.paper import PAPER_ROWS
from pronet.sim.scenarios import SCENARIOS


def add_parser(sub: Subparsers) -> None:
    parser = sub.add_parser(
        "simulate",
        help="Monte Carlo of chosen strategies on one scenario (built-in or TOML file)",
        description="Run strategies on the same simulated noise realizations and write "
        "a result folder (table, metrics, plots). Scenario and filter files: see "
        "pronet.config (the API reference: mkdocs serve, Reference → API).",
    )
    parser.add_argument(
        "--scenario",
        metavar="NAME|FILE",
        default="paper",
        help=f"built-in scenario ({', '.join(SCENARIOS)}) or a scenario .toml file "
        "(default paper); a drawn noise schedule follows --seed",
    )
    parser.add_argument(
        "--filter",
        metavar="FILE",
        default=None,
        help="filter configuration .toml: the keys it names override the scenario's filter",
    )
    parser.add_argument(
        "--formulation",
        choices=("invariant", "classic", "se23"),
        default=None,
        help="the filter's error coordinates: invariant (the default, consistent in "
        "heading), classic (the first filter's coordinates, to reproduce its results) or "
        "se23 (the position error too, consistent under large heading errors); "
        "overrides the scenario's and --filter's",
    )
    parser.add_argument(
        "--covariance-step",
        metavar="SECONDS",
        type=float,
        default=None,
        help="interval over which the filter propagates its covariance at once (default "
        "0.1 s; 0: every IMU sample; rounded to whole IMU samples); overrides the "
        "scenario's and --filter's",
    )
    parser.add_argument(
        "--strategies",
        metavar="SPECS",
        default=",".join(PAPER_ROWS.values()),
        help="comma-separated specs: constant[:FACTOR on q], oracle, adaptive[:WINDOW], "
        "mehra:WINDOW [DVL updates], detvar, learned:MODEL (shipped name or model file) "
        "(default: the paper's seven rows)",
    )
    add_monte_carlo_args(parser)
    parser.add_argument(
        "--record-every",
        metavar="SECONDS",
        type=float,
        default=1.0,
        help="seconds between the saved history samples the plots use (default 1 s)",
    )
    add_tuning_period(parser)
    parser.add_argument(
        "--smooth",
        action="store_true",
        help="also run the RTS smoother over every run: each strategy's row is followed by "
        "its smoothed one ('<spec>, smoothed')",
    )
    add_no_plots(parser)
    add_result_folder(parser, "simulate")
    add_output_flags(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pronet.experiments.simulation import simulate

    show = Output(args)
    start = time.perf_counter()
    notes: list[str] = []  # told once the folder is written (a failure is one line)
    with Bars(show) as bars:
        folder = simulate(
            args.scenario,
            args.strategies.split(","),
            args.out,
            filter_config=args.filter,
            formulation=args.formulation,
            covariance_step=args.covariance_step,
            n_runs=args.runs,
            seed=args.seed,
            threads=args.threads,
            record_every=args.record_every,
            tuning_period=args.tuning_period,
            smooth=args.smooth,
            plots=not args.no_plots,
            say=bars.say,
            on_start=bars.start,
            on_done=bars.done,
            note=notes.append,
        )
    for note in notes:  # what the runs say of the filter, also with --quiet and --json
        print(f"pronet: {note}", file=sys.stderr)
    experiment_result(show, folder, start)
    return 0
