"""Training model (c), the A-KIT-like Q model (:mod:`pronet.learn.akit`), through the
differentiable filter: the torch filter runs each window chunk by chunk between the
windows' tuning instants and the net recomputes q at each from the IMU window and the
filter's velocity there, so the gradient reaches the net through q and through the
velocity it fed back (docs/how-to/learning-q.md, "Learning from recorded missions")."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray

from pronet import _core
from pronet.experiments.qlearn.gradient import (
    RecordedTraining,
    _schedule,
    kalman_loss,
    minibatch_epoch,
    picked,
    window_targets,
)
from pronet.experiments.qlearn.sections import TrainingSection
from pronet.learn.akit import AkitNet
from pronet.recorded.passes import section_recorded
from pronet.run import Recorded

F64 = NDArray[np.float64]


def _core_velocity_plan(
    net: AkitNet, ts: TrainingSection, rec: Recorded, sc: Any, prev: tuple[F64, F64]
) -> tuple[F64, F64]:
    """One fixed-point step of the closed loop on the core: the velocity at the
    instants from a core pass with the previous plan ``prev``, then the net's q there
    (the windows' start states come from this plan; the gradient does not)."""
    result = rec.filter(_core.Strategy.external(tuple(ts.q_nominal)), *prev, aided=False)
    with torch.no_grad():
        q = net(sc.windows, torch.as_tensor(result.vel[sc.ends]))
    return np.concatenate([[rec.t0], sc.time]), np.vstack([np.array([ts.q_nominal]), q.numpy()])


def _chunked_loss(
    net: AkitNet,
    sections: Sequence[TrainingSection],
    scheds: Sequence[Any],
    passes: Sequence[Recorded],
    plans: Sequence[tuple[F64, F64]],
    win: Any,
    pick: NDArray[np.intp],
    hp: RecordedTraining,
) -> torch.Tensor:
    """The Kalman-informed loss of the picked windows, the torch filter run chunk by
    chunk between the union of their instants, each window's q recomputed at its own
    instants from its IMU window and the filter's velocity there."""
    from pronet.learn.torchfilter import Outputs, advance

    length = int(win.q.shape[1])
    state, batch = picked(win, pick)
    b_size = len(pick)
    q = torch.stack([torch.as_tensor(plans[int(win.section[w])][1])[
        scheds[int(win.section[w])].count[int(win.first[w])]] for w in pick])  # fmt: skip
    # each window's instants inside it: sample offsets where its schedule changes
    marks = np.zeros((b_size, length), dtype=bool)
    where = np.full((b_size, length), -1)
    for b, w in enumerate(pick):
        s, first = int(win.section[w]), int(win.first[w])
        k = np.searchsorted(scheds[s].ends, [first, first + length])
        for j in range(k[0], k[1]):
            off = int(scheds[s].ends[j]) - first
            if 0 < off < length:  # at offset 0 the plan's row is already in force
                marks[b, off], where[b, off] = True, j
    cuts = sorted({0, length, *np.flatnonzero(marks.any(axis=0)).tolist()})
    start_vel = state.vel
    chunks = []
    for k0, k1 in zip(cuts[:-1], cuts[1:], strict=True):
        if k0 > 0 and marks[:, k0].any():
            rows = [b for b in range(b_size) if marks[b, k0]]
            wins = torch.stack(
                [scheds[int(win.section[pick[b]])].windows[where[b, k0]] for b in rows]
            )
            q = q.clone()  # the earlier chunks keep their q in the graph
            q[rows] = net(wins, state.vel[rows])
        state, out = advance(state, batch, k0, k1, q)
        chunks.append(out)
    targets = window_targets(sections, passes, win, pick)
    return kalman_loss(start_vel, Outputs.cat(chunks), targets, hp.nll)


def train_akit(
    sections: Sequence[TrainingSection],
    hp: RecordedTraining | None = None,
    progress: Callable[[str], None] | None = None,
) -> tuple[AkitNet, dict[str, Any]]:
    """Model (c) trained on ``sections`` through the torch filter (see the module)."""
    from pronet.learn.torchfilter.windows import windows as core_windows

    hp = hp or RecordedTraining()
    threads = torch.get_num_threads()
    torch.set_num_threads(hp.threads)
    try:
        torch.manual_seed(hp.seed)
        net = AkitNet().double()
        opt = torch.optim.Adam(net.parameters(), lr=hp.lr)
        scheds = [_schedule(ts) for ts in sections]
        passes = [section_recorded(ts.section, ts.config) for ts in sections]
        plans = [
            (np.array([p.t0]), np.array([ts.q_nominal]))
            for ts, p in zip(sections, passes, strict=True)
        ]
        rng = np.random.default_rng(hp.seed)
        history, begin = [], time.perf_counter()
        for epoch in range(hp.epochs):
            plans = [
                _core_velocity_plan(net, ts, p, sc, plan)
                for ts, p, sc, plan in zip(sections, passes, scheds, plans, strict=True)
            ]
            win = core_windows(passes, plans, sections[0].q_nominal, hp.seconds)
            loss, *_ = minibatch_epoch(
                len(win.section),
                partial(_chunked_loss, net, sections, scheds, passes, plans, win, hp=hp),
                opt,
                rng,
                hp,
            )
            history.append(loss)
            if progress is not None:
                progress(
                    f"akit epoch {epoch + 1}/{hp.epochs}: loss {history[-1]:.4g} "
                    f"({time.perf_counter() - begin:.0f} s)"
                )
    finally:
        torch.set_num_threads(threads)
    record = {
        "loss": history,
        "seconds": time.perf_counter() - begin,
        "hyperparameters": hp.__dict__,
        "sections": [ts.name for ts in sections],
    }
    return net, record
