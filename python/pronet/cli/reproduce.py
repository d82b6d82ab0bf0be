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

#: The runs per strategy of ``--quick``.
QUICK_RUNS = 10
#: The runs per strategy without ``--runs`` or ``--quick``.
DEFAULT_RUNS = 100


def add_parser(sub: Subparsers) -> None:
    parser = sub.add_parser(
        "reproduce", help="run the paper's Monte Carlo experiment and print its table"
    )
    add_monte_carlo_args(parser)
    # --runs given or not: --quick with an explicit --runs is a conflict, never a choice
    parser.set_defaults(runs=None)
    parser.add_argument(
        "--quick", action="store_true", help=f"{QUICK_RUNS} runs per strategy (not with --runs)"
    )
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

    if args.quick and args.runs is not None:
        raise ValueError(
            f"--quick and --runs: give one (--quick is --runs {QUICK_RUNS}), "
            f"got --quick with --runs {args.runs}"
        )
    n_runs = QUICK_RUNS if args.quick else DEFAULT_RUNS if args.runs is None else args.runs

    show = Output(args)
    start = time.perf_counter()
    with Bars(show) as bars:
        folder = reproduce(
            args.out,
            n_runs=n_runs,
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
