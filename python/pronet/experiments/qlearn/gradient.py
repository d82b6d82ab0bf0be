"""Training a windowed CNN Q model on recorded missions through the differentiable
filter (model (b) of docs/how-to/learning-q.md, "Learning from recorded missions").

The model is a scale-free :class:`pronet.learn.models.DetrendNet` per channel
(``scaling="spread"``: ``ln q = ln s² + z(window)``; untrained, q is the window's own
detrended variance). Its q schedule over a section is the hybrid loop's: a window of
the last 200 samples every tuning period (1 s), in force from the window's newest
sample on (:func:`pronet.learn.hybrid.q_schedule`'s instants and the core's rule).

The loss (Kalman-informed): the torch filter
(:mod:`pronet.learn.torchfilter`, equal to the core to 1e-9) runs the training
sections' windows with that schedule, and the loss is the mean squared NED velocity
error at the ground-truth rows inside the windows (linearly interpolated between
epochs as :mod:`pronet.recorded.metrics` scores), optionally plus ``nll`` times the
Gaussian negative log-likelihood of those errors under the filter's own σ. The gradient
flows through the filter into q and the net; truncated back-propagation: each window
starts from the core's detached state, and the windows are cut afresh from core passes
with the current model's schedule at every epoch.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray

from pronet import _core
from pronet.experiments.qlearn.sections import TrainingSection
from pronet.learn.hybrid import DEFAULT_TUNING_PERIOD, DEFAULT_WINDOW
from pronet.learn.models import DetrendNet
from pronet.recorded.passes import section_recorded

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class RecordedTraining:
    """Hyperparameters of :func:`train_cnn` (fixed before any section is scored).

    Attributes:
        epochs: passes over the windows (each starts with fresh windows from the core).
        seconds: window length [s] of the truncated back-propagation.
        lr: Adam's step; nll: weight of the NLL term (0: the velocity error alone).
        seed: the net's initial weights.
        max_windows: windows per gradient step (a random subset each step; 0: all);
            the graph of one window of 5 s holds about 45 MB, so this bounds memory.
        steps: gradient steps per epoch (each on its own windows; 0: one pass over
            all the windows).
        threads: torch's threads (the filter's loop is many small operations, fastest
            on one thread; the process's previous setting is restored afterwards).
    """

    epochs: int = 8
    seconds: float = 5.0
    lr: float = 3e-3
    nll: float = 0.0
    seed: int = 0
    max_windows: int = 16
    steps: int = 10
    threads: int = 1


@dataclass(frozen=True)
class _Schedule:
    """A section's tuning instants: sample ends ``ends`` (k,), their times, the raw
    windows ``(k, 6, N)`` and ``count`` (n,): the schedule row in force at each sample
    (0: the prior, j: instant j − 1), under the core's rule."""

    ends: NDArray[np.intp]
    time: F64
    windows: torch.Tensor
    count: NDArray[np.intp]


def _schedule(ts: TrainingSection) -> _Schedule:
    rec = section_recorded(ts.section, ts.config)
    n = len(rec.imu)
    dt = float(np.median(np.diff(rec.imu_time)))
    ends = _core.tuning_instants(n, dt, DEFAULT_WINDOW, DEFAULT_TUNING_PERIOD)
    strided = np.lib.stride_tricks.sliding_window_view(rec.imu, DEFAULT_WINDOW, 0)
    windows = torch.as_tensor(np.ascontiguousarray(strided[ends - DEFAULT_WINDOW]))
    q_time = rec.imu_time[ends - 1]
    start = np.concatenate([[rec.t0], rec.imu_time[:-1]])
    reach = start + 0.5 * (rec.imu_time - start)
    count = np.searchsorted(q_time, np.maximum.accumulate(reach), side="right")
    return _Schedule(ends, q_time, windows, count)


def core_plan(ts: TrainingSection, rec: Any, sc: _Schedule, rows: F64) -> tuple[F64, F64]:
    """The core's schedule of a section (``rec`` its pass, ``sc`` its instants): its
    constant row's q from the start (the hybrid loop's prior until the first window is
    full), then ``rows`` at the tuning instants."""
    return np.concatenate([[rec.t0], sc.time]), np.vstack([np.array([ts.q_nominal]), rows])


def net_q(net: DetrendNet, windows: torch.Tensor) -> torch.Tensor:
    """q ``(k, 6)`` of raw windows ``(k, 6, N)`` (float64 through the net)."""
    k = windows.shape[0]
    return torch.exp(net.log_q(windows.reshape(k * 6, -1))).reshape(k, 6)


def _truth_index(ts: TrainingSection, times: F64) -> tuple[NDArray[np.intp], F64, F64, F64]:
    """For the truth rows strictly inside ``times`` (a window's epoch times): the epoch
    index i below each, the weight w of epoch i + 1, and the truth velocity ``(r, 3)``."""
    s = ts.section
    rows = np.flatnonzero((s.truth_time > times[0]) & (s.truth_time <= times[-1]))
    t = s.truth_time[rows]
    i = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(times) - 2)
    w = (t - times[i]) / (times[i + 1] - times[i])
    return i, w, s.truth_vel[rows], t


def train_cnn(
    sections: Sequence[TrainingSection],
    hp: RecordedTraining | None = None,
    progress: Callable[[str], None] | None = None,
) -> tuple[DetrendNet, dict[str, Any]]:
    """Model (b) trained on ``sections`` (see the module); returns the net (float32
    weights, as model files hold them) and the training record."""

    hp = hp or RecordedTraining()
    threads = torch.get_num_threads()
    torch.set_num_threads(hp.threads)
    try:
        return _train_cnn(sections, hp, progress)
    finally:
        torch.set_num_threads(threads)


def _train_cnn(
    sections: Sequence[TrainingSection],
    hp: RecordedTraining,
    progress: Callable[[str], None] | None,
) -> tuple[DetrendNet, dict[str, Any]]:
    from pronet.learn.torchfilter.windows import windows as core_windows

    torch.manual_seed(hp.seed)
    net = DetrendNet(window=DEFAULT_WINDOW, scaling="spread").double()
    opt = torch.optim.Adam(net.parameters(), lr=hp.lr)
    scheds = [_schedule(ts) for ts in sections]
    passes = [section_recorded(ts.section, ts.config) for ts in sections]
    rng = np.random.default_rng(hp.seed)
    history = []
    start_time = time.perf_counter()
    for epoch in range(hp.epochs):
        with torch.no_grad():
            plans = [
                core_plan(ts, p, sc, net_q(net, sc.windows).numpy())
                for ts, p, sc in zip(sections, passes, scheds, strict=True)
            ]
        win = core_windows(passes, plans, sections[0].q_nominal, hp.seconds)
        loss, steps, step, n = minibatch_epoch(
            len(win.section),
            partial(_window_loss, net, sections, scheds, passes, win, hp=hp),
            opt,
            rng,
            hp,
        )
        history.append(loss)
        if progress is not None:
            progress(
                f"epoch {epoch + 1}/{hp.epochs}: loss {loss:.4g} "
                f"({steps} steps of {step} of {n} windows, "
                f"{time.perf_counter() - start_time:.0f} s)"
            )
    record = {
        "loss": history,
        "seconds": time.perf_counter() - start_time,
        "hyperparameters": hp.__dict__,
        "sections": [ts.name for ts in sections],
    }
    return net.float(), record


def minibatch_epoch(
    n: int,
    loss_of: Callable[[NDArray[np.intp]], torch.Tensor],
    opt: torch.optim.Optimizer,
    rng: np.random.Generator,
    hp: RecordedTraining,
) -> tuple[float, int, int, int]:
    """One epoch over ``n`` windows in an order drawn from ``rng``: mini-batches of
    ``hp.max_windows`` (all when 0), at most ``hp.steps`` of them (all when 0), one
    optimiser step on ``loss_of(picked window indices)`` each. Returns the mean loss,
    the steps taken, the batch size and ``n``."""
    order = rng.permutation(n)
    step = hp.max_windows or n
    starts = list(range(0, n, step))[: hp.steps or None]
    losses = []
    for b0 in starts:
        loss = loss_of(order[b0 : b0 + step])
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(float(loss.detach()))
    return float(np.mean(losses)), len(starts), step, n


def _window_loss(
    net: DetrendNet,
    sections: Sequence[TrainingSection],
    scheds: Sequence[_Schedule],
    passes: Sequence[Any],
    win: Any,
    pick: NDArray[np.intp],
    hp: RecordedTraining,
) -> torch.Tensor:
    """The Kalman-informed loss over the windows ``pick`` of ``win``, the net's q."""
    from pronet.learn.torchfilter import advance

    length = int(win.q.shape[1])
    qs = []
    for w in pick:
        s, first = int(win.section[w]), int(win.first[w])
        # the schedule rows in force over the window: the net on those instants only
        count = scheds[s].count[first : first + length]
        used, where = np.unique(count, return_inverse=True)
        prior = torch.as_tensor(sections[s].q_nominal, dtype=torch.float64)[None]
        late = used[used > 0]
        rows = net_q(net, scheds[s].windows[late - 1]) if len(late) else prior[:0]
        table = torch.cat([prior.expand(int(np.sum(used == 0)), 6), rows])
        qs.append(table[torch.as_tensor(where)])
    state, batch = picked(win, pick)
    _, out = advance(state, batch, 0, length, torch.stack(qs))
    targets = window_targets(sections, passes, win, pick)
    return kalman_loss(state.vel, out, targets, hp.nll)


def picked(win: Any, pick: NDArray[np.intp]) -> tuple[Any, Any]:
    """``(start state, batch)`` of the windows ``pick`` of ``win``."""
    from dataclasses import replace

    from pronet.learn.torchfilter import State

    at = torch.as_tensor(pick)
    batch = replace(
        win.batch,
        **{
            k: getattr(win.batch, k)[at]
            for k in ("imu", "dt", "time", "dvl", "dvl_mask", "last", "imu_dt",
                      "dvl_variance", "lever_arm", "bias_psd")
        },
    )  # fmt: skip
    state = State(**{k: getattr(win.start, k)[at] for k in State.__dataclass_fields__})
    return state, batch


#: Per window: the epoch below each truth row, its interpolation weight, the truth velocity.
Targets = list[tuple[NDArray[np.intp], F64, F64]]


def window_targets(
    sections: Sequence[TrainingSection], passes: Sequence[Any], win: Any, pick: NDArray[np.intp]
) -> Targets:
    """The truth rows inside each picked window (:func:`_truth_index`)."""
    length = int(win.q.shape[1])
    out = []
    for w in pick:
        s, first = int(win.section[w]), int(win.first[w])
        times = np.concatenate([[passes[s].t0], passes[s].imu_time])[first : first + length + 1]
        i, wt, v, _ = _truth_index(sections[s], times)
        out.append((i, wt, v))
    return out


def kalman_loss(vel0: torch.Tensor, out: Any, targets: Targets, nll: float) -> torch.Tensor:
    """The mean over the truth rows of the squared NED velocity error [(m/s)²] of the
    filter's outputs ``out`` (``vel0``: the windows' start velocity, epoch 0), plus
    ``nll`` times the Gaussian negative log-likelihood of the errors under its σ."""
    vel = torch.cat([vel0[:, None], out.vel], dim=1)  # epoch j: out[:, j - 1]
    sigma = None
    if nll > 0:
        sig = out.sigma[..., 3:6]
        sigma = torch.cat([sig[:, :1], sig], dim=1)
    total, n_rows = vel.new_zeros(()), 0
    for b, (idx, wts, truth) in enumerate(targets):
        if not len(idx):
            continue
        at = torch.as_tensor(idx)
        weight = torch.as_tensor(wts)[:, None]
        est = (1 - weight) * vel[b, at] + weight * vel[b, at + 1]
        err = est - torch.as_tensor(truth)
        total = total + (err**2).sum()
        if sigma is not None:
            sd = (1 - weight) * sigma[b, at] + weight * sigma[b, at + 1]
            total = total + nll * 0.5 * ((err / sd) ** 2 + 2 * torch.log(sd)).sum()
        n_rows += len(idx)
    return total / max(n_rows, 1)


def cnn_card(record: dict[str, Any]) -> dict[str, Any]:
    """The card entries of a model (b) file: how it was trained."""
    return {
        "trained_on": "recorded sections (Kalman-informed loss through the torch filter)",
        "training": record,
        "note": "a scale-free DetrendNet per IMU channel; run by learned:PATH",
    }


def log(text: str) -> None:
    """Progress on stderr."""
    print(f"pronet train: {text}", file=sys.stderr, flush=True)
