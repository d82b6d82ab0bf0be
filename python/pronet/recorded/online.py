"""Online navigation: the filter fed as the data arrives, on a vehicle or from a log
read message by message (docs/how-to/online.md, "Online use").

:class:`Navigator` takes IMU samples one at a time or in blocks and each sensor's
readings by time, and answers with the navigation state and its σ at any moment. Fed in
time order, every epoch equals :func:`pronet.run_filter`'s forward pass over the same
data bit for bit, for every strategy (the native core runs the same epoch loop). The
rule, as the batch pass has it: a reading is applied at the first IMU epoch whose time
plus half its step reaches the reading's time, readings at an epoch stream by stream in
the order of ``streams``. A reading that arrives after its epoch has run, stamped no more
than ``lag`` seconds before the newest IMU sample, is applied at its own epoch: the
filter is run again from the last checkpoint before that epoch (a copy of the filter
every ``checkpoint_every`` epochs), which costs the IMU steps since then (about 0.3 µs
each, ``benches/online.py``); an older one is refused and counted
(:meth:`Navigator.tally`), never dropped silently. Memory is the lag window's history,
whatever the mission's length.

The ProNet loop runs inside: with a :class:`pronet.strategies.Learned` strategy the
regressor reads the last ``window`` raw IMU samples at every tuning instant (every
``round(tuning_period / imu_dt)`` samples once the window is full, as
:func:`pronet.learn.hybrid.q_schedule` places them), its q guarded as the batch loop
guards it, and sets the IMU noise from the next sample on; ``adaptive`` and ``mehra``
adapt inside the core as in a batch pass.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet import _core
from pronet._util.plausibility import (
    MAX_IMU_GAP,
    angles_beyond,
    attitude_beyond,
    check_imu_start,
    depth_beyond,
    gaps_fed,
    imu_period,
)
from pronet._util.validate import check_type, count, float_array, scalar
from pronet.config import filter_config
from pronet.filter import Stream, _names, sensor_names
from pronet.learn.hybrid import Guardrails, _predictions, apply_guardrails, for_loop
from pronet.montecarlo import DEFAULT_WINDOW
from pronet.recorded.alignment import Section
from pronet.recorded.navigate import LeverArms, NavigateOptions, Setup, setup
from pronet.recorded.passes import failure_reason
from pronet.recorded.solution import InitialState
from pronet.recorded.vehicle import VehicleTuning
from pronet.run import native_of
from pronet.stats import Extent, divergence, heading_linearity, tally_flag
from pronet.strategies import StrategyLike

F64 = NDArray[np.float64]

#: How late [s] a reading may be stamped before the newest IMU sample by default.
DEFAULT_LAG = 1.0
#: Tuning instants :attr:`Navigator.q_history` keeps by default (an hour at 1 s).
Q_HISTORY = 3600


@dataclass(frozen=True)
class NavigatorState:
    """The navigation state at the newest epoch.

    Attributes:
        epoch: IMU samples fed (0: the initial state).
        time: the epoch's time [s].
        lla: ``(3,)`` latitude, longitude [rad], height [m, up] of the IMU.
        vel: ``(3,)`` NED velocity [m/s].
        rpy: ``(3,)`` roll, pitch, yaw [rad].
        bias: ``(6,)`` ``[b_a (m/s²), b_g (rad/s)]``.
        sigma: ``(15,)`` 1σ of the errors (position NED [m], velocity [m/s], attitude
            [rad], biases), the covariance brought up to date.
        calibration, calibration_sigma: ``(7,)`` the DVL error states
            (:data:`pronet.filter.CALIBRATION_COLUMNS`) and the 1σ of
            ``[δk, δμ, δb]``, or None without them.
    """

    epoch: int
    time: float
    lla: F64
    vel: F64
    rpy: F64
    bias: F64
    sigma: F64
    calibration: F64 | None
    calibration_sigma: F64 | None


@dataclass(frozen=True)
class StreamTally:
    """What a navigator did with one stream's readings so far.

    Attributes:
        name: the stream's name in messages (the navigator's ``names``, else
            ``streams[i]``).
        kind: ``"velocity"``, ``"depth"``, ``"fix"`` or ``"heading"``.
        received: readings fed (an invalid one raises, uncounted).
        queued: waiting for the IMU to reach them.
        accepted, rejected: applied and accepted, or rejected by the innovation gate.
        late: of those applied, the ones that came late: stamped before the newest IMU
            sample when fed.
        refused: stamped before the lag window.
        skipped: stamped before the first IMU sample's half step (outside the pass).
        nis_sum, dof: the applied readings' NIS summed, and their components.
    """

    name: str
    kind: str
    received: int
    queued: int
    accepted: int
    rejected: int
    late: int
    refused: int
    skipped: int
    nis_sum: float
    dof: int

    @property
    def mean_nis_per_dof(self) -> float:
        """Mean NIS per degree of freedom of the applied readings (1 when consistent;
        NaN before any)."""
        return self.nis_sum / self.dof if self.dof else float("nan")


class Navigator:
    """The filter pass fed as the data arrives (see the module docstring for the rule).

    Args:
        streams: :class:`pronet.Dvl`, :class:`pronet.Depth`, :class:`pronet.Fix`,
            :class:`pronet.Heading` without rows (e.g. ``Depth([], [], sigma=0.05,
            lever_arm=...)``): each sensor's noise, frame, lever arm and gate; readings
            are fed by the stream's index.
        initial: where it starts (:func:`pronet.recorded.initial.initial_state` finds one
            in a recording's first seconds, as ``pronet navigate`` does); its
            ``p0_sigma`` is the filter's initial 1σ.
        strategy: a native strategy (``Strategy.constant``, ``adaptive``, ``mehra``) or
            a :class:`pronet.strategies.Learned` regressor.
        config: the filter's tuning (default ``FilterConfig()``); ``p0_sigma`` comes from
            ``initial``.
        bias0: ``(6,)`` initial ``[b_a, b_g]`` estimate (default zeros).
        lag: how late [s] a reading may be stamped before the newest IMU sample and still
            be applied at its own epoch (finite, >= 0). The history of the lag window is
            kept in memory: a feed about to outgrow what this process can still take is
            a ``ValueError`` naming ``lag`` (docs/results/performance.md, "Memory").
        checkpoint_every: a copy of the filter every so many epochs (>= 1): a late
            reading costs at most this many IMU steps more; each copy is ~8 kB.
        imu_dt: the IMU's sample period [s], for a learned strategy's tuning instants
            (required with one).
        window: raw samples per window the regressor reads.
        guardrails: bounds on the regressor's q (default :class:`Guardrails`).
        names: each stream's name in the navigator's errors, :meth:`tally` and
            :meth:`findings`, one per stream: the sensor or topic its user knows it by
            (:func:`navigator_for` gives ``"dvl"``, ``"depth"``, …). None:
            ``streams[i]``.
        q_history: how many of a learned strategy's latest tuning instants
            :attr:`q_history` keeps (>= 1; default :data:`Q_HISTORY`, an hour at the
            1 s period): the navigator's memory stays bounded however long it runs.

    As :func:`pronet.run_filter` does, the navigator refuses with a ``ValueError`` the
    unit and frame slips the data show: an ``initial.lla`` in degrees; a first feed of
    IMU samples whose specific force points away from where ``initial.rpy`` puts it
    (an IMU in FLU), or, over a second or more, is not gravity's; a first sample more
    than 5 IMU periods after ``initial.t0`` (with ``imu_dt``); a depth beyond the
    deepest ocean (in pascals?). Nothing is fed before the check. A reading refused
    is named by its stream and its time (``depth: the reading at 12.5 s: …``).
    """

    def __init__(
        self,
        streams: Sequence[Stream],
        *,
        initial: InitialState,
        strategy: StrategyLike,
        config: _core.FilterConfig | None = None,
        bias0: ArrayLike | None = None,
        lag: float = DEFAULT_LAG,
        checkpoint_every: int = 32,
        imu_dt: float | None = None,
        window: int = DEFAULT_WINDOW,
        guardrails: Guardrails | None = None,
        names: Sequence[str] | None = None,
        q_history: int = Q_HISTORY,
    ) -> None:
        check_type(initial, InitialState, "initial")
        kept = count(q_history, "q_history", 10**9)
        if kept < 1:
            raise ValueError(f"q_history: must be at least 1, got {kept}")
        named = _names(names, len(streams))
        self._names = named or [f"streams[{i}]" for i in range(len(streams))]
        base = _core.FilterConfig() if config is None else config
        check_type(base, _core.FilterConfig, "config")
        p0 = [float(v) for v in float_array(initial.p0_sigma, "initial.p0_sigma", (15,))]
        cfg = filter_config({"p0_sigma": p0}, "the initial state", base)
        if beyond := angles_beyond(float_array(initial.lla, "initial.lla", (3,)), "initial.lla"):
            raise ValueError(beyond)
        if beyond := attitude_beyond(float_array(initial.rpy, "initial.rpy", (3,)), "initial.rpy"):
            raise ValueError(beyond)
        native_strategy, learned = native_of(strategy)
        check_type(native_strategy, _core.Strategy, "strategy")
        if learned is not None and imu_dt is None:
            raise ValueError(
                "imu_dt: a learned strategy's tuning instants need the IMU's sample period [s]"
            )
        self._native = _core.Navigator(
            list(streams),
            t0=scalar(initial.t0, "initial.t0"),
            lla0=initial.lla,
            vel0=initial.vel,
            rpy0=initial.rpy,
            config=cfg,
            strategy=native_strategy,
            bias0=bias0,
            lag=lag,
            checkpoint_every=checkpoint_every,
            tuning_period=None if learned is None else learned.tuning_period,
            imu_dt=None if learned is None or imu_dt is None else scalar(imu_dt, "imu_dt"),
            window=window,
        )
        self._depth_streams = {i for i, st in enumerate(streams) if isinstance(st, _core.Depth)}
        self._config_dt = cfg.imu_dt
        dt = None if imu_dt is None else scalar(imu_dt, "imu_dt")
        self._start = (scalar(initial.t0, "initial.t0"), initial.rpy, dt)
        self._regressor = None if learned is None else for_loop(learned.regressor)
        if self._regressor is not None:  # a window it cannot read: said now, not mid-run
            try:
                _predictions(self._regressor, np.zeros((1, 6, window), dtype=np.float32))
            except Exception as exc:  # noqa: BLE001 - any model's own refusal, named
                raise ValueError(
                    f"window: the strategy's regressor cannot read a window of {window} "
                    f"samples: {failure_reason(exc)}"
                ) from exc
        self._guardrails = Guardrails() if guardrails is None else guardrails
        check_type(self._guardrails, Guardrails, "guardrails")
        prior = np.zeros(6) if learned is None else learned.prior_q
        self._q_prev = np.asarray(prior, dtype=np.float64)
        #: guardrail events of the learned loop so far: entries clipped into range and
        #: non-finite predictions replaced by the last good q
        self.clipped = 0
        self.non_finite = 0
        #: q set at each of the latest ``q_history`` tuning instants: ``(epoch, q (6,))``
        self.q_history: deque[tuple[int, F64]] = deque(maxlen=kept)

    def imu(self, time: float, sample: ArrayLike) -> None:
        """Feed one IMU sample ``[f (m/s²), ω (rad/s)]`` (body FRD) ending at ``time``
        [s], after the newest; a tuning instant sets q before the next."""
        if self._native.epoch == 0:
            self._check_start(
                np.array([time], dtype=np.float64), float_array(sample, "imu", (6,))[None]
            )
        self._native.imu(time, sample)
        if self._regressor is not None and self._native.tuning_due:
            self._tune()

    def imu_block(self, times: ArrayLike, samples: ArrayLike) -> None:
        """Feed IMU samples ``(n, 6)`` ending at ``times`` ``(n,)`` [s], in order: the
        batch speed, the learned loop run at its instants in between."""
        t = float_array(times, "imu_time", (None,))
        s = float_array(samples, "imu", (len(t), 6))
        if self._native.epoch == 0:
            self._check_start(t, s)
        done = 0
        while done < len(t):
            done += self._native.imu_block(t[done:], s[done:])
            if self._regressor is not None and self._native.tuning_due:
                self._tune()

    def reading(
        self, stream: int, time: float, value: ArrayLike, sigma: ArrayLike | None = None
    ) -> str:
        """Feed the reading ``value`` of ``streams[stream]`` stamped ``time`` [s] (a
        velocity ``(3,)`` [m/s], a depth [m], a fix ``[φ, λ (rad), h (m, NaN: none)]``, a
        heading [rad]) with its own 1σ ``sigma`` (None: the stream's). Returns what
        became of it: ``"queued"`` (for an epoch still to come), ``"current"`` (stamped
        within the newest epoch's half step, applied there), ``"late"`` (applied at
        its own, already run), ``"refused"`` (before the lag window) or ``"skipped"``
        (before the pass's start). A reading refused is a ``ValueError`` naming its
        stream and time."""
        try:
            if _index(stream) in self._depth_streams:
                depth = np.atleast_1d(np.asarray(value, dtype=np.float64))
                if (beyond := depth_beyond(depth, f"streams[{stream}]")) is not None:
                    raise ValueError(beyond)
            return self._native.reading(stream, time, value, sigma)
        except ValueError as exc:
            raise ValueError(self._reading_error(str(exc), stream, time)) from None

    def _reading_error(self, message: str, stream: object, time: object) -> str:
        """``message`` of a refused reading, naming its stream and time instead of
        ``streams[i]`` (as is where ``stream`` is no stream's index)."""
        k = _index(stream)
        if k is None or not 0 <= k < len(self._names):
            return message
        token = f"streams[{k}]"
        if message.startswith(f"{token}: "):
            message = message[len(token) + 2 :]
        elif message.startswith(f"{token}_"):  # the core's streams[i]_time, streams[i]_sigma
            message = message[len(token) + 1 :]
        try:
            when = f"{float(time):.10g} s"  # type: ignore[arg-type]
        except (TypeError, ValueError):
            when = repr(time)
        return f"{self._names[k]}: the reading at {when}: {message}"

    def _check_start(self, times: F64, samples: F64) -> None:
        """The first IMU samples fed against the initial state (see the class)."""
        t0, rpy, imu_dt = self._start
        if len(times) and imu_dt is not None and times[0] - t0 > MAX_IMU_GAP * imu_dt:
            raise ValueError(
                f"imu_time: the first sample ({times[0]:.10g} s) is {times[0] - t0:.4g} s after "
                f"initial.t0 ({t0:.10g} s), {(times[0] - t0) / imu_dt:.3g} IMU periods, over "
                "which it would be integrated; are they on one clock, in seconds?"
            )
        check_imu_start(samples, times, float_array(rpy, "initial.rpy", (3,)))

    def state(self) -> NavigatorState:
        """The estimate at the newest epoch (σ brought up to date on a copy: asking
        changes nothing that follows)."""
        return NavigatorState(**self._native.state())

    def tally(self) -> list[StreamTally]:
        """Each stream's tally so far, in the streams' order."""
        tallies = self._native.tally()
        return [StreamTally(**{**t, "name": n}) for t, n in zip(tallies, self._names, strict=True)]

    def findings(self) -> list[str]:
        """What the pass says about itself so far, one line each, as
        :attr:`pronet.FilterResult.health`'s ``flags`` say it of a batch pass: whether
        its IMU stamps left a gap (a step beyond 5 usual ones) or step otherwise than
        ``config.imu_dt`` (by over 15 %: the process noise is off by their ratio,
        :func:`pronet._util.plausibility.imu_period`), whether its solution
        left a physical bound (watched at every epoch), whether its heading σ passed 5°,
        then each stream whose mean NIS is out of its band or whose gate
        rejected more than a few readings ("" lines left out)."""
        extent = Extent(*self._native.extent())
        gaps = self._native.imu_gaps()
        period = imu_period(self._config_dt, gaps[-1]) or ""
        lines = [gaps_fed(*gaps), period, divergence(extent), heading_linearity(extent)]
        for t in self.tally():
            lines.append(tally_flag(t.name, t.kind, t.nis_sum, t.dof, t.accepted, t.rejected))
        return [line for line in lines if line]

    @property
    def epoch(self) -> int:
        """IMU samples fed."""
        return self._native.epoch

    @property
    def failure(self) -> str | None:
        """The error that stopped the navigator (every later call raises it), or None."""
        return self._native.failure

    def _tune(self) -> None:
        """Run the regressor on the window and set its guarded q from the next sample."""
        assert self._regressor is not None
        window = self._native.window
        assert window is not None
        q = _predictions(self._regressor, window[None])
        if q.shape != (1, 6):
            raise ValueError(
                f"regressor: predict returned shape {q.shape} for one window; expected (1, 6)"
            )
        guarded, non_finite, clipped = apply_guardrails(q, self._q_prev[None], self._guardrails)
        self.non_finite += int(non_finite.sum())
        self.clipped += int(clipped.sum())
        self._q_prev = guarded[0]
        self._native.set_q(self._q_prev)
        self.q_history.append((self._native.epoch, self._q_prev))


@dataclass(frozen=True)
class TimedReading:
    """One reading to feed: its time [s], its stream's index, its value and 1σ (as
    :meth:`Navigator.reading` takes them)."""

    time: float
    stream: int
    value: F64
    sigma: F64 | None


def navigator_for(
    section: Section,
    vehicle: VehicleTuning,
    arms: LeverArms = LeverArms(),  # noqa: B008 - frozen
    options: NavigateOptions = NavigateOptions(),  # noqa: B008 - frozen
    *,
    lag: float = DEFAULT_LAG,
    checkpoint_every: int = 32,
) -> tuple[Navigator, Setup]:
    """A navigator set up as :func:`pronet.recorded.navigate.navigate` sets up its
    filter for ``section``, and that set-up (:func:`pronet.recorded.navigate.setup`).

    ``section`` is the data so far: on a vehicle, the first minutes (the initial state
    found in them as ``pronet navigate`` finds it, q from their IMU noise, the surface
    pressure from their surface fixes); after a dive, the whole recording. The streams
    are navigate's, in its order: the DVL (index 0, the tuning's R and lever arm), then
    the depth, the fixes and the heading where used (:attr:`Setup.aiding`), each with
    the σ of its first reading (a reading fed without its own σ takes it), each named
    by its sensor (``"dvl"``, ``"depth"``, ``"fix"``, ``"heading"``) in the navigator's
    errors, tally and findings.
    :func:`readings_of` gives the section's own readings in time order. Fed the
    section's IMU samples after ``initial.t0`` and those readings in time order, its
    epochs are navigate's forward solution's (before the move to the reference point).
    """
    made = setup(section, vehicle, arms, options)
    templates: list[Stream] = [_core.Dvl([], np.zeros((0, 3)))]
    templates += [_without_rows(s) for s in made.aiding]
    after = section.imu_time[section.imu_time > made.initial.t0]
    imu_dt = float(np.median(np.diff(after))) if len(after) > 1 else None
    nav = Navigator(
        templates,
        initial=made.initial,
        strategy=made.strategy,
        config=made.config,
        lag=lag,
        checkpoint_every=checkpoint_every,
        imu_dt=imu_dt,
        names=sensor_names(templates),
    )
    return nav, made


def _index(stream: object) -> int | None:
    """``stream`` as a stream's index where it is a whole number (NumPy's too), else None
    (a bool, a list: the core names it, ``stream: expected a whole number, got list``)."""
    if isinstance(stream, int | np.integer) and not isinstance(stream, bool):
        return int(stream)
    return None


def _without_rows(stream: Stream) -> Stream:
    """``stream``'s sensor (σ, lever arm) without its rows."""
    if isinstance(stream, _core.Depth):
        sigma = np.ravel(stream.sigma)[0]
        return _core.Depth([], [], sigma=sigma, lever_arm=stream.lever_arm)
    if isinstance(stream, _core.Fix):
        sigma3 = np.asarray(stream.sigma).reshape(-1, 3)[0]
        return _core.Fix([], np.zeros((0, 3)), sigma=sigma3, lever_arm=stream.lever_arm)
    if isinstance(stream, _core.Heading):
        return _core.Heading([], [], sigma=np.ravel(stream.sigma)[0])
    raise ValueError(f"stream: expected a Depth, Fix or Heading, got {type(stream).__name__}")


def _values(stream: Stream) -> F64:
    """A depth, fix or heading stream's rows."""
    if isinstance(stream, _core.Depth):
        return stream.depth
    if isinstance(stream, _core.Fix):
        return stream.lla
    if isinstance(stream, _core.Heading):
        return stream.heading
    raise ValueError(f"stream: expected a Depth, Fix or Heading, got {type(stream).__name__}")


def readings_of(made: Setup) -> list[TimedReading]:
    """The readings of a set-up's streams in time order, as :func:`navigator_for`'s
    navigator numbers them (a tie in time: the lower stream first)."""
    out = [
        TimedReading(float(t), 0, v, None)
        for t, v in zip(made.streams.dvl_time, made.streams.dvl, strict=True)
    ]
    for i, s in enumerate(made.aiding, start=1):
        values = _values(s)
        n = len(s.time)
        sigma = np.broadcast_to(np.asarray(s.sigma, dtype=np.float64), (n, *np.shape(values)[1:]))
        out += [
            TimedReading(float(t), i, np.atleast_1d(v), np.atleast_1d(sg))
            for t, v, sg in zip(s.time, values, sigma, strict=True)
        ]
    out.sort(key=lambda r: (r.time, r.stream))
    return out
