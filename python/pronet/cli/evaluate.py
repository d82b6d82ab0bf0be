"""``pronet evaluate``: score noise regressors on the test split; draw Fig. 8."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pronet._util.files import check_new_files
from pronet.cli._common import Output, Subparsers, add_dataset_args, add_output_flags, dataset_for


def add_parser(sub: Subparsers) -> None:
    parser = sub.add_parser(
        "evaluate", help="score noise regressors on the test split; draw Fig. 8"
    )
    add_dataset_args(parser)
    parser.set_defaults(func=run)
    add_output_flags(parser)
    parser.add_argument(
        "--models",
        metavar="LIST",
        default="paper-baseline,paper-detrend,paper-hcf",
        help="comma-separated shipped names or model file paths (default: the paper's "
        "three, for Fig. 8 on the paper's dataset)",
    )
    parser.add_argument(
        "--figure", metavar="PNG", default=None, help="write predicted-vs-true q PNG here"
    )
    parser.add_argument("--force", action="store_true", help="replace an existing --figure")


def run(args: argparse.Namespace) -> int:
    from pronet import plots
    from pronet.learn import models, training

    if args.figure:  # before any model is loaded or scored
        if Path(args.figure).suffix.lower() != ".png":  # it wrote a PNG under any name
            raise ValueError(f"--figure: the figure is a .png file; got {args.figure}")
        check_new_files([Path(args.figure)], "--figure", args.force)
    names = [n.strip() for n in args.models.split(",") if n.strip()]
    if not names:  # before the dataset is built (it raised StopIteration after)
        raise ValueError(f"--models: expected shipped names or model files, got {args.models!r}")
    loaded = {n: models.load(n) for n in names}  # fail on a bad file before any work
    ds, _ = dataset_for(args)
    test = ~ds.train
    reports: dict[str, dict[str, Any]] = {}
    panels: dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
    for name, model in loaded.items():
        reports[name] = training.test_report(model, ds)
        panels[name] = (ds.q[test], model.predict(ds.windows[test]))
    out = Output(args)
    if args.figure:
        out.say(f"figure written to {plots.predicted_vs_true(panels, args.figure)}")
    out.result(training.scores_table(reports), {"models": reports, "figure": args.figure})
    return 0
