"""The ``pronet`` command line: it parses, calls the library and prints.

Each command is one module holding its parser beside its handler
(``add_parser(sub)`` and ``run(args) -> exit code``); the work itself is done by the
library (:mod:`pronet.experiments.reproduce`, :mod:`pronet.experiments.simulation`,
:mod:`pronet.recorded.real`, :mod:`pronet.experiments.sweep`, ...).

One rule for every failure the user can cause (a bad argument or file, an unwritable,
full or busy output, a size beyond memory, a command that needs an extra that is not
installed): one line ``pronet: <path or argument>:
<reason>`` on stderr, exit code 2, no traceback (:func:`user_error`). Ctrl-C exits
with 130 and SIGTERM with 143 after saying what was kept, also from inside a long
native call (the core polls for signals).
"""

from __future__ import annotations

import argparse
import errno
import signal
import sys
import threading
import warnings
from typing import NoReturn

from pronet._util.extras import MissingExtra
from pronet.cli import (
    dataset,
    evaluate,
    info,
    navigate,
    real,
    reproduce,
    simulate,
    study,
    sweep,
    train,
)
from pronet.cli._common import as_option, print_warning

#: The commands, in the order ``pronet --help`` lists them.
COMMANDS = (info, reproduce, study, dataset, train, evaluate, real, navigate, simulate, sweep)


class _Parser(argparse.ArgumentParser):
    """argparse with the CLI's one rule for a user's mistake: one line
    ``pronet: <argument>: <reason>`` and exit code 2, instead of the usage block."""

    def error(self, message: str) -> NoReturn:
        if message.startswith("argument "):  # "argument --runs: invalid int value: '1e12'"
            message = message.removeprefix("argument ")
        self.exit(2, f"pronet: {message} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The parser of every command (each module adds its own; they share its class)."""
    parser = _Parser(
        prog="pronet", description="INS/DVL navigation with learned, adaptive process noise."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    for command in COMMANDS:
        command.add_parser(sub)
    return parser


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where Python's handlers run (between bytecodes, and inside
    long native calls, which poll for signals) and handled as Ctrl-C is: finished
    shards are kept, nothing half-written is left; exit code 143."""


def _terminate(signum: int, frame: object) -> None:
    raise Terminated


def _own_warnings() -> tuple[type[Warning], ...]:
    """The warnings pronet says to a command-line user (what the data or the filter
    shows is wrong), whatever ``-W`` or ``PYTHONWARNINGS`` ask of others."""
    from pronet._util.plausibility import PlausibilityWarning
    from pronet.stats import FilterHealthWarning

    return (PlausibilityWarning, FilterHealthWarning)


def main(argv: list[str] | None = None) -> int:
    """Run the command of ``argv`` (default ``sys.argv[1:]``); returns the exit code."""
    parser = build_parser()
    args, extra = parser.parse_known_args(argv)
    if extra:  # named with the command they were given to, not pronet's top level
        unknown, command = " ".join(extra), f"pronet {args.command}"
        parser.exit(2, f"pronet: unrecognized arguments: {unknown} (see {command} --help)\n")
    on_main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminate) if on_main_thread else None
    try:
        with warnings.catch_warnings():  # one line each, not the source line under it
            warnings.showwarning = print_warning
            for said in _own_warnings():  # said whatever Python's own filters are
                warnings.simplefilter("default", said)
            return int(args.func(args))
    except KeyboardInterrupt as exc:
        for note in getattr(exc, "__notes__", ()):
            print(f"\n{note}", file=sys.stderr)
        stopped = "terminated" if isinstance(exc, Terminated) else "interrupted"
        print(f"{stopped}; no result folder was written", file=sys.stderr)
        return 143 if isinstance(exc, Terminated) else 130
    except (ValueError, OSError, MemoryError, MissingExtra) as exc:
        print(f"pronet: {user_error(exc)}", file=sys.stderr)
        return 2
    finally:
        if previous is not None:  # None: not set here, or set outside Python
            signal.signal(signal.SIGTERM, previous)


def user_error(exc: ValueError | OSError | MemoryError | MissingExtra) -> str:
    """The one line ``main`` prints for a failure the user caused: the message of a
    ``ValueError`` (which names its argument or file) or of a missing optional
    dependency (which names the extra), the file and the system's reason for an
    ``OSError``, what to do about a ``MemoryError``."""
    if isinstance(exc, MemoryError):
        return "out of memory: the requested sizes (runs, grid, windows) do not fit; ask for less"
    if isinstance(exc, OSError):
        reason = exc.strerror or str(exc)
        if exc.errno in (errno.ENOSPC, errno.EDQUOT):
            reason += "; free some space and run again"
        elif exc.errno == errno.EFBIG:
            reason += "; the file system or the file size limit (ulimit -f) refuses it"
        where = exc.filename if exc.filename is not None else "output"
        if exc.filename2 is not None:
            where = f"{where} -> {exc.filename2}"
        return f"{where}: {reason}"
    return as_option(" ".join(str(exc).split("\n")).strip())


__all__ = ["build_parser", "main", "user_error"]
