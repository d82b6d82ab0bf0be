"""``pronet dataset``: generate the noise-regression training set (.npz + card)."""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path

from pronet._util.files import check_new_files
from pronet.cli._common import Output, Subparsers, add_output_flags, out_path


def add_parser(sub: Subparsers) -> None:
    from pronet.learn.dataset import DatasetParams

    defaults = DatasetParams()
    parser = sub.add_parser(
        "dataset", help="generate the 72,000-window noise-regression training set (.npz + card)"
    )
    parser.add_argument(
        "--out",
        metavar="PATH",
        type=out_path,
        default="data/dataset.npz",
        help="output .npz path",
    )
    parser.add_argument(
        "--seed", metavar="N", type=int, default=0, help="noise and split seed (default 0)"
    )
    parser.add_argument(
        "--levels",
        metavar="N",
        type=int,
        default=defaults.n_levels,
        help="noise variances, evenly spaced from 0.001 to 0.05 (m/s²)² or (rad/s)² per "
        f"sample; 4,800 windows each (default {defaults.n_levels}, the paper's)",
    )
    parser.add_argument(
        "--grades",
        action="store_true",
        help="per-window variances log-uniform over 1e-7..1e-1 (m/s²)² and 1e-10..1e-2 "
        "(rad/s)² (pronet.learn.dataset.GRADES; --levels draws per trajectory), the training set "
        "of the shipped models (the paper's paper-* used the default)",
    )
    parser.add_argument("--force", action="store_true", help="replace an existing dataset and card")
    add_output_flags(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pronet.learn import dataset

    out = Path(args.out)
    if out.suffix == ".json":  # the card's own name: the data would be overwritten by it
        raise ValueError(f"--out: {out} is the name of a card; name the .npz file to write")
    if out.suffix != ".npz":  # train and evaluate read --dataset as an .npz
        raise ValueError(f"--out: a dataset is an .npz file; got {out}")
    # the data and its card: neither is overwritten without --force
    check_new_files([out, dataset.card_path(out)], "--out", args.force)
    base = dataset.GRADES if args.grades else dataset.DatasetParams()
    params = dataclasses.replace(base, seed=args.seed, n_levels=args.levels)
    params.validate()  # an error names the field; cli.user_error names its option
    start = time.perf_counter()
    ds = dataset.build_dataset(params)
    dataset.save_dataset(ds, out, params)
    Output(args).result(
        f"{ds.q.size} examples ({ds.n_train} train / {ds.n_test} test) written to {out} "
        f"with card {dataset.card_path(out)} in {time.perf_counter() - start:.1f} s",
        {
            "file": str(out),
            "card": str(dataset.card_path(out)),
            "examples": int(ds.q.size),
            "train": int(ds.n_train),
            "test": int(ds.n_test),
        },
    )
    return 0
