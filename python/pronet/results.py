"""Results: one table schema, one Markdown helper, one atomic result folder.

Every result folder pronet writes (``reproduce``, ``simulate``, ``sweep``, ``real``)
holds the same two tables:

- ``metrics.csv``: one row per run, columns :data:`RUN_COLUMNS` (the label columns
  :data:`LABELS`, then ``run``, the per-run metrics in SI units and ``failure``);
- ``summary.csv`` and ``metrics.json`` (the same rows as JSON records): one row per
  strategy and setting, columns :data:`SUMMARY_COLUMNS` (the labels, then mean and
  95 % CI bounds of each metric, the run counts, the paired difference from the
  scenario's first row and the learned loop's guardrail counts).

A recorded section is one "run" of its scenario (``scenario`` is the section's name);
its confidence bounds are NaN.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from pronet._util.files import atomic_folder, json_bytes
from pronet.learn.hybrid import HybridResult
from pronet.montecarlo import IN_BAND_FLAG, STATE_BLOCKS, MonteCarloResult
from pronet.sim.paper import PAPER_NAMES, PAPER_TABLE
from pronet.stats import MeanCI, format_number, mean_ci

if TYPE_CHECKING:  # pandas loads only when a table is made
    import pandas as pd

    from pronet.run import Row

#: What each result is: scenario (or recorded section), strategy, the IMU noise level
#: (a factor on the scenario's variances) and the learned loop's tuning period [s]
#: (NaN for native strategies).
LABELS = ("scenario", "strategy", "noise_level", "tuning_period_s")
#: The per-run metrics [m/s, m, -, share, count, s] in :class:`~pronet.MonteCarloResult`
#: order (the NEES and the velocity NEES's 3σ share: NaN on recorded sections).
METRICS = MonteCarloResult.PER_RUN
#: Columns of every ``metrics.csv``.
RUN_COLUMNS = (*LABELS, "run", *METRICS, "failure")
#: The metrics summarised as mean and 95 % CI in :data:`SUMMARY_COLUMNS`.
SUMMARIZED = MonteCarloResult.SUMMARIZED
#: Columns of every ``summary.csv`` / ``metrics.json`` record.
SUMMARY_COLUMNS = (
    *LABELS,
    *(f"{m}{s}" for m in SUMMARIZED for s in ("", "_low", "_high")),
    *(f"{b}_nees_in_band" for b in STATE_BLOCKS),
    "nees_band_low",
    "nees_band_high",
    "runs",
    "failed_runs",
    "diverged_runs",
    "srmse_diff",
    "srmse_diff_low",
    "srmse_diff_high",
    "tunings",
    "guardrail_clipped",
    "guardrail_non_finite",
)


def _labels(labels: dict[str, object]) -> dict[str, object]:
    missing = {"scenario", "strategy"} - set(labels)
    if missing:
        raise ValueError(f"labels: missing {sorted(missing)}")
    unknown = set(labels) - set(LABELS)
    if unknown:
        raise ValueError(f"labels: unknown {sorted(unknown)}; known {list(LABELS)}")
    period = labels.get("tuning_period_s")
    return {
        "scenario": labels["scenario"],
        "strategy": labels["strategy"],
        "noise_level": float(labels.get("noise_level", 1.0)),  # type: ignore[arg-type]
        "tuning_period_s": math.nan if period is None else float(period),  # type: ignore[arg-type]
    }


def summary_row(
    labels: dict[str, object],
    result: MonteCarloResult,
    *,
    diff: MeanCI | None = None,
    hybrid: HybridResult | None = None,
) -> dict[str, object]:
    """One :data:`SUMMARY_COLUMNS` record: ``labels`` (see :data:`LABELS`),
    ``result.summary_row()``, the paired SRMSE difference ``diff`` [m/s] (NaN if None)
    and the learned loop's counts (0 without ``hybrid``)."""
    row: dict[str, object] = {**_labels(labels), **result.summary_row()}
    d = diff if diff is not None else MeanCI(math.nan, math.nan, math.nan, 0)
    row.update(srmse_diff=d.mean, srmse_diff_low=d.low, srmse_diff_high=d.high)
    row["tunings"] = hybrid.n_tunings if hybrid is not None else 0
    row["guardrail_clipped"] = int(hybrid.clipped.sum()) if hybrid is not None else 0
    row["guardrail_non_finite"] = int(hybrid.non_finite.sum()) if hybrid is not None else 0
    return {c: row[c] for c in SUMMARY_COLUMNS}


def results_dataframe(
    labelled: Iterable[tuple[dict[str, object], MonteCarloResult]], per_run: bool = False
) -> pd.DataFrame:
    """Several results as one DataFrame: :data:`SUMMARY_COLUMNS` (one row per result), or
    with ``per_run`` :data:`RUN_COLUMNS` (one row per run). Each result's ``labels``
    name its ``scenario`` and ``strategy`` and optionally ``noise_level`` (default 1)
    and ``tuning_period_s`` (default NaN)."""
    import pandas as pd

    if not per_run:
        return pd.DataFrame(
            [summary_row(labels, result) for labels, result in labelled],
            columns=list(SUMMARY_COLUMNS),
        )
    frames = []
    for labels, result in labelled:
        df = result.to_dataframe()
        for i, (key, value) in enumerate(_labels(labels).items()):
            df.insert(i, key, value)
        frames.append(df[list(RUN_COLUMNS)])
    if not frames:
        return pd.DataFrame(columns=list(RUN_COLUMNS))
    return pd.concat(frames, ignore_index=True)


def check_a_run_finished(labelled: Iterable[tuple[str, MonteCarloResult]]) -> None:
    """``ValueError`` when not one run of any of the ``(label, result)`` pairs finished
    (every one a numerical failure): such a result folder would hold only NaN, so the
    experiment fails, as ``pronet real`` does when no section can run. The message names
    the first failed run and its reason. One finished run anywhere passes (the failed
    ones are then counted in the tables)."""
    first: tuple[str, str] | None = None
    for label, result in labelled:
        if result.n_failed < result.n_runs:
            return
        if first is None and result.n_runs:
            first = (label, str(result.failure[0]))
    if first is not None:
        raise ValueError(f"every run failed; the first, {first[0]}, run 0: {first[1]}")


def _row_labels(scenario: str, row: Row) -> dict[str, object]:
    return {"scenario": scenario, "strategy": row.label, "tuning_period_s": row.tuning_period}


def table_title(scenario: str, rows: Sequence[Row]) -> str:
    """The title of a scenario's table and figures: ``"<scenario> scenario, N runs"``."""
    runs = rows[0].result.n_runs if rows else 0
    return f"{scenario} scenario, {runs} runs"


def rows_dataframe(tables: dict[str, list[Row]], per_run: bool = False) -> pd.DataFrame:
    """Experiment rows (scenario name → rows, as :func:`pronet.run.run_strategies` makes
    them; the name fills the ``scenario`` column, as in every result) as one DataFrame:
    :data:`SUMMARY_COLUMNS` with each row's paired difference and guardrail counts, or
    with ``per_run`` :data:`RUN_COLUMNS`."""
    import pandas as pd

    if per_run:
        return results_dataframe(
            ((_row_labels(t, row), row.result) for t, rows in tables.items() for row in rows),
            per_run=True,
        )
    records = [
        summary_row(_row_labels(t, row), row.result, diff=row.srmse_diff, hybrid=row.hybrid)
        for t, rows in tables.items()
        for row in rows
    ]
    return pd.DataFrame(records, columns=list(SUMMARY_COLUMNS))


def markdown(
    header: Sequence[str], rows: Iterable[Sequence[object]], title: str | None = None
) -> str:
    """A Markdown table: an optional ``### title``, the header, one line per row (each
    cell as ``str``)."""
    out = f"### {title}\n\n" if title else ""
    out += "| " + " | ".join(header) + " |\n" + "|---" * len(header) + "|\n"
    return out + "".join("| " + " | ".join(str(c) for c in r) + " |\n" for r in rows)


def between_markers(page: str, name: str, text: str, where: str = "page") -> str:
    """``page`` (Markdown) with what lies between ``<!-- name:begin -->`` and
    ``<!-- name:end -->`` replaced by ``text`` (how the generated tables of ``docs/``
    are written); ``ValueError`` naming ``where`` if the page has no such markers."""
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    pattern = re.compile(re.escape(begin) + ".*?" + re.escape(end), re.S)
    if not pattern.search(page):
        raise ValueError(f"{where}: has no {name} markers")
    return pattern.sub(lambda _: f"{begin}\n{text}{end}", page)


#: Table columns of a filter's consistency (see :func:`consistency_cells`).
CONSISTENCY_HEADER = ("vel. NEES (in 3σ)", "att. NEES", "NIS")
#: The mark of a NEES outside its band (:func:`out_of_band`).
OUT_OF_BAND = " ⚠"


def out_of_band(result: MonteCarloResult, block: str) -> str:
    """:data:`OUT_OF_BAND` when ``block``'s run-averaged NEES lies inside its 95 % band
    at fewer than :data:`pronet.montecarlo.IN_BAND_FLAG` of the DVL epochs, else ``""``."""
    share = result.nees_in_band(block)
    return OUT_OF_BAND if share < IN_BAND_FLAG else ""


def consistency_cells(result: MonteCarloResult) -> list[str]:
    """The :data:`CONSISTENCY_HEADER` cells of ``result``: the mean velocity NEES (3 when
    consistent) with the share of epochs inside its 3σ bound (99.7 % when consistent),
    the mean attitude NEES (3 when consistent), each marked :data:`OUT_OF_BAND` where
    it leaves its band (:func:`out_of_band`), and the mean NIS (3 when consistent);
    means over the runs that did not fail."""
    nees, inside, attitude, nis = (
        mean_ci(getattr(result, name)).mean
        for name in ("velocity_nees", "velocity_nees_3sigma", "attitude_nees", "mean_nis")
    )
    return [
        f"{format_number(nees, '{:.2f}')} ({format_number(100 * inside, '{:.1f}')} %)"
        f"{out_of_band(result, 'velocity')}",
        f"{format_number(attitude, '{:.2f}')}{out_of_band(result, 'attitude')}",
        format_number(nis, "{:.2f}"),
    ]


def rows_markdown(rows: list[Row], title: str, paper: bool = True) -> str:
    """Experiment rows as a Markdown table; with ``paper``, the paper's name of each row
    and its numbers beside ours (:data:`pronet.sim.paper.PAPER_NAMES`, ``PAPER_TABLE``)."""
    header = ["approach", "SRMSE [m/s] (95 % CI)", "SMAE [m/s] (95 % CI)"]
    header.append("ΔSRMSE vs row 1 (paired 95 % CI)")
    if paper:
        header += ["paper's row", "paper SRMSE", "paper SMAE"]
    header += [*CONSISTENCY_HEADER, "failed / diverged runs", "guardrail events"]
    lines = []
    for row in rows:
        d = row.srmse_diff
        cells: list[object] = [row.label, row.srmse, row.smae]
        cells.append(f"{d.mean:+.4f} [{d.low:+.4f}, {d.high:+.4f}]")
        if paper:
            ref = PAPER_TABLE.get(row.label)
            cells.append(PAPER_NAMES.get(row.label, ""))
            cells += [f"{ref[0]:.3f}", f"{ref[1]:.3f}"] if ref else ["", ""]
        cells += consistency_cells(row.result)
        cells.append(f"{row.result.n_failed} / {row.result.n_diverged}")
        h = row.hybrid
        guard = f"{int(h.clipped.sum())} clipped, {int(h.non_finite.sum())} non-finite" if h else ""
        cells.append(guard)
        lines.append(cells)
    return markdown(header, lines, title)


def write_tables(folder: Path, summary: pd.DataFrame, per_run: pd.DataFrame, table_md: str) -> None:
    """Write ``table.md``, ``summary.csv``, ``metrics.json`` and ``metrics.csv`` into
    ``folder`` (inside :func:`~pronet._util.files.atomic_folder`), checking the schema."""
    if tuple(summary.columns) != SUMMARY_COLUMNS or tuple(per_run.columns) != RUN_COLUMNS:
        raise ValueError("results: a table does not have the result schema")
    (folder / "table.md").write_text(table_md)
    summary.to_csv(folder / "summary.csv", index=False)
    per_run.to_csv(folder / "metrics.csv", index=False)
    records = summary.to_dict(orient="records")
    (folder / "metrics.json").write_bytes(json_bytes(records))


def write_result_folder(
    folder: Path,
    tables: dict[str, list[Row]],
    config: dict[str, object],
    extra: Callable[[Path], None] | None = None,
    paper_columns: bool = True,
    notes: Sequence[str] = (),
) -> Path:
    """Write an experiment's tables (``tables``: scenario name → rows; :func:`write_tables`,
    each titled by :func:`table_title`) and ``config.json`` into
    ``folder``, plus whatever ``extra(tmp_folder)`` writes (plots, models), atomically:
    everything goes to a temporary sibling first, which is renamed into place only when
    complete. An existing folder is refused, never overwritten. With ``paper_columns``,
    the tables of the ``paper*`` scenarios show the paper's numbers beside ours;
    ``notes`` (what the runs say about themselves) follow the tables."""
    text = "\n".join(
        rows_markdown(rows, table_title(name, rows), paper_columns and name.startswith("paper"))
        for name, rows in tables.items()
    )
    if notes:
        text += "\n## Notes\n\n" + "".join(f"- {line}\n" for line in notes)
    with atomic_folder(Path(folder)) as tmp:
        write_tables(tmp, rows_dataframe(tables), rows_dataframe(tables, per_run=True), text)
        (tmp / "config.json").write_bytes(json_bytes(config))
        if extra is not None:
            extra(tmp)
    return Path(folder)
