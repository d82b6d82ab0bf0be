"""The one run path: any strategy on a simulated scenario or on recorded sensors.

Every command and experiment runs a strategy through :func:`run`; it is the only place
that tells a native strategy (constant, Mehra: the whole run in the Rust core) from a
learned one (:class:`~pronet.strategies.Learned`: the ProNet hybrid loop, the regressor
in Python every tuning period). :func:`run_strategies` runs several strategies on the
same noise realizations (common random numbers) so that their differences are paired.

- On a :class:`~pronet.sim.scenarios.Scenario`: a Monte Carlo of ``n_runs`` simulated runs
  (run i draws its noise from the streams of ``(seed, first_run + i)``), returned as a
  :class:`SimulatedRun`.
- On :class:`Recorded` sensors (one recorded stretch with its initial state): one filter
  pass, returned as a :class:`RecordedRun`. A learned strategy's q is computed from the
  raw IMU windows first (:func:`pronet.learn.hybrid.q_schedule`), then handed to the filter.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal, overload

import numpy as np
from numpy.typing import NDArray

from pronet import _core
from pronet._util.plausibility import unfilled_window
from pronet._util.validate import flag
from pronet.filter import FilterResult, Stream, accepted_updates, run_filter, sensor_names
from pronet.learn.hybrid import DEFAULT_WINDOW, HybridResult, QSchedule, q_schedule, run_hybrid
from pronet.montecarlo import MonteCarloResult, monte_carlo
from pronet.shards import ShardStore
from pronet.sim.scenarios import Scenario
from pronet.stats import NON_NEGATIVE, MeanCI, mean_ci
from pronet.strategies import Learned, StrategyLike

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Recorded:
    """One stretch of recorded sensors, ready to filter from a known initial state.

    Attributes:
        imu: ``(n, 6)`` raw IMU samples ``[f (m/s²), ω (rad/s)]``, body FRD.
        imu_time: ``(n,)`` sample end times [s], all after ``t0``.
        dvl: ``(m, 3)`` DVL body velocities [m/s] (empty: pure inertial).
        dvl_time: ``(m,)`` DVL times [s] on the IMU clock.
        t0: time of the initial state [s].
        lla0, vel0, rpy0: initial latitude, longitude [rad], height [m, up]; NED
            velocity [m/s]; roll, pitch, yaw [rad].
        config: the filter's tuning.
        epochs: which epochs the result keeps: ``"all"``, or ``"last"`` for a pass
            whose updates alone are read (see :func:`pronet.run_filter`).
        smooth: also the RTS smoother over the pass (``FilterResult.smoothed``).
        aiding: the streams applied after the DVL's, as :func:`pronet.run_filter`
            takes them (depth readings :class:`pronet.Depth`, position fixes
            :class:`pronet.Fix`, ...); empty for none.
    """

    imu: F64
    imu_time: F64
    dvl: F64
    dvl_time: F64
    t0: float
    lla0: F64
    vel0: F64
    rpy0: F64
    config: _core.FilterConfig
    epochs: Literal["all", "last"] = "all"
    smooth: bool = False
    aiding: tuple[Stream, ...] = ()

    def streams(self, *, aided: bool = True) -> list[Stream]:
        """The streams of a pass: the DVL (:class:`pronet.Dvl`, its noise, frame,
        lever arm and gate :attr:`config`'s), then with ``aided`` :attr:`aiding`."""
        return [_core.Dvl(self.dvl_time, self.dvl), *(self.aiding if aided else ())]

    def filter(
        self,
        strategy: _core.Strategy,
        q_time: F64 | None = None,
        q: F64 | None = None,
        *,
        aided: bool = True,
    ) -> FilterResult:
        """:func:`pronet.run_filter` over this stretch: its sensors, initial state,
        tuning, kept epochs and smoothing, with ``strategy`` (a native one; q from
        ``q_time`` [s] on, ``q (k, 6)``, for an external one) and the depth and fixes
        of ``aiding`` (``aided=False``: the DVL alone, as the torch filter sees it),
        each stream named in the pass's messages and health by its sensor (``"dvl"``,
        ``"depth"``, ``"fix"``, ``"heading"``: the names ``pronet real`` and ``pronet
        navigate`` give them; ``streams[i]`` where a kind repeats)."""
        streams = self.streams(aided=aided)
        return run_filter(
            self.imu,
            self.imu_time,
            streams,
            t0=self.t0,
            lla0=self.lla0,
            vel0=self.vel0,
            rpy0=self.rpy0,
            config=self.config,
            strategy=strategy,
            epochs=self.epochs,
            smooth=self.smooth,
            q_time=q_time,
            q=q,
            warn=False,  # its callers report the pass's health their own way
            names=sensor_names(streams),
        )


@dataclass(frozen=True)
class SimulatedRun:
    """A strategy's Monte Carlo on a scenario; ``hybrid`` holds the learned loop's
    record (tunings, guardrail events, timing), None for native strategies."""

    result: MonteCarloResult
    hybrid: HybridResult | None = None
    #: the learned loop's tuning period [s]; None for native strategies
    tuning_period: float | None = None


@dataclass(frozen=True)
class RecordedRun:
    """A strategy's filter pass over recorded sensors: the filter output, the learned
    q schedule and tuning period [s] (None for native strategies), the wall time
    [s], inference included, and, for a Mehra or adaptive strategy whose window the
    pass never filled, the line that says so
    (:func:`pronet._util.plausibility.unfilled_window`: the pass runs with
    ``warn=False``, its callers report it their own way)."""

    result: FilterResult
    schedule: QSchedule | None
    seconds: float
    tuning_period: float | None = None
    unfilled: str | None = None


@overload
def run(
    strategy: StrategyLike,
    target: Scenario,
    *,
    n_runs: int = ...,
    seed: int = ...,
    record_every: int = ...,
    first_run: int = ...,
    threads: int | None = ...,
    smooth: bool = ...,
) -> SimulatedRun: ...


@overload
def run(strategy: StrategyLike, target: Recorded) -> RecordedRun: ...


def run(
    strategy: StrategyLike,
    target: Scenario | Recorded,
    *,
    n_runs: int = 100,
    seed: int = 0,
    record_every: int = 0,
    first_run: int = 0,
    threads: int | None = None,
    smooth: bool = False,
) -> SimulatedRun | RecordedRun:
    """Run ``strategy`` on a simulated scenario or on recorded sensors.

    Args:
        strategy: a native :class:`pronet._core.Strategy` or a
            :class:`~pronet.strategies.Learned` regressor.
        target: a :class:`~pronet.sim.scenarios.Scenario` (Monte Carlo) or
            :class:`Recorded` sensors (one filter pass).
        n_runs: the Monte Carlo's runs on a scenario (see :func:`pronet.monte_carlo`);
            this and the next five are for a scenario only, a recorded run takes
            none of them (``run_filter(smooth=True)`` smooths one pass).
        seed: the Monte Carlo's seed.
        record_every: keep histories every this many IMU steps.
        first_run: the first run's index (a shard of runs).
        threads: worker threads.
        smooth: also the RTS smoother over every run.
    """
    smooth = flag(smooth, "smooth")
    if isinstance(target, Recorded):
        given = (n_runs, seed, record_every, first_run, threads, smooth)
        if given != (100, 0, 0, 0, None, False):
            raise ValueError(
                "run: n_runs, seed, record_every, first_run, threads and smooth are "
                "for simulated scenarios; a recorded run takes none of them"
            )
        return _recorded(strategy, target)
    if not isinstance(target, Scenario):
        raise ValueError(f"target: expected a Scenario or Recorded, got {type(target).__name__}")
    check_acts(strategy, target)
    if isinstance(strategy, Learned) and hasattr(strategy.regressor, "recorded_schedule"):
        raise ValueError(
            "strategy: this model reads the filter's velocity and runs on recorded data "
            "only (pronet real), not in the simulated hybrid loop"
        )
    common = dict(
        sensors=target.sensors,
        config=target.config,
        n_runs=n_runs,
        seed=seed,
        threads=threads,
        record_every=record_every,
        first_run=first_run,
        smooth=smooth,
    )
    if isinstance(strategy, Learned):
        h = run_hybrid(
            strategy.regressor,
            target.trajectory,
            prior_q=strategy.prior_q,
            tuning_period=strategy.tuning_period,
            **common,  # type: ignore[arg-type]
        )
        return SimulatedRun(h.result, h, strategy.tuning_period)
    return SimulatedRun(monte_carlo(target.trajectory, strategy, **common))  # type: ignore[arg-type]


def check_acts(strategy: StrategyLike, target: Scenario | Recorded, label: str = "") -> None:
    """``ValueError`` when ``strategy`` could never act on ``target``, so that its row
    would silently equal its prior q: a learned strategy whose tuning period leaves no
    tuning instant (the first needs a full window of ``DEFAULT_WINDOW`` samples), or a
    Mehra or adaptive window longer than the run's DVL updates (on a scenario: its
    duration over the DVL period, outages ignored). ``label`` prefixes the message."""
    if isinstance(target, Recorded):
        n_samples, n_updates = len(target.imu), len(target.dvl_time)
        dt = float(np.median(np.diff(target.imu_time))) if n_samples > 1 else 1.0
        if not (math.isfinite(dt) and dt > 0):
            return  # bad stamps: run_filter names them
    else:
        traj = target.trajectory
        n_samples, dt = traj.n_samples, traj.dt
        period = target.sensors.dvl_period  # 0: no DVL, no update
        n_updates = int(traj.duration / period + 1e-9) if period > 0 else 0
    where = f"{label}: " if label else ""
    span = f"the {n_samples * dt:g} s run"
    if isinstance(strategy, Learned):
        period = strategy.tuning_period
        if not len(_core.tuning_instants(n_samples, dt, DEFAULT_WINDOW, period)):
            raise ValueError(
                f"{where}tuning_period: {period:g} s leaves no tuning instant in {span} "
                f"(the first needs a full window of {DEFAULT_WINDOW} samples); the row "
                "would only ever use its prior q"
            )
    elif strategy.window is not None and strategy.window > n_updates:
        raise ValueError(
            f"{where}window: {strategy.kind} over {strategy.window} DVL updates never fills "
            f"in {span} ({n_updates} updates); the row would only ever use its prior q"
        )


def _recorded(strategy: StrategyLike, rec: Recorded) -> RecordedRun:
    check_acts(strategy, rec)
    start = time.perf_counter()
    schedule, period = None, None
    q_time: F64 | None = None
    q: F64 | None = None
    core_strategy, _ = native_of(strategy)
    if isinstance(strategy, Learned):
        period = strategy.tuning_period
        own = getattr(strategy.regressor, "recorded_schedule", None)
        if callable(own):  # a model that reads the filter's state (pronet.learn.akit)
            schedule = own(rec, strategy.prior_q)
        else:
            schedule = q_schedule(
                strategy.regressor,
                rec.imu,
                rec.imu_time,
                prior_q=strategy.prior_q,
                tuning_period=strategy.tuning_period,
            )
        if len(schedule.time):
            q_time, q = schedule.time, schedule.q
    result = rec.filter(core_strategy, q_time, q)
    kind, window = core_strategy.kind, core_strategy.window
    unfilled = unfilled_window(kind, window, accepted_updates(result.streams))
    return RecordedRun(result, schedule, time.perf_counter() - start, period, unfilled)


def native_of(strategy: StrategyLike) -> tuple[_core.Strategy, Learned | None]:
    """The native strategy a filter pass runs for ``strategy``: itself, or for a learned
    one the external strategy its regressor's q is set through (its prior until the
    first), with the :class:`Learned` (None for a native one)."""
    if isinstance(strategy, Learned):
        return _core.Strategy.external(strategy.prior_q), strategy
    return strategy, None


def _tuning_period(strategy: StrategyLike) -> float | None:
    return strategy.tuning_period if isinstance(strategy, Learned) else None


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
    #: the learned strategy's tuning period [s] (None for native strategies)
    tuning_period: float | None = None


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
    smooth: bool = False,
) -> list[Row]:
    """Run every strategy on the same noise realizations (same seed); the first strategy
    is the reference for the paired differences. With ``shards``, each finished strategy
    is saved there at once, and one already saved is loaded instead of rerun. With
    ``smooth``, each strategy's row is followed by its RTS-smoothed one (labelled
    ``"<label>, smoothed"``, paired against the first strategy's filter too); shards
    keep no smoothed result, so the two do not go together."""
    if flag(smooth, "smooth") and shards is not None:
        raise ValueError("smooth: saved shards keep no smoothed result; run without them")
    for label, strategy in strategies.items():  # all of them before any computing
        check_acts(strategy, scenario, label)
    results: dict[str, tuple[MonteCarloResult, HybridResult | None]] = {}
    periods: dict[str, float | None] = {}
    for label, strategy in strategies.items():
        saved = shards.load(scenario.name, label) if shards is not None else None
        periods[label] = _tuning_period(strategy)
        if saved is not None:
            results[label] = saved
        else:
            done = run(
                strategy,
                scenario,
                n_runs=n_runs,
                seed=seed,
                threads=threads,
                record_every=record_every,
                smooth=smooth,
            )
            results[label] = (done.result, done.hybrid)
            if shards is not None:
                shards.save(scenario.name, label, *results[label])
        if on_done is not None:
            on_done(label)
    ref = next(iter(results.values()))[0]

    def row(label: str, r: MonteCarloResult, h: HybridResult | None) -> Row:
        return Row(
            label=label,
            result=r,
            srmse=mean_ci(r.srmse, NON_NEGATIVE),
            smae=mean_ci(r.smae, NON_NEGATIVE),
            srmse_diff=mean_ci(r.srmse - ref.srmse),
            smae_diff=mean_ci(r.smae - ref.smae),
            hybrid=h,
            tuning_period=periods[label],
        )

    rows = []
    for label, (r, h) in results.items():
        rows.append(row(label, r, h))
        if r.smoothed is not None:
            smoothed = row(label, r.smoothed, h)
            rows.append(dataclasses.replace(smoothed, label=f"{label}, {SMOOTHED}"))
    return rows


#: The suffix of a smoothed row's label (``run_strategies(smooth=True)``).
SMOOTHED = "smoothed"
