"""The paper's simulation experiment: strategies, scenario, table and result folder.

The ``paper`` scenario follows the paper's Table I: the 330 s evaluation trajectory,
accelerometer noise variance 0.01² (m/s²)², gyro 0.001² (rad/s)², DVL variance
0.01 (m/s)² at 1 Hz, bias random-walk PSD ε = 0.001 in the filter. The constant rows are
the filter told the true IMU noise, and that Q multiplied by 20 (the paper's text; its
table lists the standard deviations 0.01/0.001 and 0.2/0.02).
"""

from __future__ import annotations

import csv
import io
import json
import os
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pronet import _core
from pronet.montecarlo import MonteCarloResult, monte_carlo
from pronet.stats import MeanCI, mean_ci

#: True IMU noise of the paper's scenario: per-sample variances [(m/s²)², (rad/s)²].
PAPER_Q = (1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6)

#: The paper's Table II (SRMSE, SMAE in m/s), by our row label.
PAPER_TABLE: dict[str, tuple[float, float]] = {
    "constant (true q)": (1.082, 0.961),
    "constant (20 x q)": (1.142, 0.992),
    "adaptive xi=1": (1.127, 0.983),
    "adaptive xi=5": (1.085, 0.908),
    "HCF-ensemble": (0.980, 0.866),
    "baseline net": (1.055, 0.928),
    "detrend net": (0.980, 0.831),
}


def model_based_strategies() -> dict[str, _core.Strategy]:
    """The four rows of the paper's table that need no learned model."""
    return {
        "constant (true q)": _core.Strategy.constant(PAPER_Q),
        "constant (20 x q)": _core.Strategy.constant(tuple(20 * q for q in PAPER_Q)),
        "adaptive xi=1": _core.Strategy.mehra(1, PAPER_Q),
        "adaptive xi=5": _core.Strategy.mehra(5, PAPER_Q),
    }


def paper_filter_config() -> _core.FilterConfig:
    """The paper's filter: ε = 0.001 for both bias random walks, DVL R = 0.01 I."""
    return _core.FilterConfig(accel_bias_psd=1e-3, gyro_bias_psd=1e-3, dvl_variance=(0.01,) * 3)


@dataclass(frozen=True)
class Row:
    """One strategy's Monte Carlo and its paired difference from the reference row."""

    label: str
    result: MonteCarloResult
    srmse: MeanCI
    smae: MeanCI
    srmse_diff: MeanCI
    smae_diff: MeanCI


def run_strategies(
    strategies: dict[str, _core.Strategy],
    *,
    trajectory: _core.Trajectory,
    sensors: _core.SensorConfig,
    config: _core.FilterConfig,
    n_runs: int,
    seed: int,
    threads: int | None = None,
    on_done: Callable[[str], None] | None = None,
) -> list[Row]:
    """Run every strategy on the same noise realizations (same seed); the first strategy
    is the reference for the paired differences."""
    results: dict[str, MonteCarloResult] = {}
    for label, strategy in strategies.items():
        results[label] = monte_carlo(
            trajectory,
            strategy,
            sensors=sensors,
            config=config,
            n_runs=n_runs,
            seed=seed,
            threads=threads,
        )
        if on_done is not None:
            on_done(label)
    ref = next(iter(results.values()))
    return [
        Row(
            label=label,
            result=r,
            srmse=mean_ci(r.srmse),
            smae=mean_ci(r.smae),
            srmse_diff=mean_ci(r.srmse - ref.srmse),
            smae_diff=mean_ci(r.smae - ref.smae),
        )
        for label, r in results.items()
    ]


def markdown_table(rows: list[Row], title: str) -> str:
    """The results as a Markdown table, the paper's numbers beside ours."""
    out = io.StringIO()
    out.write(f"### {title}\n\n")
    out.write(
        "| approach | SRMSE [m/s] (95 % CI) | SMAE [m/s] (95 % CI)"
        " | ΔSRMSE vs row 1 (paired 95 % CI) | paper SRMSE | paper SMAE | failed runs |\n"
        "|---|---|---|---|---|---|---|\n"
    )
    for row in rows:
        paper = PAPER_TABLE.get(row.label)
        p_srmse, p_smae = (f"{paper[0]:.3f}", f"{paper[1]:.3f}") if paper else ("", "")
        diff = f"{row.srmse_diff.mean:+.4f} [{row.srmse_diff.low:+.4f}, {row.srmse_diff.high:+.4f}]"
        out.write(
            f"| {row.label} | {row.srmse} | {row.smae} | {diff} | {p_srmse} | {p_smae} |"
            f" {row.result.n_failed} |\n"
        )
    return out.getvalue()


def _ci_json(ci: MeanCI) -> dict[str, float | int]:
    return {"mean": ci.mean, "low": ci.low, "high": ci.high, "n": ci.n}


def write_result_folder(
    folder: Path, tables: dict[str, list[Row]], config: dict[str, object]
) -> Path:
    """Write ``table.md``, ``metrics.json``, ``metrics.csv`` and ``config.json`` into
    ``folder`` atomically: everything goes to a temporary sibling first, which is renamed
    into place only when complete. An existing folder is refused, never overwritten."""
    folder = Path(folder)
    if folder.exists():
        raise FileExistsError(f"out: {folder} exists; choose a new folder")
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", dir=folder.parent))
    try:
        (tmp / "table.md").write_text(
            "\n".join(markdown_table(rows, scenario) for scenario, rows in tables.items())
        )
        metrics = {
            scenario: {
                row.label: {
                    "srmse": _ci_json(row.srmse),
                    "smae": _ci_json(row.smae),
                    "srmse_diff_vs_first": _ci_json(row.srmse_diff),
                    "smae_diff_vs_first": _ci_json(row.smae_diff),
                    "final_horizontal_error": _ci_json(mean_ci(row.result.final_horizontal_error)),
                    "mean_nis": _ci_json(mean_ci(row.result.mean_nis)),
                    "failed_runs": row.result.n_failed,
                    "paper": PAPER_TABLE.get(row.label),
                }
                for row in rows
            }
            for scenario, rows in tables.items()
        }
        (tmp / "metrics.json").write_text(json.dumps(metrics, indent=2, allow_nan=True))
        with open(tmp / "metrics.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(
                [
                    "scenario",
                    "strategy",
                    "run",
                    "srmse",
                    "smae",
                    "final_horizontal_error",
                    "max_horizontal_error",
                    "mean_nis",
                    "failure",
                ]
            )
            for scenario, rows in tables.items():
                for row in rows:
                    r = row.result
                    for i in range(r.n_runs):
                        w.writerow(
                            [
                                scenario,
                                row.label,
                                i,
                                r.srmse[i],
                                r.smae[i],
                                r.final_horizontal_error[i],
                                r.max_horizontal_error[i],
                                r.mean_nis[i],
                                r.failure[i] or "",
                            ]
                        )
        (tmp / "config.json").write_text(json.dumps(config, indent=2, default=_jsonable))
        os.replace(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return folder


def _jsonable(value: object) -> object:
    if isinstance(value, np.ndarray):
        return value.tolist()
    return repr(value)
