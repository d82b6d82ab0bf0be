"""A row of ``benches/run.py``'s table and how it reads against the run's reference.

Every timed row is given as a ratio to the **reference** measured in the same run: the
constant-Q Monte Carlo of ``paper`` at one IMU step (100 runs × 330 s, 2 threads,
:data:`REFERENCE_STEPS` filter steps), timed in a fresh process before the rows. A row
in seconds is divided by the reference's seconds, a row in ns per step by the
reference's ns per filter step (its wall over its filter steps). Much of a machine's
speed cancels from that ratio; what is left of its drift shows in a second reading of
the reference after the rows, printed below the table. Absolute seconds stay in the
``measured`` column as information.
"""

from __future__ import annotations

import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

SCRIPT = "python benches/run.py"
#: Monte Carlo runs of the reference.
REFERENCE_RUNS = 100
#: IMU steps of one run of ``paper`` (330 s at 100 Hz).
PAPER_STEPS = 33_000
#: Filter steps of the reference: its runs × :data:`PAPER_STEPS`.
REFERENCE_STEPS = REFERENCE_RUNS * PAPER_STEPS
#: The reference's wall time [s] on the machine the former targets in seconds were
#: set on: a target of T seconds reads as T / 1.03 × the reference.
TARGET_MACHINE_REFERENCE = 1.03


@dataclass
class Row:
    """One line of the table.

    Attributes:
        what: what was timed.
        measured: the measurement as text, absolute seconds or ns included (information).
        target: the target as text ("—" or "" for none).
        met: whether ``ratio`` (else ``value``) meets the target; None without one.
        command: the command that measures this row alone.
        value: the headline number in ``unit`` (for --json and --compare).
        unit: "s", "ns per step", "x" (a ratio measured within the row), "MiB", "µs"
            (the online navigator's late reading), or "" without a number.
        ratio: ``value`` over the reference (seconds over its seconds, ns per step over
            its ns per filter step); None for rows that are ratios already.
        ns_per_step: wall time [ns] per filter step, where the row counts its steps.
    """

    what: str
    measured: str
    target: str
    met: bool | None
    command: str
    value: float | None = None
    unit: str = ""
    ratio: float | None = None
    ns_per_step: float | None = None


@dataclass(frozen=True)
class Reference:
    """The reference's wall time [s] measured in this run before the rows (the one the
    ratios divide by), and after them (None until then: the drift in between)."""

    wall: float
    after: float | None = None

    @property
    def ns_per_step(self) -> float:
        """Wall time [ns] per filter step."""
        return self.wall / REFERENCE_STEPS * 1e9

    def describe(self) -> str:
        """One comment line: the readings and their spread."""
        after = ""
        if self.after is not None:
            after = f", after them {self.after:.3f} s ({self.after / self.wall - 1:+.1%})"
        return (
            f"# reference: constant-Q Monte Carlo of paper, {REFERENCE_RUNS} runs × 330 s, "
            f"2 threads, every IMU step: {self.wall:.3f} s before the rows "
            f"({self.ns_per_step:.0f} ns per filter step; the ratios divide by it){after}"
        )


#: The reference, best of N, in a fresh process: the core alone, without torch's
#: threads beside rayon's, the trajectory built before the clock starts.
MONTE_CARLO = """
import sys, time
import pronet
from pronet.sim import paper, scenarios
kind, n_runs, threads, repeat = sys.argv[1], *map(int, sys.argv[2:5])
sc = scenarios.SCENARIOS["paper"]()
q = paper.PAPER_Q
strategy = pronet.Strategy.constant(q) if kind == "constant" else pronet.Strategy.mehra(5, q)
assert "torch" not in sys.modules
best = float("inf")
for _ in range(repeat):
    t0 = time.perf_counter()
    pronet.monte_carlo(sc.trajectory, strategy, sensors=sc.sensors,
                       config=paper.paper_filter_config(), n_runs=n_runs, seed=0, threads=threads)
    best = min(best, time.perf_counter() - t0)
print(best)
"""


def monte_carlo_wall(kind: str, runs: int, threads: int, repeat: int) -> float:
    """Best wall time [s] of ``repeat`` Monte Carlos of ``paper`` (``kind``: "constant"
    or "mehra", ξ = 5) in a fresh process."""
    argv = [kind, str(runs), str(threads), str(repeat)]
    out = subprocess.run(
        [sys.executable, "-c", MONTE_CARLO, *argv], check=True, capture_output=True, text=True
    )
    return float(out.stdout)


def measure_reference(repeat: int) -> float:
    """One reading of the reference [s], best of ``repeat``."""
    return monte_carlo_wall("constant", REFERENCE_RUNS, 2, repeat)


def best_of(repeat: int, f: Callable[[], object]) -> float:
    """Smallest wall time [s] of ``repeat`` calls of ``f``."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t0)
    return float(best)


def _against(row: Row, at_most: float | None) -> Row:
    """``row`` (its ratio set) with the target ``at_most`` (a ratio, rounded as
    printed) and its verdict."""
    limit = as_printed(at_most)
    if limit is not None and row.ratio is not None:
        row.target, row.met = f"≤ {times(limit)}", row.ratio <= limit
    return row


def timed_row(
    what: str,
    seconds: float,
    ref: Reference,
    command: str,
    *,
    detail: str = "",
    at_most: float | None = None,
    steps: int | None = None,
) -> Row:
    """A row timed in seconds, as a ratio to the reference; ``at_most``: the target as
    a ratio; ``steps``: the filter steps it ran (for ns per step)."""
    wall = f"{seconds:.2f} s" if seconds >= 0.1 else f"{seconds * 1e3:.2f} ms"
    measured = wall + (f" ({detail})" if detail else "")
    ns = seconds / steps * 1e9 if steps else None
    row = Row(what, measured, "—", None, command, seconds, "s", seconds / ref.wall, ns)
    return _against(row, at_most)


def per_step_row(
    what: str,
    ns: float,
    ref: Reference,
    command: str,
    *,
    detail: str = "",
    at_most: float | None = None,
) -> Row:
    """A row in ns per step, as a ratio to the reference's ns per filter step."""
    measured = f"{ns:.0f} ns per step" + (f" ({detail})" if detail else "")
    row = Row(what, measured, "—", None, command, ns, "ns per step", ns / ref.ns_per_step, ns)
    return _against(row, at_most)


def times(ratio: float) -> str:
    """A ratio as printed: three significant digits below 1, two decimals below 10,
    one below 100, none above."""
    if ratio < 1:
        return f"{ratio:.3g}×"
    digits = 2 if ratio < 10 else 1 if ratio < 100 else 0
    return f"{ratio:.{digits}f}×"


def as_printed(target: float | None) -> float | None:
    """A target rounded as :func:`times` prints it, so that the verdict reads off the
    table."""
    return None if target is None else float(times(target)[:-1])


def from_seconds_target(seconds: float) -> float:
    """A former target in seconds as a ratio to the reference
    (:data:`TARGET_MACHINE_REFERENCE`), rounded as printed."""
    return round(seconds / TARGET_MACHINE_REFERENCE, 2)


def cells(row: Row) -> list[str]:
    """The row's cells in the printed table."""
    met = {True: "yes", False: "**no**", None: ""}[row.met]
    ratio = "" if row.ratio is None else times(row.ratio)
    ns = "" if row.ns_per_step is None else f"{row.ns_per_step:.0f}"
    return [row.what, ratio, ns, row.measured, row.target, met, f"`{row.command}`"]


HEADER = "| what | × reference | ns per filter step | measured | target | met | command |"
