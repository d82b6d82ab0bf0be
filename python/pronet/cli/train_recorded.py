"""``pronet train --recorded DIR`` / ``--simulated N``: Q models learned through the
filter on sections with ground truth (docs/learning.md, "Learning from recorded
missions"): train one and write it, or score models honestly (leave-one-section-out,
or a held-out split) with a ledger of what was scored."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pronet._util.files import check_new_files
from pronet.cli._common import Output

#: ``--model`` choices that only exist with --recorded/--simulated.
RECORDED_ONLY = ("a", "cnn", "akit")


def add_recorded_args(parser: argparse.ArgumentParser) -> None:
    """The options of training on sections with ground truth."""
    group = parser.add_argument_group("Q models from sections with ground truth")
    group.add_argument(
        "--recorded",
        metavar="DIR",
        default=None,
        help="train on the recorded sections under DIR (read where they lie; Snapir "
        "format unless --format generic)",
    )
    group.add_argument(
        "--simulated",
        metavar="N",
        type=int,
        default=None,
        help="train on N simulated recordings of the study's regimes scenario instead "
        "(drawn from seeds --data-seed .. --data-seed + N - 1; by default from --seed, "
        "which also seeds the training)",
    )
    group.add_argument(
        "--format", choices=("snapir", "generic"), default="snapir", help="--recorded's format"
    )
    group.add_argument(
        "--sections", metavar="A,B", default=None, help="only these sections of --recorded"
    )
    group.add_argument(
        "--cross-validate",
        action="store_true",
        help="instead of training one model: leave-one-section-out, each section scored "
        "by a model that never saw it, beside the constant row and the per-section best "
        "constant (table.md, metrics.json in --out)",
    )
    group.add_argument(
        "--held-out",
        metavar="N",
        type=int,
        default=0,
        help="instead: train on all but the last N sections, score those once",
    )
    group.add_argument(
        "--ledger",
        metavar="FILE",
        default="results/qtrain-ledger.jsonl",
        help="the record of (model, test set) pairs already scored; a pair is scored once "
        "(default results/qtrain-ledger.jsonl)",
    )
    group.add_argument(
        "--models",
        metavar="A,B",
        default=None,
        help="with --cross-validate/--held-out: several of a, cnn, akit scored side by side "
        "on the same folds (default: --model)",
    )
    group.add_argument(
        "--epochs", metavar="N", type=int, default=6, help="cnn, akit: epochs (default 6)"
    )
    group.add_argument(
        "--steps",
        metavar="N",
        type=int,
        default=10,
        help="cnn, akit: gradient steps per epoch, 16 windows each (default 10)",
    )
    group.add_argument(
        "--window-seconds", metavar="S", type=float, default=5.0, help="cnn: window length (5 s)"
    )


def _sections(args: argparse.Namespace) -> list:
    from pronet.experiments.qlearn.sections import (
        check_simulated_memory,
        recorded_sections,
        simulated_sections,
    )

    if args.recorded is not None and args.simulated is not None:
        raise ValueError("--recorded, --simulated: give one")
    if args.simulated is not None:
        if args.simulated < 2:
            raise ValueError(f"--simulated: needs at least 2 recordings, got {args.simulated}")
        seed = args.seed if args.data_seed is None else args.data_seed
        if seed < 0:
            name = "--seed" if args.data_seed is None else "--data-seed"
            raise ValueError(f"{name}: must be >= 0, got {seed}")
        check_simulated_memory(args.simulated, name="--simulated")
        return simulated_sections(args.simulated, seed=seed)
    if not Path(args.recorded).is_dir():
        raise ValueError(f"--recorded: {args.recorded} is not a folder")
    names = args.sections.split(",") if args.sections else None
    return recorded_sections(args.recorded, args.format, names)


def run_recorded(args: argparse.Namespace) -> int:
    from pronet.experiments.qlearn.commands import RECORDED_MODELS, evaluate, train_model
    from pronet.experiments.qlearn.gradient import RecordedTraining
    from pronet.experiments.qlearn.protocol import Ledger
    from pronet.learn.modelfile import paths

    model = args.model or "a"
    if model not in RECORDED_MODELS:
        raise ValueError(f"--model: with --recorded/--simulated one of a, cnn, akit, got {model}")
    if args.epochs < 1:
        raise ValueError(f"--epochs: must be at least 1, got {args.epochs}")
    if args.steps < 1:
        raise ValueError(f"--steps: must be at least 1, got {args.steps}")
    models = args.models.split(",") if args.models else [model]
    for m in models:
        if m not in RECORDED_MODELS:
            raise ValueError(f"--models: each one of a, cnn, akit, got {m!r}")
    if not args.window_seconds > 0:
        raise ValueError(f"--window-seconds: must be > 0, got {args.window_seconds}")
    hp = RecordedTraining(
        epochs=args.epochs, seconds=args.window_seconds, seed=args.seed, steps=args.steps
    )
    out = Output(args)

    def say(text: str) -> None:
        if not out.quiet:
            print(f"pronet train: {text}", file=sys.stderr, flush=True)

    evaluating = args.cross_validate or args.held_out
    if evaluating:
        from pronet._util.outputs import new_result_folder

        folder = new_result_folder(args.out, "qtrain")
    else:
        target = Path(args.out or f"models/recorded-{model}")
        check_new_files(list(paths(target)), "--out", args.force)
    sections = _sections(args)
    say(f"{len(sections)} sections: {', '.join(s.name for s in sections)}")
    if evaluating:
        if args.cross_validate and args.held_out:
            raise ValueError("--cross-validate, --held-out: give one")
        train, test = sections, []
        if args.held_out:
            if not 0 < args.held_out < len(sections):
                raise ValueError(f"--held-out: between 1 and {len(sections) - 1}")
            train, test = sections[: -args.held_out], sections[-args.held_out :]
        table, record = evaluate(
            train, models, folder, test=test, ledger=Ledger(args.ledger), hp=hp, say=say
        )
        out.result(table, {"folder": str(folder), **record})
        return 0
    card, record = train_model(sections, model, target, hp=hp, say=say)
    out.result(f"{model}: trained in {record['seconds']:.0f} s -> {card}", {"card": str(card)})
    return 0
