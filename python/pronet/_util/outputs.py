"""What the experiments (``reproduce``, ``simulate``, ``real``, ``sweep``) share about
their output: where a new result folder goes, the ``<out>.partial`` folder an
interrupted run leaves beside it, and the progress callbacks through which they report
(the library never prints). Errors are ``ValueError`` naming the command-line option
(``--out``, ``--resume``).
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Callable
from pathlib import Path

from pronet._util.files import check_out_folder, reserve_folder, sibling

#: ``say(text)``: a message for people (the library never prints).
Say = Callable[[str], None]
#: ``on_start(total, unit, description)``: a stage of ``total`` steps begins.
OnStart = Callable[[int, str, str | None], None]
#: ``on_done(label)``: one step of the current stage is finished.
OnDone = Callable[[str], None]


def new_result_folder(out: str | Path | None, command: str) -> Path:
    """``out``, or ``results/<command>-<YYYYmmdd-HHMMSS>`` (local time) when it is None,
    checked and reserved for this run before it computes anything
    (:func:`pronet._util.files.check_out_folder`, :func:`pronet._util.files.reserve_folder`):
    ``ValueError`` if ``out`` is an empty or blank string (an unset variable: refused as
    the command line's empty ``--out`` is, not taken for the default), or if that folder
    exists (it is never overwritten), cannot be created there, or another run is
    writing it."""
    if isinstance(out, str) and not out.strip():
        raise ValueError(
            f"--out: expected a path, got {out!r}; None (the option left out) for the "
            f"default results/{command}-<time>"
        )
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    folder = Path(out) if out is not None else Path("results") / f"{command}-{stamp}"
    check_out_folder(folder)
    reserve_folder(folder)
    return folder


def partial_folder(out: Path, resume: bool) -> Path:
    """Where the finished pieces of a run into ``out`` are kept (``<out>.partial``, its
    name shortened by a hash if that would be too long: :func:`~pronet._util.files.sibling`);
    ``ValueError`` if an interrupted run left some there and ``resume`` is not set."""
    partial = sibling(out, ".partial")
    if partial.exists() and not resume:
        raise ValueError(
            f"{partial} holds an interrupted run of this folder; add --resume to continue "
            "it, or remove it"
        )
    return partial
