"""``pronet study``: when does adaptive process noise pay? (:mod:`pronet.experiments.study`)."""

from __future__ import annotations

import argparse
import time

from pronet.cli._common import (
    Bars,
    Output,
    Subparsers,
    add_monte_carlo_args,
    add_output_flags,
    add_result_folder,
    add_tuning_period,
    experiment_result,
)
from pronet.sim.scenarios import STUDY_SCENARIOS


def add_parser(sub: Subparsers) -> None:
    parser = sub.add_parser(
        "study",
        help="the study: every estimator of q on the study scenarios (oracle ceiling, "
        "statistics, adaptive, learned)",
        description="Run every study strategy (pronet.experiments.study.STUDY_ROWS) on the study "
        "scenarios with common random numbers and write table, metrics, figure and "
        "config (docs/results/study.md).",
    )
    parser.add_argument(
        "--scenarios",
        metavar="LIST",
        default=",".join(STUDY_SCENARIOS),
        help=f"comma-separated built-in scenarios (default {','.join(STUDY_SCENARIOS)})",
    )
    parser.add_argument(
        "--strategies",
        metavar="LABELS",
        default=None,
        help="comma-separated row labels of pronet.experiments.study.STUDY_ROWS (default: all)",
    )
    add_monte_carlo_args(parser)
    add_tuning_period(parser)
    parser.add_argument(
        "--smooth",
        action="store_true",
        help="also run the RTS smoother over every run: each row is followed by its "
        "smoothed one ('<label>, smoothed'); off by default (a smoothed Monte Carlo "
        "costs 2-3.3 plain ones)",
    )
    add_result_folder(parser, "study")
    add_output_flags(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pronet.experiments.study import study

    show = Output(args)
    start = time.perf_counter()
    with Bars(show) as bars:
        folder = study(
            args.out,
            n_runs=args.runs,
            seed=args.seed,
            scenarios=[s.strip() for s in args.scenarios.split(",") if s.strip()],
            labels=args.strategies.split(",") if args.strategies else None,
            threads=args.threads,
            say=bars.say,
            on_start=bars.start,
            on_done=bars.done,
            smooth=args.smooth,
            tuning_period=args.tuning_period,
        )
    experiment_result(show, folder, start)
    return 0
