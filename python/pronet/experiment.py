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
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pronet import _core
from pronet._files import atomic_folder
from pronet._validate import float_array
from pronet.hybrid import DEFAULT_TUNING_PERIOD, HybridResult, run_hybrid
from pronet.montecarlo import MonteCarloResult, monte_carlo, results_dataframe
from pronet.shards import ShardStore
from pronet.stats import MeanCI, mean_ci
from pronet.trajectory import builtin_trajectory

if TYPE_CHECKING:  # torch loads only when a model does
    from pronet.models import Regressor

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


@dataclass(frozen=True)
class Learned:
    """A regressor-driven row: the hybrid loop with ``regressor`` (prior ``prior_q``
    until the first window is full)."""

    regressor: Regressor
    prior_q: tuple[float, ...]
    tuning_period: float = DEFAULT_TUNING_PERIOD


StrategyLike = _core.Strategy | Learned


@dataclass(frozen=True)
class Scenario:
    """A simulated evaluation scenario.

    Attributes:
        name: ``"paper"`` or ``"varying-noise"`` (or a user's).
        trajectory: truth and ideal IMU.
        sensors: simulated IMU and DVL.
        config: filter tuning (bias walk, DVL R, P0).
        q_nominal: 6 per-sample variances the constant rows are told (and every
            adaptive row starts from): the true q, or its time average when it varies.
        schedule_time: ``(k,)`` [s] start of each piece of the true noise schedule.
        schedule_q: ``(k, 6)`` true per-sample variances of each piece.
    """

    name: str
    trajectory: _core.Trajectory
    sensors: _core.SensorConfig
    config: _core.FilterConfig
    q_nominal: tuple[float, ...]
    schedule_time: np.ndarray
    schedule_q: np.ndarray


def paper_scenario() -> Scenario:
    """The paper's Table I: constant accelerometer 0.01², gyro 0.001² variances."""
    return Scenario(
        name="paper",
        trajectory=builtin_trajectory("paper"),
        sensors=_core.SensorConfig(imu_variance=PAPER_Q),
        config=paper_filter_config(),
        q_nominal=PAPER_Q,
        schedule_time=np.zeros(1),
        schedule_q=np.array([PAPER_Q]),
    )


def noise_schedule(
    duration: float, seed: int, q_range: tuple[float, float] = (0.001, 0.05)
) -> tuple[np.ndarray, np.ndarray]:
    """A piecewise-constant variance schedule ``(times (k,), q (k, 6))``: each channel
    independently holds a value drawn uniformly from ``q_range`` for 30–60 s (drawn
    uniformly), then changes. ``times`` merges every channel's change instants."""
    rng = np.random.default_rng([seed, 77])
    changes, values = [], []
    for _ in range(6):
        t = [0.0]
        while t[-1] + 30.0 < duration:
            t.append(t[-1] + rng.uniform(30.0, 60.0))
        t = [x for x in t if x < duration]
        changes.append(np.array(t))
        values.append(rng.uniform(*q_range, size=len(t)))
    times = np.unique(np.concatenate(changes))
    q = np.stack(
        [
            v[np.searchsorted(c, times, side="right") - 1]
            for c, v in zip(changes, values, strict=True)
        ],
        axis=1,
    )
    return times, q


def varying_noise_scenario(seed: int = 0) -> Scenario:
    """The paper's trajectory and filter, with each IMU channel's noise variance changing
    every 30–60 s inside the training range [0.001, 0.05] (:func:`noise_schedule`). The
    constant rows are told each channel's time-averaged variance."""
    trajectory = builtin_trajectory("paper")
    times, q = noise_schedule(trajectory.duration, seed)
    mean_q = time_average_q(times, q, trajectory.duration)
    return Scenario(
        name="varying-noise",
        trajectory=trajectory,
        sensors=_core.SensorConfig(imu_variance=q, imu_variance_times=times),
        config=paper_filter_config(),
        q_nominal=mean_q,
        schedule_time=times,
        schedule_q=q,
    )


def time_average_q(
    times: np.ndarray, q: np.ndarray, duration: float
) -> tuple[float, float, float, float, float, float]:
    """Each channel's time-averaged variance over ``[0, duration]`` s of the
    piecewise-constant schedule ``times (k,)`` [s, from 0], ``q (k, 6)``."""
    times = np.asarray(times, dtype=np.float64)
    inside = times < duration
    held = np.diff(np.append(times[inside], duration))
    mean = (np.asarray(q, dtype=np.float64)[inside] * held[:, None]).sum(axis=0) / held.sum()
    return tuple(float(v) for v in mean)  # type: ignore[return-value]


SCENARIOS: dict[str, Callable[[], Scenario]] = {
    "paper": paper_scenario,
    "varying-noise": varying_noise_scenario,
}


#: The paper's rows, by table label: the strategy spec of each (see :class:`StrategySpec`).
PAPER_ROWS = {
    "constant (true q)": "constant",
    "constant (20 x q)": "constant:20",
    "adaptive xi=1": "mehra:1",
    "adaptive xi=5": "mehra:5",
    "HCF-ensemble": "learned:hcf",
    "baseline net": "learned:baseline",
    "detrend net": "learned:detrend",
}

#: Table label of each learned row, by model name.
LEARNED_LABELS = {
    spec.removeprefix("learned:"): label
    for label, spec in PAPER_ROWS.items()
    if spec.startswith("learned:")
}


@dataclass(frozen=True)
class StrategySpec:
    """A strategy named in text, as configs and the command line give it:

    - ``constant`` or ``constant:S``: constant Q, the scenario's nominal q times S
      (default 1);
    - ``mehra:W``: Mehra's innovation-adaptive Q over a window of W DVL updates;
    - ``learned:MODEL``: the hybrid loop with a regressor: a shipped model name
      (``baseline``, ``detrend``, ``hcf``) or the path of a model file.

    Attributes:
        text: the spec as written (the row label in simulations and sweeps).
        kind: ``"constant"``, ``"mehra"`` or ``"learned"``.
        factor: constant: the factor on q; mehra: the window; learned: 0.
        model: learned: the model name or path; otherwise ``""``.
    """

    text: str
    kind: str
    factor: float = 0.0
    model: str = ""

    @classmethod
    def parse(cls, text: object) -> StrategySpec:
        """The spec in ``text``, or ``ValueError`` saying what is wrong with it."""
        if not isinstance(text, str):
            raise ValueError(f"strategy: expected text such as 'mehra:5', got {text!r}")
        kind, _, arg = text.strip().partition(":")
        arg = arg.strip()
        if kind == "constant":
            factor = _spec_number(arg, text) if arg else 1.0
            if not 0 < factor < math.inf:
                raise ValueError(f"strategy {text!r}: the factor on q must be finite and > 0")
            return cls(text, kind, factor)
        if kind == "mehra":
            if not arg.isdigit() or int(arg) < 1:
                raise ValueError(f"strategy {text!r}: mehra needs a window >= 1, e.g. mehra:5")
            return cls(text, kind, float(int(arg)))
        if kind == "learned":
            if not arg:
                raise ValueError(f"strategy {text!r}: learned needs a model, e.g. learned:detrend")
            return cls(text, kind, model=arg)
        raise ValueError(f"strategy {text!r}: expected constant[:S], mehra:W or learned:MODEL")

    @property
    def uses_tuning_period(self) -> bool:
        """Whether the tuning period changes this strategy (only learned ones)."""
        return self.kind == "learned"


def _spec_number(text: str, spec: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"strategy {spec!r}: {text!r} is not a number") from None


def strategy(
    spec: StrategySpec,
    q: tuple[float, ...],
    tuning_period: float = DEFAULT_TUNING_PERIOD,
    regressor: Regressor | None = None,
) -> StrategyLike:
    """The strategy ``spec`` describes around the nominal ``q`` (6 per-sample
    variances [(m/s²)², (rad/s)²]); a learned one runs ``regressor`` (default:
    ``models.load(spec.model)``) every ``tuning_period`` seconds."""
    q = tuple(float(v) for v in float_array(q, "q", (6,)))  # factor x q in float64
    if spec.kind == "constant":
        return _core.Strategy.constant(q if spec.factor == 1 else tuple(spec.factor * v for v in q))
    if spec.kind == "mehra":
        return _core.Strategy.mehra(int(spec.factor), q)
    if regressor is None:
        from pronet import models

        regressor = models.load(spec.model)
    return Learned(regressor, q, tuning_period)


def model_based_strategies(q: tuple[float, ...] = PAPER_Q) -> dict[str, _core.Strategy]:
    """The four rows of the paper's table that need no learned model, around ``q``."""
    specs = {label: StrategySpec.parse(text) for label, text in PAPER_ROWS.items()}
    return {
        label: strategy(spec, q)  # type: ignore[misc]
        for label, spec in specs.items()
        if spec.kind != "learned"
    }


def paper_strategies(
    q: tuple[float, ...], models: dict[str, Regressor], tuning_period: float
) -> dict[str, StrategyLike]:
    """The paper's seven rows: the model-based four around ``q``, then the learned
    rows for the regressors in ``models`` (keys as in :data:`LEARNED_LABELS`)."""
    rows: dict[str, StrategyLike] = dict(model_based_strategies(q))
    for name, label in LEARNED_LABELS.items():
        if name in models:
            rows[label] = Learned(models[name], q, tuning_period)
    return rows


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
    hybrid: HybridResult | None = None


def run_strategies(
    strategies: dict[str, StrategyLike],
    scenario: Scenario,
    *,
    n_runs: int,
    seed: int,
    threads: int | None = None,
    record_every: int = 0,
    on_done: Callable[[str], None] | None = None,
    shards: ShardStore | None = None,
) -> list[Row]:
    """Run every strategy on the same noise realizations (same seed); the first strategy
    is the reference for the paired differences. With ``shards``, each finished strategy
    is saved there at once, and one already saved is loaded instead of rerun."""
    results: dict[str, tuple[MonteCarloResult, HybridResult | None]] = {}
    common = dict(
        sensors=scenario.sensors,
        config=scenario.config,
        n_runs=n_runs,
        seed=seed,
        threads=threads,
        record_every=record_every,
    )
    for label, strategy in strategies.items():
        saved = shards.load(scenario.name, label) if shards is not None else None
        if saved is not None:
            results[label] = saved
        elif isinstance(strategy, Learned):
            h = run_hybrid(
                strategy.regressor,
                scenario.trajectory,
                prior_q=strategy.prior_q,
                tuning_period=strategy.tuning_period,
                **common,
            )
            results[label] = (h.result, h)
        else:
            results[label] = (monte_carlo(scenario.trajectory, strategy, **common), None)
        if shards is not None and saved is None:
            shards.save(scenario.name, label, *results[label])
        if on_done is not None:
            on_done(label)
    ref = next(iter(results.values()))[0]
    return [
        Row(
            label=label,
            result=r,
            srmse=mean_ci(r.srmse),
            smae=mean_ci(r.smae),
            srmse_diff=mean_ci(r.srmse - ref.srmse),
            smae_diff=mean_ci(r.smae - ref.smae),
            hybrid=h,
        )
        for label, (r, h) in results.items()
    ]


def to_dataframe(tables: dict[str, list[Row]], per_run: bool = False):  # -> pandas.DataFrame
    """Experiment results (title → rows, as ``pronet reproduce`` and ``simulate`` make
    them) as one DataFrame: per strategy, ``scenario``, ``strategy`` and
    :meth:`~pronet.MonteCarloResult.summary_row`'s columns; with ``per_run``, one row
    per run with :meth:`~pronet.MonteCarloResult.to_dataframe`'s columns."""
    labelled = (
        ({"scenario": title, "strategy": row.label}, row.result)
        for title, rows in tables.items()
        for row in rows
    )
    return results_dataframe(labelled, per_run)


def markdown_table(rows: list[Row], title: str, paper: bool = True) -> str:
    """The results as a Markdown table; with ``paper``, the paper's numbers beside ours."""
    out = io.StringIO()
    out.write(f"### {title}\n\n")
    head = "| approach | SRMSE [m/s] (95 % CI) | SMAE [m/s] (95 % CI)"
    head += " | ΔSRMSE vs row 1 (paired 95 % CI)"
    head += " | paper SRMSE | paper SMAE |" if paper else " |"
    out.write(head + " failed / diverged runs | guardrail events |\n")
    out.write("|---" * (7 if paper else 5) + "|---|\n")
    for row in rows:
        diff = f"{row.srmse_diff.mean:+.4f} [{row.srmse_diff.low:+.4f}, {row.srmse_diff.high:+.4f}]"
        line = f"| {row.label} | {row.srmse} | {row.smae} | {diff} |"
        if paper:
            ref = PAPER_TABLE.get(row.label)
            line += f" {ref[0]:.3f} | {ref[1]:.3f} |" if ref else " | |"
        guard = ""
        if row.hybrid is not None:
            h = row.hybrid
            guard = f"{int(h.clipped.sum())} clipped, {int(h.non_finite.sum())} non-finite"
        r = row.result
        out.write(f"{line} {r.n_failed} / {r.n_diverged} | {guard} |\n")
    return out.getvalue()


def _ci_json(ci: MeanCI) -> dict[str, float | int]:
    return {"mean": ci.mean, "low": ci.low, "high": ci.high, "n": ci.n}


def write_result_folder(
    folder: Path,
    tables: dict[str, list[Row]],
    config: dict[str, object],
    extra: Callable[[Path], None] | None = None,
    paper_columns: bool = True,
) -> Path:
    """Write ``table.md``, ``metrics.json``, ``metrics.csv`` and ``config.json`` into
    ``folder``, plus whatever ``extra(tmp_folder)`` writes (plots, models), atomically:
    everything goes to a temporary sibling first, which is renamed into place only when
    complete. An existing folder is refused, never overwritten. With ``paper_columns``,
    tables titled ``paper ...`` show the paper's numbers beside ours."""
    with atomic_folder(Path(folder)) as tmp:
        (tmp / "table.md").write_text(
            "\n".join(
                markdown_table(rows, scenario, paper=paper_columns and scenario.startswith("paper"))
                for scenario, rows in tables.items()
            )
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
                    "diverged_runs": row.result.n_diverged,
                    "paper": PAPER_TABLE.get(row.label)
                    if paper_columns and scenario.startswith("paper")
                    else None,
                    **(_hybrid_json(row.hybrid) if row.hybrid is not None else {}),
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
        if extra is not None:
            extra(tmp)
    return folder


def _hybrid_json(h: HybridResult) -> dict[str, object]:
    return {
        "tunings": h.n_tunings,
        "guardrail_clipped": int(h.clipped.sum()),
        "guardrail_non_finite": int(h.non_finite.sum()),
        "guardrail_range": [h.guardrails.q_min, h.guardrails.q_max],
        "rust_seconds": h.rust_seconds,
        "model_seconds": h.model_seconds,
    }


def _jsonable(value: object) -> object:
    if isinstance(value, np.ndarray):
        return value.tolist()
    return repr(value)
