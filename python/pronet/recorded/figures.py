"""The figures of ``pronet real``: what each section's three figures show, taken from
its runs as small arrays (:class:`pronet.plots.sections.SectionCurves`), and drawn in worker
processes while the other sections are still being filtered.

matplotlib holds the GIL for nearly all of a figure's drawing, so figures drawn on a
thread would wait for the filters' Python steps and the other way round; a worker
process draws beside them and hands back the PNG bytes, which the caller writes into
its result folder. Only the thinned curves cross to the worker (a few MB per section,
against ~200 MB of runs).
"""

from __future__ import annotations

import os
import pickle
import queue
import signal
import struct
import subprocess
import sys
import threading
from collections.abc import Callable, Mapping
from concurrent.futures import Future
from pathlib import Path
from typing import IO, TYPE_CHECKING

import numpy as np

from pronet._util.cores import usable_cores
from pronet._util.files import atomic_write
from pronet._util.waiting import result_of
from pronet.plots.sections import SECTION_FIGURES, SectionFigure

if TYPE_CHECKING:
    from pronet.plots.sections import SectionCurves
    from pronet.recorded.alignment import Section
    from pronet.recorded.runs import SectionRun

#: Points per line beyond which a long series is drawn thinned (every k-th point, the
#: last one kept): a 40,000-sample track drawn at ~800 pixels looks the same, and
#: takes a fifth of the time.
MAX_LINE_POINTS = 4000

#: The figures of each section, by kind (each goes to ``<kind>_<section>.png``).
FIGURES = SECTION_FIGURES


def _thin(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every k-th sample of equally long ``x`` and ``y`` (and the last), at most about
    :data:`MAX_LINE_POINTS` of them."""
    n = len(x)
    k = -(-n // MAX_LINE_POINTS)
    if k <= 1:
        return np.asarray(x), np.asarray(y)
    keep = np.r_[np.arange(0, n - 1, k), n - 1]
    return np.asarray(x)[keep], np.asarray(y)[keep]


def section_curves(
    section: Section,
    runs: list[SectionRun],
    constant_q: Mapping[str, tuple[float, ...]],
    imu_dt: float,
) -> SectionCurves:
    """What the figures of ``section`` show for its strategy ``runs``.

    Args:
        section: the aligned section (truth in geodetic lla [rad, rad, m] and NED
            velocity [m/s]).
        runs: its strategy rows, in table order.
        constant_q: label → the 6 variances of each constant row (drawn flat).
        imu_dt: the IMU sample interval [s] the filter assumed: Mehra's discrete Q_d
            is shown as the q that would give the same velocity and attitude blocks,
            ``trace / (3 Δt_imu Δt)``.
    """
    from pronet import earth_radii
    from pronet.plots.sections import SectionCurves
    from pronet.recorded.metrics import estimate_at_truth

    lla0 = section.truth_lla[0]
    r_n, r_e = earth_radii(float(lla0[0]))

    def east_north(label: str, lla: np.ndarray) -> tuple[str, np.ndarray, np.ndarray]:
        lla = np.asarray(lla)
        north = (lla[:, 0] - lla0[0]) * (r_n + lla0[2])
        east = (lla[:, 1] - lla0[1]) * (r_e + lla0[2]) * np.cos(lla0[0])
        east, north = _thin(east, north)
        return label, east, north

    track = [east_north("ground truth", section.truth_lla)]
    velocity: list[tuple[str, np.ndarray, np.ndarray]] = []
    q: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]] = []
    for run in runs:
        track.append(east_north(run.label, run.result.lla))
        rows, _, vel = estimate_at_truth(section, run.result)
        dv = vel - section.truth_vel[rows]
        time, dv = _thin(section.truth_time[rows], dv)
        velocity.append((run.label, time, dv))
        used = _q_used(run, constant_q, imu_dt)
        if used is not None:
            q.append((run.label, *used))
    return SectionCurves(section.name, track, velocity, q)


def _q_used(
    run: SectionRun, constant_q: Mapping[str, tuple[float, ...]], imu_dt: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """``(time, accelerometer q, gyro q)`` of one strategy row, each the mean over its
    three channels; None for a row without a q (an estimator that never set one)."""
    r = run.result
    if run.label in constant_q:
        qc = np.asarray(constant_q[run.label], float)
        return r.time[[0, -1]], np.full(2, qc[:3].mean()), np.full(2, qc[3:].mean())
    if run.schedule is not None and len(run.schedule.time):
        qs = run.schedule.q
        return run.schedule.time, qs[:, :3].mean(axis=1), qs[:, 3:].mean(axis=1)
    if np.isfinite(r.adaptive_q).any():
        applied = r.dvl_epoch >= 0
        qd = r.adaptive_q[applied]
        steps = np.diff(r.time)  # between consecutive epochs (of those kept, if thinned)
        if r.epoch.size:
            steps = steps[np.diff(r.epoch) == 1]
        scale = 3 * imu_dt * float(np.median(steps))
        return (
            r.time[r.rows_of(r.dvl_epoch[applied])],
            np.trace(qd[:, 3:6, 3:6], axis1=1, axis2=2) / scale,
            np.trace(qd[:, 6:9, 6:9], axis1=1, axis2=2) / scale,
        )
    return None


def draw_figure(
    kind: str, curves: SectionCurves, kept: dict[str, SectionFigure] | None = None
) -> bytes:
    """One of the figures of a section (``kind`` in :data:`FIGURES`), as PNG bytes.

    ``kept``: figures to draw again, by kind (a worker's; one is added on a kind's
    first use), instead of a new figure each time: the same bytes, at about half the
    cost (:class:`pronet.plots.sections.SectionFigure`)."""
    if kept is None:
        return SectionFigure(kind).png(curves)
    if kind not in kept:
        kept[kind] = SectionFigure(kind)
    return kept[kind].png(curves)


def figure_name(kind: str, section: str) -> str:
    """The file of one figure of a section: ``<kind>_<section>.png``."""
    return f"{kind}_{section}.png"


class FigureError(RuntimeError):
    """A figure a worker could not draw: the message is one line, the last of the
    worker's traceback (its exception's type and message); :attr:`traceback` is the
    whole of it."""

    def __init__(self, traceback: str) -> None:
        lines = [line.strip() for line in traceback.splitlines() if line.strip()]
        super().__init__(lines[-1] if lines else "the figure worker failed")
        self.traceback = traceback


def default_workers() -> int:
    """:class:`FigurePool`'s default: half the cores this process may use, at least
    one."""
    return max(1, usable_cores() // 2)


class FigurePool:
    """Draws sections' figures in worker processes as the sections are handed in;
    :meth:`write` collects them into a folder. Use as a context manager: leaving it
    normally lets the workers finish and exit; leaving it on an error or Ctrl-C kills
    them at once, mid-figure.

    Each worker is ``python -m pronet.recorded.figures`` on a pipe: it is told a figure (the
    pickled curves) and answers its PNG bytes. Not :mod:`multiprocessing`: its spawned
    workers import the caller's main script again (an unguarded script would run
    twice), forked ones copy the caller's memory page by page as it writes, and a
    worker killed inside its pool's queue lock can hang the pool's shutdown.

    ``workers``: how many (default: half the cores, at least one). The filters are most
    of the work and keep the cores first (the workers run at nice +10); a worker more
    than the cores they leave idle only adds its start-up (on 2 cores, two workers made
    ``pronet real`` on the Snapir data 8.3-9.0 s against 7.8-8.3 s with one).
    """

    def __init__(self, workers: int | None = None) -> None:
        import pronet

        n = max(1, workers if workers is not None else default_workers())
        env = dict(os.environ)  # the workers import this pronet, wherever it lies
        here = str(Path(pronet.__file__).resolve().parents[1])
        env["PYTHONPATH"] = os.pathsep.join(p for p in (here, env.get("PYTHONPATH")) if p)
        self._tasks: queue.SimpleQueue[tuple[str, SectionCurves, Future[bytes]] | None]
        self._tasks = queue.SimpleQueue()
        self._figures: dict[str, list[Future[bytes]]] = {}
        self._workers: list[subprocess.Popen[bytes]] = []
        try:
            for _ in range(n):
                # a session of its own: a terminal's Ctrl-C reaches the caller alone,
                # which kills the workers; a worker whose caller died ends with its stdin
                self._workers.append(
                    subprocess.Popen(
                        [sys.executable, "-m", "pronet.recorded.figures"],
                        stdin=subprocess.PIPE,
                        stdout=subprocess.PIPE,
                        env=env,
                        start_new_session=True,
                    )
                )
        except OSError:
            for w in self._workers:
                w.kill()
                w.wait()
            raise
        self._feeders = [
            threading.Thread(target=self._feed, args=(w,), daemon=True) for w in self._workers
        ]
        for t in self._feeders:
            t.start()

    def __enter__(self) -> FigurePool:
        return self

    def __exit__(self, kind: type[BaseException] | None, *exc: object) -> None:
        if kind is not None:
            for w in self._workers:
                w.kill()
        for _ in self._feeders:
            self._tasks.put(None)
        for t in self._feeders:
            t.join()
        for w in self._workers:
            w.wait()

    def _feed(self, worker: subprocess.Popen[bytes]) -> None:
        """Hand ``worker`` one figure at a time from the shared queue (so that the
        workers share the load) until told to stop; then close its pipe."""
        assert worker.stdin is not None and worker.stdout is not None
        while (task := self._tasks.get()) is not None:
            kind, curves, figure = task
            try:
                request = pickle.dumps((kind, curves), pickle.HIGHEST_PROTOCOL)
            except Exception as exc:  # nothing sent: the worker goes on with the next
                why = f"{type(exc).__name__}: {exc}"
                figure.set_exception(RuntimeError(f"its curves cannot be sent ({why})"))
                continue
            try:
                _send(worker.stdin, request)
                ok, body = _receive(worker.stdout)
            except (OSError, EOFError) as exc:
                figure.set_exception(RuntimeError(f"the figure worker stopped ({exc})"))
                continue
            if ok:
                figure.set_result(body)
            else:
                figure.set_exception(FigureError(body.decode("utf-8", "replace")))
        try:
            worker.stdin.close()
        except OSError:  # a killed worker's pipe
            pass

    def submit(self, curves: SectionCurves) -> None:
        """Queue one section's figures (each its own task, so that the last section's
        three are drawn side by side too); returns at once."""
        figures = [Future[bytes]() for _ in FIGURES]
        for kind, figure in zip(FIGURES, figures, strict=True):
            self._tasks.put((kind, curves, figure))
        self._figures[curves.name] = figures

    def submit_section(
        self, aligned: Section, runs: list[SectionRun], constants: dict[str, tuple[float, ...]]
    ) -> None:
        """:meth:`submit` the curves of one finished section (:func:`section_curves` at
        its IMU step): the ``on_section`` hook of :func:`pronet.recorded.real.run_sections`.
        Curves that cannot be made fail the section's figures (:meth:`write` returns
        them), not its rows: this never raises but ``MemoryError``."""
        from pronet.recorded.tuning import imu_step

        try:
            curves = section_curves(aligned, runs, constants, imu_step(aligned.imu_time))
        except MemoryError:
            raise
        except Exception as exc:
            why = f"its curves could not be made ({type(exc).__name__}: {exc})"
            self._figures[aligned.name] = [Future[bytes]() for _ in FIGURES]
            for figure in self._figures[aligned.name]:
                figure.set_exception(RuntimeError(why))
            return
        self.submit(curves)

    def write(
        self,
        folder: Path,
        names: list[str],
        on_done: Callable[[str], None] | None = None,
    ) -> dict[str, dict[str, Exception]]:
        """Wait for the figures of the sections ``names`` (each handed in) and write them
        into ``folder``, in that order; ``on_done(name)`` after each section. Returns
        the figures that could not be drawn, by section and file, each with its error
        (a one-line message: a worker's :class:`FigureError`, which keeps the worker's
        traceback, or a RuntimeError saying the worker stopped); the others are
        written all the same."""
        failed: dict[str, dict[str, Exception]] = {}
        for name in names:
            for kind, png in zip(FIGURES, self._figures[name], strict=True):
                file = figure_name(kind, name)
                try:
                    drawn = result_of(png)
                except Exception as exc:  # this figure alone
                    failed.setdefault(name, {})[file] = exc
                    continue
                atomic_write(folder / file, drawn)
            if on_done is not None:
                on_done(name)
        return failed


def _send(pipe: IO[bytes], payload: bytes, ok: bool = True) -> None:
    """One message: a status byte, the length (8 bytes, little-endian), the payload."""
    pipe.write(struct.pack("<?Q", ok, len(payload)))
    pipe.write(payload)
    pipe.flush()


def _receive(pipe: IO[bytes]) -> tuple[bool, bytes]:
    """One message written by :func:`_send`; EOFError when the pipe ends first."""
    head = pipe.read(struct.calcsize("<?Q"))
    if len(head) < struct.calcsize("<?Q"):
        raise EOFError("the pipe closed")
    ok, n = struct.unpack("<?Q", head)
    body = pipe.read(n)
    if len(body) < n:
        raise EOFError("the pipe closed mid-message")
    return bool(ok), body


def _serve() -> None:
    """The worker (``python -m pronet.recorded.figures``): draws each figure its stdin asks
    for and answers its PNG bytes, or the traceback of what went wrong, until stdin
    ends. Ctrl-C is its parent's to handle (it runs in a session of its own, and
    ignores the signal if it comes anyway)."""
    import traceback

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.nice(10)  # the filters first: a worker takes the cores they leave idle
    import matplotlib.backends.backend_agg  # noqa: F401  # before the first request

    source = sys.stdin.buffer
    # the answers get their own copy of stdout; anything else printed goes to stderr
    sink = os.fdopen(os.dup(sys.stdout.fileno()), "wb")
    os.dup2(sys.stderr.fileno(), sys.stdout.fileno())
    kept: dict[str, SectionFigure] = {}  # one figure of each kind, drawn again and again
    while True:
        try:
            _, request = _receive(source)
        except EOFError:
            return
        try:
            kind, curves = pickle.loads(request)
            _send(sink, draw_figure(kind, curves, kept))
        except Exception:  # the parent raises it, with this traceback
            _send(sink, traceback.format_exc().encode(), ok=False)


if __name__ == "__main__":
    _serve()
