"""``pronet train --recorded DIR`` / ``--simulated N``: Q models learned through the
filter on sections with ground truth (docs/how-to/learning-q.md, "Learning from recorded
missions"): train one and write it, or score models honestly (leave-one-section-out,
or a held-out split) with a ledger of what was scored."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from collections.abc import Iterator
from pathlib import Path

from pronet._util.files import check_new_files
from pronet.cli._common import Output, vector3

#: ``--model`` choices that only exist with --recorded/--simulated.
RECORDED_ONLY = ("a", "cnn", "akit")
#: Options of --recorded alone (their ``dest``), and of --recorded or --simulated: None
#: (or False) unless given, so that one given where it does not apply is refused.
RECORDED_DIR_OPTIONS = ("format", "sections", "imu_lever_arm", "dvl_lever_arm")
SECTION_OPTIONS = (
    *RECORDED_DIR_OPTIONS,
    "cross_validate",
    "held_out",
    "ledger",
    "models",
    "epochs",
    "steps",
    "window_seconds",
)
#: The values of the options above when not given.
_DEFAULTS = {
    "format": "snapir",
    "ledger": "results/qtrain-ledger.jsonl",
    "epochs": 6,
    "steps": 10,
    "window_seconds": 5.0,
}


def refuse_given(args: argparse.Namespace, dests: tuple[str, ...], why: str) -> None:
    """``ValueError`` naming every option of ``dests`` the command line gave (as it
    spells them), followed by ``why``; nothing when none was given."""
    given = [f"--{d.replace('_', '-')}" for d in dests if getattr(args, d) not in (None, False)]
    if given:
        raise ValueError(f"{', '.join(given)}: {why}")


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
        "--format",
        choices=("snapir", "generic"),
        default=None,
        help="--recorded's format (default snapir)",
    )
    group.add_argument(
        "--sections", metavar="A,B", default=None, help="only these sections of --recorded"
    )
    for sensor in ("imu", "dvl"):
        group.add_argument(
            f"--{sensor}-lever-arm",
            metavar="X,Y,Z",
            type=vector3,
            default=None,
            help=f"--recorded: the {sensor.upper()}'s position from the ground-truth point, "
            "x,y,z [m, body FRD] (default Snapir's with --format snapir; required with "
            "--format generic)",
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
        default=None,
        help="instead: train on all but the last N sections (N >= 1), score those once",
    )
    group.add_argument(
        "--ledger",
        metavar="FILE",
        default=None,
        help="with --cross-validate/--held-out: the record of (model, test set) pairs "
        "already scored; a pair is scored once (default results/qtrain-ledger.jsonl)",
    )
    group.add_argument(
        "--models",
        metavar="A,B",
        default=None,
        help="with --cross-validate/--held-out: several of a, cnn, akit scored side by side "
        "on the same folds (default: --model)",
    )
    group.add_argument(
        "--epochs",
        metavar="N",
        type=int,
        default=None,
        help=f"cnn, akit: epochs (default {_DEFAULTS['epochs']})",
    )
    group.add_argument(
        "--steps",
        metavar="N",
        type=int,
        default=None,
        help=f"cnn, akit: gradient steps per epoch, 16 windows each (default {_DEFAULTS['steps']})",
    )
    group.add_argument(
        "--window-seconds",
        metavar="S",
        type=float,
        default=None,
        help=f"cnn, akit: window length (default {_DEFAULTS['window_seconds']:g} s)",
    )


def _sections(args: argparse.Namespace) -> list:
    from pronet.experiments.qlearn.sections import (
        check_simulated_memory,
        recorded_sections,
        simulated_sections,
    )

    if args.simulated is not None:
        seed = args.seed if args.data_seed is None else args.data_seed
        check_simulated_memory(args.simulated, name="--simulated")
        return simulated_sections(args.simulated, seed=seed)
    if not Path(args.recorded).is_dir():
        raise ValueError(f"--recorded: {args.recorded} is not a folder")
    names = args.sections.split(",") if args.sections else None
    return recorded_sections(
        args.recorded,
        args.format,
        names,
        imu_lever_arm=args.imu_lever_arm,
        dvl_lever_arm=args.dvl_lever_arm,
    )


def _check_sources(args: argparse.Namespace) -> None:
    """The options of where the sections come from, each applied or refused."""
    refuse_given(
        args,
        ("dataset", "max_epochs"),
        "only without --recorded/--simulated (the noise-regression dataset's regressors)",
    )
    if args.recorded is not None and args.simulated is not None:
        raise ValueError("--recorded, --simulated: give one")
    if args.simulated is not None:
        refuse_given(args, RECORDED_DIR_OPTIONS, "only with --recorded DIR")
        if args.simulated < 2:
            raise ValueError(f"--simulated: needs at least 2 recordings, got {args.simulated}")
        seed = args.seed if args.data_seed is None else args.data_seed
        if seed < 0:
            name = "--seed" if args.data_seed is None else "--data-seed"
            raise ValueError(f"{name}: must be >= 0, got {seed}")
        return
    refuse_given(
        args, ("data_seed",), "only with --simulated N (or without --recorded: the dataset's)"
    )
    args.format = args.format or _DEFAULTS["format"]
    if args.format == "generic" and None in (args.imu_lever_arm, args.dvl_lever_arm):
        raise ValueError(
            "--format generic: needs --imu-lever-arm and --dvl-lever-arm, the IMU's and the "
            "DVL's positions from the ground-truth point [m, body FRD] (0,0,0 for a truth "
            "at the sensor)"
        )


def _check_models(args: argparse.Namespace, evaluating: bool) -> list[str]:
    """The models to train (``--model``, or with --cross-validate/--held-out
    ``--models``), their options each applied or refused; the defaults filled in."""
    from pronet.experiments.qlearn.commands import RECORDED_MODELS

    if args.model is not None and args.model not in RECORDED_MODELS:
        raise ValueError(
            f"--model: with --recorded/--simulated one of a, cnn, akit, got {args.model}"
        )
    if not evaluating:
        refuse_given(args, ("models", "ledger"), "only with --cross-validate or --held-out")
    elif args.models is not None and args.model is not None:
        raise ValueError("--model, --models: give one (--models takes one or several)")
    models = args.models.split(",") if args.models else [args.model or "a"]
    for m in models:
        if m not in RECORDED_MODELS:
            raise ValueError(f"--models: each one of a, cnn, akit, got {m!r}")
    if not {"cnn", "akit"} & set(models):
        refuse_given(
            args,
            ("epochs", "steps", "window_seconds"),
            "only with a cnn or akit model (model a is fitted by a grid search)",
        )
    for dest, value in _DEFAULTS.items():
        if getattr(args, dest) is None:
            setattr(args, dest, value)
    if args.epochs < 1:
        raise ValueError(f"--epochs: must be at least 1, got {args.epochs}")
    if args.steps < 1:
        raise ValueError(f"--steps: must be at least 1, got {args.steps}")
    if not args.window_seconds > 0:
        raise ValueError(f"--window-seconds: must be > 0, got {args.window_seconds}")
    return models


def model_target(out: str | None, model: str) -> Path:
    """Where ``--out`` puts the model file of one trained ``model``: ``out`` itself
    (``NAME`` -> ``NAME.safetensors`` + ``NAME.json``), or inside it as
    ``recorded-MODEL`` when it names a folder (an existing one, or one ending in a
    slash); default ``models/recorded-MODEL``."""
    default = f"recorded-{model}"
    if out is None:
        return Path("models") / default
    if out.endswith(("/", os.sep)) or Path(out).is_dir():
        return Path(out) / default
    return Path(out)


@contextlib.contextmanager
def _window_option() -> Iterator[None]:
    """The training's window length, its library argument ``seconds``, named as the
    option that set it: a window no section holds, or one shorter than an IMU period,
    was refused as ``seconds: ...``."""
    try:
        yield
    except ValueError as exc:
        if not str(exc).startswith("seconds: "):
            raise
        raise ValueError(f"--window-seconds: {str(exc).removeprefix('seconds: ')}") from None


def run_recorded(args: argparse.Namespace) -> int:
    from pronet.experiments.qlearn.commands import evaluate, train_model
    from pronet.experiments.qlearn.gradient import RecordedTraining
    from pronet.experiments.qlearn.protocol import Ledger
    from pronet.learn.modelfile import paths

    _check_sources(args)
    if args.cross_validate and args.held_out is not None:
        raise ValueError("--cross-validate, --held-out: give one")
    if args.held_out is not None and args.held_out < 1:
        raise ValueError(f"--held-out: must be at least 1, got {args.held_out}")
    evaluating = args.cross_validate or args.held_out is not None
    models = _check_models(args, evaluating)
    hp = RecordedTraining(
        epochs=args.epochs, seconds=args.window_seconds, seed=args.seed, steps=args.steps
    )
    out = Output(args)

    def say(text: str) -> None:
        if not out.quiet:
            print(f"pronet train: {text}", file=sys.stderr, flush=True)

    if evaluating:
        from pronet._util.outputs import new_result_folder

        refuse_given(
            args,
            ("force",),
            "only when training one model (--out is then a new result folder, never replaced)",
        )
        folder = new_result_folder(args.out, "qtrain")
    else:
        target = model_target(args.out, models[0])
        check_new_files(list(paths(target)), "--out", args.force)
    sections = _sections(args)
    say(f"{len(sections)} sections: {', '.join(s.name for s in sections)}")
    if evaluating:
        train, test = sections, []
        if args.held_out is not None:
            if not args.held_out < len(sections):
                raise ValueError(f"--held-out: between 1 and {len(sections) - 1}")
            train, test = sections[: -args.held_out], sections[-args.held_out :]
        with _window_option():
            table, record = evaluate(
                train, models, folder, test=test, ledger=Ledger(args.ledger), hp=hp, say=say
            )
        out.result(table, {"folder": str(folder), **record})
        return 0
    model = models[0]
    with _window_option():
        card, record = train_model(sections, model, target, hp=hp, say=say)
    out.result(f"{model}: trained in {record['seconds']:.0f} s -> {card}", {"card": str(card)})
    return 0
