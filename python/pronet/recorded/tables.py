"""The tables and records of ``pronet real`` (:mod:`pronet.recorded.real`): Markdown tables of
the section runs' metrics, their rows in ``metrics.csv`` / ``summary.csv``, and the
run's ``config.json`` (:func:`real_config`)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from pronet.recorded import missing
from pronet.recorded.aidingtables import aiding_table, heading_table
from pronet.recorded.alignment import Format, Section
from pronet.recorded.tuning import real_filter_config
from pronet.results import (
    OUT_OF_BAND,
    RUN_COLUMNS,
    SUMMARIZED,
    SUMMARY_COLUMNS,
    markdown,
    write_tables,
)
from pronet.stats import format_number

if TYPE_CHECKING:
    from pronet import _core
    from pronet.learn.models import Regressor
    from pronet.recorded.dvltruth import TruthCalibration
    from pronet.recorded.runs import RealRuns, SectionDvlNoise, SectionRun

METRIC_COLUMNS = (
    ("srmse", "SRMSE [m/s]", "{:.4f}"),
    ("smae", "SMAE [m/s]", "{:.4f}"),
    ("final_horizontal", "final horiz. error [m]", "{:.2f}"),
    ("max_horizontal", "max horiz. error [m]", "{:.2f}"),
    ("final_percent", "final error [% of distance]", "{:.2f}"),
    ("mean_nis", "mean NIS", "{:.2f}"),
    ("heading_ratio", "heading error / σ (RMS)", "{:.2f}"),
    ("velocity_3sigma", "vel. error within 3σ (share)", "{:.3f}"),
    ("velocity_3sigma_truth", "vel. error within 3σ, truth's error included (share)", "{:.3f}"),
    ("dvl_autocorrelation", "DVL innovations' lag-1 autocorrelation", "{:+.2f}"),
)


#: The setup of the first strategy on a section as stamped (its label's suffix too).
STAMPED = "stamps as given, no lever arms"
#: The title of ``table.md``'s rows whose filter failed.
ROWS_FAILED = "Rows failed (the section's other rows are complete)"

#: A heading error RMS beyond this many of the filter's σ is flagged
#: (:data:`pronet.results.OUT_OF_BAND`): a consistent filter's is about 1.
HEADING_FLAG = 3.0


def _cell(key: str, fmt: str, value: float) -> str:
    flag = OUT_OF_BAND if key == "heading_ratio" and value > HEADING_FLAG else ""
    return format_number(value, fmt) + flag


def summary_table(runs: list[SectionRun], title: str) -> str:
    """Markdown: one row per strategy, each metric's mean over the sections (the heading
    ratio flagged beyond :data:`HEADING_FLAG`)."""
    labels = list(dict.fromkeys(r.label for r in runs))
    n = len({r.section for r in runs})
    lines = []
    for label in labels:
        mine = [r.metrics for r in runs if r.label == label]
        cells = [
            _cell(key, fmt, float(np.mean([getattr(m, key) for m in mine])))
            for key, _, fmt in METRIC_COLUMNS
        ]  # a row left out or failed on some section: over those it ran on
        lines.append([label + (f" ({len(mine)} of {n})" if len(mine) < n else ""), *cells])
    header = ["strategy", *(head for _, head, _ in METRIC_COLUMNS)]
    return markdown(header, lines, f"{title}: mean over {n} section{'' if n == 1 else 's'}")


def per_section_table(runs: list[SectionRun], key: str, title: str) -> str:
    """Markdown: sections as rows, strategies as columns, one metric."""
    labels = list(dict.fromkeys(r.label for r in runs))
    sections = list(dict.fromkeys(r.section for r in runs))
    head, fmt = next((h, f) for k, h, f in METRIC_COLUMNS if k == key)
    value = {(r.section, r.label): getattr(r.metrics, key) for r in runs}

    def cell(s: str, lb: str) -> str:  # "—" where a section has no such row
        return format_number(value[s, lb], fmt) if (s, lb) in value else "—"

    lines: list[list[object]] = [[s, *(cell(s, lb) for lb in labels)] for s in sections]
    means = [
        fmt.format(np.mean([value[s, lb] for s in sections if (s, lb) in value])) for lb in labels
    ]
    lines.append(["**mean**", *(f"**{m}**" for m in means)])
    return markdown(["section", *labels], lines, f"{title}: {head}")


def _scenario_label(run: SectionRun) -> str:
    return run.section if run.setup == "aligned" else f"{run.section} ({run.setup})"


def run_record(run: SectionRun) -> dict[str, object]:
    """One :data:`pronet.results.RUN_COLUMNS` row: the section (with its setup unless
    aligned) as scenario, the strategy label, the run's metrics."""
    r, m = run.result, run.metrics
    applied = r.dvl_epoch >= 0
    return {
        "scenario": _scenario_label(run),
        "strategy": run.label,
        "noise_level": 1.0,
        "tuning_period_s": math.nan if run.tuning_period is None else run.tuning_period,
        "run": 0,
        "srmse": m.srmse,
        "smae": m.smae,
        "final_horizontal_error": m.final_horizontal,
        "max_horizontal_error": m.max_horizontal,
        "mean_nis": m.mean_nis,
        "velocity_nees": math.nan,  # the sections' truth has no NEES here (yet)
        "velocity_nees_3sigma": math.nan,
        "attitude_nees": math.nan,
        "position_nees": math.nan,
        "accel_bias_nees": math.nan,
        "gyro_bias_nees": math.nan,
        "rejected_updates": int((applied & ~r.accepted).sum()),
        "missed_updates": m.missed_updates,
        "diverged_at": math.nan if r.diverged_at is None else r.diverged_at,
        "failure": None,
    }


def summary_record(run: SectionRun) -> dict[str, object]:
    """One :data:`pronet.results.SUMMARY_COLUMNS` row for a single section run (its
    confidence bounds NaN: one run)."""
    rec = run_record(run)
    out: dict[str, object] = {k: rec[k] for k in ("scenario", "strategy", "noise_level")}
    out["tuning_period_s"] = rec["tuning_period_s"]
    for name in SUMMARIZED:
        out.update({name: rec[name], f"{name}_low": math.nan, f"{name}_high": math.nan})
    out.update({c: math.nan for c in SUMMARY_COLUMNS if "_band" in c})  # no NEES: no truth
    out.update(runs=1, failed_runs=0, diverged_runs=int(run.result.diverged_at is not None))
    out.update(srmse_diff=math.nan, srmse_diff_low=math.nan, srmse_diff_high=math.nan)
    sched = run.schedule
    out["tunings"] = len(sched.time) if sched is not None else 0
    out["guardrail_clipped"] = sched.clipped if sched is not None else 0
    out["guardrail_non_finite"] = sched.non_finite if sched is not None else 0
    return out


def failed_records(done: RealRuns) -> tuple[list[dict[str, object]], list[dict[str, object]]]:
    """The ``metrics.csv`` and ``summary.csv`` rows of what failed: per section that
    failed (:attr:`pronet.recorded.runs.RealRuns.failed`) one per strategy of the aligned
    setup, then one per failed row (:attr:`~pronet.recorded.runs.RealRuns.rows_failed`);
    every metric NaN, the reason in ``failure`` and ``failed_runs`` = 1."""
    template: dict[str, SectionRun] = {}
    for run in done.runs:  # every row label some section ran, in order
        template.setdefault(run.label, run)
    failures = [
        (name, label, run.tuning_period, reason)
        for name, reason in done.failed.items()
        for label, run in template.items()
    ]
    for name, rows in done.rows_failed.items():
        for label, reason in rows.items():
            scenario = f"{name} ({STAMPED})" if label.endswith(f", {STAMPED}") else name
            period = template[label].tuning_period if label in template else None
            failures.append((scenario, label, period, reason))
    per_run: list[dict[str, object]] = []
    summary: list[dict[str, object]] = []
    for scenario, label, period, reason in failures:
        rec: dict[str, object] = {c: math.nan for c in RUN_COLUMNS}
        rec.update(scenario=scenario, strategy=label, noise_level=1.0, run=0, failure=reason)
        rec.update(tuning_period_s=math.nan if period is None else period)
        rec.update(rejected_updates=0, missed_updates=0)
        per_run.append(rec)
        row: dict[str, object] = {c: math.nan for c in SUMMARY_COLUMNS}
        row.update({k: rec[k] for k in ("scenario", "strategy", "noise_level", "tuning_period_s")})
        row.update(runs=1, failed_runs=1, diverged_runs=0, tunings=0)
        row.update(guardrail_clipped=0, guardrail_non_finite=0)
        summary.append(row)
    return per_run, summary


def write_metrics(
    folder: Path,
    runs: list[SectionRun],
    table_md: str,
    failed: tuple[list[dict[str, object]], list[dict[str, object]]] = ([], []),
) -> None:
    """The result tables of recorded runs (:func:`pronet.results.write_tables`): one
    ``metrics.csv`` row per setup × section × strategy, the same in ``summary.csv``,
    then the rows of the sections that failed (:func:`failed_records`)."""
    import pandas as pd

    per_run = [run_record(r) for r in runs] + failed[0]
    summary = [summary_record(r) for r in runs] + failed[1]
    write_tables(
        folder,
        pd.DataFrame(summary, columns=list(SUMMARY_COLUMNS)),
        pd.DataFrame(per_run, columns=list(RUN_COLUMNS)),
        table_md,
    )


def failed_table(failed: dict[str, str]) -> str:
    """Markdown: the sections that could not be read or filtered, with the reason."""
    lines: list[list[object]] = [[name, reason] for name, reason in failed.items()]
    return markdown(["section", "reason"], lines, "Sections not run")


def rows_not_run_table(
    rows: dict[str, dict[str, str]], title: str = "Rows not run (they could never act)"
) -> str:
    """Markdown: the rows left out of a section (or, titled so, that failed), with the
    reason."""
    lines: list[list[object]] = [
        [name, label, reason] for name, by in rows.items() for label, reason in by.items()
    ]
    return markdown(["section", "row", "reason"], lines, title)


def dvl_skipped(section: Section) -> dict[str, float]:
    """A section's DVL rows skipped as missing readings, by reason
    (:data:`pronet.recorded.missing.REASONS`), their total, the rows used and the
    longest stretch between used rows that held skipped ones [s]."""
    found = missing.counts(section.dvl_skipped_reason)
    gap = missing.longest_gap(section.dvl_time, section.dvl_skipped_time)
    return {
        **found,
        "skipped": sum(found.values()),
        "used": len(section.dvl_time),
        "longest_gap_s": gap,
    }


def dvl_skipped_table(done: RealRuns) -> str:
    """Markdown: each section's DVL rows skipped as missing readings (missed updates)."""
    lines: list[list[object]] = []
    for aligned, _ in done.sections:
        d = dvl_skipped(aligned)
        counts = [int(d[r]) for r in missing.REASONS]
        lines.append([aligned.name, int(d["used"]), *counts, f"{d['longest_gap_s']:.1f}"])
    header = ["section", "used", *missing.REASONS, "longest dropout [s]"]
    return markdown(header, lines, "DVL readings skipped as missing (missed updates)")


def dvl_noise_table(done: RealRuns) -> str:
    """Markdown: each section's DVL noise 1σ per body axis [m/s]: the R its strategy
    rows used (marked "the bag's" when it is the R a ROS bag's covariance states), the
    second-difference estimate and the innovation-matched one."""
    stated = {a.name: a.dvl_variance for a, _ in done.sections}

    def sigma(v: tuple[float, float, float]) -> str:
        return " / ".join(f"{math.sqrt(x):.4f}" for x in v)

    lines: list[list[object]] = []
    for name, (noise, used) in done.dvl_noise.items():
        cell = sigma(used) + (" (the bag's)" if stated.get(name) == tuple(used) else "")
        if isinstance(noise, str):
            lines.append([name, cell, f"not estimated: {noise}", "", "", ""])
            continue
        m = noise.matched
        state = f"{m.passes} passes" + ("" if m.converged else ", not converged")
        both = sigma(noise.matched_calibrated.variance)
        lines.append([name, cell, sigma(noise.second_difference), sigma(m.variance), both, state])
    header = [
        "section",
        "used",
        "second differences",
        "matched to innovations",
        "matched, with calibration states",
        "matching (without)",
    ]
    return markdown(header, lines, "DVL noise 1σ, x / y / z [m/s]")


#: Units of the reported DVL calibration ``[k, roll, pitch, yaw]``: % and degrees.
_CALIBRATION_UNITS = (100.0, 180.0 / math.pi, 180.0 / math.pi, 180.0 / math.pi)
_CALIBRATION_NAMES = ("scale [%]", "roll [°]", "pitch [°]", "yaw [°]")


def final_calibration(run: SectionRun) -> tuple[np.ndarray, np.ndarray] | None:
    """The run's final DVL calibration ``[k, roll, pitch, yaw]`` and its 1σ (scale;
    rad), or None for a run without the calibration states."""
    r = run.result
    if r.calibration.shape[0] == 0 or not np.any(r.calibration_sigma[:, :4] > 0):
        return None
    return r.calibration[-1, :4], r.calibration_sigma[-1, :4]


def calibration_agreement(values: np.ndarray, sigmas: np.ndarray) -> tuple[float, float, int]:
    """The inverse-variance weighted mean of one quantity over sections, its 1σ, and
    how many sections lie more than 3σ from it (σ of the difference: each section's
    own and the mean's, taken as independent). Sections with a zero or non-finite σ
    or value are left out (NaN and 0 when none is left)."""
    ok = np.isfinite(values) & np.isfinite(sigmas) & (sigmas > 0)
    if not ok.any():
        return math.nan, math.nan, 0
    v, s = values[ok], sigmas[ok]
    w = 1.0 / s**2
    mean = float(np.sum(w * v) / np.sum(w))
    sigma = float(1.0 / math.sqrt(np.sum(w)))
    off = np.abs(v - mean) > 3 * np.sqrt(s**2 + sigma**2)
    return mean, sigma, int(np.sum(off))


#: The label of the calibration the ground truth implies, in :func:`calibration_table`.
TRUTH_LABEL = "ground truth, least squares (no filter)"


def calibration_table(
    runs: list[SectionRun], truth: Mapping[str, TruthCalibration | str] | None = None
) -> str:
    """Markdown: each calibrated row's final DVL scale and mounting angles per section
    with 1σ, and (``truth``) the calibration each section's ground truth implies without
    a filter (:func:`pronet.recorded.dvltruth.truth_calibration`); then per row the weighted mean
    over sections and how many sections lie beyond 3σ of it (one vehicle, one
    installation: they should agree)."""
    found: list[tuple[str, str, np.ndarray, np.ndarray]] = [
        (r.section, r.label, *c) for r in runs if (c := final_calibration(r)) is not None
    ]
    found += [
        (name, TRUTH_LABEL, t.estimate, t.sigma)
        for name, t in (truth or {}).items()
        if not isinstance(t, str)
    ]
    labels = list(dict.fromkeys(label for _, label, _, _ in found))
    units = np.array(_CALIBRATION_UNITS)

    def cell(v: float, s: float, unit: float) -> str:
        return f"{v * unit:+.3f} ± {s * unit:.3f}"

    lines: list[list[object]] = []
    for label in labels:
        mine = [(name, v, s) for name, lb, v, s in found if lb == label]
        for name, v, s in mine:
            lines.append([name, label, *(cell(*x) for x in zip(v, s, units, strict=True))])
        values = np.array([v for _, v, _ in mine])
        sigmas = np.array([s for _, _, s in mine])
        summary = []
        for j in range(4):
            mean, sigma, off = calibration_agreement(values[:, j], sigmas[:, j])
            summary.append(f"**{cell(mean, sigma, units[j])}** ({off} beyond 3σ)")
        lines.append(["**weighted mean**", label, *summary])
    header = ["section", "row", *_CALIBRATION_NAMES]
    return markdown(header, lines, "DVL calibration: final estimate ± 1σ")


def real_tables(done: RealRuns) -> str:
    """The Markdown of ``table.md``: the summary, per-section SRMSE, final error, mean
    NIS, whiteness and share within 3σ (with the truth's error too where the sections
    state it), the DVL noise per section, the alignment comparison, the inertial sanity
    check and the sections that failed."""
    first_label = done.runs[0].label
    return "\n".join(
        [
            summary_table(done.runs, "Clocks estimated, lever arms applied"),
            per_section_table(done.runs, "srmse", "Per section"),
            per_section_table(done.runs, "final_horizontal", "Per section"),
            per_section_table(done.runs, "mean_nis", "Per section"),
            per_section_table(done.runs, "dvl_autocorrelation", "Per section (white: 0 ± 2/√n)"),
            per_section_table(done.runs, "velocity_3sigma", "Per section"),
            *(
                [per_section_table(done.runs, "velocity_3sigma_truth", "Per section")]
                if any(a.truth_velocity_sigma is not None for a, _ in done.sections)
                else []
            ),
            *([dvl_noise_table(done)] if done.dvl_noise else []),
            *(
                [aiding_table(done)]
                if any(a.depth is not None or a.fixes is not None for a, _ in done.sections)
                else []
            ),
            *(
                [heading_table(done)]
                if any(a.heading is not None for a, _ in done.sections)
                else []
            ),
            *(
                [dvl_skipped_table(done)]
                if any(len(a.dvl_skipped_time) for a, _ in done.sections)
                else []
            ),
            *(
                [calibration_table(done.runs, done.truth_calibration)]
                if any(final_calibration(r) is not None for r in done.runs)
                else []
            ),
            summary_table(
                [r for r in done.runs if r.label == first_label] + done.stamped,
                f"{first_label}: alignment handled against stamps as given",
            ),
            summary_table(done.inertial, "Sanity: pure inertial, no DVL"),
            *([rows_not_run_table(done.rows_not_run)] if done.rows_not_run else []),
            *([rows_not_run_table(done.rows_failed, ROWS_FAILED)] if done.rows_failed else []),
            *([failed_table(done.failed)] if done.failed else []),
            *(
                ["## What the filters say\n\n" + "".join(f"- {n}\n" for n in done.notes)]
                if done.notes
                else []
            ),  # fmt: skip
        ]
    )


def clocks_record(section: Section) -> dict[str, Any]:
    """``section``'s clocks as a ``config.json`` records them (``pronet real``'s per
    section, ``pronet navigate``'s): the epoch its times count from [s], each stream's
    ``[offset (s), scale]`` (:class:`~pronet.recorded.alignment.Clock`: ``t_imu =
    offset + scale · t_stamp``, both from the epoch: the truth's, the DVL's, the depth's,
    fixes' and heading's) and how the truth's and the DVL's were found (``how``:
    :data:`~pronet.recorded.alignment.CLOCK_HOW`)."""
    a = section.alignment
    return {
        "epoch_s": section.epoch,
        "gt": [a.gt_clock.offset, a.gt_clock.scale],
        "dvl": [a.dvl_clock.offset, a.dvl_clock.scale],
        "aiding": [a.aiding_clock.offset, a.aiding_clock.scale],
        "how": {"gt": a.gt_clock_how, "dvl": a.dvl_clock_how},
    }


def real_config(
    data: str | Path,
    fmt: Format,
    tuning_period: float,
    arms: tuple[tuple[float, float, float], tuple[float, float, float] | None],
    dvl_noise: str,
    done: RealRuns,
    regressors: Mapping[str, Regressor],
    tuning: _core.FilterConfig | None = None,
) -> dict[str, object]:
    """``config.json`` of a ``pronet real`` folder: what ran, on what (``tuning``: the
    strategy rows' filter, lever arms aside; default :func:`real_filter_config`'s),
    and the per-section estimates (clocks, q, DVL noise and calibration) and the truth's
    stated velocity error per NED axis [m/s] (``truth_velocity_sigma_ned``, None where
    not stated: :mod:`pronet.recorded.trutherror`)."""
    imu_arm, dvl_arm = arms
    return {
        "data": str(Path(data).resolve()),
        "format": fmt if isinstance(fmt, str) else fmt.record(),
        "sections": [a.name for a, _ in done.sections],
        "failed_sections": done.failed,
        "tuning_period_s": tuning_period,
        "filter": repr(tuning if tuning is not None else real_filter_config((0.0, 0.0, 0.0))),
        "imu_dt_s": done.imu_dt,
        "rows_not_run": done.rows_not_run,
        "rows_failed": done.rows_failed,
        "notes": done.notes,
        "imu_lever_arm_m": imu_arm,
        "dvl_lever_arm_m": dvl_arm,
        "clocks": {a.name: clocks_record(a) for a, _ in done.sections},
        "q_estimated": done.q_estimated,
        "truth_velocity_sigma_ned": {a.name: a.truth_velocity_sigma for a, _ in done.sections},
        "dvl_skipped": {a.name: dvl_skipped(a) for a, _ in done.sections},
        "dvl_noise": dvl_noise,
        "dvl_variance_bag": {a.name: a.dvl_variance for a, _ in done.sections if a.dvl_variance},
        "dvl_variance": {
            name: {"used": list(used), **_noise_record(noise)}
            for name, (noise, used) in done.dvl_noise.items()
        },
        "dvl_calibration": {
            f"{r.section}: {r.label}": {
                "scale_roll_pitch_yaw": c[0].tolist(),
                "sigma": c[1].tolist(),
            }
            for r in done.runs
            if (c := final_calibration(r)) is not None
        },
        "dvl_calibration_from_truth": {
            name: (
                {"failure": t}
                if isinstance(t, str)
                else {
                    "scale_roll_pitch_yaw": t.estimate.tolist(),
                    "sigma": t.sigma.tolist(),
                    "rms_residual": t.rms_residual,
                    "rows": t.rows,
                }
            )
            for name, t in done.truth_calibration.items()
        },
        "models": {k: (getattr(m, "card", None) or {}).get("test") for k, m in regressors.items()},
    }


def _noise_record(noise: SectionDvlNoise | str) -> dict[str, object]:
    """A section's DVL noise estimates for ``config.json`` (or why there are none)."""
    if isinstance(noise, str):
        return {"failure": noise}
    out: dict[str, object] = {"second_difference": list(noise.second_difference)}
    for key, m in (("matched", noise.matched), ("matched_calibrated", noise.matched_calibrated)):
        out.update({key: list(m.variance), f"{key}_passes": m.passes})
        out[f"{key}_converged"] = m.converged
    return out
