"""Accuracy baselines: pinned accuracy and consistency figures, checked in both directions.

Each row (scenario × strategy) records velocity SRMSE and SMAE, final and maximum
horizontal position error, mean NIS, mean velocity NEES, the fraction of velocity
errors inside ±3σ, and two counts that must match exactly: the epochs scored and the
non-finite samples dropped. Rows cover the ``paper`` and ``varying-noise`` scenarios at
:data:`GATE_RUNS` runs (seed 0) and, where the Snapir data is present, its sections.

:func:`compare` fails a row when a metric gets worse by more than
:data:`WORSE_TOLERANCE` (relative), and also when it gets *better* by more than
:data:`BETTER_TOLERANCE`: an improvement nobody recorded is one the next change can
silently undo. "Worse" means a larger error, or NIS/NEES and the ±3σ fraction farther
from their consistent values (3 and 0.9973). With fixed seeds on one machine the runs
repeat to floating-point noise (the Rust core is deterministic across thread counts;
the nets run in float32), so the tolerances are small.

Re-blessing (``pronet baselines --bless``) rewrites the file and the README's tables;
it is legitimate only when a change is *meant* to move the numbers (a fixed bug, a
better discretization, a new scenario), and the commit says why.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from pronet._files import atomic_write

#: Monte Carlo runs per simulated row in the gate.
GATE_RUNS = 8
#: Relative change allowed in the worse direction (floating-point noise and float32
#: inference across machines), and in the better direction before it must be recorded.
WORSE_TOLERANCE = 1e-5
BETTER_TOLERANCE = 1e-3
#: Metrics, each with its "badness": how far from ideal a value is.
METRICS: dict[str, Callable[[float], float]] = {
    "srmse": abs,
    "smae": abs,
    "final_horizontal": abs,
    "max_horizontal": abs,
    "mean_nis": lambda v: abs(v - 3.0),
    "mean_velocity_nees": lambda v: abs(v - 3.0),
    "inside_3sigma": lambda v: abs(v - 0.9973),
}
#: Counts that must match exactly.
COUNTS = ("n_scored", "n_dropped")

Row = dict[str, float | int]
Rows = dict[str, dict[str, Row]]  # scenario → strategy → metrics


def monte_carlo_row(result) -> Row:  # result: pronet.MonteCarloResult with histories
    """The gate's figures of one Monte Carlo (means over runs and epochs)."""
    if result.error is None or result.sigma is None:
        raise ValueError("result: needs error and sigma histories (record_every > 0)")
    nis, nees_v = result.nis, result.nees[:, :, 1]
    err, sig = result.error[:, :, 3:6], result.sigma[:, :, 3:6]
    finite = np.isfinite(err) & np.isfinite(sig)
    return {
        "srmse": _mean(result.srmse),
        "smae": _mean(result.smae),
        "final_horizontal": _mean(result.final_horizontal_error),
        "max_horizontal": _mean(result.max_horizontal_error),
        "mean_nis": _mean(nis),
        "mean_velocity_nees": _mean(nees_v),
        "inside_3sigma": float(np.mean(np.abs(err[finite]) <= 3 * sig[finite])),
        "n_scored": int(np.isfinite(nis).sum()),
        "n_dropped": int((~np.isfinite(nis)).sum() + (~np.isfinite(nees_v)).sum()),
    }


def section_row(section, run) -> Row:  # pronet.alignment.Section, pronet.realdata.SectionRun
    """The gate's figures of one recorded-section run, at its ground-truth rows. The
    velocity NEES uses the filter's per-axis σ (the recorded diagonal)."""
    from pronet.realdata import estimate_at_truth

    r = run.result
    rows, _, vel = estimate_at_truth(section, r)
    dv = vel - section.truth_vel[rows]
    t = section.truth_time[rows]
    sig = np.stack([np.interp(t, r.time, r.sigma[:, 3 + j]) for j in range(3)], axis=1)
    m = run.metrics
    return {
        "srmse": m.srmse,
        "smae": m.smae,
        "final_horizontal": m.final_horizontal,
        "max_horizontal": m.max_horizontal,
        "mean_nis": m.mean_nis,
        "mean_velocity_nees": _mean(np.sum((dv / sig) ** 2, axis=1)),
        "inside_3sigma": float(np.mean(np.abs(dv) <= 3 * sig)),
        "n_scored": m.n_scored,
        "n_dropped": int((~np.isfinite(r.nis[r.dvl_epoch >= 0])).sum()),
    }


def _mean(values: np.ndarray) -> float:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else math.nan


def simulated_rows(n_runs: int = GATE_RUNS, seed: int = 0) -> Rows:
    """Every strategy of both simulated scenarios, with the shipped models."""
    from pronet import experiment, models

    regressors = {k: models.load(k) for k in models.SHIPPED}
    out: Rows = {}
    for name, build in experiment.SCENARIOS.items():
        sc = build()
        strategies = experiment.paper_strategies(sc.q_nominal, regressors, 1.0)
        rows = experiment.run_strategies(
            strategies, sc, n_runs=n_runs, seed=seed, threads=None, record_every=100
        )
        out[f"{name}, {n_runs} runs"] = {row.label: monte_carlo_row(row.result) for row in rows}
    return out


def real_rows(loaded: list) -> Rows:
    """Every strategy on each aligned recorded section (``loaded``: ``(aligned, _)``
    pairs from :func:`pronet.realdata.load_section`)."""
    from pronet import models, realdata

    regressors = {k: models.load(k) for k in models.SHIPPED}
    out: Rows = {}
    for aligned, _ in loaded:
        q = realdata.white_noise_q(aligned.imu)
        config = realdata.real_filter_config(aligned.alignment.filter_lever_arm)
        rows: dict[str, Row] = {}
        for label, strategy in realdata.real_strategies(q, regressors, 1.0).items():
            run = realdata.run_section(aligned, strategy, config, label=label)
            rows[label] = section_row(aligned, run)
        out[f"real: {aligned.name}"] = rows
    return out


def compare(recorded: Rows, fresh: Rows) -> list[str]:
    """Every way ``fresh`` departs from ``recorded`` beyond the tolerances (empty: pass).
    Rows recorded but not computed (no data here) are not compared; rows computed but
    not recorded are failures."""
    problems = []
    for scenario, rows in fresh.items():
        for label, new in rows.items():
            old = recorded.get(scenario, {}).get(label)
            where = f"{scenario} / {label}"
            if old is None:
                problems.append(f"{where}: not recorded; re-bless to add it")
                continue
            for key in COUNTS:
                if new[key] != old[key]:
                    problems.append(f"{where}: {key} {new[key]} != recorded {old[key]}")
            for key, badness in METRICS.items():
                a, b = float(old[key]), float(new[key])
                if math.isnan(a) and math.isnan(b):
                    continue
                if math.isnan(a) != math.isnan(b):
                    problems.append(f"{where}: {key} {b} against recorded {a}")
                    continue
                scale = max(abs(a), 1e-12)
                change = (badness(b) - badness(a)) / scale
                if change > WORSE_TOLERANCE:
                    problems.append(
                        f"{where}: {key} worse: {b:.9g} against recorded {a:.9g} "
                        f"({100 * change:+.4f} % of it)"
                    )
                elif change < -BETTER_TOLERANCE:
                    problems.append(
                        f"{where}: {key} improved beyond {100 * BETTER_TOLERANCE:g} % without "
                        f"being recorded: {b:.9g} against {a:.9g}; re-bless if intended"
                    )
    return problems


def load(path: str | Path) -> Rows:
    """The recorded baselines (JSON)."""
    data = json.loads(Path(path).read_text())
    if data.get("format") != "pronet-accuracy-baselines" or data.get("version") != 1:
        raise ValueError(f"{path}: not a pronet accuracy-baselines file (version 1)")
    return data["rows"]


def save(path: str | Path, rows: Rows) -> Path:
    """Write ``rows`` as the baselines file, atomically."""
    path = Path(path)
    doc = {
        "format": "pronet-accuracy-baselines",
        "version": 1,
        "about": "pinned accuracy figures; regenerate with `pronet baselines --bless`",
        "gate_runs": GATE_RUNS,
        "worse_tolerance": WORSE_TOLERANCE,
        "better_tolerance": BETTER_TOLERANCE,
        "rows": rows,
    }
    atomic_write(path, (json.dumps(doc, indent=1, allow_nan=True) + "\n").encode())
    return path


COLUMNS = (
    ("srmse", "SRMSE [m/s]", "{:.4f}"),
    ("smae", "SMAE [m/s]", "{:.4f}"),
    ("final_horizontal", "final horiz. [m]", "{:.2f}"),
    ("max_horizontal", "max horiz. [m]", "{:.2f}"),
    ("mean_nis", "mean NIS", "{:.2f}"),
    ("mean_velocity_nees", "mean vel. NEES", "{:.2f}"),
    ("inside_3sigma", "inside ±3σ", "{:.3f}"),
    ("n_scored", "epochs", "{}"),
    ("n_dropped", "non-finite", "{}"),
)


def markdown(rows: Mapping[str, Mapping[str, Row]]) -> str:
    """The README's accuracy tables, generated from the baselines."""
    out = []
    for scenario, table in rows.items():
        out.append(f"#### {scenario}\n")
        out.append("| strategy | " + " | ".join(h for _, h, _ in COLUMNS) + " |")
        out.append("|---" * (len(COLUMNS) + 1) + "|")
        for label, row in table.items():
            cells = [fmt.format(row[key]) for key, _, fmt in COLUMNS]
            out.append(f"| {label} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


BEGIN, END = "<!-- accuracy-baselines:begin -->", "<!-- accuracy-baselines:end -->"


def readme_with_tables(readme: str, rows: Rows) -> str:
    """``readme`` with the text between the baseline markers replaced by the tables."""
    pattern = re.compile(re.escape(BEGIN) + ".*?" + re.escape(END), re.S)
    if not pattern.search(readme):
        raise ValueError("readme: has no accuracy-baselines markers")
    return pattern.sub(lambda _: f"{BEGIN}\n{markdown(rows)}{END}", readme)
