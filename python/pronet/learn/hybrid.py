"""The ProNet hybrid loop: a regressor sets the process noise of running filters.

The Monte Carlo runs live in Rust, stepped in lockstep by a :class:`pronet.Ensemble`
(GIL released, threads across runs). At every tuning instant the loop

1. takes the last ``window`` raw IMU samples of every run, float32 ``(n_runs, 6, N)``;
2. runs the regressor once on the whole batch (``regressor.predict``; for the shipped
   CNNs the loop calls their forward pass frozen in pronet's core, in float32
   (:data:`LOOP_PRECISION`), see :func:`for_loop`);
3. applies the guardrails and hands q ``(n_runs, 6)`` back to Rust, where it becomes
   each run's IMU white-noise PSD ``q·Δt_imu`` in Q^c.

Until ``window`` samples exist, every run uses ``prior_q``.

Tuning period: 1 s by default. It matches the DVL rate, so every update interval runs
on a fresh estimate, and with the 2 s window consecutive estimates overlap by half:
a noise change shows fully in the estimate within 2 s. A shorter period costs more
inference calls (328 per 330 s mission at 1 s: the first comes once the 2 s window is
full) without new information per call.

Precision: the loop runs a CNN's blocks in float32 (:data:`LOOP_PRECISION`), ~1.7×
as fast as float64 and within 1e-5 relative of its q (the window is still
prepared in float64; :mod:`pronet.learn.frozen`), far below a regressor's own error;
``predict(native=True)`` and :class:`pronet.learn.frozen.FrozenNet` keep float64, the
torch model's function, by default.

Guardrails: predictions are clipped to ``[q_min, q_max]`` (default 1e-9 to 1 per-sample
variance, (m/s²)² or (rad/s)²: far outside any IMU this toolkit simulates on both ends,
so a sane prediction is never changed, while a negative, zero or absurd one cannot
reach the filter). A non-finite prediction keeps that channel's previous q. Both events
are counted per run and reported.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet import _core
from pronet._util.validate import check_type, float_array, real_array, scalar
from pronet.learn.frozen import FrozenNet, Precision
from pronet.montecarlo import DEFAULT_TUNING_PERIOD, DEFAULT_WINDOW, Ensemble, MonteCarloResult

if TYPE_CHECKING:  # torch loads only when a model does
    from pronet.learn.models import Regressor

#: The precision the loops run a CNN frozen in the core in (see the module docstring).
LOOP_PRECISION: Precision = "float32"


@dataclass(frozen=True)
class Guardrails:
    """Bounds on a regressor's q [(unit)² per sample]; see the module docstring."""

    q_min: float = 1e-9
    q_max: float = 1.0

    def __post_init__(self) -> None:
        lo, hi = scalar(self.q_min, "q_min"), scalar(self.q_max, "q_max")
        if not (0 < lo < hi < np.inf):
            raise ValueError(f"q_min, q_max: need 0 < q_min < q_max < inf, got {lo}, {hi}")


@dataclass(frozen=True)
class HybridResult:
    """A hybrid Monte Carlo: the usual metrics plus what the loop did.

    Attributes:
        result: the Monte Carlo metrics (as :func:`pronet.monte_carlo` returns them).
        n_tunings: tuning instants (regressor calls).
        clipped: ``(n_runs,)`` predictions clipped into the guardrail range.
        non_finite: ``(n_runs,)`` non-finite predictions replaced by the previous q.
        rust_seconds: wall time stepping the filters (inside the native core).
        model_seconds: wall time in ``regressor.predict``.
    """

    result: MonteCarloResult
    n_tunings: int
    clipped: NDArray[np.int64]
    non_finite: NDArray[np.int64]
    rust_seconds: float
    model_seconds: float
    guardrails: Guardrails = field(default_factory=Guardrails)

    @classmethod
    def concat(cls, parts: Sequence[HybridResult]) -> HybridResult:
        """Shards of one hybrid Monte Carlo (in run order) as one result: runs and
        guardrail counts joined, wall times summed."""
        if not parts:
            raise ValueError("parts: need at least one shard")
        return cls(
            result=MonteCarloResult.concat([p.result for p in parts]),
            n_tunings=parts[0].n_tunings,
            clipped=np.concatenate([p.clipped for p in parts]),
            non_finite=np.concatenate([p.non_finite for p in parts]),
            rust_seconds=sum(p.rust_seconds for p in parts),
            model_seconds=sum(p.model_seconds for p in parts),
            guardrails=parts[0].guardrails,
        )


def run_hybrid(
    regressor: Regressor,
    trajectory: _core.Trajectory,
    *,
    prior_q: ArrayLike,
    sensors: _core.SensorConfig | None = None,
    config: _core.FilterConfig | None = None,
    n_runs: int = 100,
    seed: int = 0,
    window: int = DEFAULT_WINDOW,
    tuning_period: float = DEFAULT_TUNING_PERIOD,
    guardrails: Guardrails | None = None,
    record_every: int = 0,
    sample_initial_error: bool = True,
    threads: int | None = None,
    first_run: int = 0,
    smooth: bool = False,
) -> HybridResult:
    """Monte Carlo with the process noise set by ``regressor`` while the filters run.

    Args:
        regressor: anything with ``predict(windows (n_runs, 6, window)) -> (n_runs, 6)``.
        trajectory: truth and ideal IMU.
        prior_q: 6 per-sample IMU variances used until the first prediction.
        sensors: as for :func:`pronet.monte_carlo` (default: the paper's).
        config: as for :func:`pronet.monte_carlo` (default: the paper's).
        n_runs: the Monte Carlo's runs.
        seed: the Monte Carlo's seed; run i sees the same noise as run i of any other
            strategy with this seed (common random numbers).
        window: IMU samples per window.
        tuning_period: seconds between predictions.
        guardrails: clip range for predictions (default :class:`Guardrails`).
        record_every: keep error, 1σ and q histories every this many IMU steps.
        sample_initial_error: as for :func:`pronet.monte_carlo`.
        threads: as for :func:`pronet.monte_carlo`.
        first_run: as for :func:`pronet.monte_carlo` (a shard of runs
            ``first_run .. first_run + n_runs`` sees their noise).
        smooth: also the RTS smoother over every run, as for :func:`pronet.monte_carlo`
            (the result's ``smoothed``).
    """
    if not callable(getattr(regressor, "predict", None)):
        raise ValueError(
            f"regressor: needs a predict(windows) method, got {type(regressor).__name__}"
        )
    check_type(trajectory, _core.Trajectory, "trajectory")
    prior = float_array(prior_q, "prior_q", (6,))
    guardrails = Guardrails() if guardrails is None else guardrails
    check_type(guardrails, Guardrails, "guardrails")
    # The Ensemble checks the counts, the seed, the window (1 to the trajectory's length),
    # the tuning period and the thread count, naming each.
    ens = Ensemble(
        trajectory,
        prior,
        sensors=sensors,
        config=config,
        n_runs=n_runs,
        seed=seed,
        window=window,
        tuning_period=tuning_period,
        record_every=record_every,
        sample_initial_error=sample_initial_error,
        threads=threads,
        first_run=first_run,
        smooth=smooth,
    )
    return _drive(ens, for_loop(regressor, threads), prior, guardrails)


def for_loop(
    regressor: Regressor, threads: int | None = None, precision: Precision = LOOP_PRECISION
) -> Regressor:
    """What a loop calls many times: ``regressor.frozen(threads)`` where the regressor
    offers it (the shipped models: their prediction in pronet's core, on ``threads``
    worker threads, no torch threads competing with the filters), a CNN's in
    ``precision`` (:data:`LOOP_PRECISION` by default), else ``regressor``."""
    if isinstance(regressor, FrozenNet):
        return regressor.frozen(threads, precision)
    frozen = getattr(regressor, "frozen", None)
    if not callable(frozen):
        return regressor
    try:
        loop = frozen(threads)
    except NotImplementedError:  # e.g. a subclass of a shipped net with its own forward
        return regressor
    if isinstance(loop, FrozenNet):  # a torch net frozen in float64: in `precision`
        loop = loop.frozen(threads, precision)
    return cast("Regressor", loop)


def _drive(
    ens: Ensemble, regressor: Regressor, prior: NDArray[np.float64], guardrails: Guardrails
) -> HybridResult:
    """Step ``ens`` to the end, setting the guarded predictions of ``regressor`` as its
    q at every tuning instant; the wall time inside the core and the model is kept."""
    n_runs = ens.n_runs
    q_prev = np.tile(prior, (n_runs, 1))
    clipped = np.zeros(n_runs, dtype=np.int64)
    non_finite = np.zeros(n_runs, dtype=np.int64)
    rust = model = 0.0
    n_tunings = 0
    while True:
        t0 = time.perf_counter()
        windows = ens.advance()
        t1 = time.perf_counter()
        rust += t1 - t0
        if windows is None:
            break
        q = _predictions(regressor, windows)
        model += time.perf_counter() - t1
        if q.shape != (n_runs, 6):
            raise ValueError(
                f"regressor: predict returned shape {q.shape} for windows {windows.shape}; "
                f"expected ({n_runs}, 6)"
            )
        q, n_bad, n_clip = apply_guardrails(q, q_prev, guardrails)
        non_finite += n_bad
        clipped += n_clip
        t2 = time.perf_counter()
        ens.set_q(q)
        rust += time.perf_counter() - t2
        q_prev = q
        n_tunings += 1
    t3 = time.perf_counter()
    result = ens.finish()
    rust += time.perf_counter() - t3
    return HybridResult(
        result=result,
        n_tunings=n_tunings,
        clipped=clipped,
        non_finite=non_finite,
        rust_seconds=rust,
        model_seconds=model,
        guardrails=guardrails,
    )


def _predictions(regressor: Regressor, windows: NDArray[np.float32]) -> NDArray[np.float64]:
    """``regressor.predict(windows)`` as float64; real numbers only (no complex parts
    dropped, no strings parsed), else ``ValueError`` naming the regressor."""
    return real_array(regressor.predict(windows), "regressor").astype(np.float64)


def apply_guardrails(
    q: NDArray[np.float64], q_prev: NDArray[np.float64], guardrails: Guardrails
) -> tuple[NDArray[np.float64], NDArray[np.int64], NDArray[np.int64]]:
    """``(q, non_finite, clipped)``: non-finite entries replaced by ``q_prev``, then
    everything clipped into range; the counts are per row."""
    bad = ~np.isfinite(q)
    q = np.where(bad, q_prev, q)
    out_of_range = (q < guardrails.q_min) | (q > guardrails.q_max)
    q = np.clip(q, guardrails.q_min, guardrails.q_max)
    return q, bad.sum(axis=1), out_of_range.sum(axis=1)


class ConstantRegressor:
    """Predicts the same q for every window: the boundary check and a user template."""

    def __init__(self, q: Sequence[float]) -> None:
        self.q = float_array(q, "q", (6,))

    def predict(self, windows: ArrayLike) -> NDArray[np.float64]:
        w = np.asarray(windows)
        return np.broadcast_to(self.q, (*w.shape[:-2], 6)).copy()


@dataclass(frozen=True)
class QSchedule:
    """A regressor's q over a recorded IMU stream (the hybrid loop on recorded data).

    Attributes:
        time: ``(k,)`` tuning instants [s]: the time of the newest sample of each window.
        q: ``(k, 6)`` guarded per-sample variances, in force from ``time`` on.
        clipped, non_finite: guardrail events over the whole stream.
        model_seconds: wall time in ``regressor.predict``.
    """

    time: NDArray[np.float64]
    q: NDArray[np.float64]
    clipped: int
    non_finite: int
    model_seconds: float


def q_schedule(
    regressor: Regressor,
    imu: ArrayLike,
    imu_time: ArrayLike,
    *,
    prior_q: ArrayLike,
    window: int = DEFAULT_WINDOW,
    tuning_period: float = DEFAULT_TUNING_PERIOD,
    guardrails: Guardrails | None = None,
) -> QSchedule:
    """Run ``regressor`` over a recorded IMU stream at the hybrid loop's tuning instants.

    The windows the loop reads are raw IMU samples, which do not depend on the filter,
    so on recorded data the whole schedule is computed first, in one batched call, and
    handed to :func:`pronet.run_filter` (``q_time``, ``q``). Instants are every
    ``round(tuning_period / Δt)`` samples (halves round away from zero; a period of no
    step is refused) once ``window`` samples exist, exactly as :class:`pronet.Ensemble`
    places them (Δt: the median sample step): both take them from
    ``_core.tuning_instants``.

    Args:
        regressor: anything with ``predict(windows (k, 6, window)) -> (k, 6)``.
        imu: ``(n, 6)`` the samples the filter will run on, ``[f (m/s²), ω (rad/s)]``.
        imu_time: ``(n,)`` their times [s].
        prior_q: 6 variances standing in for a non-finite first prediction.
        window: as for :func:`run_hybrid`.
        tuning_period: as for :func:`run_hybrid`.
        guardrails: as for :func:`run_hybrid`.
    """
    if not callable(getattr(regressor, "predict", None)):
        raise ValueError(
            f"regressor: needs a predict(windows) method, got {type(regressor).__name__}"
        )
    samples = float_array(imu, "imu", (None, 6))
    times = float_array(imu_time, "imu_time", (len(samples),))
    prior = float_array(prior_q, "prior_q", (6,))
    guardrails = Guardrails() if guardrails is None else guardrails
    check_type(guardrails, Guardrails, "guardrails")
    if len(samples) < 2:
        raise ValueError(f"imu: needs at least two samples, got {len(samples)}")
    steps = np.diff(times)
    if not (np.isfinite(times).all() and (steps > 0).all()):
        raise ValueError("imu_time: must be finite and strictly increasing")
    if not (np.isfinite(prior).all() and (prior >= 0).all()):
        raise ValueError(f"prior_q: must be finite and >= 0, got {prior}")
    # The instants come from the native core, the same rule the Ensemble stops at; it
    # checks window and tuning_period, naming each. Samples before each instant:
    ends = _core.tuning_instants(len(samples), float(np.median(steps)), window, tuning_period)
    window = int(window)
    if ends.size == 0:
        empty = np.zeros((0, 6))
        return QSchedule(np.zeros(0), empty, 0, 0, 0.0)
    strided = np.lib.stride_tricks.sliding_window_view(samples.astype(np.float32), window, 0)
    windows = np.ascontiguousarray(strided[ends - window])  # (k, 6, window), oldest first
    t0 = time.perf_counter()
    q = _predictions(for_loop(regressor), windows)
    seconds = time.perf_counter() - t0
    if q.shape != (ends.size, 6):
        raise ValueError(
            f"regressor: predict returned shape {q.shape} for windows {windows.shape}; "
            f"expected ({ends.size}, 6)"
        )
    guarded, non_finite, clipped = guard_schedule(q, prior, guardrails)
    return QSchedule(times[ends - 1], guarded, clipped, non_finite, seconds)


def guard_schedule(
    q: NDArray[np.float64], prior: NDArray[np.float64], guardrails: Guardrails
) -> tuple[NDArray[np.float64], int, int]:
    """``(guarded, non_finite, clipped)``: :func:`apply_guardrails` instant after instant
    down the rows of ``q`` ``(k, 6)``, each row's ``q_prev`` the previous guarded row
    (``prior`` before the first), in whole-array operations: a non-finite entry takes
    the channel's last guarded value, every other is clipped. The counts are over the
    whole schedule; a filled entry counts as clipped only where it is the first row's
    and ``prior`` is out of range (later ones take an in-range value)."""
    lo, hi = guardrails.q_min, guardrails.q_max
    bad = ~np.isfinite(q)
    with np.errstate(invalid="ignore"):
        out_of_range = ((q < lo) | (q > hi)) & ~bad  # ±inf is non-finite, not clipped
    rows = np.arange(1, len(q) + 1)[:, None]
    last_good = np.maximum.accumulate(np.where(bad, 0, rows), axis=0)  # 0: none yet
    values = np.vstack([np.clip(prior, lo, hi)[None, :], np.clip(q, lo, hi)])
    guarded = np.take_along_axis(values, last_good, axis=0)
    prior_out = (prior < lo) | (prior > hi)
    clipped = int(out_of_range.sum()) + int(np.sum(bad[:1] & prior_out))
    return guarded, int(bad.sum()), clipped
