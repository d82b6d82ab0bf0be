"""Windows for truncated back-propagation: the core runs whole passes with a q schedule,
and the passes are cut into windows of equal length that start where the core's P is up
to date (the pass's start, or right after a DVL update), each with the core's state
there as its detached start (:func:`windows`). The gradient then flows within a window
only; the starts come from the filter users run."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray
from torch import Tensor

from pronet import _core
from pronet.filter import FilterResult, run_filter
from pronet.learn.torchfilter.state import (
    Batch,
    State,
    as_tensor,
    dvl_epochs,
    sensor_batch,
    start_state,
)


class Pass(Protocol):
    """A pass over recorded sensors as :class:`pronet.run.Recorded` holds it (the
    arrays and start of :func:`pronet.run_filter`, and the filter's config)."""

    @property
    def imu(self) -> NDArray[np.float64]: ...
    @property
    def imu_time(self) -> NDArray[np.float64]: ...
    @property
    def dvl(self) -> NDArray[np.float64]: ...
    @property
    def dvl_time(self) -> NDArray[np.float64]: ...
    @property
    def t0(self) -> float: ...
    @property
    def lla0(self) -> NDArray[np.float64]: ...
    @property
    def vel0(self) -> NDArray[np.float64]: ...
    @property
    def rpy0(self) -> NDArray[np.float64]: ...
    @property
    def config(self) -> _core.FilterConfig: ...


def per_sample_q(
    q_time: ArrayLike, q: ArrayLike, imu_time: ArrayLike, t0: float, prior_q: ArrayLike
) -> NDArray[np.float64]:
    """``(n, 6)`` the IMU variances in force at each sample of a pass under the core's
    schedule rule (:func:`pronet.run_filter`'s ``q_time``, ``q`` with
    ``Strategy.external(prior_q)``): row j is set before the step whose start is within
    half a step of ``q_time[j]`` (``q_time[j] ≤ t_{k-1} + Δt_k/2``)."""
    t = np.asarray(imu_time, dtype=np.float64)
    start = np.concatenate([[t0], t[:-1]])
    reach = start + 0.5 * (t - start)
    times = np.asarray(q_time, dtype=np.float64).reshape(-1)
    rows = np.vstack([np.asarray(prior_q, dtype=np.float64)[None], np.reshape(q, (-1, 6))])
    # the number of rows set by sample k: those with q_time <= max reach so far
    count = np.searchsorted(times, np.maximum.accumulate(reach), side="right")
    return rows[count]


def take(batch: Batch, first: int, length: int) -> Batch:
    """Samples ``first..first + length`` of every sequence of ``batch``."""
    cut = slice(first, first + length)
    return replace(
        batch,
        imu=batch.imu[:, cut],
        dt=batch.dt[:, cut],
        time=batch.time[:, cut],
        dvl=batch.dvl[:, cut],
        dvl_mask=batch.dvl_mask[:, cut],
        last=batch.last[:, cut],
    )


def state_at(result: FilterResult, epochs: ArrayLike, batch: Batch) -> State:
    """The core's state at ``epochs`` of a pass (B = len(epochs)): its solution and
    biases there and the covariance ``result.covariances`` kept at those epochs (in
    order; classic coordinates, mapped into the filter's own at the epoch's velocity).
    The epochs must be ones where P is up to date (the start, or after a DVL update):
    the reported σ there is P's own. ``batch``: the pass's (its setup). The last
    bias-corrected rate (the lever arm's term) starts at zero: the next sample sets it
    before any update reads it. No covariance step is under way there."""
    e = np.asarray(epochs, dtype=np.int64)
    if len(result.covariances) != len(e) or not np.array_equal(result.covariance_epoch, e):
        raise ValueError("epochs: the result must keep the covariance at exactly these epochs")
    state = start_state(
        result.lla[e], result.vel[e], result.rpy[e], result.covariances,
        result.time[e], batch.setup, result.bias[e],
    )  # fmt: skip
    return replace(state, var_current=as_tensor(result.sigma[e] ** 2)).detach()


@dataclass(frozen=True)
class Windows:
    """Windows cut from passes the core ran (W windows of T samples).

    Attributes:
        batch: the windows' sensors, ``(W, T, ...)``.
        start: the core's state at each window's first epoch (detached).
        q: ``(W, T, 6)`` the IMU variances the core had in force at each sample.
        section: ``(W,)`` the pass each window came from; first: ``(W,)`` the epoch of
            its pass it starts at (its first sample is the pass's sample ``first``).
        core: the core's run of each pass (``FilterResult``), in order (None for a
            pass too short for a window).
    """

    batch: Batch
    start: State
    q: Tensor
    section: NDArray[np.int64]
    first: NDArray[np.int64]
    core: list[FilterResult | None]


def window_starts(
    imu_time: NDArray[np.float64], t0: float, dvl_time: ArrayLike, length: int
) -> list[int]:
    """The epochs windows of ``length`` samples start at: the pass's start, then each
    first epoch with a DVL update at least ``length`` samples after the last start, as
    long as a whole window fits."""
    n = len(imu_time)
    epochs = dvl_epochs(imu_time, t0, np.asarray(dvl_time, dtype=np.float64))
    updates = np.unique(epochs[(epochs >= 1) & (epochs <= n)])
    starts, nxt = [], 0
    for e in [0, *updates.tolist()]:
        if e >= nxt and e + length <= n:
            starts.append(int(e))
            nxt = e + length
    return starts


def windows(
    passes: Sequence[Pass],
    schedules: Sequence[tuple[ArrayLike, ArrayLike]],
    prior_q: ArrayLike,
    seconds: float,
) -> Windows:
    """Run the core over each of ``passes`` (``pronet.run.Recorded``, as
    :func:`pronet.recorded.passes.section_recorded` makes them; one setup for all) with
    its q schedule ``(q_time (k,), q (k, 6))`` under ``Strategy.external(prior_q)``, and
    cut them into windows of ``seconds`` (a whole number of the first pass's nominal IMU
    periods) starting at :func:`window_starts`."""
    if len(passes) != len(schedules) or not passes:
        raise ValueError("schedules: one (q_time, q) per pass, at least one pass")
    length = int(round(seconds / passes[0].config.imu_dt))
    if length < 1:
        raise ValueError(f"seconds: must be at least one IMU period, got {seconds}")
    parts, states, qs, section, first = [], [], [], [], []
    core: list[FilterResult | None] = []
    for i, (rec, (q_time, q)) in enumerate(zip(passes, schedules, strict=True)):
        starts = window_starts(rec.imu_time, rec.t0, rec.dvl_time, length)
        if not starts:
            core.append(None)
            continue
        epoch_time = np.concatenate([[rec.t0], rec.imu_time])
        result = run_filter(
            rec.imu, rec.imu_time, [_core.Dvl(rec.dvl_time, rec.dvl)], t0=rec.t0, lla0=rec.lla0,
            vel0=rec.vel0, rpy0=rec.rpy0, config=rec.config,
            strategy=_core.Strategy.external(prior_q), q_time=q_time, q=q,
            covariance_time=epoch_time[starts], warn=False,
        )  # fmt: skip
        whole = sensor_batch(rec.imu, rec.imu_time, rec.dvl, rec.dvl_time, rec.t0, rec.config)
        in_force = torch.as_tensor(per_sample_q(q_time, q, rec.imu_time, rec.t0, prior_q))
        states.append(state_at(result, starts, whole))
        parts += [take(whole, e, length) for e in starts]
        qs += [in_force[e : e + length] for e in starts]
        section += [i] * len(starts)
        first += starts
        core.append(result)
    if not parts:
        raise ValueError(f"seconds: no pass is long enough for a window of {seconds} s")
    start = State(
        **{k: torch.cat([getattr(s, k) for s in states]) for k in State.__dataclass_fields__}
    )
    return Windows(
        Batch.stack(parts), start, torch.stack(qs), np.array(section), np.array(first), core
    )
