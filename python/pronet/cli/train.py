"""``pronet train``: train noise regressors; safetensors weights + JSON card each."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

from pronet._util.files import check_new_files
from pronet.cli._common import (
    Output,
    Subparsers,
    add_dataset_args,
    add_output_flags,
    dataset_for,
    out_path,
)
from pronet.cli.train_recorded import (
    RECORDED_DIR_OPTIONS,
    RECORDED_ONLY,
    SECTION_OPTIONS,
    add_recorded_args,
    refuse_given,
    run_recorded,
)

#: ``--max-epochs``'s default.
MAX_EPOCHS = 20


def add_parser(sub: Subparsers) -> None:
    parser = sub.add_parser(
        "train", help="train a noise regressor and write safetensors weights + JSON card"
    )
    add_dataset_args(parser)
    parser.set_defaults(func=run)
    add_output_flags(parser)
    parser.add_argument(
        "--model",
        choices=("baseline", "detrend", "hcf", "all", "a", "cnn", "akit"),
        default=None,
        help="which regressor to train (default all three); with --recorded or "
        "--simulated a Q model learned through the filter: a (one scale per channel "
        "group, the default), cnn (a windowed CNN) or akit (A-KIT-like: the IMU and the "
        "filter's velocity); docs/how-to/learning-q.md",
    )
    parser.add_argument(
        "--out",
        metavar="PATH",
        type=out_path,
        default=None,
        help="output folder (default models/); with --recorded/--simulated the model "
        "file to write (NAME -> NAME.safetensors + NAME.json, default models/recorded-MODEL), "
        "or with --cross-validate/--held-out the result folder (default results/qtrain-TIME)",
    )
    add_recorded_args(parser)
    parser.add_argument(
        "--seed", metavar="N", type=int, default=0, help="training seed (default 0)"
    )
    parser.add_argument(
        "--force", action="store_true", help="replace models of the same name in --out"
    )
    parser.add_argument(
        "--max-epochs",
        metavar="N",
        type=int,
        default=None,
        help=f"epoch limit for the nets (default {MAX_EPOCHS}; not with --recorded/--simulated, "
        "whose nets take --epochs)",
    )


def run(args: argparse.Namespace) -> int:
    from pronet.learn import modelfile, training

    if args.recorded is not None or args.simulated is not None:
        return run_recorded(args)
    if args.model in RECORDED_ONLY:
        raise ValueError(f"--model {args.model}: needs --recorded DIR or --simulated N")
    refuse_given(args, RECORDED_DIR_OPTIONS, "only with --recorded DIR")
    refuse_given(args, SECTION_OPTIONS, "only with --recorded DIR or --simulated N")
    args.max_epochs = MAX_EPOCHS if args.max_epochs is None else args.max_epochs
    args.out = args.out or "models"
    kinds = training.MODEL_KINDS if args.model in (None, "all") else (args.model,)
    hp = training.NetTraining(seed=args.seed, max_epochs=args.max_epochs)
    folder = Path(args.out)
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"--out: {folder} is a file, not a folder")
    # every model's weights and card: a model trained earlier is not replaced silently
    written = [p for kind in kinds for p in modelfile.paths(folder / kind)]
    check_new_files(written, "--out", args.force)
    ds, params = dataset_for(args)
    out = Output(args)
    reports: dict[str, dict[str, Any]] = {}
    for kind in kinds:
        start = time.perf_counter()
        reports[kind] = training.train_and_save(
            kind, ds, params, args.out, hp=hp, progress=not out.quiet
        )
        out.say(f"{kind}: trained in {time.perf_counter() - start:.0f} s -> {args.out}/{kind}.*")
    out.result(training.scores_table(reports), {"folder": str(args.out), "models": reports})
    return 0
