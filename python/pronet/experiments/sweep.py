"""Sweeps: a grid of Monte Carlos (scenario × strategy × noise level × tuning period ×
runs), run as shards on this machine or on a Ray cluster, merged into one result.

A shard is one native Monte Carlo call: runs ``first_run .. first_run + n`` of one grid
point. By the seed scheme (:mod:`pronet.montecarlo`) a run's numbers depend only on the
seed and its index, so the shards of a grid point joined in run order equal the whole
Monte Carlo, and where a shard ran (which process, which machine, how many threads)
changes nothing: the Ray engine gives exactly the local engine's numbers. Learned
strategies run their model frozen in the core, as ``pronet simulate`` does (no torch).

Every grid point with the same scenario and noise level sees the same noise
realizations (common random numbers), so strategies are compared on paired runs. The
tuning period only applies to learned strategies; the others appear once per noise
level, with ``tuning_period`` None.

Ray: ``engine="ray"`` with ``address=None`` starts a private Ray on this machine (one
CPU per shard by default); ``address="auto"`` or ``"ray://HEAD:10001"`` joins a running
cluster, whose every node must have the same version of pronet installed (and any model
file a learned strategy names, at the same path). A shard whose worker process or node
dies is run again (up to :data:`RAY_RETRIES` times; it gives the same numbers); an
error the shard itself raises ends the sweep, naming the shard.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import hashlib
import os
from collections.abc import Callable, Generator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pronet
from pronet import _core
from pronet._util.files import atomic_folder, json_bytes
from pronet._util.validate import threads as threads_arg
from pronet.config import ScenarioSource, SweepGrid, sensor_kwargs
from pronet.learn.hybrid import HybridResult
from pronet.montecarlo import MonteCarloResult
from pronet.results import (
    CONSISTENCY_HEADER,
    SUMMARY_COLUMNS,
    consistency_cells,
    markdown,
    results_dataframe,
    summary_row,
    write_tables,
)
from pronet.run import check_acts as check_acts_on
from pronet.run import run
from pronet.shards import ShardStore
from pronet.sim.scenarios import Scenario
from pronet.stats import MeanCI
from pronet.strategies import StrategySpec, check_distinct, strategy

if TYPE_CHECKING:
    import pandas as pd

    from pronet.learn.models import Regressor

#: Engines :func:`run_sweep` knows.
ENGINES = ("local", "ray")
#: How often Ray reruns a shard whose worker process or node died. Shards are
#: deterministic, so a rerun gives the numbers the lost one would have; a Python error
#: raised by the shard is not retried.
RAY_RETRIES = 3


@dataclass(frozen=True)
class GridPoint:
    """One cell of the grid.

    Attributes:
        scenario: scenario name.
        strategy: strategy spec text (``constant``, ``mehra:5``, ``learned:detrend`` ...).
        noise_level: factor on the scenario's true IMU noise variance.
        tuning_period: seconds between regressor calls; None for non-learned strategies.
    """

    scenario: str
    strategy: str
    noise_level: float
    tuning_period: float | None

    @property
    def key(self) -> str:
        """A readable name, unique for every point (shard files, messages): the numbers
        in full, so that close values never share a name."""
        tp = "" if self.tuning_period is None else f", tuning {self.tuning_period!r} s"
        return f"{self.scenario}: {self.strategy}, noise x{self.noise_level!r}{tp}"


@dataclass(frozen=True)
class Shard:
    """Runs ``first_run .. first_run + n_runs`` of one grid point: plain data, so it can
    be sent to another process or machine and run there by :func:`run_shard`."""

    point: GridPoint
    source: ScenarioSource
    spec: StrategySpec
    first_run: int
    n_runs: int
    seed: int

    @property
    def label(self) -> str:
        return f"runs {self.first_run}-{self.first_run + self.n_runs - 1}"


def check_size(grid: SweepGrid) -> None:
    """``ValueError`` naming the grid when its merged results would exceed the core's
    memory limit for one Monte Carlo (:func:`pronet._core.check_result_size`): every
    grid point of a scenario holds ``runs`` runs of it until the sweep is written.
    Checked before any shard is planned, so a huge grid never builds its shard list."""
    per_scenario = len(grid.noise_levels) * sum(
        len(grid.tuning_periods) if spec.uses_tuning_period else 1 for spec in grid.strategies
    )
    for source in grid.scenarios:
        sc = _scenario(source, grid.seed)
        try:
            _core.check_result_size(sc.trajectory, sc.sensors, n_runs=per_scenario * grid.runs)
        except ValueError as exc:
            raise ValueError(
                f"grid: {per_scenario} grid points x {grid.runs} runs of {source.name}: {exc}"
            ) from None


def check_acts(grid: SweepGrid) -> None:
    """``ValueError`` naming the scenario, strategy and tuning period when a strategy
    could never act on a scenario of ``grid`` (:func:`pronet.run.check_acts`: a tuning
    period that leaves no tuning instant, a Mehra or adaptive window the run's DVL
    updates never fill), before any shard runs: a shard found it, after the sweep's
    ``<out>.partial`` was made."""
    for source in grid.scenarios:
        sc = _scenario(source, grid.seed)
        for spec in grid.strategies:
            regressor = _model(spec.model) if spec.kind == "learned" else None
            periods = grid.tuning_periods if spec.uses_tuning_period else (None,)
            for period in periods:
                chosen = strategy(spec, sc.q_nominal, 1.0 if period is None else period, regressor)
                try:
                    check_acts_on(chosen, sc)
                except ValueError as exc:
                    tp = "" if period is None else f", tuning {period!r} s"
                    raise ValueError(f"grid: {source.name}: {spec.text}{tp}: {exc}") from None


def check_levels(grid: SweepGrid) -> None:
    """``ValueError`` naming the scenario and noise level whose scaled IMU noise the
    core refuses (:func:`noisier`: past any IMU's full scale), before any shard runs."""
    for source in grid.scenarios:
        sc = _scenario(source, grid.seed)
        for level in grid.noise_levels:
            try:
                noisier(sc.sensors, level)
            except ValueError as exc:
                raise ValueError(f"grid: {source.name}, noise x{level!r}: {exc}") from None


def plan(grid: SweepGrid) -> list[Shard]:
    """Every shard of ``grid``, grid point by grid point (scenario, noise level,
    strategy, tuning period), each point's shards in run order (after
    :func:`check_size`, :func:`check_levels` and :func:`check_acts`)."""
    check_size(grid)
    check_levels(grid)
    check_distinct(grid.strategies, "grid: strategies")
    check_acts(grid)
    shards = []
    for source in grid.scenarios:
        for level in grid.noise_levels:
            for spec in grid.strategies:
                periods: Sequence[float | None] = (
                    grid.tuning_periods if spec.uses_tuning_period else (None,)
                )
                for period in periods:
                    point = GridPoint(source.name, spec.text, level, period)
                    for first in range(0, grid.runs, grid.shard_runs):
                        n = min(grid.shard_runs, grid.runs - first)
                        shards.append(Shard(point, source, spec, first, n, grid.seed))
    # a SweepGrid made by hand may list a value twice; shards must never be merged twice
    pieces = [(s.point, s.first_run) for s in shards]
    points = {s.point for s in shards}
    if len(set(pieces)) != len(pieces) or len({p.key for p in points}) != len(points):
        raise ValueError("grid: two grid points are the same (a value listed twice?)")
    return shards


@functools.lru_cache(maxsize=8)
def _scenario(source: ScenarioSource, seed: int) -> Scenario:
    return source.build(seed)


@functools.lru_cache(maxsize=8)
def _model(name_or_path: str) -> Regressor:
    """A learned strategy's model, frozen in the core (no torch), as ``simulate`` runs it."""
    from pronet.learn.frozen import load_frozen

    return load_frozen(name_or_path)


def noisier(sensors: _core.SensorConfig, level: float) -> _core.SensorConfig:
    """``sensors`` with every IMU noise variance multiplied by ``level`` (the schedule,
    if any, keeps its times); everything else unchanged."""
    kwargs = sensor_kwargs(sensors)
    kwargs["imu_variance"] = kwargs["imu_variance"] * level
    return _core.SensorConfig(**kwargs)


def run_shard(
    shard: Shard, threads: int | None = None
) -> tuple[MonteCarloResult, HybridResult | None]:
    """Run one shard (in this process); ``threads`` for the native core (default: all
    cores). The scenario and learned models are built once per process; a learned
    strategy runs its model frozen in the core, as ``pronet simulate`` does, so that a
    shard's numbers do not depend on the machine or the thread count."""
    p = shard.point
    base = _scenario(shard.source, shard.seed)
    scenario = dataclasses.replace(base, sensors=noisier(base.sensors, p.noise_level))
    regressor = _model(shard.spec.model) if shard.spec.kind == "learned" else None
    period = p.tuning_period if p.tuning_period is not None else 1.0
    chosen = strategy(shard.spec, scenario.q_nominal, period, regressor)
    done = run(
        chosen,
        scenario,
        n_runs=shard.n_runs,
        seed=shard.seed,
        threads=threads,
        first_run=shard.first_run,
    )
    return done.result, done.hybrid


ShardResult = tuple[MonteCarloResult, HybridResult | None]


def _local(
    shards: Sequence[Shard], threads: int | None
) -> Generator[tuple[Shard, ShardResult], None, None]:
    for shard in shards:
        yield shard, run_shard(shard, threads)


def check_engine(engine: str, address: str | None, threads: int | None) -> None:
    """``ValueError`` for an engine, address or thread count :func:`run_sweep` cannot
    use (Ray not installed included), before anything is started or saved."""
    if engine not in ENGINES:
        raise ValueError(f"engine: expected one of {', '.join(ENGINES)}, got {engine!r}")
    if address is not None and engine != "ray":
        raise ValueError("address: only the ray engine connects to a cluster")
    # ray: CPUs per shard on the cluster's machines, not threads on this one
    threads_arg(threads, "threads", per_core=engine != "ray")
    if engine == "ray":
        try:
            import ray  # noqa: F401
        except ImportError:
            raise ValueError(
                "engine: ray is not installed; pip install 'pronet[ray]' (or ray) first"
            ) from None


def _ray(
    shards: Sequence[Shard], address: str | None, cpus_per_shard: int
) -> Generator[tuple[Shard, ShardResult], None, None]:
    import ray

    started = not ray.is_initialized()
    if started:
        try:
            ray.init(
                address=address,
                include_dashboard=False,
                log_to_driver=False,
                configure_logging=False,
            )
        except (ConnectionError, RuntimeError, ValueError) as exc:
            where = "a private Ray" if address is None else f"Ray at {address!r}"
            raise ValueError(f"address: cannot start or join {where}: {exc}") from None
    pending: dict[Any, Shard] = {}
    try:
        remote = ray.remote(num_cpus=cpus_per_shard, max_retries=RAY_RETRIES)(run_shard)
        pending = {remote.remote(s, cpus_per_shard): s for s in shards}  # type: ignore[call-arg]
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            shard = pending.pop(done[0])
            try:
                result = ray.get(done[0])
            except ray.exceptions.RayError as exc:
                # the task's own exception (a RayTaskError's cause), not Ray's report of it
                cause = getattr(exc, "cause", None) or exc
                raise ValueError(f"shard {shard.point.key}, {shard.label}: {cause}") from None
            yield shard, result
    finally:
        for ref in pending:  # on a cluster they would run on after an error or Ctrl-C
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()


@dataclass(frozen=True)
class PointResult:
    """A grid point's merged Monte Carlo (``hybrid`` for learned strategies)."""

    point: GridPoint
    result: MonteCarloResult
    hybrid: HybridResult | None

    def summary(self) -> dict[str, MeanCI]:
        return self.result.summary()


@dataclass(frozen=True)
class SweepResult:
    """Every grid point's result, in :func:`plan` order."""

    grid: SweepGrid
    points: list[PointResult]

    def _labels(self, pr: PointResult) -> dict[str, object]:
        p = pr.point
        return {
            "scenario": p.scenario,
            "strategy": p.strategy,
            "noise_level": p.noise_level,
            "tuning_period_s": p.tuning_period,
        }

    def to_dataframe(self, per_run: bool = False) -> pd.DataFrame:
        """One row per grid point (:data:`pronet.results.SUMMARY_COLUMNS`: the grid
        columns, then mean and 95 % CI bounds of each per-run metric in m/s, m, the run
        counts and the learned loop's guardrail counts). With ``per_run``: one row per
        run (:data:`pronet.results.RUN_COLUMNS`)."""
        import pandas as pd

        if per_run:
            return results_dataframe(((self._labels(pr), pr.result) for pr in self.points), True)
        records = [summary_row(self._labels(pr), pr.result, hybrid=pr.hybrid) for pr in self.points]
        return pd.DataFrame(records, columns=list(SUMMARY_COLUMNS))

    def markdown(self) -> str:
        """The summary as a Markdown table, one block per scenario."""
        header = [
            "strategy",
            "noise level",
            "tuning period [s]",
            "SRMSE [m/s] (95 % CI)",
            "SMAE [m/s] (95 % CI)",
            "final horizontal error [m] (95 % CI)",
            *CONSISTENCY_HEADER,
            "failed / diverged runs",
        ]
        blocks = []
        for scenario in dict.fromkeys(p.point.scenario for p in self.points):
            lines = []
            for pr in self.points:
                p, s = pr.point, pr.summary()
                if p.scenario != scenario:
                    continue
                tp = "" if p.tuning_period is None else f"{p.tuning_period:g}"
                lines.append(
                    [p.strategy, f"{p.noise_level:g}", tp, s["srmse"], s["smae"]]
                    + [s["final_horizontal_error"], *consistency_cells(pr.result)]
                    + [f"{pr.result.n_failed} / {pr.result.n_diverged}"]
                )
            title = f"{scenario}: {self.grid.runs} runs per row, seed {self.grid.seed}"
            blocks.append(markdown(header, lines, title) + "\n")
        return "".join(blocks)


def settings(grid: SweepGrid) -> dict[str, Any]:
    """What a sweep's numbers depend on: the grid, the versions, the weights of every
    model it uses and the precision the loop runs a CNN in (a resumed sweep must match
    all of it)."""
    from pronet.learn import frozen, modelfile
    from pronet.learn.hybrid import LOOP_PRECISION

    weights = {}
    for spec in grid.strategies:
        if spec.kind == "learned":
            if spec.model in frozen.SHIPPED:
                weights["shipped"] = frozen.shipped_sha256()
            else:  # the card too: its kind and architecture choose the network
                h = hashlib.sha256()
                for file in modelfile.paths(spec.model):
                    h.update(file.read_bytes())
                weights[spec.model] = h.hexdigest()
    return {
        "grid": grid.as_dict(),
        "pronet": pronet.__version__,
        "native_core": _core.__version__,
        "weights": weights,
        "loop_precision": LOOP_PRECISION,
    }


def run_sweep(
    grid: SweepGrid,
    *,
    engine: str = "local",
    address: str | None = None,
    threads: int | None = None,
    store: ShardStore | None = None,
    on_shard: Callable[[Shard], None] | None = None,
) -> SweepResult:
    """Run every shard of ``grid`` and merge them.

    Args:
        grid: the sweep (see :func:`pronet.config.load_sweep`).
        engine: ``"local"`` (this process, shard after shard) or ``"ray"``.
        address: Ray only: a running cluster (``"auto"``, ``"ray://HEAD:10001"``);
            None starts a private Ray on this machine.
        threads: local: native threads per shard (default all cores). Ray: CPUs each
            shard asks for and uses (default 1).
        store: finished shards are saved there as they arrive, and shards already
            there are loaded instead of run (resume).
        on_shard: called after each shard, loaded or run (progress).
    """
    check_engine(engine, address, threads)
    shards = plan(grid)
    results: dict[tuple[GridPoint, int], ShardResult] = {}
    todo = []
    for shard in shards:
        saved = store.load(shard.point.key, shard.label) if store is not None else None
        if saved is None:
            todo.append(shard)
            continue
        results[(shard.point, shard.first_run)] = saved
        if on_shard is not None:
            on_shard(shard)
    if todo:  # nothing to run (a finished resume): no Ray to start
        ran = _local(todo, threads) if engine == "local" else _ray(todo, address, threads or 1)
        with contextlib.closing(ran):  # an error here still shuts Ray down
            for shard, result in ran:
                results[(shard.point, shard.first_run)] = result
                if store is not None:
                    store.save(shard.point.key, shard.label, *result)
                if on_shard is not None:
                    on_shard(shard)
    points = []
    for point in dict.fromkeys(s.point for s in shards):
        parts = [results[(s.point, s.first_run)] for s in shards if s.point == point]
        hybrids = [h for _, h in parts if h is not None]
        points.append(
            PointResult(
                point,
                MonteCarloResult.concat([r for r, _ in parts]),
                HybridResult.concat(hybrids) if hybrids else None,
            )
        )
    return SweepResult(grid, points)


def write_result_folder(
    folder: str | os.PathLike[str], result: SweepResult, config: dict[str, Any]
) -> Path:
    """Write the sweep's tables (:func:`pronet.results.write_tables`: ``table.md``,
    ``summary.csv``, ``metrics.json``, ``metrics.csv``), ``config.json`` and its
    figures into ``folder``, atomically (nothing appears until all of it is written)."""
    from pronet import plots

    folder = Path(folder)
    summary = result.to_dataframe()
    with atomic_folder(folder) as tmp:
        write_tables(tmp, summary, result.to_dataframe(per_run=True), result.markdown())
        (tmp / "config.json").write_bytes(json_bytes(config))
        plots.sweep_metric(summary, "noise_level", tmp / "srmse_vs_noise_level.png")
        if len(result.grid.tuning_periods) > 1 and summary["tuning_period_s"].notna().any():
            plots.sweep_metric(summary, "tuning_period_s", tmp / "srmse_vs_tuning_period.png")
    return folder
