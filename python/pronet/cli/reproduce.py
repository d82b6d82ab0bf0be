"""``pronet reproduce``: the paper's Monte Carlo experiment
(:mod:`pronet.experiments.reproduce`)."""

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


def add_parser(sub: Subparsers) -> None:
    parser = sub.add_parser(
        "reproduce", help="run the paper's Monte Carlo experiment and print its table"
    )
    add_monte_carlo_args(parser)
    parser.add_argument("--quick", action="store_true", help="10 runs per strategy")
    add_result_folder(parser, "reproduce")
    parser.add_argument(
        "--retrain", action="store_true", help="train all three regressors first (~10 min)"
    )
    add_tuning_period(parser)
    add_output_flags(parser)
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue an interrupted run of the same --out from its <out>.partial "
        "folder, without redoing the Monte Carlos it finished",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pronet.experiments.reproduce import reproduce

    show = Output(args)
    start = time.perf_counter()
    with Bars(show) as bars:
        folder = reproduce(
            args.out,
            n_runs=10 if args.quick else args.runs,
            seed=args.seed,
            threads=args.threads,
            tuning_period=args.tuning_period,
            retrain=args.retrain,
            resume=args.resume,
            train_progress=not show.quiet,
            say=bars.say,
            on_start=bars.start,
            on_done=bars.done,
        )
    experiment_result(show, folder, start)
    return 0
