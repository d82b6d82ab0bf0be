"""Chosen strategies on one simulated scenario: a Monte Carlo each on the same noise
realizations, written as one result folder (table, metrics, configuration and plots).
``pronet simulate`` is a thin face over :func:`simulate`.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from pathlib import Path

from pronet import _core
from pronet._util.files import release_folder
from pronet._util.outputs import OnDone, OnStart, Say, new_result_folder
from pronet._util.plausibility import warn_of_imu_dt
from pronet._util.validate import seconds as seconds_arg
from pronet._util.validate import threads as threads_arg
from pronet.montecarlo import chance_bound, runs_flag, runs_outside_band
from pronet.results import check_a_run_finished, table_title, write_result_folder
from pronet.run import Row, run_strategies
from pronet.sim.scenarios import Scenario
from pronet.strategies import StrategySpec, check_distinct, strategy


def _scenario(
    scenario: str | Path | Scenario,
    filter_config: str | Path | None,
    seed: int,
    formulation: str | None = None,
    covariance_step: float | None = None,
) -> Scenario:
    """``scenario`` (built-in name or ``.toml`` file, its noise schedule drawn from
    ``seed``; or an object), with the keys of the ``filter_config`` file, if given,
    overriding its filter's, and then ``formulation`` and ``covariance_step``, if given."""
    from pronet import config

    if not isinstance(scenario, Scenario):
        scenario = config.load_scenario(scenario, seed)
    if filter_config:
        tuned = config.load_filter_config(filter_config, base=scenario.config)
        if tuned.imu_dt != scenario.config.imu_dt:  # the file's: against the trajectory's
            warn_of_imu_dt(tuned.imu_dt, scenario.trajectory.dt, f"{filter_config}:")
        scenario = dataclasses.replace(scenario, config=tuned)
    for key, value in (("formulation", formulation), ("covariance_step", covariance_step)):
        if value is not None:
            where = f"--{key.replace('_', '-')}:"
            tuned = config.filter_config({key: value}, where, base=scenario.config)
            scenario = dataclasses.replace(scenario, config=tuned)
    return scenario


def _specs(specs: Sequence[str | StrategySpec]) -> list[StrategySpec]:
    """``specs`` parsed; ``ValueError`` unless there is at least one and all differ, in
    text and in what they run (``constant`` and ``constant:1`` are one strategy)."""
    texts = [s.text if isinstance(s, StrategySpec) else str(s).strip() for s in specs]
    kept = [(t, s) for t, s in zip(texts, specs, strict=True) if t]
    if not kept or len({t for t, _ in kept}) != len(kept):
        raise ValueError(
            f"strategies: expected distinct comma-separated specs, got {[t for t, _ in kept]}"
        )
    parsed = [s if isinstance(s, StrategySpec) else StrategySpec.parse(t) for t, s in kept]
    check_distinct(parsed)
    return parsed


def _check_numbers(
    n_runs: int, threads: int | None, record_every: float, tuning_period: float
) -> None:
    """``ValueError`` naming the option unless the numbers of :func:`simulate` are valid."""
    if n_runs < 1:
        raise ValueError(f"--runs: must be at least 1, got {n_runs}")
    seconds_arg(tuning_period, "--tuning-period")
    seconds_arg(record_every, "--record-every")
    threads_arg(threads, "--threads")


def _record_steps(seconds: float, trajectory: _core.Trajectory) -> int:
    """``seconds`` between saved history samples as IMU steps, at least 1: one beyond
    the trajectory's samples (which keeps its first only) for any longer time, which the
    core would refuse beyond 2⁶⁴ steps naming its own argument and a 23-digit count."""
    return min(max(1, round(seconds / trajectory.dt)), trajectory.n_samples + 1)


def simulate(
    scenario: str | Path | Scenario,
    specs: Sequence[str | StrategySpec],
    out: str | Path | None = None,
    *,
    filter_config: str | Path | None = None,
    formulation: str | None = None,
    covariance_step: float | None = None,
    n_runs: int = 100,
    seed: int = 0,
    threads: int | None = None,
    record_every: float = 1.0,
    tuning_period: float = 1.0,
    smooth: bool = False,
    plots: bool = True,
    say: Say | None = None,
    on_start: OnStart | None = None,
    on_done: OnDone | None = None,
    note: Say | None = None,
) -> Path:
    """Run every strategy of ``specs`` on ``scenario`` and write the result folder;
    returns the folder. Everything is read and checked before anything runs.

    Args:
        scenario: a built-in scenario name (:data:`pronet.sim.scenarios.SCENARIOS`), a
            scenario ``.toml`` file (see :mod:`pronet.config`) or a
            :class:`~pronet.sim.scenarios.Scenario`; a drawn noise schedule comes from
            ``seed`` unless the file sets ``schedule_seed``.
        specs: distinct strategy specs (see :class:`~pronet.strategies.StrategySpec`);
            the first is the reference of the paired differences.
        out: the result folder to create (default ``results/simulate-<time>``); an
            existing one is refused.
        filter_config: a filter ``.toml`` file; the keys it names override the
            scenario's filter, the rest stay.
        formulation: the filter's error coordinates, ``"invariant"`` or ``"classic"``
            (default: the scenario's or the filter file's, else the invariant one).
        covariance_step: the filter's covariance step [s] (default: the scenario's or
            the filter file's, else ``FilterConfig``'s 0.1 s; 0: every IMU sample).
        n_runs: Monte Carlo runs per strategy (>= 1); seed: their seed.
        threads: worker threads, 1 to 8 per core (default: one per core, or
            ``RAYON_NUM_THREADS``).
        record_every: seconds between the saved history samples the plots use (> 0).
        tuning_period: seconds between regressor calls of learned strategies (> 0).
        smooth: also the RTS smoother over every run: each strategy's row is followed
            by its smoothed one (``"<spec>, smoothed"``; see :func:`pronet.monte_carlo`).
        plots: False: the tables, metrics and config only (the plots take most of the
            time of a short run).
        say: a progress callback for one line of text (see :mod:`pronet._util.outputs`).
        on_start: the callback told a stage's start: one
            stage, a step per strategy labelled with its spec.
        on_done: the callback told each step done.
        note: told each note of what the runs say of the filter (a row whose runs leave
            their NIS band; also in ``config.json``'s ``notes``); default ``say``.

    Raises:
        ValueError: a bad argument, file or spec, before any computation; or, after
            it, when every run of every strategy failed (the first one named; no
            folder is written).
    """
    _check_numbers(n_runs, threads, record_every, tuning_period)
    sc = _scenario(scenario, filter_config, seed, formulation, covariance_step)
    parsed = _specs(specs)
    strategies = {spec.text: strategy(spec, sc.q_nominal, tuning_period) for spec in parsed}
    out = new_result_folder(out, "simulate")
    if say is not None:
        say(
            f"scenario {sc.name} ({sc.trajectory.duration:g} s): "
            f"{len(strategies)} strategies, {n_runs} Monte Carlo runs each, seed {seed}"
        )
    if on_start is not None:
        on_start(len(strategies), "strategy", None)
    rows = run_strategies(
        strategies,
        sc,
        n_runs=n_runs,
        seed=seed,
        threads=threads,
        record_every=_record_steps(record_every, sc.trajectory),
        on_done=on_done,
        smooth=smooth,
    )
    try:  # not one run finished: an error, not a folder of NaN
        check_a_run_finished((f"{sc.name}: {row.label}", row.result) for row in rows)
    except ValueError:
        release_folder(out)
        raise
    # What the runs say about themselves: rows whose DVL NIS leave their band too often,
    # over the runs that finished (a failed run's NIS stops where it failed).
    outside = {row.label: runs_outside_band(row.result.nis[row.result.finished]) for row in rows}
    notes = [line for label, o in outside.items() if (line := runs_flag(label, o))]
    for line in notes:
        if (tell := note or say) is not None:
            tell(line)
    settings: dict[str, object] = {
        "scenario": scenario.name if isinstance(scenario, Scenario) else str(scenario),
        "filter": repr(sc.config),
        "sensors": repr(sc.sensors),
        "trajectory": sc.trajectory.name,
        "q_nominal": list(sc.q_nominal),
        "schedule_seed": sc.schedule_seed,
        "strategies": [spec.text for spec in parsed],
        "n_runs": n_runs,
        "seed": seed,
        "tuning_period_s": tuning_period,
        "smooth": smooth,
        "health": {
            label: {
                "runs_nis_outside_band": int(o.sum()),
                "runs": len(o),
                "failed_runs": row.result.n_failed,
                "chance_allows": chance_bound(len(o)),
            }
            for row, (label, o) in zip(rows, outside.items(), strict=True)
        },
        "notes": notes,
    }
    return write_result_folder(
        out,
        {sc.name: rows},
        settings,
        extra=(lambda folder: _figures(folder, sc, rows)) if plots else None,
        paper_columns=False,
        notes=notes,
    )


def _figures(folder: Path, scenario: Scenario, rows: list[Row]) -> None:
    """The plots of a simulation's result folder."""
    from pronet import plots

    title = table_title(scenario.name, rows)
    plots.metrics_with_ci({title: rows}, folder / "srmse_smae.png")
    plots.trajectory(scenario.trajectory, folder / "trajectory.png", scenario.name)
    plots.velocity_error(rows, folder / "velocity_error.png", title)
    plots.q_tracking(rows, scenario.schedule_time, scenario.schedule_q, folder / "q.png", title)
