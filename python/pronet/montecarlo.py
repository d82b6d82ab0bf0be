"""Monte Carlo runs of a simulated scenario with one process-noise strategy.

Seed scheme: run i of a Monte Carlo with seed s draws all its noise (IMU, DVL and the
initial error) from its own ChaCha8 streams keyed by (s, i). So results are bit-identical
whatever the thread count, a run's numbers do not depend on the other runs, a Monte Carlo
split into shards (``first_run``) equals the same runs computed whole, and every
strategy run with the same seed sees the same noise realizations (common random
numbers): differences between strategies are paired.

:class:`Ensemble` steps the same runs in lockstep for a q estimator of your own: it takes
the arguments of :func:`monte_carlo` (an initial q in place of the strategy, and the
window and tuning period of the loop), and its :meth:`~Ensemble.finish` returns the same
:class:`MonteCarloResult`. The runs live in the native core (:class:`pronet._core.Ensemble`).

How many runs may leave their NIS band by chance before a strategy is named
(:func:`runs_outside_band`, :func:`chance_bound`, :func:`runs_flag`).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, fields, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import special

from pronet import _core
from pronet._util.validate import check_type, flag, float_array
from pronet.stats import NON_NEGATIVE, SHARE, MeanCI, chi2_mean_band, mean_ci

#: Run indices stay below 2^62: run i's random streams are numbered 4·i + k
#: (``montecarlo::MAX_RUN_INDEX`` in Rust).
MAX_RUN_INDEX = _core.MAX_RUN_INDEX

#: Names of the five 3-blocks of the error state, in order: NED position [m], NED
#: velocity [m/s], attitude (the small rotation ψ [rad] of docs/reference/filter.md),
#: accelerometer bias [m/s²] and gyro bias [rad/s] (:meth:`MonteCarloResult.block_nees`,
#: :meth:`MonteCarloResult.mean_nees`, :meth:`MonteCarloResult.nees_in_band`).
STATE_BLOCKS = ("position", "velocity", "attitude", "accel_bias", "gyro_bias")

#: A result whose block NEES lies inside its 95 % band at fewer than this share of the
#: DVL epochs is flagged in the tables (:meth:`MonteCarloResult.nees_in_band`; a
#: consistent filter's share is 95 %).
IN_BAND_FLAG = 0.9

#: The χ² (3 dof) quantile of probability 0.9973 (a Gaussian's ±3σ share): a consistent
#: filter's 3-dof NEES lies below it at 99.73 % of epochs.
CHI2_3DOF_3SIGMA = 14.1563


@dataclass(frozen=True)
class MonteCarloResult:
    """Per-run metrics and per-epoch consistency statistics.

    Attributes:
        srmse: ``(n_runs,)`` velocity SRMSE ``sqrt(mean_k Σ_NED δv²)`` [m/s].
        smae: ``(n_runs,)`` velocity SMAE ``mean_k Σ_NED |δv|`` [m/s].
        final_horizontal_error: ``(n_runs,)`` horizontal position error at the end [m].
        max_horizontal_error: ``(n_runs,)`` largest horizontal position error [m].
        mean_nis: ``(n_runs,)`` mean NIS over the applied DVL updates (NaN for a run
            with none: undefined, not 0).
        rejected_updates: ``(n_runs,)`` DVL updates the innovation gate rejected
            (``FilterConfig(innovation_gate=...)``; 0 without a gate).
        diverged_at: ``(n_runs,)`` time [s] at which the NIS showed divergence (its mean
            over the last 20 updates above 25), NaN where it never did.
        failure: per run, None or the message of the numerical failure that stopped it
            (its metrics are then NaN).
        dvl_time: ``(m,)`` DVL epoch times [s].
        nis: ``(n_runs, m)`` NIS at each DVL epoch (3 dof), gate-rejected ones included.
        nees: ``(n_runs, m, 5)`` NEES after each update of the blocks in
            :data:`STATE_BLOCKS` (3 dof each).
        record_time: ``(r,)`` history epochs [s] (empty without ``record_every``).
        error: ``(n_runs, r, 15)`` true error ``[δp (NED m), δv (m/s), ψ (rad), δb_a, δb_g]``.
        sigma: ``(n_runs, r, 15)`` filter 1σ of the same.
        q: ``(n_runs, r, 6)`` IMU variances the strategy used (NaN where it has none).
        calibration_error: with ``FilterConfig(dvl_calibration=True)``, ``(n_runs, 4)``
            the final error of the DVL calibration states ``[δk, δμ_x, δμ_y, δμ_z]``
            (estimate minus the simulated DVL's; scale, rad about the body axes);
            None without the states.
        calibration_sigma: ``(n_runs, 4)`` the filter's final 1σ of the same.
        calibration_nees: ``(n_runs, m)`` NEES of the four calibration states after
            each update (4 dof).
        missed_updates: ``(n_runs,)`` DVL readings that were due but missing (the
            sensors' ``dvl_dropout``: bottom lock lost; on a recorded section the rows
            skipped as missing readings); their NIS and NEES are NaN. 0 without.
        depth_updates: ``(n_runs,)`` depth readings applied (the sensors'
            ``depth_sigma``); 0 without a depth sensor.
        fix_updates: ``(n_runs,)`` position fixes applied (the sensors' ``fixes``).
        mean_aiding_nis: ``(n_runs,)`` the mean NIS per degree of freedom over the depth,
            fix and heading updates (1 when the filter is consistent with their σ); NaN
            without any, or for a failed run.
        smoothed: with ``smooth=True``, the same result for the RTS-smoothed solution
            of every run: its ``srmse``, ``smae``, horizontal errors, ``nees`` (at the
            same DVL epochs) and ``error``/``sigma`` histories; the NIS, failures,
            divergence and missed updates are the filter's, ``q`` None. Else None.
    """

    srmse: NDArray[np.float64]
    smae: NDArray[np.float64]
    final_horizontal_error: NDArray[np.float64]
    max_horizontal_error: NDArray[np.float64]
    mean_nis: NDArray[np.float64]
    rejected_updates: NDArray[np.int64]
    diverged_at: NDArray[np.float64]
    failure: list[str | None]
    dvl_time: NDArray[np.float64]
    nis: NDArray[np.float64]
    nees: NDArray[np.float64]
    record_time: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    error: NDArray[np.float64] | None = None
    sigma: NDArray[np.float64] | None = None
    q: NDArray[np.float64] | None = None
    calibration_error: NDArray[np.float64] | None = None
    calibration_sigma: NDArray[np.float64] | None = None
    calibration_nees: NDArray[np.float64] | None = None
    missed_updates: NDArray[np.int64] | None = None
    depth_updates: NDArray[np.int64] | None = None
    fix_updates: NDArray[np.int64] | None = None
    mean_aiding_nis: NDArray[np.float64] | None = None
    smoothed: MonteCarloResult | None = None

    def __post_init__(self) -> None:
        n = len(self.srmse)
        # results made before these existed: no missed readings, no aiding sensors
        for name in ("missed_updates", "depth_updates", "fix_updates"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, np.zeros(n, np.int64))
        if self.mean_aiding_nis is None:
            object.__setattr__(self, "mean_aiding_nis", np.full(n, np.nan))

    @property
    def n_runs(self) -> int:
        return int(self.srmse.shape[0])

    @property
    def n_failed(self) -> int:
        return sum(f is not None for f in self.failure)

    @property
    def finished(self) -> NDArray[np.bool_]:
        """``(n_runs,)`` whether each run ran to its end (no numerical failure)."""
        return np.array([f is None for f in self.failure], dtype=bool)

    @property
    def n_diverged(self) -> int:
        """Runs whose NIS showed divergence (see ``diverged_at``)."""
        return int(np.isfinite(self.diverged_at).sum())

    def block_nees(self, block: str) -> NDArray[np.float64]:
        """``(n_runs, m)`` the NEES of one block of :data:`STATE_BLOCKS` at each DVL
        epoch (3 dof; in the coordinates of ``docs/reference/filter.md``, "Metrics")."""
        if block not in STATE_BLOCKS:
            raise ValueError(f"block: expected one of {list(STATE_BLOCKS)}, got {block!r}")
        if self.nees.ndim != 3:
            return np.empty((self.n_runs, 0))
        return self.nees[:, :, STATE_BLOCKS.index(block)]

    def mean_nees(self, block: str) -> NDArray[np.float64]:
        """``(n_runs,)`` each run's mean NEES of one block of :data:`STATE_BLOCKS` over
        the DVL epochs (3 dof: 3 when consistent, above 3 overconfident; NaN for a failed
        run or one without epochs). The properties ``position_nees`` ...
        ``gyro_bias_nees`` are this for each block."""
        return self._unless_failed(_row_mean(self.block_nees(block)))

    def _unless_failed(self, per_run: NDArray[np.float64]) -> NDArray[np.float64]:
        """``per_run`` with NaN for the failed runs: the core keeps the epochs a run
        had before its failure, which are no run's metric (they counted as one)."""
        finished = self.finished
        return per_run if finished.all() else np.where(finished, per_run, np.nan)

    @property
    def position_nees(self) -> NDArray[np.float64]:
        """``(n_runs,)`` mean NED position NEES (:meth:`mean_nees`)."""
        return self.mean_nees("position")

    @property
    def velocity_nees(self) -> NDArray[np.float64]:
        """``(n_runs,)`` mean NED velocity NEES (:meth:`mean_nees`)."""
        return self.mean_nees("velocity")

    @property
    def attitude_nees(self) -> NDArray[np.float64]:
        """``(n_runs,)`` mean attitude (roll, pitch, heading) NEES (:meth:`mean_nees`)."""
        return self.mean_nees("attitude")

    @property
    def accel_bias_nees(self) -> NDArray[np.float64]:
        """``(n_runs,)`` mean accelerometer-bias NEES (:meth:`mean_nees`)."""
        return self.mean_nees("accel_bias")

    @property
    def gyro_bias_nees(self) -> NDArray[np.float64]:
        """``(n_runs,)`` mean gyro-bias NEES (:meth:`mean_nees`)."""
        return self.mean_nees("gyro_bias")

    def nees_band(self) -> tuple[float, float]:
        """The 95 % band ``(low, high)`` of a consistent filter's 3-dof NEES averaged over
        the runs that did not fail, at one epoch (:func:`pronet.stats.chi2_mean_band`):
        what :meth:`nees_in_band` tests each epoch's mean against; NaN without such
        runs."""
        n_ok = self.n_runs - self.n_failed
        return chi2_mean_band(3, n_ok) if n_ok > 0 else (float("nan"), float("nan"))

    def nees_in_band(self, block: str) -> float:
        """The share of DVL epochs at which ``block``'s NEES (:data:`STATE_BLOCKS`),
        averaged over the runs that did not fail, lies inside the 95 % band of a
        consistent filter's (:func:`pronet.stats.chi2_mean_band`): 0.95 in expectation
        when consistent; NaN without such runs or epochs. Where readings were lost (a
        DVL dropout) an epoch's mean is over the runs that had it, against the band of
        that many runs. Below :data:`IN_BAND_FLAG` the tables flag it. For a block whose
        error changes slowly within a run (position, attitude, the biases) the epochs
        are few independent samples, so one draw of the runs gives a share near 0 or
        1 even for a consistent filter; the NEES averaged over the epochs
        (``np.nanmean(block_nees(block))``, 3 when consistent) is steadier
        (``docs/results/smoother.md``, "One draw of 100 runs")."""
        v = self.block_nees(block)[[f is None for f in self.failure]]
        if v.size == 0:
            return float("nan")
        if not np.isnan(v).any():
            low, high = self.nees_band()
            mean = v.mean(axis=0)
            return float(np.mean((mean >= low) & (mean <= high)))
        # Missed updates (a DVL dropout): each epoch's mean over the runs that had it,
        # against the band of that many runs (a mean over fewer runs spreads more).
        counts = np.isfinite(v).sum(axis=0)
        kept = counts > 0
        if not kept.any():
            return float("nan")
        with np.errstate(invalid="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            mean = np.nanmean(v[:, kept], axis=0)
        bands = {int(n): chi2_mean_band(3, int(n)) for n in np.unique(counts[kept])}
        lows = np.array([bands[int(n)][0] for n in counts[kept]])
        highs = np.array([bands[int(n)][1] for n in counts[kept]])
        return float(np.mean((mean >= lows) & (mean <= highs)))

    @property
    def velocity_nees_3sigma(self) -> NDArray[np.float64]:
        """``(n_runs,)`` share of DVL epochs whose velocity NEES is inside the 3σ bound
        :data:`CHI2_3DOF_3SIGMA` (0.9973 when consistent; NaN for a failed run)."""
        v = self.block_nees("velocity")
        with np.errstate(invalid="ignore"):
            inside = np.where(np.isfinite(v), (v <= CHI2_3DOF_3SIGMA).astype(np.float64), np.nan)
        return self._unless_failed(_row_mean(inside))

    @classmethod
    def concat(cls, parts: Sequence[MonteCarloResult]) -> MonteCarloResult:
        """The runs of ``parts`` (shards of one Monte Carlo, in run order) as one result.

        The shards must share their DVL epochs and history epochs; ``ValueError`` if not."""
        if not parts:
            raise ValueError("parts: need at least one shard")
        first = parts[0]
        for p in parts[1:]:
            if not (
                np.array_equal(p.dvl_time, first.dvl_time)
                and np.array_equal(p.record_time, first.record_time)
            ):
                raise ValueError("parts: shards of different scenarios or histories")
        joined: dict[str, object] = {}
        for f in fields(cls):
            values = [getattr(p, f.name) for p in parts]
            if f.name in ("dvl_time", "record_time"):
                joined[f.name] = values[0]
            elif f.name == "failure":
                joined[f.name] = [msg for v in values for msg in v]
            elif f.name == "smoothed":
                if any(v is None for v in values) and not all(v is None for v in values):
                    raise ValueError("parts: some shards were smoothed and some not")
                joined[f.name] = None if values[0] is None else cls.concat(values)
            elif values[0] is None:
                joined[f.name] = None
            else:
                joined[f.name] = np.concatenate(values, axis=0)
        return cls(**joined)  # type: ignore[arg-type]

    #: Per-run metrics, in the order of :meth:`to_dataframe`'s columns.
    PER_RUN = (
        "srmse",
        "smae",
        "final_horizontal_error",
        "max_horizontal_error",
        "mean_nis",
        "velocity_nees",
        "velocity_nees_3sigma",
        "attitude_nees",
        "position_nees",
        "accel_bias_nees",
        "gyro_bias_nees",
        "rejected_updates",
        "missed_updates",
        "diverged_at",
    )

    def to_dataframe(self):  # -> pandas.DataFrame
        """One row per run: ``run`` and the per-run metrics (SI units, as the
        attributes), and ``failure`` (None or the message)."""
        import pandas as pd

        data: dict[str, object] = {"run": np.arange(self.n_runs)}
        data.update({name: getattr(self, name) for name in self.PER_RUN})
        data["failure"] = list(self.failure)
        return pd.DataFrame(data)

    def summary_row(self) -> dict[str, float | int]:
        """:meth:`summary` flattened for a table: ``srmse``, ``srmse_low``,
        ``srmse_high`` ... (mean and 95 % CI bounds, units as the attributes; every
        block's NEES among them), then each block's ``{block}_nees_in_band``
        (:meth:`nees_in_band`), the band ``nees_band_low`` and ``nees_band_high``
        (:meth:`nees_band`), ``runs``, ``failed_runs`` and ``diverged_runs``."""
        row: dict[str, float | int] = {}
        for name, ci in self.summary().items():
            row.update({name: ci.mean, f"{name}_low": ci.low, f"{name}_high": ci.high})
        row.update({f"{b}_nees_in_band": self.nees_in_band(b) for b in STATE_BLOCKS})
        row["nees_band_low"], row["nees_band_high"] = self.nees_band()
        row.update(runs=self.n_runs, failed_runs=self.n_failed, diverged_runs=self.n_diverged)
        return row

    #: The per-run metrics :meth:`summary` gives a mean and 95 % CI of (all but the counts
    #: and times: ``rejected_updates``, ``missed_updates``, ``diverged_at``).
    SUMMARIZED = tuple(
        m for m in PER_RUN if m not in ("rejected_updates", "missed_updates", "diverged_at")
    )

    def summary(self) -> dict[str, MeanCI]:
        """Mean and 95 % CI over runs of every metric in :data:`SUMMARIZED`: the errors,
        the NIS and every block's NEES (``position_nees`` ... ``gyro_bias_nees``, 3 when
        consistent), each within its range (the ``*_3sigma`` shares in [0, 1], every
        other metric non-negative; see :func:`pronet.stats.mean_ci`). The band a
        consistent filter's NEES lies in is :meth:`nees_band`, the share of epochs inside
        it :meth:`nees_in_band`; :meth:`summary_row` has both."""
        return {
            name: mean_ci(getattr(self, name), SHARE if name.endswith("_3sigma") else NON_NEGATIVE)
            for name in self.SUMMARIZED
        }


def _row_mean(v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Each row's mean over its finite entries; NaN for a row with none (a failed run)."""
    finite = np.isfinite(v)
    n = finite.sum(axis=1)
    total = np.where(finite, v, 0.0).sum(axis=1)
    return np.where(n > 0, total / np.maximum(n, 1), np.nan)


def monte_carlo(
    trajectory: _core.Trajectory,
    strategy: _core.Strategy,
    *,
    sensors: _core.SensorConfig | None = None,
    config: _core.FilterConfig | None = None,
    n_runs: int = 100,
    seed: int = 0,
    record_every: int = 0,
    sample_initial_error: bool = True,
    threads: int | None = None,
    first_run: int = 0,
    smooth: bool = False,
) -> MonteCarloResult:
    """Simulate ``n_runs`` noisy runs along ``trajectory`` and filter each one.

    Args:
        trajectory: truth and ideal IMU (e.g. ``builtin_trajectory("paper")``).
        strategy: process-noise strategy; not an external one (nothing sets its q in a
            Monte Carlo: ``ValueError`` naming ``strategy``; an :class:`Ensemble` does).
        sensors: sensor models (default ``SensorConfig()``: the paper's IMU and DVL).
        config: filter tuning (default ``FilterConfig()``).
        n_runs: number of runs.
        seed: Monte Carlo seed (run i uses the streams of (seed, i)).
        record_every: keep the error and 1σ history every this many IMU steps (0: none).
        sample_initial_error: start each run's navigation solution at the truth plus
            an error drawn from the filter's P0 and the IMU's turn-on bias at
            ``sensors.imu_bias`` less a draw from P0 (True), or both exactly at the
            truth and ``imu_bias`` (False). The bias estimates start at zero.
        threads: worker threads, 1 to 8 per core (default: one per core, or
            ``RAYON_NUM_THREADS``).
        first_run: index of the first run (a shard of a larger Monte Carlo: runs
            ``first_run .. first_run + n_runs``, identical to those runs of the whole).
        smooth: also run the RTS smoother backward over every run
            (:attr:`MonteCarloResult.smoothed`; the filter's numbers are unchanged). A
            run then keeps its solution at every IMU epoch until it is smoothed (120
            bytes each, and 36 while it is smoothed) and, under a covariance step, each
            close of the step (2.0 kB: ~200 bytes per IMU epoch at 0.1 s and 100 Hz); at
            every IMU sample, the raw samples and the bias estimates (96 bytes an epoch)
            and, while it smooths an interval between two DVL updates, a covariance and
            the error dynamics per IMU step of it (about 2.5 kB, per thread). It costs
            about 2.2 plain runs at the default 0.1 s step, 3 at every IMU sample
            (docs/reference/smoother.md, "The RTS smoother").

    Memory: before it allocates, a Monte Carlo that would hold more than this process
    can still take (every run's records and their arrays, the runs under way and their
    smoothers) raises ``ValueError`` naming ``n_runs``, ``record_every`` or ``smooth``
    (docs/results/performance.md, "Memory").
    """
    check_type(trajectory, _core.Trajectory, "trajectory")
    check_type(strategy, _core.Strategy, "strategy")
    sensors = sensors if sensors is not None else _core.SensorConfig()
    config = config if config is not None else _core.FilterConfig()
    check_type(sensors, _core.SensorConfig, "sensors")
    check_type(config, _core.FilterConfig, "config")
    # The native core checks the counts, the seed and the thread count, naming each.
    out = _core.monte_carlo(
        trajectory,
        sensors,
        config,
        strategy,
        n_runs=n_runs,
        seed=seed,
        record_every=record_every,
        sample_initial_error=sample_initial_error,
        threads=threads,
        first_run=first_run,
        smooth=flag(smooth, "smooth"),
    )
    return result_of(out)


def result_of(out: dict) -> MonteCarloResult:
    """The result of the native core's dict (``monte_carlo``, ``Ensemble.finish``)."""
    smoothed = out.pop("smoothed", None)
    result = MonteCarloResult(**out)
    if smoothed is None:
        return result
    return replace(result, smoothed=replace(result, q=None, **smoothed))


#: The default window of raw IMU samples handed out at each tuning instant (the paper's N)
#: and time between tuning instants [s]; :mod:`pronet.learn.hybrid` explains them.
DEFAULT_WINDOW = 200
DEFAULT_TUNING_PERIOD = 1.0


class Ensemble:
    """``n_runs`` simulated runs along ``trajectory``, filtered in lockstep, their IMU
    variances set from outside at every tuning instant.

    Loop: ``windows = ens.advance()`` steps every run to the next tuning instant
    (:func:`pronet._core.tuning_instants`) and returns the last ``window`` raw IMU
    samples of every run, float32 ``(n_runs, 6, window)`` oldest first (body FRD,
    ``[f (m/s²), ω (rad/s)]``), or None at the end; ``ens.set_q(q)`` sets each run's
    per-sample IMU variances ``q (n_runs, 6)`` [(m/s²)², (rad/s)²] until the next
    setting; ``ens.finish()`` runs to the end and returns the
    :class:`~pronet.MonteCarloResult`. Until the first ``set_q`` every run uses
    ``prior_q``. Run i draws its noise as run i of :func:`pronet.monte_carlo` with the
    same seed does (common random numbers), so the two compare pairwise.

    Args:
        trajectory: truth and ideal IMU (e.g. ``builtin_trajectory("paper")``).
        prior_q: 6 per-sample IMU variances [(m/s²)², (rad/s)²] in force until the first
            ``set_q``.
        sensors: as for :func:`pronet.monte_carlo` (same default).
        config: as for :func:`pronet.monte_carlo` (same default).
        n_runs: as for :func:`pronet.monte_carlo` (same default).
        seed: as for :func:`pronet.monte_carlo` (same default).
        record_every: as for :func:`pronet.monte_carlo` (same default).
        sample_initial_error: as for :func:`pronet.monte_carlo` (same default).
        threads: as for :func:`pronet.monte_carlo` (same default).
        first_run: as for :func:`pronet.monte_carlo` (same default).
        smooth: as for :func:`pronet.monte_carlo` (same default).
        window: IMU samples per window handed out, 1 to the trajectory's length.
        tuning_period: time between tuning instants [s], > 0.

    ``advance`` and ``finish`` end within a fraction of a second on Ctrl-C or SIGTERM
    (``KeyboardInterrupt``); the ensemble is then unusable (``ValueError``), as it is
    after ``finish``.
    """

    def __init__(
        self,
        trajectory: _core.Trajectory,
        prior_q: ArrayLike,
        *,
        sensors: _core.SensorConfig | None = None,
        config: _core.FilterConfig | None = None,
        n_runs: int = 100,
        seed: int = 0,
        window: int = DEFAULT_WINDOW,
        tuning_period: float = DEFAULT_TUNING_PERIOD,
        record_every: int = 0,
        sample_initial_error: bool = True,
        threads: int | None = None,
        first_run: int = 0,
        smooth: bool = False,
    ) -> None:
        check_type(trajectory, _core.Trajectory, "trajectory")
        sensors = sensors if sensors is not None else _core.SensorConfig()
        config = config if config is not None else _core.FilterConfig()
        check_type(sensors, _core.SensorConfig, "sensors")
        check_type(config, _core.FilterConfig, "config")
        # The native core checks the counts, the seed, the window, the tuning period and
        # the thread count, naming each.
        self._native = _core.Ensemble(
            trajectory,
            sensors,
            config,
            prior_q,  # 6 finite real numbers of any sequence, checked by the core
            n_runs=n_runs,
            seed=seed,
            window=window,
            tuning_period=tuning_period,
            record_every=record_every,
            sample_initial_error=sample_initial_error,
            threads=threads,
            first_run=first_run,
            smooth=flag(smooth, "smooth"),
        )

    def advance(self) -> NDArray[np.float32] | None:
        """Step all runs to the next tuning instant; the windows float32
        ``(n_runs, 6, window)``, oldest sample first, or None at the end."""
        return self._native.advance()

    def set_q(self, q: ArrayLike) -> None:
        """Set each run's per-sample IMU variances: ``q`` ``(n_runs, 6)``
        [(m/s²)², (rad/s)²], finite and >= 0."""
        self._native.set_q(float_array(q, "q", (None, 6)))

    def finish(self) -> MonteCarloResult:
        """Run to the end; the result as :func:`pronet.monte_carlo` returns it. The
        ensemble cannot be used afterwards."""
        return result_of(self._native.finish())

    @property
    def n_runs(self) -> int:
        return self._native.n_runs

    @property
    def window(self) -> int:
        """IMU samples per window."""
        return self._native.window

    @property
    def steps(self) -> int:
        """IMU steps taken so far."""
        return self._native.steps

    @property
    def time(self) -> float:
        """Current time [s]."""
        return self._native.time

    @property
    def done(self) -> bool:
        """Whether every run reached the end (or the ensemble finished)."""
        return self._native.done


def runs_outside_band(nis: ArrayLike, dof: int = 3) -> NDArray[np.bool_]:
    """Whether each run's mean NIS (``nis`` ``(n_runs, m)``, NaN where a reading was not
    applied) lies outside its 95 % band, χ²(dof·k)/k over its ``k`` readings (False for
    a run without any)."""
    nis = np.asarray(nis, dtype=np.float64)
    out = np.zeros(len(nis), dtype=bool)
    for r, row in enumerate(nis):
        seen = row[np.isfinite(row)]
        if len(seen):
            lo, hi = chi2_mean_band(dof, len(seen))
            out[r] = not lo <= float(seen.mean()) <= hi
    return out


def chance_bound(n: int, p: float = 0.05, level: float = 0.99) -> int:
    """The most of ``n`` independent trials that land outside a band of probability
    ``1 − p`` by chance, at ``level``: the smallest ``k`` with P(Binomial(n, p) ≤ k) ≥
    ``level`` (``scipy.special``'s binomial CDF)."""
    cdf = special.bdtr(np.arange(n + 1), n, p)
    reached = np.flatnonzero(cdf >= level)
    return int(reached[0]) if len(reached) else n


def runs_flag(label: str, outside: NDArray[np.bool_], what: str = "DVL") -> str:
    """One line when more runs' mean NIS lie outside their band than chance allows
    (:func:`chance_bound`), else ""."""
    n, k = len(outside), int(np.sum(outside))
    allowed = chance_bound(n)
    if k <= allowed:
        return ""
    return (
        f"{label}: {k} of {n} runs' mean {what} NIS outside their 95 % band (chance "
        f"allows {allowed}): the filter is told a model other than the simulation's "
        "(its R, Q or initial σ); check the filter configuration against the sensors'"
    )
