"""Waiting for worker threads without going deaf to signals.

Python runs signal handlers (Ctrl-C's ``KeyboardInterrupt``, the CLI's SIGTERM
handler) in the main thread only, between bytecodes. The kernel may hand a
process's signal to any of its threads that does not block it: a section thread of
``pronet real``, a figure feeder, a native worker. Then the signal only sets a flag,
and a main thread blocked in one long wait (``Future.result()`` without a timeout)
sees it when that wait ends: seconds later, once a whole section is done. So the main
thread waits here in slices of :data:`POLL` seconds.
"""

from __future__ import annotations

from collections.abc import Generator, Sequence
from concurrent.futures import Future, wait
from typing import TypeVar

T = TypeVar("T")

#: Longest single wait [s] of the waits made here: a signal is acted upon within it.
POLL = 0.05


def result_of(future: Future[T]) -> T:
    """``future.result()`` (its value, or its exception raised), waited for in slices
    of :data:`POLL` seconds."""
    while not future.done():
        wait([future], timeout=POLL)
    return future.result()


def results_in_order(futures: Sequence[Future[T]]) -> Generator[T, None, None]:
    """Each future's :func:`result_of`, in order. When the iteration stops early (an
    error, Ctrl-C), the futures that have not started are cancelled once the generator
    is closed: at once for an exception raised in here; for one raised in the
    caller's loop body, hold it in ``contextlib.closing``."""
    try:
        for future in futures:
            yield result_of(future)
    finally:
        for future in futures:
            future.cancel()
