"""The ``pronet`` command line: it parses, calls the library and prints.

Each command is one module holding its parser beside its handler
(``add_parser(sub)`` and ``run(args) -> exit code``); the work itself is done by the
library (:mod:`pronet.reproduce`, :mod:`pronet.simulation`, :mod:`pronet.realdata`,
:mod:`pronet.sweep`, ...). A ``ValueError`` from anywhere is printed as one line,
``pronet <command>: <message>``, with exit code 2; Ctrl-C exits with 130 after saying
what was kept.
"""

from __future__ import annotations

import argparse
import sys

from pronet.cli import (
    dataset,
    evaluate,
    info,
    real,
    reproduce,
    simulate,
    study,
    sweep,
    train,
)

#: The commands, in the order ``pronet --help`` lists them.
COMMANDS = (info, reproduce, study, dataset, train, evaluate, real, simulate, sweep)


def build_parser() -> argparse.ArgumentParser:
    """The parser of every command (each module adds its own)."""
    parser = argparse.ArgumentParser(
        prog="pronet", description="INS/DVL navigation with learned, adaptive process noise."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Run the command of ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except KeyboardInterrupt as exc:
        for note in getattr(exc, "__notes__", ()):
            print(f"\n{note}", file=sys.stderr)
        print("interrupted; no result folder was written", file=sys.stderr)
        return 130
    except ValueError as exc:
        print(f"pronet {args.command}: {exc}", file=sys.stderr)
        return 2


__all__ = ["build_parser", "main"]
