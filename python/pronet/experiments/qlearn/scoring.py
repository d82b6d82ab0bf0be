"""Scoring q on training sections with the core: one pass with a given q schedule
(:func:`score`), the constant row and its scaled versions (:func:`scale_grid`), the
per-section best constant (:func:`best_constant`: the oracle ceiling of a constant q on
recorded data, found on the section itself, so never a prediction) and the paired
comparison of rows over sections (:func:`paired_rows`, :func:`comparison_table`).

Every pass runs the Rust core's recorded filter (:func:`pronet.run_filter`) from the
ground truth at the section's first truth row (:func:`pronet.recorded.passes.start_index`)
and is scored by :func:`pronet.recorded.metrics.section_metrics` (velocity SRMSE at the
truth rows, final and maximum horizontal error), exactly as ``pronet real`` scores its
rows. A scale pair ``(s_a, s_g)`` multiplies the constant row's q: ``s_a`` the three
accelerometer variances, ``s_g`` the three gyro ones.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet import _core
from pronet._util.cores import usable_cores
from pronet.experiments.qlearn.sections import TrainingSection
from pronet.filter import FilterResult
from pronet.recorded.metrics import SectionMetrics, section_metrics
from pronet.recorded.passes import section_recorded
from pronet.stats import MeanCI, mean_ci

F64 = NDArray[np.float64]

#: log10 of the scales the constant grid searches, per channel group: from 1e-4 to 1e2
#: times the constant row's q in half decades (scaling the constant q over five decades
#: moves the Snapir mean SRMSE by about 4 %: the optimum is broad; on Snapir the gyro's
#: lies below 1e-2 for most sections, hence the lower reach).
GRID_LOG10 = np.linspace(-4.0, 2.0, 13)


def scaled_q(q: Sequence[float], scales: ArrayLike) -> F64:
    """``q`` (6,) with its accelerometer entries times ``scales[0]`` and its gyro
    entries times ``scales[1]``; ``scales`` ``(..., 2)`` gives ``(..., 6)``."""
    s = np.asarray(scales, dtype=np.float64)
    return np.asarray(q, dtype=np.float64) * np.repeat(s, 3, axis=-1)


def run_pass(
    ts: TrainingSection,
    q_time: ArrayLike | None = None,
    q: ArrayLike | None = None,
    prior: Sequence[float] | None = None,
) -> FilterResult:
    """The core's pass over ``ts`` with q ``prior`` (default the constant row's) until
    the first of ``q_time`` (s, in force from each on) and ``q`` ``(k, 6)`` after."""
    rec = section_recorded(ts.section, ts.config)
    prior_q = tuple(float(v) for v in (ts.q_nominal if prior is None else prior))
    given = q_time is not None and len(np.asarray(q_time))
    return rec.filter(
        _core.Strategy.external(prior_q),
        np.asarray(q_time, dtype=np.float64) if given else None,
        np.asarray(q, dtype=np.float64) if given else None,
        aided=False,
    )


def score(
    ts: TrainingSection,
    q_time: ArrayLike | None = None,
    q: ArrayLike | None = None,
    prior: Sequence[float] | None = None,
) -> SectionMetrics:
    """:func:`run_pass` scored against the section's truth."""
    return section_metrics(ts.section, run_pass(ts, q_time, q, prior))


def constant_metrics(ts: TrainingSection, scales: ArrayLike = (1.0, 1.0)) -> SectionMetrics:
    """The constant row's q times the group ``scales`` over the whole section."""
    return score(ts, prior=tuple(scaled_q(ts.q_nominal, scales)))


def oracle_metrics(ts: TrainingSection) -> SectionMetrics:
    """The filter told the true q schedule at every step (simulation only)."""
    if ts.oracle_time is None or ts.oracle_q is None:
        raise ValueError(f"section {ts.name}: no true q schedule (recorded data has none)")
    return score(ts, ts.oracle_time, ts.oracle_q, prior=tuple(ts.oracle_q[0]))


@dataclass(frozen=True)
class ScaleGrid:
    """The constant row's q scaled over a grid, on one section.

    Attributes:
        name: the section's.
        log10: ``(m,)`` log10 of the scales of each channel group.
        srmse, final: ``(m, m)`` velocity SRMSE [m/s] and final horizontal error [m],
            indexed ``[accelerometer scale, gyro scale]``.
    """

    name: str
    log10: F64
    srmse: F64
    final: F64

    def best(self) -> tuple[float, float, float, float]:
        """``(s_a, s_g, srmse, final)`` at the grid's lowest SRMSE: the per-section
        best constant."""
        i, j = np.unravel_index(int(np.nanargmin(self.srmse)), self.srmse.shape)
        return (
            float(10 ** self.log10[i]),
            float(10 ** self.log10[j]),
            float(self.srmse[i, j]),
            float(self.final[i, j]),
        )

    def at(self, scales: Sequence[float]) -> tuple[float, float]:
        """``(srmse, final)`` at the grid point nearest ``scales`` (in log10)."""
        i, j = (int(np.argmin(np.abs(self.log10 - math.log10(s)))) for s in scales)
        return float(self.srmse[i, j]), float(self.final[i, j])


def scale_grid(ts: TrainingSection, log10: ArrayLike = GRID_LOG10) -> ScaleGrid:
    """The section's SRMSE and final error at every pair of group scales ``10**log10``
    (one core pass each; a pass that fails scores NaN)."""
    grid = np.asarray(log10, dtype=np.float64)
    pairs = [(a, g) for a in grid for g in grid]

    def one(pair: tuple[float, float]) -> tuple[float, float]:
        try:
            m = constant_metrics(ts, (10 ** pair[0], 10 ** pair[1]))
        except ValueError:
            return math.nan, math.nan
        return m.srmse, m.final_horizontal

    # each pass is one native call without the GIL: threads run them side by side
    with ThreadPoolExecutor(max_workers=usable_cores()) as pool:
        done = np.array(list(pool.map(one, pairs))).reshape(grid.size, grid.size, 2)
    return ScaleGrid(ts.name, grid, done[..., 0], done[..., 1])


def best_constant(ts: TrainingSection, log10: ArrayLike = GRID_LOG10) -> tuple[float, float]:
    """The per-section best constant's group scales on ``ts`` (a 2-D grid search on the
    core, :func:`scale_grid`): the ceiling of any constant q, known only after the fact."""
    s_a, s_g, _, _ = scale_grid(ts, log10).best()
    return s_a, s_g


@dataclass(frozen=True)
class Paired:
    """Row ``label`` against the reference row over the same sections: the mean of
    each and the paired 95 % CI of the mean difference (row − reference), for the
    SRMSE [m/s] and the final horizontal error [m]."""

    label: str
    srmse: MeanCI
    final: MeanCI
    d_srmse: MeanCI
    d_final: MeanCI
    relative_srmse: float  # mean relative change of the SRMSE [%]


def paired_rows(rows: Mapping[str, Mapping[str, SectionMetrics]], reference: str) -> list[Paired]:
    """Each row of ``rows`` (label → section → metrics) paired with ``reference`` over
    the sections both have."""
    ref = rows[reference]
    out = []
    for label, by_section in rows.items():
        names = [n for n in by_section if n in ref]
        s = np.array([by_section[n].srmse for n in names])
        f = np.array([by_section[n].final_horizontal for n in names])
        rs = np.array([ref[n].srmse for n in names])
        rf = np.array([ref[n].final_horizontal for n in names])
        out.append(
            Paired(
                label,
                mean_ci(s),
                mean_ci(f),
                mean_ci(s - rs),
                mean_ci(f - rf),
                float(100 * np.mean((s - rs) / rs)) if names else math.nan,
            )
        )
    return out


def comparison_table(
    rows: Mapping[str, Mapping[str, SectionMetrics]], reference: str, title: str
) -> str:
    """Markdown: per section the SRMSE and final error of every row, then each row's
    mean with the paired 95 % CI of its difference from ``reference``."""
    labels = list(rows)
    names = list(rows[reference])
    head = "| section | " + " | ".join(f"{lab} SRMSE / final" for lab in labels) + " |"
    lines = [f"### {title}", "", head, "|---" * (len(labels) + 1) + "|"]
    for n in names:
        cells = []
        for lab in labels:
            m = rows[lab].get(n)
            cells.append("—" if m is None else f"{m.srmse:.4f} / {m.final_horizontal:.2f}")
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "| row | mean SRMSE [m/s] | Δ SRMSE vs " + reference + " (paired 95 % CI) "
        "| mean change | mean final [m] | Δ final (paired 95 % CI) |",
        "|---|---|---|---|---|---|",
    ]
    for p in paired_rows(rows, reference):
        lines.append(
            f"| {p.label} | {p.srmse.mean:.4f} | {_ci(p.d_srmse, 5)} | "
            f"{p.relative_srmse:+.1f} % | {p.final.mean:.2f} | {_ci(p.d_final, 2)} |"
        )
    return "\n".join(lines) + "\n"


def _ci(m: MeanCI, digits: int) -> str:
    if not math.isfinite(m.low):
        return f"{m.mean:+.{digits}f}"
    return f"{m.mean:+.{digits}f} [{m.low:+.{digits}f}, {m.high:+.{digits}f}]"
