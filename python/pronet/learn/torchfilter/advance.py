"""The filter's loop over epochs: :func:`advance` runs B sequences from a
:class:`~pronet.learn.torchfilter.state.State` over samples ``k0..k1`` of a
:class:`~pronet.learn.torchfilter.state.Batch` with given IMU variances q, the same
algorithm as the core's ``filter_recorded`` (``rust/src/ekf/recorded.rs``): at each
sample the covariance step accumulates (or P moves, at every sample), the strapdown
step, the step's close when due (or at a DVL update, or at the pass's end), then the
DVL rows of the epoch, each an update with feedback."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import torch
from numpy.typing import NDArray
from torch import Tensor

from pronet.learn.torchfilter import ekf
from pronet.learn.torchfilter.earth import rates
from pronet.learn.torchfilter.mechanization import strapdown_step
from pronet.learn.torchfilter.outputs import Outputs, classic_variance
from pronet.learn.torchfilter.state import Batch, State, as_tensor


@dataclass(frozen=True)
class Schedule:
    """Where the covariance steps open and close over a call, ``(B, n)`` each, and the
    bias walks accumulated at each close ``(B, n, 6)``: all fixed by the time steps and
    the DVL rows, so computed before the loop (q does not move them)."""

    opens: NDArray[np.bool_]
    due: NDArray[np.bool_]
    span: NDArray[np.float64]
    current: NDArray[np.bool_]
    walk: NDArray[np.float64]
    elapsed: NDArray[np.float64]
    walk_end: NDArray[np.float64]


def step_schedule(state: State, batch: Batch, k0: int, k1: int, every: bool) -> Schedule:
    """The :class:`Schedule` of samples ``k0..k1`` from ``state``'s step under way."""
    dt = batch.dt[:, k0:k1].detach().numpy()
    batch_size, n = dt.shape
    if every:
        none = np.zeros((batch_size, n), dtype=bool)
        zero = np.zeros((batch_size, n))
        walks = np.zeros((batch_size, n, 6))
        return Schedule(none, none, zero, ~none, walks, zero[:, 0], walks[:, 0])
    forced = (batch.dvl_mask[:, k0:k1].any(-1) | batch.last[:, k0:k1]).numpy()
    half = 0.5 * batch.imu_dt.detach().numpy()
    psd = batch.bias_psd.detach().numpy()
    step = batch.setup.covariance_step
    elapsed = state.elapsed.detach().numpy().copy()
    walk = state.walk.detach().numpy().copy()
    opens, due = np.zeros((batch_size, n), bool), np.zeros((batch_size, n), bool)
    span, walks = np.zeros((batch_size, n)), np.zeros((batch_size, n, 6))
    current = np.zeros((batch_size, n), bool)
    for i in range(n):
        opens[:, i] = elapsed == 0.0
        elapsed = elapsed + dt[:, i]
        walk = walk + psd * dt[:, i, None]
        due[:, i] = (elapsed + half >= step) | forced[:, i]
        walks[:, i], span[:, i] = walk, elapsed
        elapsed = np.where(due[:, i], 0.0, elapsed)
        walk = np.where(due[:, i, None], 0.0, walk)
        current[:, i] = elapsed == 0.0
    return Schedule(opens, due, span, current, walks, elapsed, walk)


def advance(state: State, batch: Batch, k0: int, k1: int, q: Tensor) -> tuple[State, Outputs]:
    """Run samples ``k0..k1`` (epochs ``k0 + 1..k1``) of ``batch`` from ``state`` with
    the per-sample IMU variances ``q`` [(m/s²)², (rad/s)²] in force: ``(B, 6)`` for the
    whole call or ``(B, k1 − k0, 6)`` per sample. Returns the state after epoch ``k1``
    and the :class:`Outputs` of the call's epochs. Differentiable in q and in the
    state's tensors; calls over consecutive ranges equal one call over their union."""
    if not 0 <= k0 < k1 <= batch.length:
        raise ValueError(f"k0, k1: need 0 <= k0 < k1 <= {batch.length}, got {k0}, {k1}")
    q = as_tensor(q)
    n = k1 - k0
    if q.shape not in ((batch.size, 6), (batch.size, n, 6)):
        raise ValueError(
            f"q: expected ({batch.size}, 6) or ({batch.size}, {n}, 6), got {tuple(q.shape)}"
        )
    every = batch.every_sample()
    sched = step_schedule(state, batch, k0, k1, every)
    white_dt = (batch.imu_dt[:, None] * batch.dt[:, k0:k1])[..., None]  # Δt_imu Δt
    qdt = (q[:, None, :] if q.dim() == 2 else q) * white_dt
    loop = _Loop(state, batch, every, k0)
    for i in range(n):
        loop.sample(k0 + i, qdt[:, i], sched, i)
        loop.updates(k0 + i)
        loop.record()
    return loop.finish(sched)


class _Loop:
    """The running filter of one :func:`advance` call and its per-epoch records."""

    def __init__(self, state: State, batch: Batch, every: bool, k0: int) -> None:
        self.s, self.start, self.batch, self.every, self.k0 = state, state, batch, every, k0
        self.inv = batch.setup.invariant
        self.rows: dict[str, list[Tensor]] = {}
        self._blocks()
        self.closed_blocks = self.blocks
        self.vel_closed = state.vel
        self.innovations: list[Tensor] = []
        self.nis: list[Tensor] = []
        self.accepted: list[Tensor] = []

    def _blocks(self) -> None:
        """P's diagonal and the blocks the classic variances need, now."""
        p = self.s.p
        self.blocks = (torch.diagonal(p, dim1=-2, dim2=-1), p[:, 6:9, 6:9], p[:, 6:9, 3:6])

    def sample(self, k: int, qdt: Tensor, sched: Schedule, i: int) -> None:
        """Sample k: P (or the step under way), the strapdown step, a close if due."""
        s, b = self.s, self.batch
        f = b.imu[:, k, :3] - s.bias[:, :3]
        w = b.imu[:, k, 3:] - s.bias[:, 3:]
        dt = b.dt[:, k]
        r = rates(s.lla, s.vel)
        if self.every:
            fm = ekf.error_dynamics(s.vel, s.dcm, r, s.lla[:, 2], _rotate(s.dcm, f), self.inv)
            noise = ekf.imu_noise(s.vel, s.dcm, qdt, b.bias_psd * dt[:, None], self.inv)
            s = replace(s, p=ekf.propagate_sample(s.p, fm, noise, dt))
        else:
            opens = torch.as_tensor(sched.opens[:, i])
            if bool(opens.any()):
                s = replace(
                    s,
                    step_lla=_pick(opens, s.lla, s.step_lla),
                    step_vel=_pick(opens, s.vel, s.step_vel),
                    step_dcm=_pick(opens, s.dcm, s.step_dcm),
                )
            force = s.force + _rotate(s.dcm, f) * dt[:, None]
            s = replace(s, force=force, white=s.white + qdt)
        lla, vel, dcm = strapdown_step(s.lla, s.vel, s.dcm, f, w, dt, r)
        self.s = replace(s, lla=lla, vel=vel, dcm=dcm, gyro=w, time=b.time[:, k])
        if self.every:
            self._blocks()
            return
        due = torch.as_tensor(sched.due[:, i])
        if bool(due.any()):
            span = torch.as_tensor(np.where(sched.due[:, i], sched.span[:, i], 1.0))
            self._close(due, span, as_tensor(sched.walk[:, i]))

    def _close(self, due: Tensor, span: Tensor, walk: Tensor) -> None:
        """Close the covariance step (of ``span`` [s], bias walks ``walk``) of the
        sequences ``due``."""
        s = self.s
        r = rates(s.step_lla, s.step_vel)
        f_ned = s.force / span[:, None]
        fm = ekf.error_dynamics(s.step_vel, s.step_dcm, r, s.step_lla[:, 2], f_ned, self.inv)
        noise = ekf.imu_noise(s.step_vel, s.step_dcm, s.white, walk, self.inv)
        p = ekf.propagate_interval(s.p, fm, noise, span)
        zero3 = torch.zeros_like(s.force)
        self.s = replace(
            s,
            p=_pick(due, p, s.p),
            force=_pick(due, zero3, s.force),
            white=_pick(due, torch.zeros_like(s.white), s.white),
        )
        self._blocks()
        self.closed_blocks, self.vel_closed = self.blocks, self.s.vel

    def updates(self, k: int) -> None:
        """The DVL rows of epoch k + 1, each an update (where present) and feedback."""
        b = self.batch
        rows = b.dvl_mask.shape[2]
        for j in range(rows):
            mask = b.dvl_mask[:, k, j]
            if not bool(mask.any()):
                self._no_row()
                continue
            s = self.s
            pred, h = ekf.measurement(s.vel, s.dcm, s.gyro, b.lever_arm, b.setup.aiding, self.inv)
            nu = b.dvl[:, k, j] - pred
            p, dx, nis = ekf.kalman_update(s.p, h, nu, b.dvl_variance)
            gate = b.setup.innovation_gate
            take = mask if gate is None else mask & (nis.detach() <= gate)
            lla, vel, dcm, bias = ekf.feedback(s.lla, s.vel, s.dcm, s.bias, dx, self.inv)
            self.s = replace(
                s,
                p=_pick(take, p, s.p),
                lla=_pick(take, lla, s.lla),
                vel=_pick(take, vel, s.vel),
                dcm=_pick(take, dcm, s.dcm),
                bias=_pick(take, bias, s.bias),
            )
            self._blocks()
            self.innovations.append(_pick(mask, nu, torch.zeros_like(nu)))
            self.nis.append(torch.where(mask, nis, torch.zeros_like(nis)))
            self.accepted.append(take)

    def _no_row(self) -> None:
        s = self.s
        self.innovations.append(s.vel.new_zeros(s.vel.shape))
        self.nis.append(s.vel.new_zeros(s.vel.shape[0]))
        self.accepted.append(torch.zeros(s.vel.shape[0], dtype=torch.bool))

    def record(self) -> None:
        """Keep the epoch's estimate (references: nothing is copied here)."""
        s = self.s
        for name, value in (
            ("time", s.time), ("lla", s.lla), ("vel", s.vel), ("dcm", s.dcm),
            ("bias", s.bias), ("diag", self.blocks[0]), ("p_aa", self.blocks[1]),
            ("p_av", self.blocks[2]), ("c_diag", self.closed_blocks[0]),
            ("c_p_aa", self.closed_blocks[1]), ("c_p_av", self.closed_blocks[2]),
            ("c_vel", self.vel_closed),
        ):  # fmt: skip
            self.rows.setdefault(name, []).append(value)

    def finish(self, sched: Schedule) -> tuple[State, Outputs]:
        """The state after the call and its outputs."""
        s, rows = self.s, self.rows

        def cat(name: str) -> Tensor:
            return torch.stack(rows[name], dim=1)

        def variance(prefix: str, vel: Tensor) -> Tensor:
            diag = cat(prefix + "diag")
            if not self.inv:
                return diag
            return classic_variance(diag, cat(prefix + "p_aa"), cat(prefix + "p_av"), vel)

        vel = cat("vel")
        batch, n = vel.shape[:2]
        var_stale = variance("", vel)
        current = torch.as_tensor(sched.current)
        k = int(self.batch.dvl_mask.shape[2])
        out = Outputs(
            time=cat("time"),
            lla=cat("lla"),
            vel=vel,
            dcm=cat("dcm"),
            bias=cat("bias"),
            var_stale=var_stale,
            var_closed=variance("c_", cat("c_vel")),
            closed=torch.as_tensor(sched.due),
            current=current,
            innovation=torch.stack(self.innovations, 1).reshape(batch, n, k, 3),
            nis=torch.stack(self.nis, 1).reshape(batch, n, k),
            dvl_mask=self.batch.dvl_mask[:, self.k0 : self.k0 + n],
            accepted=torch.stack(self.accepted, 1).reshape(batch, n, k),
            var_start=self.start.var_current,
            time_start=self.start.time_current,
        )
        last = torch.where(current, torch.arange(n), -1).max(dim=1).values
        seen = last >= 0
        rows_at = last.clamp_min(0)
        pick = torch.arange(batch)
        state = replace(
            s,
            elapsed=as_tensor(sched.elapsed),
            walk=as_tensor(sched.walk_end),
            var_current=_pick(seen, var_stale[pick, rows_at], s.var_current),
            time_current=_pick(seen, out.time[pick, rows_at], s.time_current),
        )
        return state, out


def _rotate(dcm: Tensor, v: Tensor) -> Tensor:
    """``C v`` for ``(B, 3, 3)`` and ``(B, 3)``."""
    return (dcm @ v.unsqueeze(-1)).squeeze(-1)


def _pick(mask: Tensor, new: Tensor, old: Tensor) -> Tensor:
    """``new`` where ``mask`` ``(B,)``, else ``old``."""
    return torch.where(mask.reshape(-1, *([1] * (new.dim() - 1))), new, old)
