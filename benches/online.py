"""The online navigator's cost (``pronet.recorded.online.Navigator``), measured side by
side with the batch pass (``run_filter``) over the same data in one process.

    python benches/online.py [--quick] [--rounds N] [--seconds S] [--clock cpu|wall]
                             [--json FILE]

The data: a simulated survey (:func:`survey`), a vehicle at 1.5 m/s turning every
minute, 100 Hz IMU with the paper's noise, a body-frame DVL at 5 Hz, depth, position
fixes and a compass heading at 1 Hz each; the filter: ``FilterConfig()`` (its 0.1 s
covariance step), ``Strategy.constant`` (the paper's q), the navigator's default lag
(1 s) and checkpoints (every 32 epochs). ``run_filter`` over the same streams is the
core's own step (``epochs="last"``: the filter alone, as the navigator keeps no epochs).

Every case runs once per round, the rounds alternating the cases (``--rounds``; each
navigator made and its readings queued before the clock starts, the garbage collector
off while it runs); a case's time is the median over the rounds, a ratio or a
difference the median of the rounds' own, with their range, so that the machine's
drift between rounds cancels. The clock is the process's CPU time (``--clock wall``:
the wall; ``--json`` keeps both), which another job on the same cores moves less. The
rows:

1. One IMU sample per call from a plain Python loop, ``_core.Navigator.imu`` and the
   wrapper ``Navigator.imu`` (readings queued before): µs per sample, the difference
   from ``run_filter``'s (the target: at most 1 µs over it) and the ratio; with the
   arguments as ``zip(imu_time, imu)`` gives them (a NumPy float and a row view), as
   Python floats and row views, and as floats and lists; Python's floor for each (the
   same loop calling an empty function with the same arguments); the whole feed in one
   ``imu_block`` call (the navigator in the core, without the per-call cost), and with
   a checkpoint every epoch (what one checkpoint costs); and the GIL released and taken
   back once (``py.detach``'s share of a call: ctypes' ``CDLL`` over ``PyDLL``).
2. ``imu_block`` in blocks of 1000 samples (native and wrapper), readings queued
   before, over ``run_filter`` (the target: the batch speed).
3. Late readings, fed as from a log (:class:`Feed`): each reading at its arrival, the
   IMU samples before it in one ``imu_block`` call. The cost of a DVL reading 0.5 s
   late (the pass run again from the last checkpoint before its epoch): every DVL
   reading 0.5 s late against all in order, µs per late reading and per epoch run
   again; and the whole feed with every DVL reading 0.2–0.5 s late over the in-order
   feed. Every feed must end on ``run_filter``'s last epoch bit for bit (checked once
   before the rounds, and printed).
4. Memory: a fresh process (``--memory HOURS``) feeds 1 h, another 10 h of the survey
   as from a log, every DVL reading 0.2–0.5 s late, the survey made two minutes at a
   time (:func:`chunks`: the inputs do not grow with the duration); the peak resident
   memory at the end, ``VmHWM`` (the process's own; ``ru_maxrss`` is printed too, but
   a child's carries its parent's resident memory across ``exec``), and the 10 h over
   the 1 h (the target: within 5 %).

``--quick`` (2 minutes of data, 3 rounds, 0.1 h and 0.5 h; a few seconds) checks that
the script works (``tests/test_bench_run.py``); it measures nothing. ``--json FILE``
also writes the rows, every round's times on both clocks and the memory readings.
``benches/run.py --only online`` runs this in a fresh process and prints its rows in
run.py's table.
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import json
import os
import resource
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from functools import partial
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

import pronet
from pronet import _core
from pronet.filter import Stream
from pronet.recorded.alignment import dcm_from_euler
from pronet.recorded.online import Navigator
from pronet.recorded.solution import InitialState
from pronet.sim import paper

F64 = NDArray[np.float64]
SCRIPT = "python benches/online.py"
#: The IMU's variances [(m/s²)², (rad/s)²]: the simulated noise and the filter's q.
Q = paper.PAPER_Q
#: The sensors' 1σ: DVL [m/s], depth [m], fix [m], heading [rad].
DVL_SIGMA, DEPTH_SIGMA, FIX_SIGMA, HEADING_SIGMA = 0.05, 0.05, 1.5, np.radians(1.0)
#: Every so many IMU samples (100 Hz): a DVL reading (5 Hz), depth, fix and heading (1 Hz).
DVL_EVERY, ONE_HZ = 20, 100
EARTH_RADIUS = 6_378_137.0
START = (np.radians(32.0), np.radians(34.0), -5.0)
SPEED = 1.5
#: Samples per ``imu_block`` call in the block rows.
BLOCK = 1000
#: Seconds of survey the memory feed makes at a time.
CHUNK = 120.0
#: The most the issue allows one sample fed from Python to cost over the core's step [µs].
PER_SAMPLE_TARGET_US = 1.0
#: The most the 10 h feed's peak memory may exceed the 1 h feed's.
MEMORY_TARGET = 1.05
#: The most the block feed may cost over ``run_filter`` (the batch speed, within noise).
BLOCK_TARGET = 1.1


@dataclass
class Survey:
    """A stretch of the simulated survey.

    Attributes:
        imu_time, imu: ``(n,)`` sample end times [s], ``(n, 6)`` samples (noisy).
        readings: per stream (DVL, depth, fix, heading) its stamps ``(m,)`` [s] and
            values (``(m, 3)`` body velocity [m/s], depth [m], ``(m, 3)`` lla, yaw [rad]).
        t0, lla, vel, rpy: the true state at the start.
        end_lla, end_rpy: the true state at the end (the next stretch's start).
    """

    imu_time: F64
    imu: F64
    readings: list[tuple[F64, F64]]
    t0: float
    lla: F64
    vel: F64
    rpy: F64
    end_lla: F64
    end_rpy: F64


def survey(
    seconds: float,
    rng: np.random.Generator,
    *,
    t0: float = 0.0,
    lla0: Any = START,
    rpy0: Any = (0.0, 0.0, 0.0),
) -> Survey:
    """``seconds`` (whole minutes) of the survey from ``t0`` [s] at ``lla0``, ``rpy0``:
    minute-long legs turning at ±0.02 rad/s in turn (an even count ends on the start's
    heading), the paper's IMU noise, each sensor at its rate, readings stamped at IMU
    epochs, the first one step after ``t0``."""
    legs = [[60.0, 0.0, (-1) ** i * 0.02, 0.0] for i in range(max(1, round(seconds / 60)))]
    traj = pronet.trajectory_from_segments(legs, lla0=lla0, speed0=SPEED, rpy0=rpy0)
    n = traj.n_samples
    imu = traj.imu + rng.normal(size=traj.imu.shape) * np.sqrt(Q)
    time = traj.time + t0
    fast, slow = np.arange(DVL_EVERY, n + 1, DVL_EVERY), np.arange(ONE_HZ, n + 1, ONE_HZ)
    body = np.einsum("nji,nj->ni", dcm_from_euler(traj.rpy[fast]), traj.vel_ned[fast])
    m = len(slow)
    metres = np.ones((m, 3))  # per radian of latitude and longitude, per metre of height
    metres[:, 0] = EARTH_RADIUS
    metres[:, 1] = EARTH_RADIUS * np.cos(traj.lla[slow, 0])
    fix = traj.lla[slow] + rng.normal(size=(m, 3)) * FIX_SIGMA / metres
    readings = [
        (time[fast], body + rng.normal(size=body.shape) * DVL_SIGMA),
        (time[slow], -traj.lla[slow, 2] + rng.normal(size=m) * DEPTH_SIGMA),
        (time[slow], fix),
        (time[slow], traj.rpy[slow, 2] + rng.normal(size=m) * HEADING_SIGMA),
    ]
    return Survey(
        imu_time=time[1:],
        imu=imu,
        readings=readings,
        t0=float(time[0]),
        lla=traj.lla[0],
        vel=traj.vel_ned[0],
        rpy=traj.rpy[0],
        end_lla=traj.lla[-1],
        end_rpy=traj.rpy[-1],
    )


def sensors(s: Survey | None = None) -> list[Stream]:
    """The four streams with ``s``'s readings (``run_filter``'s), or without rows (the
    navigator's sensors)."""
    if s is None:
        empty = np.empty(0)
        rows = [
            (empty, np.empty((0, 3))),
            (empty, empty),
            (empty, np.empty((0, 3))),
            (empty, empty),
        ]
    else:
        rows = s.readings
    (dvl_t, dvl), (depth_t, depth), (fix_t, fix), (heading_t, heading) = rows
    return [
        pronet.Dvl(dvl_t, dvl, sigma=DVL_SIGMA),
        pronet.Depth(depth_t, depth, sigma=DEPTH_SIGMA),
        pronet.Fix(fix_t, fix, sigma=(FIX_SIGMA,) * 3),
        pronet.Heading(heading_t, heading, sigma=HEADING_SIGMA),
    ]


CONFIG = pronet.FilterConfig()
STRATEGY = pronet.Strategy.constant(Q)


def batch(s: Survey, epochs: Literal["all", "last"] = "last") -> pronet.FilterResult:
    """``run_filter`` over ``s``: the core's own step."""
    return pronet.run_filter(
        s.imu, s.imu_time, sensors(s), t0=s.t0, lla0=s.lla, vel0=s.vel, rpy0=s.rpy,
        config=CONFIG, strategy=STRATEGY, epochs=epochs,
    )  # fmt: skip


def native(s: Survey, **lag: Any) -> _core.Navigator:
    """A native navigator at ``s``'s start (``lag``: ``lag``, ``checkpoint_every``)."""
    return _core.Navigator(
        sensors(), t0=s.t0, lla0=s.lla, vel0=s.vel, rpy0=s.rpy, config=CONFIG,
        strategy=STRATEGY, **lag,
    )  # fmt: skip


def wrapper(s: Survey) -> Navigator:
    """The Python navigator at ``s``'s start."""
    initial = InitialState(
        t0=s.t0, lla=s.lla, vel=s.vel, rpy=s.rpy, p0_sigma=np.array(CONFIG.p0_sigma)
    )
    return Navigator(sensors(), initial=initial, strategy=STRATEGY, config=CONFIG)


#: One reading as it arrives: ``(arrival [s], stream, stamp [s], value)``.
Arrival = tuple[float, int, float, Any]


def arrivals(s: Survey, dvl_delay: F64 | None = None) -> list[Arrival]:
    """Every reading of ``s`` in order of arrival: at its stamp, the DVL's
    ``dvl_delay`` [s] later (one per reading)."""
    out: list[Arrival] = []
    for stream, (stamps, values) in enumerate(s.readings):
        delay = dvl_delay if stream == 0 and dvl_delay is not None else np.zeros(len(stamps))
        for t, d, v in zip(stamps.tolist(), delay.tolist(), values, strict=True):
            out.append((t + d, stream, t, v))
    out.sort(key=lambda a: a[0])
    return out


def queued(nav: Any, s: Survey) -> Any:
    """``nav`` with every reading of ``s`` fed first (all queued)."""
    for _, stream, stamp, value in arrivals(s):
        nav.reading(stream, stamp, value)
    return nav


@dataclass
class Feed:
    """A feed as from a log: each reading at its arrival, the IMU samples before it
    (``cuts[i]``: the samples fed before reading i) in one ``imu_block`` call."""

    arrivals: list[Arrival]
    cuts: list[int]

    @classmethod
    def of(cls, s: Survey, dvl_delay: F64 | None = None) -> Feed:
        a = arrivals(s, dvl_delay)
        cuts = np.searchsorted(s.imu_time, [x[0] for x in a], side="left")
        return cls(a, cuts.tolist())

    def rerun_epochs(self, s: Survey, every: int = 32) -> float:
        """The epochs a late DVL reading runs again, on average: from the last
        checkpoint (every ``every`` epochs) before its own to the newest epoch."""
        dvl = [
            (stamp, cut)
            for (_, stream, stamp, _), cut in zip(self.arrivals, self.cuts, strict=True)
            if stream == 0
        ]
        stamps, newest = np.array(dvl).T
        half = np.diff(s.imu_time, prepend=s.t0) / 2
        epoch = np.searchsorted(s.imu_time + half, stamps, side="left") + 1
        late = epoch <= newest
        return float(np.mean(newest[late] - (epoch[late] - 1) // every * every))

    def __call__(self, nav: _core.Navigator, *, s: Survey) -> list[str]:
        times, rows = s.imu_time, s.imu
        block, reading = nav.imu_block, nav.reading
        fates, done = [], 0
        for (_, stream, stamp, value), cut in zip(self.arrivals, self.cuts, strict=True):
            if cut > done:
                block(times[done:cut], rows[done:cut])
                done = cut
            fates.append(reading(stream, stamp, value))
        if done < len(times):
            block(times[done:], rows[done:])
        return fates


def one_at_a_time(nav: Any, times: Any, rows: Any) -> None:
    """The plain Python loop: one ``nav.imu(t, sample)`` call per sample."""
    imu = nav.imu
    for t, sample in zip(times, rows, strict=True):
        imu(t, sample)


def _nothing(t: Any, sample: Any) -> None:
    return None


def floor(times: Any, rows: Any) -> None:
    """The same loop calling an empty function with the same arguments."""
    call = _nothing
    for t, sample in zip(times, rows, strict=True):
        call(t, sample)


def in_blocks(nav: Any, s: Survey, size: int = BLOCK) -> None:
    for i in range(0, len(s.imu), size):
        nav.imu_block(s.imu_time[i : i + size], s.imu[i : i + size])


def gil_round_trip_ns(calls: int, rounds: int, clock: Callable[[], float]) -> list[float]:
    """Per round: one ``labs`` call through ctypes' ``CDLL`` (which releases the GIL
    around it, as ``py.detach`` does) less one through ``PyDLL`` (which keeps it) [ns]."""
    libc = ctypes.CDLL(None).labs, ctypes.PyDLL(None).labs
    for f in libc:
        f.argtypes, f.restype = [ctypes.c_long], ctypes.c_long
    out = []
    for _ in range(rounds):
        took = []
        for f in libc:
            t0 = clock()
            for _ in range(calls):
                f(1)
            took.append(clock() - t0)
        out.append((took[0] - took[1]) / calls * 1e9)
    return out


@dataclass
class Case:
    """What a round times: ``run(setup())``, the setup untimed."""

    setup: Callable[[], Any]
    run: Callable[[Any], object]


def cases(s: Survey) -> tuple[dict[str, Case], dict[str, Feed]]:
    """The timed cases over ``s`` (their names are the JSON's keys) and the log feeds."""
    t_float, lists = s.imu_time.tolist(), s.imu.tolist()
    rng = np.random.default_rng(1)
    n_dvl = len(s.readings[0][0])
    feeds = {
        "in_order": Feed.of(s),
        "late_05": Feed.of(s, np.full(n_dvl, 0.5)),
        "late_02_05": Feed.of(s, rng.uniform(0.2, 0.5, n_dvl)),
    }

    def nav() -> _core.Navigator:
        return queued(native(s), s)

    def none() -> None:
        return None

    out = {
        "run_filter": Case(none, lambda _: batch(s)),
        "run_filter_all": Case(none, lambda _: batch(s, "all")),
        # zip(imu_time, imu): a NumPy float and a row view made for each sample
        "imu_np": Case(nav, lambda n: one_at_a_time(n, s.imu_time, s.imu)),
        "imu_float": Case(nav, lambda n: one_at_a_time(n, t_float, s.imu)),
        "imu_list": Case(nav, lambda n: one_at_a_time(n, t_float, lists)),
        "wrapper_imu": Case(
            lambda: queued(wrapper(s), s), lambda n: one_at_a_time(n, s.imu_time, s.imu)
        ),
        "floor_np": Case(none, lambda _: floor(s.imu_time, s.imu)),
        "floor_float": Case(none, lambda _: floor(t_float, s.imu)),
        "floor_list": Case(none, lambda _: floor(t_float, lists)),
        "block_whole": Case(nav, lambda n: n.imu_block(s.imu_time, s.imu)),
        "block_whole_checkpoint_every_epoch": Case(
            lambda: queued(native(s, checkpoint_every=1), s),
            lambda n: n.imu_block(s.imu_time, s.imu),
        ),
        "block_1000": Case(nav, lambda n: in_blocks(n, s)),
        "wrapper_block_1000": Case(lambda: queued(wrapper(s), s), lambda n: in_blocks(n, s)),
    }
    for name, feed in feeds.items():
        out[f"feed_{name}"] = Case(lambda: native(s), partial(feed, s=s))
    return out, feeds


#: The clocks a case is timed on: the wall, and the CPU time of the process's threads
#: (``time.process_time``), which other work on a shared machine moves less.
CLOCKS: dict[str, Callable[[], float]] = {"wall": time.perf_counter, "cpu": time.process_time}


def timed_rounds(named: dict[str, Case], rounds: int) -> dict[str, dict[str, list[float]]]:
    """Per clock, every case's time [s] in each round, the cases alternating; the
    garbage collector off while the clocks run (as ``timeit`` does)."""
    out: dict[str, dict[str, list[float]]] = {c: {name: [] for name in named} for c in CLOCKS}
    wall, cpu = CLOCKS["wall"], CLOCKS["cpu"]
    for _ in range(rounds):
        for name, case in named.items():
            state = case.setup()
            gc.collect()
            gc.disable()
            try:
                w0, c0 = wall(), cpu()
                case.run(state)
                c1, w1 = cpu(), wall()
            finally:
                gc.enable()
            out["wall"][name].append(w1 - w0)
            out["cpu"][name].append(c1 - c0)
    return out


def checks(s: Survey, feeds: dict[str, Feed]) -> dict[str, Any]:
    """Whether every way of feeding ``s`` ends on ``run_filter``'s last epoch bit for
    bit, and what became of the readings in each log feed."""
    last = batch(s)
    want = np.concatenate([last.lla[-1], last.vel[-1]])

    def same(nav: Any) -> bool:
        state = nav.state()
        got = np.concatenate(
            [state["lla"], state["vel"]] if isinstance(state, dict) else [state.lla, state.vel]
        )
        return bool(np.array_equal(got, want))

    out: dict[str, Any] = {}
    for name in ("imu_np", "wrapper_imu", "block_1000"):
        nav = queued(wrapper(s) if name.startswith("wrapper") else native(s), s)
        if name == "block_1000":
            in_blocks(nav, s)
        else:
            one_at_a_time(nav, s.imu_time, s.imu)
        out[name] = same(nav)
    for name, feed in feeds.items():
        nav = native(s)
        fates = feed(nav, s=s)
        out[f"feed_{name}"] = same(nav)
        out[f"feed_{name}_fates"] = {f: fates.count(f) for f in sorted(set(fates))}
    return out


# -- memory ------------------------------------------------------------------------------


def status_mib(key: str) -> float:
    """A memory figure of this process from ``/proc/self/status`` [MiB]: ``VmHWM`` (its
    peak resident memory), ``VmRSS`` (resident now)."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(f"{key}:"):
                return int(line.split()[1]) / 1024
    raise RuntimeError(f"no {key} in /proc/self/status")


def chunks(hours: float, seed: int = 0) -> Iterator[Survey]:
    """``hours`` of the survey, :data:`CHUNK` seconds at a time, each starting where the
    last ended."""
    rng = np.random.default_rng(seed)
    t0, lla, rpy = 0.0, np.array(START), np.zeros(3)
    left = hours * 3600
    while left > 0:
        s = survey(min(CHUNK, left), rng, t0=t0, lla0=lla, rpy0=rpy)
        yield s
        t0, lla, rpy = float(s.imu_time[-1]), s.end_lla, s.end_rpy
        left -= CHUNK


def memory_feed(hours: float) -> dict[str, Any]:
    """Feed ``hours`` of the survey to one native navigator as from a log, every DVL
    reading 0.2–0.5 s late, the survey made chunk by chunk; this process's peak memory
    [MiB] after the first chunk and at the end."""
    t0 = time.perf_counter()
    late = np.random.default_rng(1)
    nav = None
    samples, first = 0, 0.0
    for s in chunks(hours):
        if nav is None:
            nav = native(s)
        # A chunk's last readings, due after its last sample, come at its end: still late.
        Feed.of(s, late.uniform(0.2, 0.5, len(s.readings[0][0])))(nav, s=s)
        samples += len(s.imu)
        first = first or status_mib("VmHWM")
    assert nav is not None and nav.failure is None
    tally = nav.tally()
    return {
        "hours": hours,
        "imu_samples": samples,
        "epoch": nav.epoch,
        "readings": sum(t["received"] for t in tally),
        "applied": sum(t["accepted"] + t["rejected"] for t in tally),
        "late": sum(t["late"] for t in tally),
        "peak_after_first_chunk_mib": first,
        "peak_mib": status_mib("VmHWM"),
        "rss_end_mib": status_mib("VmRSS"),
        "ru_maxrss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
        "seconds": time.perf_counter() - t0,
    }


def memory_in_fresh_process(hours: float) -> dict[str, Any]:
    done = subprocess.run(
        [sys.executable, __file__, "--memory", str(hours)],
        check=True,
        capture_output=True,
        text=True,
    )
    return json.loads(done.stdout)


# -- rows --------------------------------------------------------------------------------


@dataclass
class Row:
    """One line of the table.

    Attributes:
        key: its name in ``--json`` (a timed case's, or ``late_reading``,
            ``late_feed``, ``gil``, ``memory_<hours>h``, ``memory_ratio``).
        what: what was measured.
        measured: the measurement as text (medians, ranges, absolute times as information).
        target: the target as text ("—" for none).
        met: whether the target is met (None without one).
        value: the headline number in ``unit`` ("µs per sample", "µs", "x", "MiB", "ns").
        over_run_filter: the median of the rounds' time over ``run_filter``'s, where
            the row is a time per IMU sample.
    """

    key: str
    what: str
    measured: str
    target: str
    met: bool | None
    value: float
    unit: str
    over_run_filter: float | None = None


def spread(values: list[float], fmt: str) -> str:
    """The median and, with more than one value, the range: ``"m (lo–hi)"``."""
    m = fmt.format(statistics.median(values))
    if len(values) < 2:
        return m
    return f"{m} ({fmt.format(min(values))}–{fmt.format(max(values))})"


def rows_of(
    t: dict[str, list[float]],
    s: Survey,
    rerun: float,
    gil: list[float],
    memory: list[dict[str, Any]],
) -> list[Row]:
    """The table from the rounds' times ``t`` [s] over the survey ``s``, the epochs a
    0.5 s late reading runs again (``rerun``), the GIL's round trips [ns] and the memory
    feeds (the shorter first)."""
    n = len(s.imu)
    us = {k: [v / n * 1e6 for v in walls] for k, walls in t.items()}
    ref = us["run_filter"]

    def per_sample(name: str, what: str, target: str = "—", over: bool = True) -> Row:
        """Row ``name`` in µs per sample, and (``over``) its difference from
        ``run_filter``'s; its ratio to it, the rounds' median."""
        mine = us[name]
        diff = [a - b for a, b in zip(mine, ref, strict=True)]
        ratio = [a / b for a, b in zip(mine, ref, strict=True)]
        measured = f"{spread(mine, '{:.3f}')} µs per sample"
        if over:
            measured += f"; {spread(diff, '{:+.3f}')} µs over run_filter"
        row = Row(
            name, what, measured, target, None, statistics.median(mine), "µs per sample",
            statistics.median(ratio),
        )  # fmt: skip
        if target.endswith("µs over run_filter"):
            row.met = statistics.median(diff) <= PER_SAMPLE_TARGET_US
        elif target.endswith("× run_filter"):
            row.met = statistics.median(ratio) <= BLOCK_TARGET
        return row

    one = f"≤ +{PER_SAMPLE_TARGET_US:g} µs over run_filter"
    rows = [
        per_sample("run_filter", '`run_filter(epochs="last")`: the core\'s own step', over=False),
        per_sample("run_filter_all", '`run_filter`, every epoch kept (`epochs="all"`)'),
        per_sample(
            "imu_np",
            "`_core.Navigator.imu`, one sample per call in a Python loop over "
            "`zip(imu_time, imu)` (a NumPy float, a row view)",
            one,
        ),
        per_sample("wrapper_imu", "`Navigator.imu` (the Python wrapper), the same loop", one),
        per_sample("imu_float", "`_core.Navigator.imu`, times as Python floats, row views"),
        per_sample("imu_list", "`_core.Navigator.imu`, Python floats and lists of 6"),
        per_sample(
            "floor_np",
            "Python's floor: the loop over `zip(imu_time, imu)` calling an empty function",
            over=False,
        ),
        per_sample("floor_float", "Python's floor over floats and row views", over=False),
        per_sample("floor_list", "Python's floor over floats and lists of 6", over=False),
        per_sample("block_whole", "`_core.Navigator.imu_block`, the whole feed in one call"),
        per_sample(
            "block_whole_checkpoint_every_epoch",
            "`_core.Navigator.imu_block`, whole feed, a checkpoint every epoch (not 32)",
        ),
        Row(
            "gil",
            "the GIL released and taken back once (ctypes `CDLL` over `PyDLL` `labs`): "
            "`py.detach`'s share of a call",
            spread(gil, "{:.0f}") + " ns",
            "—",
            None,
            statistics.median(gil),
            "ns",
        ),
        per_sample(
            "block_1000",
            f"`_core.Navigator.imu_block`, blocks of {BLOCK}, readings queued before",
            f"≤ {BLOCK_TARGET}× run_filter",
        ),
        per_sample(
            "wrapper_block_1000",
            f"`Navigator.imu_block` (the wrapper), blocks of {BLOCK}",
            f"≤ {BLOCK_TARGET}× run_filter",
        ),
        per_sample(
            "feed_in_order",
            "as from a log, in order: each reading at its time, the IMU samples before it "
            "in one `imu_block` call",
        ),
    ]
    n_dvl = len(s.readings[0][0])
    in_order = t["feed_in_order"]
    late = [(a - b) / n_dvl * 1e6 for a, b in zip(t["feed_late_05"], in_order, strict=True)]
    per_epoch = [x / rerun for x in late]
    rows.append(
        Row(
            "late_reading",
            "a DVL reading 0.5 s late: the pass run again from the last checkpoint "
            "before its epoch (every DVL reading late, over the in-order feed)",
            f"{spread(late, '{:.1f}')} µs per late reading ({rerun:.1f} epochs run again "
            f"on average: {spread(per_epoch, '{:.3f}')} µs each)",
            "—",
            None,
            statistics.median(late),
            "µs",
        )
    )
    ratio = [a / b for a, b in zip(t["feed_late_02_05"], in_order, strict=True)]
    rows.append(
        Row(
            "late_feed",
            "every DVL reading 0.2–0.5 s late: the whole feed over the in-order feed",
            spread(ratio, "{:.2f}") + "×",
            "—",
            None,
            statistics.median(ratio),
            "x",
        )
    )
    for m in memory:
        rows.append(
            Row(
                f"memory_{m['hours']:g}h",
                f"peak memory feeding {m['hours']:g} h of 100 Hz IMU and the four streams "
                "(DVL 0.2–0.5 s late; a fresh process, `VmHWM`)",
                f"{m['peak_mib']:.1f} MiB ({m['peak_after_first_chunk_mib']:.1f} after the "
                f"first {CHUNK:g} s, {m['rss_end_mib']:.1f} resident at the end; ru_maxrss "
                f"{m['ru_maxrss_mib']:.1f}; {m['imu_samples']:,} samples in "
                f"{m['seconds']:.1f} s)",
                "—",
                None,
                m["peak_mib"],
                "MiB",
            )
        )
    if len(memory) == 2:
        short, long = memory
        grow = long["peak_mib"] / short["peak_mib"]
        rows.append(
            Row(
                "memory_ratio",
                f"peak memory, {long['hours']:g} h over {short['hours']:g} h",
                f"{grow:.3f}× ({short['peak_mib']:.1f} → {long['peak_mib']:.1f} MiB)",
                f"≤ {MEMORY_TARGET}×",
                grow <= MEMORY_TARGET,
                grow,
                "x",
            )
        )
    return rows


def where_it_goes(t: dict[str, list[float]], n: int, gil: list[float]) -> list[str]:
    """Comment lines: one sample per call split into the core's step, the navigator's
    bookkeeping, Python's loop and the binding's call (medians of the rounds'
    differences)."""

    def med(name: str, minus: str | None = None) -> float:
        a = t[name]
        b = t[minus] if minus else [0.0] * len(a)
        return statistics.median((x - y) / n * 1e6 for x, y in zip(a, b, strict=True))

    def call(form: str) -> float:
        """The binding's call with the arguments in ``form``: one sample per call over
        the whole feed in one call, less Python's loop over the same arguments."""
        return med(f"imu_{form}", "block_whole") - med(f"floor_{form}")

    # A checkpoint every epoch over every 32nd: 31/32 of a copy more per sample.
    copy = med("block_whole_checkpoint_every_epoch", "block_whole") * 32 / 31
    return [
        "# where one sample per call goes (µs per sample, medians of the rounds' differences):",
        f"#   run_filter's step {med('run_filter'):.3f}; the navigator in the core "
        f"(imu_block, whole feed) over it {med('block_whole', 'run_filter'):+.3f}, of which "
        f"its checkpoints {copy / 32:.3f} (one copy {copy:.2f} every 32 epochs);",
        f"#   Python's loop over zip(imu_time, imu) and an empty call {med('floor_np'):.3f}; "
        f"the binding's call over those {call('np'):.3f} (pyo3's dispatch, the arguments, "
        f"py.detach ≈ {statistics.median(gil) / 1e3:.3f});",
        f"#   the binding's call with a Python float for time {call('float'):.3f}, with a "
        f"float and a list of 6 {call('list'):.3f}.",
    ]


def machine() -> str:
    load = ", ".join(f"{x:.1f}" for x in os.getloadavg())
    return (
        f"{len(os.sched_getaffinity(0))} cores, python {sys.version.split()[0]}, "
        f"numpy {np.__version__}, load average {load}"
    )


def parse(argv: list[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a fast smoke run, not a measurement")
    parser.add_argument("--rounds", type=int, help="alternating rounds (default 25; quick 3)")
    parser.add_argument("--seconds", type=float, help="survey seconds timed (default 600)")
    parser.add_argument(
        "--clock",
        choices=list(CLOCKS),
        default="cpu",
        help="the rows' clock: the process's CPU time (default) or the wall (both in --json)",
    )
    parser.add_argument("--json", metavar="FILE", help="also write the rows to FILE")
    parser.add_argument("--memory", type=float, metavar="HOURS", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    args.rounds = args.rounds or (3 if args.quick else 25)
    args.seconds = args.seconds or (120.0 if args.quick else 600.0)
    args.hours = (0.1, 0.5) if args.quick else (1.0, 10.0)
    return args


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    if args.memory is not None:
        print(json.dumps(memory_feed(args.memory)))
        return 0
    command = f"{SCRIPT} {' '.join(sys.argv[1:] if argv is None else argv)}".rstrip()
    print(f"# {command}")
    print(f"# machine: {machine()}")
    s = survey(args.seconds, np.random.default_rng(0))
    n = len(s.imu)
    print(
        f"# {args.seconds:g} s of survey, {n:,} IMU samples, {args.rounds} rounds, "
        f"{args.clock} time"
    )
    named, feeds = cases(s)
    identical = checks(s, feeds)
    timed = timed_rounds(named, args.rounds)
    walls = timed[args.clock]
    gil = gil_round_trip_ns(20_000 if args.quick else 200_000, args.rounds, CLOCKS[args.clock])
    memory = [memory_in_fresh_process(h) for h in args.hours]
    rows = rows_of(walls, s, feeds["late_05"].rerun_epochs(s), gil, memory)
    print("| what | measured | × run_filter | target | met |")
    print("|---|---|---|---|---|")
    for r in rows:
        ratio = "" if r.over_run_filter is None else f"{r.over_run_filter:.2f}×"
        met = {True: "yes", False: "**no**", None: ""}[r.met]
        print(f"| {r.what} | {r.measured} | {ratio} | {r.target} | {met} |")
    for line in where_it_goes(walls, n, gil):
        print(line)
    same = all(v for k, v in identical.items() if not k.endswith("_fates"))
    print(f"# every feed ends on run_filter's last epoch bit for bit: {'yes' if same else 'NO'}")
    for name in feeds:
        print(f"# readings of the feed {name}: {identical[f'feed_{name}_fates']}")
    print(f"# machine after: {machine()}")
    if args.json:
        record = {
            "command": command,
            "machine": machine(),
            "date": time.strftime("%Y-%m-%d %H:%M:%S"),
            "seconds": args.seconds,
            "imu_samples": n,
            "rounds": args.rounds,
            "rows": [asdict(r) for r in rows],
            "clock": args.clock,
            "times_s": timed,
            "gil_ns": gil,
            "memory": memory,
            "identical": identical,
        }
        Path(args.json).write_text(json.dumps(record, indent=1) + "\n")
        print(f"# wrote {args.json}")
    assert "torch" not in sys.modules
    return 0


if __name__ == "__main__":
    sys.exit(main())
