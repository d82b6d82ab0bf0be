"""The paper's experiment end to end: every built-in scenario × the paper's seven rows,
a Monte Carlo each, written as one result folder (tables, metrics, configuration and
figures). ``pronet reproduce`` is a thin face over :func:`reproduce`.

With the shipped weights, each finished (scenario, strategy) Monte Carlo is saved at
once in ``<out>.partial`` (a :class:`~pronet.shards.ShardStore`), so an interrupted run
continues with ``resume=True`` without redoing them; the store is removed once the
result folder is written.
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import pronet
from pronet import _core
from pronet._util.outputs import OnDone, OnStart, Say, new_result_folder, partial_folder
from pronet._util.validate import seconds as seconds_arg
from pronet._util.validate import threads as threads_arg
from pronet.learn.dataset import Dataset, DatasetParams, build_dataset
from pronet.results import table_title, write_result_folder
from pronet.run import Row, check_acts, run_strategies
from pronet.shards import ShardStore
from pronet.sim.paper import LEARNED_LABELS, paper_strategies
from pronet.sim.scenarios import PAPER_SCENARIOS, SCENARIOS, Scenario
from pronet.strategies import StrategyLike

if TYPE_CHECKING:  # torch loads only when a model does
    from pronet.learn.models import Regressor

#: History every this many IMU steps (1 s at 100 Hz), for the plots.
RECORD_EVERY = 100


def _check_arguments(
    out: str | Path | None,
    *,
    n_runs: int,
    threads: int | None,
    tuning_period: float,
    retrain: bool,
    resume: bool,
) -> tuple[Path, Path]:
    """``(out, partial)``: the result folder and its ``.partial`` sibling, once every
    argument of :func:`reproduce` is checked (``ValueError`` naming the option)."""
    if n_runs < 1:
        raise ValueError(f"--runs: must be at least 1, got {n_runs}")
    seconds_arg(tuning_period, "--tuning-period")
    threads_arg(threads, "--threads")
    if resume and (not out or retrain):
        raise ValueError(
            "--resume: needs the --out of the interrupted run, and cannot be used with --retrain"
        )
    folder = new_result_folder(out, "reproduce")
    return folder, partial_folder(folder, resume)


def reproduce(
    out: str | Path | None = None,
    *,
    n_runs: int = 100,
    seed: int = 0,
    threads: int | None = None,
    tuning_period: float = 1.0,
    retrain: bool = False,
    resume: bool = False,
    train_progress: bool = False,
    say: Say | None = None,
    on_start: OnStart | None = None,
    on_done: OnDone | None = None,
) -> Path:
    """Run the paper's experiment and write its result folder; returns the folder.

    Args:
        out: the result folder to create (default ``results/reproduce-<time>``); an
            existing one is refused.
        n_runs: Monte Carlo runs per strategy (>= 1); seed: their seed.
        threads: worker threads, 1 to 8 per core (default: one per core, or
            ``RAYON_NUM_THREADS``).
        tuning_period: seconds between regressor calls in the learned rows (> 0).
        retrain: train the three regressors first (~10 min) instead of using the
            shipped weights; those runs are not saved for resuming.
        resume: continue the interrupted run of ``out`` from ``<out>.partial``.
        train_progress: show the training's own progress bars.
        say: a progress callback for one line of text (see :mod:`pronet._util.outputs`).
        on_start: the callback told a stage's start: one
            stage, a step per (scenario, strategy) labelled ``"<scenario>: <strategy>"``.
        on_done: the callback told each step done.

    Raises:
        ValueError: a bad argument, before any computation.
        KeyboardInterrupt: with a note saying how many Monte Carlos were kept.
    """
    out, partial = _check_arguments(
        out,
        n_runs=n_runs,
        threads=threads,
        tuning_period=tuning_period,
        retrain=retrain,
        resume=resume,
    )
    trained_dir = Path(tempfile.mkdtemp(prefix="pronet-models-")) if retrain else None
    try:
        ds, regressors = _regressors(trained_dir, train_progress)
        scenarios = [SCENARIOS[name](seed) for name in PAPER_SCENARIOS]
        jobs = {
            sc.name: paper_strategies(sc.q_nominal, regressors, tuning_period) for sc in scenarios
        }
        if say is not None:
            say(
                f"{len(scenarios)} scenarios x {len(jobs['paper'])} strategies, {n_runs} "
                f"Monte Carlo runs each, seed {seed}; weights: "
                f"{'retrained' if retrain else 'shipped'}"
            )
        for sc in scenarios:  # every row could act, before any <out>.partial is made
            for label, chosen in jobs[sc.name].items():
                check_acts(chosen, sc, label)
        settings = {"n_runs": n_runs, "seed": seed, "tuning_period": tuning_period}
        shards = None if retrain else _shard_store(partial, settings, say)
        if on_start is not None:
            on_start(sum(len(j) for j in jobs.values()), "strategy", None)
        tables = _run_tables(scenarios, jobs, n_runs, seed, threads, shards, on_done)
        config = _config(scenarios, jobs, regressors, settings, retrain)
        folder = write_result_folder(
            out,
            tables,
            config,
            extra=lambda tmp: _figures(tmp, ds, regressors, scenarios, tables, trained_dir),
        )
        if shards is not None:
            shards.remove()
        return folder
    finally:
        if trained_dir is not None:
            shutil.rmtree(trained_dir, ignore_errors=True)


def _regressors(
    trained_dir: Path | None, train_progress: bool
) -> tuple[Dataset | None, dict[str, Regressor]]:
    """The paper's shipped regressors (:data:`pronet.learn.models.PAPER_MODELS`), or (with
    ``trained_dir``) three trained there on the paper's dataset, which is returned too;
    keyed by shipped name either way."""
    from pronet.learn.frozen import PAPER_MODELS, load_frozen  # frozen in the core

    if trained_dir is None:
        return None, {k: load_frozen(k) for k in PAPER_MODELS}
    from pronet.learn import training  # training needs torch

    params = DatasetParams()
    ds = build_dataset(params)
    for kind in training.MODEL_KINDS:
        training.train_and_save(kind, ds, params, trained_dir, progress=train_progress)
    return ds, {f"paper-{k}": load_frozen(trained_dir / k) for k in training.MODEL_KINDS}


def _shard_store(partial: Path, settings: dict[str, int | float], say: Say | None) -> ShardStore:
    """The store of finished Monte Carlos, keyed by everything that shapes their numbers:
    shards of another version, other weights or other settings must not be mixed in."""
    from pronet.learn.frozen import shipped_sha256
    from pronet.learn.hybrid import LOOP_PRECISION

    store = ShardStore(
        partial,
        {
            "n_runs": settings["n_runs"],
            "seed": settings["seed"],
            "tuning_period": settings["tuning_period"],
            "record_every": RECORD_EVERY,
            "pronet": pronet.__version__,
            "native_core": _core.__version__,
            "weights": shipped_sha256(),
            "loop_precision": LOOP_PRECISION,
        },
    )
    if len(store) and say is not None:
        say(f"resuming: {len(store)} finished Monte Carlos loaded from {partial}")
    return store


def _run_tables(
    scenarios: list[Scenario],
    jobs: dict[str, dict[str, StrategyLike]],
    n_runs: int,
    seed: int,
    threads: int | None,
    shards: ShardStore | None,
    on_done: OnDone | None,
) -> dict[str, list[Row]]:
    """Every scenario's Monte Carlos, as tables keyed by the scenario's name.
    On Ctrl-C the interrupt carries a note on what ``shards`` kept."""
    tables: dict[str, list[Row]] = {}
    try:
        for sc in scenarios:

            def done(label: str, sc: Scenario = sc) -> None:
                if on_done is not None:
                    on_done(f"{sc.name}: {label}")

            tables[sc.name] = run_strategies(
                jobs[sc.name],
                sc,
                n_runs=n_runs,
                seed=seed,
                threads=threads,
                record_every=RECORD_EVERY,
                on_done=done,
                shards=shards,
            )
    except KeyboardInterrupt as exc:
        if shards is not None:
            exc.add_note(
                f"interrupted: {len(shards)} finished Monte Carlos kept in {shards.folder}; "
                "the same command with --resume continues from there"
            )
        raise
    return tables


def _config(
    scenarios: list[Scenario],
    jobs: dict[str, dict[str, StrategyLike]],
    regressors: dict[str, Regressor],
    settings: dict[str, int | float],
    retrain: bool,
) -> dict[str, object]:
    """The result folder's ``config.json``: what was run, with what."""
    return {
        "n_runs": settings["n_runs"],
        "seed": settings["seed"],
        "tuning_period_s": settings["tuning_period"],
        "weights": "retrained" if retrain else "shipped",
        "scenarios": {
            sc.name: {
                "trajectory": "paper",
                "filter": repr(sc.config),
                "sensors": repr(sc.sensors),
                "q_nominal": list(sc.q_nominal),
                "schedule_time_s": sc.schedule_time,
                "schedule_q": sc.schedule_q,
                "schedule_seed": sc.schedule_seed,
                "strategies": {k: repr(v) for k, v in jobs[sc.name].items()},
            }
            for sc in scenarios
        },
        "models": {k: getattr(m, "card", {}).get("test") for k, m in regressors.items()},
    }


def _figures(
    folder: Path,
    ds: Dataset | None,
    regressors: dict[str, Regressor],
    scenarios: list[Scenario],
    tables: dict[str, list[Row]],
    trained_dir: Path | None,
) -> None:
    """The figures of the result folder (and the retrained models, if any)."""
    from pronet import plots

    if ds is None:
        ds = build_dataset(DatasetParams())
    test = ~ds.train
    plots.predicted_vs_true(
        {
            LEARNED_LABELS[k]: (ds.q[test], m.predict(ds.windows[test]))
            for k, m in regressors.items()
        },
        folder / "predicted_vs_true_q.png",
    )
    titled = {table_title(name, rows): rows for name, rows in tables.items()}
    plots.metrics_with_ci(titled, folder / "srmse_smae.png")
    plots.trajectory(scenarios[0].trajectory, folder / "trajectory.png", "paper trajectory")
    for sc, (title, rows) in zip(scenarios, titled.items(), strict=True):
        plots.velocity_error(rows, folder / f"velocity_error_{sc.name}.png", title)
        plots.q_tracking(rows, sc.schedule_time, sc.schedule_q, folder / f"q_{sc.name}.png", title)
    if trained_dir is not None:
        shutil.copytree(trained_dir, folder / "models")
