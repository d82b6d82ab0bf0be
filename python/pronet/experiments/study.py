"""The study: when does adaptive process noise pay, and which estimator to trust?

Every scenario of :data:`pronet.sim.scenarios.STUDY_SCENARIOS` × every row of
:data:`STUDY_ROWS`, each a Monte Carlo through :func:`pronet.run.run` on the same noise
realizations (common random numbers: one seed, so every difference is paired). Per row
the study reports accuracy (SRMSE, SMAE, final and maximum horizontal error, the error
at the end of each DVL outage), consistency (velocity NEES and its 3σ share, NIS,
diverged runs), cost (wall time), the paired 95 % CI of the SRMSE difference from the
constant told the truth, and the share of the oracle's gain with a bootstrap CI.

``pronet study`` is a thin face over :func:`run_study` and :func:`write_study`;
``docs/results/study.md`` is generated from a study's ``study.csv`` (:func:`study_markdown`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from pronet._util.files import atomic_folder, json_bytes
from pronet._util.outputs import OnDone, OnStart, Say, new_result_folder
from pronet._util.validate import seconds as seconds_arg
from pronet._util.validate import threads as threads_arg
from pronet.learn.hybrid import HybridResult
from pronet.montecarlo import IN_BAND_FLAG, MonteCarloResult
from pronet.results import (
    OUT_OF_BAND,
    SUMMARY_COLUMNS,
    markdown,
    results_dataframe,
    summary_row,
    write_tables,
)
from pronet.run import check_acts, run
from pronet.sim.scenarios import SCENARIOS, STUDY_SCENARIOS, Scenario
from pronet.stats import BOOTSTRAP, mean_ci
from pronet.strategies import StrategyLike, StrategySpec, strategy

if TYPE_CHECKING:  # pandas and torch load only when used
    import pandas as pd

    from pronet.learn.models import Regressor

#: The study's rows by label: their strategy specs (see
#: :class:`~pronet.strategies.StrategySpec`). The first is the reference of the paired
#: differences; ``oracle`` is the ceiling of the oracle-gain share. The learned rows run
#: the regressors trained for real sensor grades (:data:`pronet.learn.models.GRADE_MODELS`).
STUDY_ROWS = {
    "constant (true q)": "constant",
    "constant (0.1 x q)": "constant:0.1",
    "constant (10 x q)": "constant:10",
    "oracle": "oracle",
    "adaptive": "adaptive",
    "mehra xi=5": "mehra:5",
    "detvar": "detvar",
    "HCF-ensemble": "learned:hcf",
    "baseline net": "learned:baseline",
    "detrend net": "learned:detrend",
}
REFERENCE = "constant (true q)"
ORACLE = "oracle"
#: The suffix of a smoothed row's label (``run_study(smooth=True)``).
SMOOTHED = "smoothed"


def study_strategies(
    q: tuple[float, ...],
    regressors: Mapping[str, Regressor],
    tuning_period: float = 1.0,
    labels: Sequence[str] | None = None,
) -> dict[str, StrategyLike]:
    """The rows of :data:`STUDY_ROWS` (or only ``labels``) around the nominal ``q``; a
    learned row runs ``regressors[model]``."""
    out: dict[str, StrategyLike] = {}
    for label in labels if labels is not None else STUDY_ROWS:
        spec = StrategySpec.parse(STUDY_ROWS[label])
        model = regressors.get(spec.model) if spec.kind == "learned" else None
        out[label] = strategy(spec, q, tuning_period, model)
    return out


@dataclass(frozen=True)
class StudyRow:
    """One strategy's Monte Carlo on one study scenario.

    Attributes:
        scenario, label: where and what.
        result: the Monte Carlo metrics.
        hybrid: the learned loop's record (None for native strategies).
        seconds: wall time of the Monte Carlo [s], inference included (with
            ``smooth``, the smoothed Monte Carlo's, forward and backward, on both rows).
        outage_error: ``(n_runs, k)`` horizontal position error [m] at the end of each
            of the scenario's k DVL outages (the last second without the DVL).
    """

    scenario: str
    label: str
    result: MonteCarloResult
    hybrid: HybridResult | None
    seconds: float
    outage_error: NDArray[np.float64]


def _chosen_rows(
    n_runs: int,
    scenarios: Sequence[str],
    labels: Sequence[str] | None,
    threads: int | None,
    tuning_period: float,
) -> list[str]:
    """The study's rows, the reference first, after checking every argument (ValueError
    naming the option)."""
    if n_runs < 1:
        raise ValueError(f"--runs: must be at least 1, got {n_runs}")
    threads_arg(threads, "--threads")
    seconds_arg(tuning_period, "--tuning-period")
    unknown = [s for s in scenarios if s not in SCENARIOS]
    if unknown or not scenarios:
        raise ValueError(f"--scenarios: unknown {unknown}; known {list(SCENARIOS)}")
    chosen = list(STUDY_ROWS) if labels is None else list(labels)
    bad = [label for label in chosen if label not in STUDY_ROWS]
    if bad or not chosen:
        raise ValueError(f"--strategies: unknown {bad}; known {list(STUDY_ROWS)}")
    if len(set(chosen)) != len(chosen) or len(set(scenarios)) != len(scenarios):
        raise ValueError("--strategies, --scenarios: a value is listed twice")
    if chosen[0] != REFERENCE:
        chosen = [REFERENCE, *(label for label in chosen if label != REFERENCE)]
    return chosen


def run_study(
    n_runs: int = 100,
    seed: int = 0,
    *,
    scenarios: Sequence[str] = STUDY_SCENARIOS,
    labels: Sequence[str] | None = None,
    threads: int | None = None,
    tuning_period: float = 1.0,
    on_start: OnStart | None = None,
    on_done: OnDone | None = None,
    smooth: bool = False,
) -> list[StudyRow]:
    """Every row of :data:`STUDY_ROWS` (or ``labels``; the reference first) on every
    scenario, ``n_runs`` runs each from ``seed`` (the noise schedules too). With
    ``smooth``, each row is followed by its RTS-smoothed one (``"<label>, smoothed"``,
    the same runs smoothed; its paired differences are still taken from the forward
    reference); a smoothed Monte Carlo costs about 2.1–2.3 plain ones. Everything is checked
    before anything runs; ``on_done("<scenario>: <label>")`` after each."""
    chosen = _chosen_rows(n_runs, scenarios, labels, threads, tuning_period)
    regressors = _regressors(chosen)
    planned = {name: SCENARIOS[name](seed) for name in scenarios}
    for name, sc in planned.items():  # a row that could never act, named before any run
        for label, chosen_strategy in study_strategies(
            sc.q_nominal, regressors, tuning_period, chosen
        ).items():
            check_acts(chosen_strategy, sc, f"{name}: {label}")
    if on_start is not None:
        on_start(len(scenarios) * len(chosen), "run", None)
    rows = []
    for name, sc in planned.items():
        every = max(1, round(1.0 / sc.trajectory.dt)) if len(sc.dvl_outages) else 0
        for label, chosen_strategy in study_strategies(
            sc.q_nominal, regressors, tuning_period, chosen
        ).items():
            start = time.perf_counter()
            done = run(
                chosen_strategy, sc, n_runs=n_runs, seed=seed, threads=threads,
                record_every=every, smooth=smooth,
            )  # fmt: skip
            seconds = time.perf_counter() - start
            rows.append(
                StudyRow(
                    name, label, done.result, done.hybrid, seconds, _outage_error(sc, done.result)
                )
            )
            smoothed = done.result.smoothed
            if smoothed is not None:
                outage = _outage_error(sc, smoothed)
                rows.append(StudyRow(name, f"{label}, {SMOOTHED}", smoothed, None, seconds, outage))
            if on_done is not None:
                on_done(f"{name}: {label}")
    return rows


def _regressors(labels: Sequence[str]) -> dict[str, Regressor]:
    specs = [StrategySpec.parse(STUDY_ROWS[label]) for label in labels]
    names = [s.model for s in specs if s.kind == "learned"]
    if not names:
        return {}
    from pronet.learn.frozen import load_frozen  # frozen in the core: no torch

    return {name: load_frozen(name) for name in names}


def _outage_error(sc: Scenario, result: MonteCarloResult) -> NDArray[np.float64]:
    """Horizontal error [m] at the last recorded epoch before each outage ends."""
    ends = sc.dvl_outages[:, 1]
    if ends.size == 0 or result.error is None:
        return np.empty((result.n_runs, 0))
    idx = [int(np.searchsorted(result.record_time, end, side="left")) - 1 for end in ends]
    err = result.error[:, idx, :2]  # north, east position errors
    return np.hypot(err[..., 0], err[..., 1])


def oracle_share(
    reference: NDArray[np.float64],
    row: NDArray[np.float64],
    oracle: NDArray[np.float64],
    seed: int = 0,
) -> tuple[float, float, float]:
    """The share of the oracle's SRMSE gain a row achieves, ``mean(ref − row) /
    mean(ref − oracle)`` over the runs where all three are finite, with a paired
    percentile-bootstrap 95 % CI (:data:`pronet.stats.BOOTSTRAP` resamples of the runs). NaN where
    the oracle gains nothing measurable (its gain's 95 % CI includes 0): a share of
    nothing is no number."""
    ok = np.isfinite(reference) & np.isfinite(row) & np.isfinite(oracle)
    gain, ceiling = (reference - row)[ok], (reference - oracle)[ok]
    ci = mean_ci(ceiling)
    if gain.size < 2 or not ci.low > 0:
        return math.nan, math.nan, math.nan
    rng = np.random.default_rng([seed, 79])
    idx = rng.integers(0, gain.size, size=(BOOTSTRAP, gain.size))
    shares = gain[idx].mean(axis=1) / ceiling[idx].mean(axis=1)
    low, high = np.percentile(shares, [2.5, 97.5])
    return float(gain.mean() / ceiling.mean()), float(low), float(high)


#: Columns of ``study.csv``: labels, accuracy (mean and 95 % CI), outage-end error,
#: consistency, cost, the paired SRMSE difference from the reference and the oracle share.
STUDY_COLUMNS = (
    "scenario",
    "strategy",
    "runs",
    *(f"{m}{s}" for m in ("srmse", "smae") for s in ("", "_low", "_high")),
    "final_horizontal_error",
    "max_horizontal_error",
    "outage_end_error",
    "velocity_nees",
    "velocity_nees_3sigma",
    "velocity_nees_in_band",
    "attitude_nees",
    "attitude_nees_in_band",
    "mean_nis",
    "diverged_runs",
    "failed_runs",
    "seconds",
    "srmse_diff",
    "srmse_diff_low",
    "srmse_diff_high",
    "oracle_share",
    "oracle_share_low",
    "oracle_share_high",
)


def study_dataframe(rows: Sequence[StudyRow]) -> pd.DataFrame:
    """The study table (:data:`STUDY_COLUMNS`), one line per scenario and strategy."""
    import pandas as pd

    records = []
    for name in dict.fromkeys(r.scenario for r in rows):
        mine = {r.label: r for r in rows if r.scenario == name}
        ref = mine[REFERENCE].result.srmse
        oracle = mine[ORACLE].result.srmse if ORACLE in mine else None
        for label, r in mine.items():
            res = r.result
            s = res.summary()
            d = mean_ci(res.srmse - ref)
            share = oracle_share(ref, res.srmse, oracle) if oracle is not None else (math.nan,) * 3
            outage = r.outage_error
            records.append(
                {
                    "scenario": name,
                    "strategy": label,
                    "runs": res.n_runs,
                    **{
                        f"{m}{k}": getattr(s[m], a)
                        for m in ("srmse", "smae")
                        for k, a in (("", "mean"), ("_low", "low"), ("_high", "high"))
                    },
                    "final_horizontal_error": s["final_horizontal_error"].mean,
                    "max_horizontal_error": s["max_horizontal_error"].mean,
                    "outage_end_error": float(np.nanmean(outage)) if outage.size else math.nan,
                    "velocity_nees": s["velocity_nees"].mean,
                    "velocity_nees_3sigma": s["velocity_nees_3sigma"].mean,
                    "velocity_nees_in_band": res.nees_in_band("velocity"),
                    "attitude_nees": s["attitude_nees"].mean,
                    "attitude_nees_in_band": res.nees_in_band("attitude"),
                    "mean_nis": s["mean_nis"].mean,
                    "diverged_runs": res.n_diverged,
                    "failed_runs": res.n_failed,
                    "seconds": r.seconds,
                    "srmse_diff": d.mean,
                    "srmse_diff_low": d.low,
                    "srmse_diff_high": d.high,
                    "oracle_share": share[0],
                    "oracle_share_low": share[1],
                    "oracle_share_high": share[2],
                }
            )
    return pd.DataFrame(records, columns=list(STUDY_COLUMNS))


def _pct(value: float, ref: float) -> str:
    return f"{100 * value / ref:+.1f}" if math.isfinite(value) and ref else "—"


def _flag(in_band: float) -> str:
    """:data:`pronet.results.OUT_OF_BAND` for a NEES inside its band at fewer than
    :data:`pronet.montecarlo.IN_BAND_FLAG` of the epochs (a study row's record)."""
    return OUT_OF_BAND if in_band < IN_BAND_FLAG else ""


def study_markdown(table: pd.DataFrame) -> str:
    """The study table as Markdown, one block per scenario: ΔSRMSE in % of the
    reference's SRMSE with its paired 95 % CI, the oracle-gain share with its bootstrap
    CI, and the other figures rounded for reading."""
    header = [
        "strategy",
        "SRMSE [m/s]",
        "ΔSRMSE vs constant (true q) [%] (95 % CI)",
        "share of the oracle's gain (95 % CI)",
        "SMAE [m/s]",
        "final / max horiz. [m]",
        "outage end [m]",
        "vel. NEES (in 3σ)",
        "att. NEES",
        "NIS",
        "diverged",
        "time [s]",
    ]
    blocks = []
    for name in dict.fromkeys(table["scenario"]):
        part = table[table["scenario"] == name]
        ref = float(part[part["strategy"] == REFERENCE]["srmse"].iloc[0])
        lines = []
        for _, r in part.iterrows():
            low, high = _pct(r.srmse_diff_low, ref), _pct(r.srmse_diff_high, ref)
            diff = f"{_pct(r.srmse_diff, ref)} [{low}, {high}]"
            share = (
                f"{r.oracle_share:.2f} [{r.oracle_share_low:.2f}, {r.oracle_share_high:.2f}]"
                if math.isfinite(r.oracle_share)
                else "—"
            )
            outage = f"{r.outage_end_error:.2f}" if math.isfinite(r.outage_end_error) else "—"
            lines.append(
                [
                    r.strategy,
                    f"{r.srmse:.4f}",
                    diff if r.strategy != REFERENCE else "reference",
                    share,
                    f"{r.smae:.4f}",
                    f"{r.final_horizontal_error:.2f} / {r.max_horizontal_error:.2f}",
                    outage,
                    f"{r.velocity_nees:.2f} ({100 * r.velocity_nees_3sigma:.1f} %)"
                    + _flag(r.velocity_nees_in_band),
                    f"{r.attitude_nees:.2f}" + _flag(r.attitude_nees_in_band),
                    f"{r.mean_nis:.2f}",
                    f"{r.diverged_runs} / {r.runs}",
                    f"{r.seconds:.1f}",
                ]
            )
        runs = int(part["runs"].iloc[0])
        blocks.append(markdown(header, lines, f"{name}: {runs} runs per row"))
    return "\n".join(blocks)


def write_study(folder: Path, rows: Sequence[StudyRow], config: dict[str, object]) -> Path:
    """Write the study's result folder atomically: the common result tables
    (:func:`pronet.results.write_tables`), ``study.csv`` (:data:`STUDY_COLUMNS`),
    ``table.md`` (:func:`study_markdown`), ``config.json`` and ``study.png``."""
    from pronet import plots

    table = study_dataframe(rows)
    import pandas as pd

    labelled: list[tuple[dict[str, object], MonteCarloResult]] = [
        ({"scenario": r.scenario, "strategy": r.label}, r.result) for r in rows
    ]
    ref = {r.scenario: r.result.srmse for r in rows if r.label == REFERENCE}
    summary = pd.DataFrame(
        [
            summary_row(
                labels, r.result, diff=mean_ci(r.result.srmse - ref[r.scenario]), hybrid=r.hybrid
            )
            for (labels, _), r in zip(labelled, rows, strict=True)
        ],
        columns=list(SUMMARY_COLUMNS),
    )
    with atomic_folder(Path(folder)) as tmp:
        write_tables(tmp, summary, results_dataframe(labelled, per_run=True), study_markdown(table))
        table.to_csv(tmp / "study.csv", index=False)
        (tmp / "config.json").write_bytes(json_bytes(config))
        plots.study_figure(table, tmp / "study.png")
    return Path(folder)


def study(
    out: str | Path | None = None,
    *,
    n_runs: int = 100,
    seed: int = 0,
    scenarios: Sequence[str] = STUDY_SCENARIOS,
    labels: Sequence[str] | None = None,
    threads: int | None = None,
    say: Say | None = None,
    on_start: OnStart | None = None,
    on_done: OnDone | None = None,
    smooth: bool = False,
    tuning_period: float = 1.0,
) -> Path:
    """Run the study (:func:`run_study`; ``smooth``: with the smoothed rows; the learned
    rows and detvar estimate q every ``tuning_period`` seconds) and write its folder
    (:func:`write_study`, default ``results/study-<time>``; an existing one is refused);
    returns the folder."""
    # checked before anything
    n_rows = len(_chosen_rows(n_runs, scenarios, labels, threads, tuning_period))
    folder = new_result_folder(out, "study")
    if say is not None:
        say(
            f"study: {len(scenarios)} scenarios x {n_rows} strategies, {n_runs} runs "
            f"each, seed {seed}"
        )
    rows = run_study(
        n_runs,
        seed,
        scenarios=scenarios,
        labels=labels,
        threads=threads,
        on_start=on_start,
        on_done=on_done,
        smooth=smooth,
        tuning_period=tuning_period,
    )
    config: dict[str, object] = {
        "n_runs": n_runs,
        "seed": seed,
        "smooth": smooth,
        "tuning_period_s": tuning_period,
        "scenarios": {
            name: {
                "filter": repr(sc.config),
                "sensors": repr(sc.sensors),
                "q_nominal": list(sc.q_nominal),
                "schedule_seed": sc.schedule_seed,
                "schedule_time_s": sc.schedule_time.tolist(),
                "schedule_q": sc.schedule_q.tolist(),
            }
            for name in scenarios
            for sc in [SCENARIOS[name](seed)]
        },
        "strategies": {r.label: STUDY_ROWS[r.label.removesuffix(f", {SMOOTHED}")] for r in rows},
    }  # no wall time: identical runs write identical files (study.csv has the timings)
    return write_study(folder, rows, config)
