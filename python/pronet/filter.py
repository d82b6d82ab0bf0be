"""One filter pass over given IMU arrays and sensor streams (:class:`~pronet.Dvl`,
:class:`~pronet.Depth`, :class:`~pronet.Fix`, :class:`~pronet.Heading`): the way recorded
data is filtered."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal, TypeAlias, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet import _core
from pronet._util import plausibility
from pronet._util.deprecated import deprecated_streams
from pronet._util.validate import check_type, flag, float_array, scalar
from pronet.stats import Extent, PassHealth, pass_health, sources_of, warn_about

#: An aiding sensor's stream, as :func:`run_filter` takes them.
Stream: TypeAlias = _core.Dvl | _core.Depth | _core.Fix | _core.Heading


@dataclass(frozen=True)
class StreamResult:
    """What a pass did with each of one stream's r rows (:attr:`FilterResult.streams`).

    Attributes:
        kind: ``"velocity"`` (a :class:`~pronet.Dvl`), ``"depth"``
            (:class:`~pronet.Depth`), ``"fix"`` (:class:`~pronet.Fix`) or ``"heading"``
            (:class:`~pronet.Heading`).
        epoch: ``(r,)`` the epoch index each row was applied at (the index
            :attr:`FilterResult.epoch` counts in: 0 the initial state, j + 1 after IMU
            sample j), -1 where it fell outside the run.
        nis: ``(r,)`` normalized innovation squared (χ² with 3 dof for a velocity, 1
            for a depth or a heading, 2 or 3 for a fix without or with its height,
            when consistent); NaN outside the run.
        innovation: a velocity stream's ``(r, 3)`` ``z − h(x̂)`` [m/s] in its frame
            (NaN outside the run); None for the other kinds, as the four below.
        innovation_cov: ``(r, 3, 3)`` innovation covariance S [(m/s)²].
        gain: ``(r, 15, 3)`` Kalman gains.
        accepted: ``(r,)`` whether each row was applied (False where the innovation
            gate rejected it, or it fell outside the run).
        adaptive_q: ``(r, 15, 15)`` the per-IMU-step Q_d a Mehra strategy set after
            each update (as :attr:`FilterResult.adaptive_q`).
    """

    kind: Literal["velocity", "depth", "fix", "heading"]
    epoch: NDArray[np.int64]
    nis: NDArray[np.float64]
    innovation: NDArray[np.float64] | None = None
    innovation_cov: NDArray[np.float64] | None = None
    gain: NDArray[np.float64] | None = None
    accepted: NDArray[np.bool_] | None = None
    adaptive_q: NDArray[np.float64] | None = None


@dataclass(frozen=True)
class SmoothedResult:
    """The RTS-smoothed solution at the epochs a pass keeps (``run_filter(smooth=True)``;
    every epoch, or with ``output_step`` some): each epoch's estimate given every
    measurement of the pass, before and after it. The rows are the forward pass's
    (:attr:`FilterResult.time`, :attr:`FilterResult.epoch`); ``n+1`` below.

    Attributes:
        time: ``(n+1,)`` epoch times [s], the forward pass's.
        lla: ``(n+1, 3)`` latitude, longitude [rad], height [m, up].
        vel: ``(n+1, 3)`` NED velocity [m/s].
        rpy: ``(n+1, 3)`` roll, pitch, yaw [rad].
        bias: ``(n+1, 6)`` accelerometer [m/s²] and gyro [rad/s] bias estimates.
        sigma: ``(n+1, 15)`` smoothed 1σ of ``[δp (NED m), δv (m/s), ψ (rad), δb_a,
            δb_g]`` (:data:`ERROR_STATES`), never above the forward pass's: the
            forward σ with each variance changed by the smoothing (with a covariance
            step, at an epoch inside a step that change is interpolated linearly in
            time between the steps' closes on either side).
        calibration: ``(n+1, 7)`` with the DVL error states, the smoothed
            :attr:`FilterResult.calibration`; ``(0, 7)`` without.
        calibration_sigma: ``(n+1, 7)`` their smoothed 1σ; ``(0, 7)`` without.
        epoch: the forward pass's :attr:`FilterResult.epoch`.
    """

    time: NDArray[np.float64]
    lla: NDArray[np.float64]
    vel: NDArray[np.float64]
    rpy: NDArray[np.float64]
    bias: NDArray[np.float64]
    sigma: NDArray[np.float64]
    calibration: NDArray[np.float64] = field(default_factory=lambda: np.empty((0, 7)))
    calibration_sigma: NDArray[np.float64] = field(default_factory=lambda: np.empty((0, 7)))
    epoch: NDArray[np.int64] = field(default_factory=lambda: np.empty(0, np.int64))

    def to_dataframe(self):  # -> pd.DataFrame
        """One row per epoch, indexed by the epoch, columns :data:`EPOCH_COLUMNS`
        (then the calibration states' with them), SI units as the attributes."""
        return _epoch_table(self)


@dataclass(frozen=True)
class FilterResult:
    """The estimate at every IMU epoch and what became of every stream's rows.

    Epoch arrays have n + 1 rows: the initial state at ``t0``, then one per IMU sample
    (after the updates applied there, if any); a pass run with ``epochs="last"``
    keeps only the last of them (one row), one run with ``output_step`` the rows of
    :attr:`epoch`. Each stream's rows are in :attr:`streams`; the update arrays below
    (``dvl_epoch`` to ``adaptive_q``) are the first velocity stream's, one row per
    row of it (rows that fell outside the run hold NaN and ``dvl_epoch = -1``; no rows
    without a velocity stream), and ``depth_*``, ``fix_*`` the first depth and fix
    stream's.

    Attributes:
        time: ``(n+1,)`` epoch times [s].
        lla: ``(n+1, 3)`` latitude, longitude [rad], height [m, up].
        vel: ``(n+1, 3)`` NED velocity [m/s].
        rpy: ``(n+1, 3)`` roll, pitch, yaw [rad].
        bias: ``(n+1, 6)`` accelerometer [m/s²] and gyro [rad/s] bias estimates.
        sigma: ``(n+1, 15)`` filter 1σ of ``[δp (NED m), δv (m/s), ψ (rad), δb_a, δb_g]``
            (with a covariance step, at an epoch inside a step its variance is
            interpolated linearly in time up to the step's close).
        calibration: ``(n+1, 7)`` with the DVL error states
            (``FilterConfig(dvl_calibration=True)`` or ``dvl_bias_sigma``,
            :data:`CALIBRATION_COLUMNS`): the DVL's estimated scale-factor error k (it
            reads ``1 + k`` times the velocity), its mounting roll, pitch, yaw in the
            body frame [rad] (k 0 and the angles nominal where only the correlated error
            is estimated), and its correlated velocity error in its own axes [m/s] (0
            without it); ``(0, 7)`` without the states.
        calibration_sigma: ``(n+1, 7)`` the filter's 1σ of the same (the angles' as
            small rotations about the body axes); ``(0, 7)`` without.
        covariance: ``(15, 15)`` covariance at the last epoch.
        covariance_epoch: ``(j,)`` the epoch index each time of ``covariance_time`` was
            kept at (the epoch nearest it), -1 where it fell outside the run; ``(0,)``
            when none was asked for.
        covariances: ``(j, 15, 15)`` the full covariance at those epochs, after their
            update, in the order and units of :data:`ERROR_STATES` (NaN where outside
            the run); its diagonal is ``sigma**2`` there (with a covariance step, at an
            epoch inside a step this covariance is brought up to date and ``sigma`` is
            interpolated, so the two differ slightly).
        dvl_epoch: ``(m,)`` epoch index each DVL row was applied at (the first velocity
            stream's, as the keys to ``adaptive_q``).
        innovation: ``(m, 3)`` ``z − h(x̂)`` [m/s].
        innovation_cov: ``(m, 3, 3)`` innovation covariance S [(m/s)²].
        nis: ``(m,)`` normalized innovation squared (χ², 3 dof when consistent).
        gain: ``(m, 15, 3)`` Kalman gains.
        accepted: ``(m,)`` whether each DVL row was applied (False where the innovation
            gate rejected it, or the row fell outside the run).
        diverged_at: time [s] at which the NIS showed divergence (mean over the last 20
            updates above 25, about 8× the consistent 3), or None.
        adaptive_q: ``(m, 15, 15)`` the per-IMU-step discrete Q_d a Mehra strategy set
            after each update (``K C Kᵀ`` spread over the interval's steps); NaN for
            other strategies and before Mehra has its ξ innovations (for other
            strategies a read-only view of one NaN, which costs no memory).
        depth_epoch, fix_epoch: ``(d,)``, ``(f,)`` the epoch each depth reading and
            position fix of the first depth and fix stream was applied at (-1 outside
            the run; no rows without one).
        depth_nis, fix_nis: their normalized innovation squared (χ² with 1 dof for a
            depth, 2 or 3 for a fix without or with its height; NaN outside the run).
        smoothed: the RTS-smoothed solution at the kept epochs with ``smooth=True``
            (:class:`SmoothedResult`), else None.
        epoch: with ``output_step``, ``(k,)`` the index of each row among all epochs
            (0 the initial state, j + 1 after IMU sample j: the index ``dvl_epoch``,
            ``depth_epoch``, ``fix_epoch`` and ``covariance_epoch`` count in); with
            ``epochs="last"``, ``(1,)`` the last epoch's, n; ``(0,)`` with every epoch
            kept (row j is epoch j).
        streams: one :class:`StreamResult` per stream given, in their order.
        health: what the pass says about itself (:mod:`pronet.stats`): each stream's
            NIS against its band, the gate, and a diverged solution.
    """

    time: NDArray[np.float64]
    lla: NDArray[np.float64]
    vel: NDArray[np.float64]
    rpy: NDArray[np.float64]
    bias: NDArray[np.float64]
    sigma: NDArray[np.float64]
    calibration: NDArray[np.float64]
    calibration_sigma: NDArray[np.float64]
    covariance: NDArray[np.float64]
    covariance_epoch: NDArray[np.int64]
    covariances: NDArray[np.float64]
    dvl_epoch: NDArray[np.int64]
    innovation: NDArray[np.float64]
    innovation_cov: NDArray[np.float64]
    nis: NDArray[np.float64]
    gain: NDArray[np.float64]
    adaptive_q: NDArray[np.float64]
    accepted: NDArray[np.bool_]
    diverged_at: float | None
    depth_epoch: NDArray[np.int64] = field(default_factory=lambda: np.empty(0, np.int64))
    depth_nis: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    fix_epoch: NDArray[np.int64] = field(default_factory=lambda: np.empty(0, np.int64))
    fix_nis: NDArray[np.float64] = field(default_factory=lambda: np.empty(0))
    smoothed: SmoothedResult | None = None
    epoch: NDArray[np.int64] = field(default_factory=lambda: np.empty(0, np.int64))
    streams: tuple[StreamResult, ...] = ()
    health: PassHealth = field(default_factory=PassHealth)

    def rows_of(self, epochs: ArrayLike) -> NDArray[np.intp]:
        """The rows of the per-epoch arrays (``time``, ``lla``, ...) that hold the epochs
        ``epochs`` (indices among all epochs, as :attr:`dvl_epoch` counts), in a pass
        with every epoch kept or thinned (:attr:`epoch`); ``ValueError`` for an epoch
        the result does not keep."""
        values = float_array(epochs, "epochs", (None,))
        if not np.all(np.isfinite(values) & (values == np.round(values))):
            raise ValueError(f"epochs: expected whole numbers, got {values[:5]}")
        e = values.astype(np.int64)
        if self.epoch.size == 0:  # every epoch kept: row j is epoch j
            rows = e.astype(np.intp)
            missing = (rows < 0) | (rows >= len(self.time))
        else:
            rows = np.minimum(np.searchsorted(self.epoch, e), len(self.epoch) - 1)
            missing = self.epoch[rows] != e
        if missing.any():
            raise ValueError(f"epochs: epoch {int(e[missing][0])} is not kept in this result")
        return rows

    def to_dataframe(self, rows: Literal["epochs", "updates"] = "epochs"):  # -> pd.DataFrame
        """The result as a pandas table, SI units as the attributes.

        ``rows="epochs"``: one row per epoch kept, indexed by its epoch (``"epoch"``, as
        :attr:`epoch`: ``updates.join(epochs, on="dvl_epoch")`` finds each update's row,
        with ``output_step`` too), columns :data:`EPOCH_COLUMNS` (``time``, ``lat``,
        ``lon`` [rad], ``h`` [m], NED velocity, roll, pitch, yaw, the bias estimates and
        the 1σ of the 15 error states), then with the DVL calibration states
        :data:`CALIBRATION_COLUMNS` and their ``sigma_`` twins. ``rows="updates"``: one
        row per row of the first velocity stream, columns :data:`UPDATE_COLUMNS` (the
        epoch and its time, or -1 and NaN for a row outside the run, the time NaN too
        where the epoch was not kept, with ``output_step`` or ``epochs="last"``; the
        innovation [m/s], body x, y, z or, for a ``frame="ned"`` stream, N, E, D; the
        NIS; whether it was applied).
        """
        import pandas as pd

        if rows == "updates":
            inside = self.dvl_epoch >= 0
            t = np.full(len(self.dvl_epoch), np.nan)
            if len(self.epoch):  # output_step or epochs="last": the kept epochs' times
                row = np.searchsorted(self.epoch, self.dvl_epoch)
                row = np.minimum(row, len(self.epoch) - 1)
                kept = inside & (self.epoch[row] == self.dvl_epoch)
                t[kept] = self.time[row[kept]]
            else:
                t[inside] = self.time[self.dvl_epoch[inside]]
            data = {"dvl_epoch": self.dvl_epoch, "time": t}
            data.update(zip(UPDATE_COLUMNS[2:5], self.innovation.T, strict=True))
            data.update(nis=self.nis, accepted=self.accepted)
            return pd.DataFrame(data, columns=list(UPDATE_COLUMNS))
        if rows != "epochs":
            raise ValueError(f'rows: expected "epochs" or "updates", got {rows!r}')
        return _epoch_table(self)


def _epoch_table(r: FilterResult | SmoothedResult):  # -> pd.DataFrame
    """``r``'s epoch columns (:data:`EPOCH_COLUMNS`, then the calibration states' with
    them) as a data frame indexed by the epoch (``"epoch"``: :attr:`FilterResult.epoch`,
    or every epoch's)."""
    import pandas as pd

    parts = [r.time[:, None], r.lla, r.vel, r.rpy, r.bias, r.sigma]
    columns = list(EPOCH_COLUMNS)
    if len(r.calibration):
        parts += [r.calibration, r.calibration_sigma]
        columns += [*CALIBRATION_COLUMNS, *(f"sigma_{c}" for c in CALIBRATION_COLUMNS)]
    every = pd.RangeIndex(len(r.time), name="epoch")
    index = pd.Index(r.epoch, name="epoch") if len(r.epoch) else every
    return pd.DataFrame(np.hstack(parts), columns=columns, index=index)


#: The 15 error states, in order (:attr:`FilterResult.sigma`): NED position [m], NED
#: velocity [m/s], attitude ψ [rad], accelerometer [m/s²] and gyro [rad/s] biases.
ERROR_STATES = (
    *(f"dp_{a}" for a in "ned"),
    *(f"dv_{a}" for a in "ned"),
    *(f"psi_{a}" for a in "ned"),
    *(f"ba_{a}" for a in "xyz"),
    *(f"bg_{a}" for a in "xyz"),
)
#: Columns of :meth:`FilterResult.to_dataframe` (one row per epoch).
EPOCH_COLUMNS = (
    "time",
    "lat",
    "lon",
    "h",
    *(f"vel_{a}" for a in "ned"),
    "roll",
    "pitch",
    "yaw",
    *(f"bias_a{a}" for a in "xyz"),
    *(f"bias_g{a}" for a in "xyz"),
    *(f"sigma_{s}" for s in ERROR_STATES),
)
#: The DVL error states' columns (with ``FilterConfig(dvl_calibration=True)`` or
#: ``dvl_bias_sigma``): scale, mounting angles [rad], correlated velocity error [m/s].
CALIBRATION_COLUMNS = (
    "dvl_scale",
    "dvl_roll",
    "dvl_pitch",
    "dvl_yaw",
    *(f"dvl_bias_{a}" for a in "xyz"),
)
#: Columns of :meth:`FilterResult.to_dataframe` with ``rows="updates"``.
UPDATE_COLUMNS = (
    "dvl_epoch",
    "time",
    "innovation_x",
    "innovation_y",
    "innovation_z",
    "nis",
    "accepted",
)


@overload
def run_filter(
    imu: ArrayLike,
    imu_time: ArrayLike,
    streams: Sequence[Stream] = (),
    *,
    t0: float,
    lla0: ArrayLike,
    vel0: ArrayLike,
    rpy0: ArrayLike,
    config: _core.FilterConfig | None = None,
    strategy: _core.Strategy,
    bias0: ArrayLike | None = None,
    q_time: ArrayLike | None = None,
    q: ArrayLike | None = None,
    epochs: Literal["all", "last"] = "all",
    output_step: float | None = None,
    covariance_time: ArrayLike | None = None,
    smooth: bool = False,
    warn: bool = True,
    names: Sequence[str] | None = None,
) -> FilterResult: ...


@overload
def run_filter(  # deprecated: the arrays before streams
    imu: ArrayLike,
    imu_time: ArrayLike,
    dvl: ArrayLike,
    dvl_time: ArrayLike,
    /,
    *,
    t0: float,
    lla0: ArrayLike,
    vel0: ArrayLike,
    rpy0: ArrayLike,
    config: _core.FilterConfig | None = None,
    strategy: _core.Strategy,
    bias0: ArrayLike | None = None,
    q_time: ArrayLike | None = None,
    q: ArrayLike | None = None,
    epochs: Literal["all", "last"] = "all",
    output_step: float | None = None,
    covariance_time: ArrayLike | None = None,
    smooth: bool = False,
    warn: bool = True,
    names: Sequence[str] | None = None,
    depth: ArrayLike | None = None,
    depth_time: ArrayLike | None = None,
    depth_sigma: float | None = None,
    fix: ArrayLike | None = None,
    fix_time: ArrayLike | None = None,
    fix_sigma: ArrayLike | None = None,
) -> FilterResult: ...


def run_filter(
    imu: ArrayLike,
    imu_time: ArrayLike,
    streams: Sequence[Stream] | ArrayLike = (),
    *deprecated: ArrayLike,
    t0: float,
    lla0: ArrayLike,
    vel0: ArrayLike,
    rpy0: ArrayLike,
    config: _core.FilterConfig | None = None,
    strategy: _core.Strategy,
    bias0: ArrayLike | None = None,
    q_time: ArrayLike | None = None,
    q: ArrayLike | None = None,
    epochs: Literal["all", "last"] = "all",
    output_step: float | None = None,
    covariance_time: ArrayLike | None = None,
    smooth: bool = False,
    warn: bool = True,
    names: Sequence[str] | None = None,
    **deprecated_keywords: Any,
) -> FilterResult:
    """Run the INS error-state EKF over IMU arrays and aiding sensors' streams.

    Args:
        imu: ``(n, 6)`` raw IMU samples ``[f (m/s²), w (rad/s)]``, body frame FRD; row k
            covers ``(imu_time[k-1], imu_time[k]]`` with ``imu_time[-1] = t0``.
        imu_time: ``(n,)`` sample end times [s], strictly increasing, all after ``t0``.
        streams: the aiding sensors, any number of each kind in any order:
            :class:`~pronet.Dvl` (a DVL's body-frame velocity, or a NED velocity),
            :class:`~pronet.Depth` (a pressure sensor's depth), :class:`~pronet.Fix`
            (GNSS, USBL, LBL position fixes), each with its times, noise and lever arm,
            and :class:`~pronet.Heading` (a compass's or an AHRS's yaw).
            Each row is applied at the IMU epoch nearest its time; at an epoch the rows
            due are applied stream by stream, in this order (docs/reference/aiding.md,
            "Position and depth updates"). None (the default, ``()``) is a pure
            inertial pass. ``Dvl(dvl_time, dvl)`` with nothing else is the DVL the
            ``config`` describes (its R, aiding frame, lever arm and gate).
        t0: time of the initial state [s].
        lla0: initial position [rad, rad, m].
        vel0: initial NED velocity [m/s].
        rpy0: initial attitude, roll, pitch, yaw [rad].
        config: filter tuning (defaults: ``FilterConfig()``).
        strategy: process-noise strategy, e.g. ``Strategy.constant(q)``; the adaptive
            ones (Mehra, adaptive) read every velocity stream's innovations.
        bias0: initial ``[b_a (m/s²), b_g (rad/s)]`` estimate (default zeros).
        q_time: the times of a schedule of per-sample IMU variances for an external
            strategy, ``(k,)`` [s] strictly increasing.
        q: that schedule's ``(k, 6)`` variances
            [(m/s²)², (rad/s)²]; row j is in force from the IMU epoch nearest
            ``q_time[j]`` on (``Strategy.external(prior_q)`` holds before the first).
            This is the ProNet loop on recorded data: the windows a regressor reads are
            raw IMU samples, known before the filter runs (see
            :func:`pronet.learn.hybrid.q_schedule`).
        epochs: ``"all"`` keeps the estimate at every epoch; ``"last"`` only at the
            last one, for a pass whose updates alone are read (matching R to the
            innovations): it skips storing the estimate (~250 bytes) at every IMU
            sample. ``dvl_epoch`` still counts every epoch.
        output_step: an output period [s] (finite, > 0; with ``epochs="all"``): keep
            the initial state, the epoch nearest each multiple of it after ``t0`` and
            the last epoch (:attr:`FilterResult.epoch` says which), each row bit for bit
            the one every epoch would give, forward and smoothed. Memory then grows with
            the kept epochs (and, smoothed, the updates), not the IMU samples: a 10 h,
            100 Hz pass smoothed with ``output_step=1.0`` fits in 1 GiB
            (docs/results/performance.md). None (default): every epoch.
        covariance_time: ``(j,)`` times [s], strictly increasing, at which to keep the
            full 15 × 15 covariance (:attr:`FilterResult.covariances`), each at the
            epoch nearest it. Memory is 1,800 bytes per time asked for, whatever the
            pass's length (every epoch of a 1 h, 100 Hz pass would be 650 MB; σ alone
            is kept at every epoch).
        smooth: also run the Rauch–Tung–Striebel smoother backward over the pass
            (:attr:`FilterResult.smoothed`, at the kept epochs: not with
            ``epochs="last"``; with the DVL calibration states all 19 are smoothed; with a
            covariance step the smoother's grid is the steps' closes). It keeps one
            covariance per DVL epoch and, while it smooths an interval between two, a
            covariance and the error dynamics per IMU step of that interval (about
            2.5 kB: a long stretch without an update, an outage, costs memory in
            proportion), and costs 2–5 forward passes (docs/reference/smoother.md, "The RTS
            smoother"). With ``output_step`` the forward solution is kept at the updates
            alone and integrated again between them.
        warn: a :class:`pronet.stats.FilterHealthWarning` for each line of
            :attr:`FilterResult.health` (a stream out of its NIS band, a gate that
            rejected most of a stream, a diverged solution); False: the lines only there.
        names: each stream's name in this pass's messages and :attr:`FilterResult.health`,
            one per stream: the sensor, topic or file its user knows it by (``pronet real``
            and ``pronet navigate`` give ``"dvl"``, ``"depth"``, …). None (the default):
            ``streams[i]``.

    Refused before any computation, as a slip of unit or frame (a ``ValueError`` naming
    the argument; :mod:`pronet._util.plausibility` has the bounds and why): ``t0`` more
    than 5 median IMU steps before the first sample, a mean specific force off gravity
    by 20 %, one over the first second more than 90° from where ``rpy0`` puts it (FLU),
    a depth beyond −10 … 12 km, an ``rpy0`` roll or pitch beyond ±π or yaw beyond ±2π
    (in degrees?). A stream none of whose rows falls within the run, and
    (with ``warn``) a lever arm beyond 10 m (in cm?), IMU stamps that jitter beyond 15 %
    of a step, leave a gap of over 5 steps or step otherwise than ``config.imu_dt`` by
    over 15 % (its process noise would be off by their ratio), and a Mehra or adaptive
    strategy whose window the pass's accepted velocity updates never filled, are warned of
    (:class:`~pronet.PlausibilityWarning`).

    Memory: before it allocates, the pass estimates what it would hold at its peak;
    where that is more than this process can still take, it raises ``ValueError``
    naming the argument that bounds the most of it (``output_step``, ``streams``,
    ``strategy``, ``covariance_time`` or ``smooth``), with the estimate and what to
    change, instead of running out (docs/results/performance.md, "Memory").

    Deprecated (for one release): the arrays before streams,
    ``run_filter(imu, imu_time, dvl, dvl_time, *, ..., depth=, depth_time=,
    depth_sigma=, fix=, fix_time=, fix_sigma=)``, warns (``DeprecationWarning``) and runs
    ``streams=[Dvl(dvl_time, dvl), Depth(depth_time, depth, sigma=depth_sigma),
    Fix(fix_time, fix, sigma=fix_sigma)]`` (the depth and fix streams where given, all
    three of a group or none), with the same result bit for bit. Streams and these
    arrays together are a ``ValueError``.
    """
    if deprecated or deprecated_keywords:
        streams = deprecated_streams(streams, deprecated, deprecated_keywords)
    config = config if config is not None else _core.FilterConfig()
    check_type(config, _core.FilterConfig, "config")
    check_type(strategy, _core.Strategy, "strategy")
    smooth = flag(smooth, "smooth")
    warn = flag(warn, "warn")
    given = _stream_list(streams)
    named = _names(names, len(given))
    samples, stamps = float_array(imu, "imu", (None, 6)), float_array(imu_time, "imu_time", (None,))
    start, attitude = scalar(t0, "t0"), float_array(rpy0, "rpy0", (3,))
    plausibility.check_pass(samples, stamps, start, attitude, given, named)
    if warn:  # a caller that says the pass's findings its own way has checked these
        plausibility.long_lever_arms(config.lever_arm, given, named)
        plausibility.warn_of_stamps(stamps, config.imu_dt)
    out = _core.run_filter(
        samples,
        stamps,
        given,
        t0=start,
        lla0=float_array(lla0, "lla0", (3,)),
        vel0=float_array(vel0, "vel0", (3,)),
        rpy0=attitude,
        config=config,
        strategy=strategy,
        bias0=None if bias0 is None else float_array(bias0, "bias0", (6,)),
        q_time=None if q_time is None else float_array(q_time, "q_time", (None,)),
        q=None if q is None else float_array(q, "q", (None, 6)),
        epochs=epochs,
        output_step=None if output_step is None else scalar(output_step, "output_step"),
        covariance_time=(
            None
            if covariance_time is None
            else float_array(covariance_time, "covariance_time", (None,))
        ),
        smooth=smooth,
    )
    per_stream = tuple(StreamResult(**_with_adaptive_q(d)) for d in out.pop("streams"))
    span = (start, float(stamps[-1]))
    plausibility.warn_unapplied(given, [s.epoch for s in per_stream], span, named)
    if warn:
        plausibility.warn_unfilled_window(
            strategy.kind, strategy.window, accepted_updates(per_stream)
        )
    _with_adaptive_q(out)
    if epochs == "last":
        out["epoch"] = np.array([len(samples)], dtype=np.int64)
    smoothed, extent = out.pop("smoothed"), Extent(*out.pop("extent"))
    if smoothed is not None:
        smoothed = SmoothedResult(time=out["time"], epoch=out["epoch"], **smoothed)
    result = FilterResult(**out, smoothed=smoothed, streams=per_stream)
    sources = sources_of(given, [r.kind for r in per_stream])
    if named is not None:
        sources = [dataclasses.replace(s, name=n) for s, n in zip(sources, named, strict=True)]
    health = pass_health(per_stream, sources, lla=result.lla, vel=result.vel,
                         sigma=result.sigma, time=result.time, extent=extent)  # fmt: skip
    if warn:
        warn_about(health)
    return dataclasses.replace(result, health=health)


def accepted_updates(streams: Sequence[StreamResult]) -> int:
    """The velocity updates a pass applied (its velocity streams' ``accepted`` rows),
    what fills a Mehra or adaptive strategy's window
    (:func:`pronet._util.plausibility.unfilled_window`)."""
    return sum(int(s.accepted.sum()) for s in streams if s.accepted is not None)


def _with_adaptive_q(out: dict[str, Any]) -> dict[str, Any]:
    """``out`` (a velocity stream's arrays) with an ``adaptive_q`` of None, where no
    row has one, made the all-NaN ``(m, 15, 15)`` (a read-only view of one NaN)."""
    if "adaptive_q" in out and out["adaptive_q"] is None:
        out["adaptive_q"] = np.broadcast_to(np.nan, (len(out["nis"]), 15, 15))
    return out


def sensor_names(streams: Sequence[Stream]) -> list[str] | None:
    """Each stream named by its sensor's kind (``"dvl"``, ``"depth"``, ``"fix"``,
    ``"heading"``: the names ``pronet real`` and ``pronet navigate`` give), or None
    (``streams[i]``) where a kind repeats."""
    names = [type(s).__name__.lower() for s in streams]
    return names if len(set(names)) == len(names) else None


def _names(names: object, count: int) -> list[str] | None:
    """``names`` as a list of ``count`` strings (None stays None), or ``ValueError``
    naming the argument."""
    if names is None:
        return None
    if not isinstance(names, Sequence) or isinstance(names, str | bytes):
        raise ValueError(
            f"names: expected a sequence of strings, one per stream, got {type(names).__name__}"
        )
    if len(names) != count or not all(isinstance(n, str) and n for n in names):
        raise ValueError(
            f"names: expected {count} non-empty strings, one per stream, got {list(names)!r}"
        )
    return list(names)


def _stream_list(streams: object) -> list[Stream]:
    """``streams`` as a list, or ``ValueError`` naming it or the item that is no stream."""
    kinds = (_core.Dvl, _core.Depth, _core.Fix, _core.Heading)
    if not isinstance(streams, Sequence) or isinstance(streams, str | bytes):
        raise ValueError(
            "streams: expected a sequence (a list or tuple) of Dvl, Depth, Fix and Heading "
            "streams, "
            f"got {type(streams).__name__}"
        )
    for i, s in enumerate(streams):
        if not isinstance(s, kinds):
            raise ValueError(
                f"streams[{i}]: expected a Dvl, Depth, Fix or Heading, got {type(s).__name__}"
            )
    return list(streams)
