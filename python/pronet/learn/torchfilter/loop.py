"""The filter's loop over epochs: :func:`advance` runs B sequences from a
:class:`~pronet.learn.torchfilter.state.State` over samples ``k0..k1`` of a
:class:`~pronet.learn.torchfilter.state.Batch` with given IMU variances q, the same
algorithm as the core's ``filter_recorded`` (``rust/src/recorded/filter.rs``): at each
sample the covariance step accumulates (or P moves, at every sample), the strapdown
step, the step's close when due (or at a DVL update, or at the pass's end), then the
DVL rows of the epoch, each an update with feedback."""

from __future__ import annotations

import bisect
from dataclasses import dataclass, fields, replace
from typing import TypeVar, cast

import numpy as np
import torch
from numpy.typing import NDArray
from torch import Tensor

from pronet.learn.torchfilter import ekf
from pronet.learn.torchfilter.attitude import matmul
from pronet.learn.torchfilter.earth import rates
from pronet.learn.torchfilter.mechanization import body_half_turns, strapdown_step
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
    state's tensors (when none needs a gradient, or grad mode is off, it runs under
    ``torch.inference_mode``: the same numbers; the results are ordinary tensors either
    way); calls over consecutive ranges equal one call over their union."""
    if not 0 <= k0 < k1 <= batch.length:
        raise ValueError(f"k0, k1: need 0 <= k0 < k1 <= {batch.length}, got {k0}, {k1}")
    q = as_tensor(q)
    n = k1 - k0
    if q.shape not in ((batch.size, 6), (batch.size, n, 6)):
        raise ValueError(
            f"q: expected ({batch.size}, 6) or ({batch.size}, {n}, 6), got {tuple(q.shape)}"
        )
    if torch.is_grad_enabled() and any(x.requires_grad for x in _tensors(q, state, batch)):
        return _run(state, batch, k0, k1, q)
    # nothing to differentiate: the same operations without autograd's bookkeeping (a
    # fifth of the time), the results made ordinary tensors again
    with torch.inference_mode():
        state, out = _run(state, batch, k0, k1, q)
    return _ordinary(state), _ordinary(out)


def _tensors(q: Tensor, state: State, batch: Batch) -> list[Tensor]:
    """q and the tensors of ``state`` and ``batch``."""
    parts = [getattr(x, f.name) for x in (state, batch) for f in fields(x)]
    return [q, *(x for x in parts if isinstance(x, Tensor))]


_D = TypeVar("_D", State, Outputs)


def _ordinary(x: _D) -> _D:
    """``x`` with its tensors copied out of inference mode (usable with autograd)."""
    return replace(x, **{f.name: getattr(x, f.name).clone() for f in fields(x)})


def _run(state: State, batch: Batch, k0: int, k1: int, q: Tensor) -> tuple[State, Outputs]:
    """:func:`advance` once its arguments are checked."""
    n = k1 - k0
    every = batch.every_sample()
    sched = step_schedule(state, batch, k0, k1, every)
    white_dt = (batch.imu_dt[:, None] * batch.dt[:, k0:k1])[..., None]  # Δt_imu Δt
    # unbound once: indexing a tensor that needs a gradient at every step would make
    # the backward pass build a zero tensor of the whole chunk per step (quadratic)
    qdt = ((q[:, None, :] if q.dim() == 2 else q) * white_dt).unbind(1)
    loop = _Loop(state, batch, every, k0, k1, sched)
    for i in range(n):
        loop.sample(k0 + i, qdt[i], sched, i)
        loop.updates(k0 + i)
        loop.record()
    return loop.finish(sched)


class _Loop:
    """The running filter of one :func:`advance` call and its per-epoch records."""

    def __init__(
        self, state: State, batch: Batch, every: bool, k0: int, k1: int, sched: Schedule
    ) -> None:
        self.s, self.start, self.batch, self.every, self.k0 = state, state, batch, every, k0
        self.inv = batch.setup.invariant
        self.rows: dict[str, list[Tensor]] = {}
        self._blocks()
        self.closed_blocks = self.blocks
        self.vel_closed = state.vel
        # the samples after which a bias may change: the batch's DVL epochs, the end
        events = batch.dvl_mask[:, k0:k1].any(-1).any(0).tolist()
        self.segment_ends = [k0 + i for i, e in enumerate(events) if e] + [k1 - 1]
        self.segment: tuple[int, list[Tensor], list[Tensor], list[Tensor]] = (-1, [], [], [])
        # the last sample's q Δt_imu Δt and Δt: its gyro white-noise variance per axis,
        # q_g Δt_imu/Δt, which the lever arm's ω̂ × r reads (taken at an update only)
        size = state.vel.shape[0]
        self.last_white = (state.vel.new_zeros(size, 6), state.vel.new_ones(size))
        self.innovations: list[Tensor] = []
        self.nis: list[Tensor] = []
        self.accepted: list[Tensor] = []
        # per sample of the call, taken apart once (not indexed at every step)
        chunk = slice(k0, k1)
        self.dt = batch.dt[:, chunk].unbind(1)
        self.dt_col = batch.dt[:, chunk, None].unbind(1)
        self.time = batch.time[:, chunk].unbind(1)
        self.walk_dt = (batch.bias_psd[:, None] * batch.dt[:, chunk, None]).unbind(1)
        self.present = batch.dvl_mask[:, chunk].numpy()
        # whether any sequence has a DVL row, a step opening, a step closing (Python
        # booleans: numpy's any() on a few elements costs microseconds per call)
        self.any_row = cast(list[list[bool]], self.present.any(0).tolist())
        self.any_opens = cast(list[bool], sched.opens.any(0).tolist())
        self.any_due = cast(list[bool], sched.due.any(0).tolist())
        # what an epoch without a DVL row records (shared: stacked at the end)
        self.no_row = (
            state.vel.new_zeros(state.vel.shape),
            state.vel.new_zeros(size),
            torch.zeros(size, dtype=torch.bool),
        )

    def _blocks(self) -> None:
        """P's diagonal and the blocks the classic variances need, now."""
        p = self.s.p
        self.blocks = (torch.diagonal(p, dim1=-2, dim2=-1), p[:, 6:9, 6:9], p[:, 6:9, 3:6])

    def _corrected(self, k: int) -> tuple[Tensor, Tensor, Tensor]:
        """Sample k's bias-corrected specific force and rate and its body half-turn,
        computed at once for the samples up to the next DVL epoch of the batch (the
        biases hold until an update)."""
        end, f, w, turns = self.segment
        if k > end:
            b, bias = self.batch, self.s.bias
            end = self.segment_ends[bisect.bisect_left(self.segment_ends, k)]
            raw = b.imu[:, k : end + 1]
            f_all = raw[..., :3] - bias[:, None, :3]
            w_all = raw[..., 3:] - bias[:, None, 3:]
            turns_all = body_half_turns(w_all, b.dt[:, k : end + 1])
            f, w, turns = list(f_all.unbind(1)), list(w_all.unbind(1)), list(turns_all.unbind(1))
            self.segment = (end, f, w, turns)
        i = k - (end + 1 - len(f))
        return f[i], w[i], turns[i]

    def sample(self, k: int, qdt: Tensor, sched: Schedule, i: int) -> None:
        """Sample k: P (or the step under way), the strapdown step, a close if due."""
        s = self.s
        f, w, body_half = self._corrected(k)
        dt = self.dt[i]
        self.last_white = (qdt, dt)
        r = rates(s.lla, s.vel)
        if self.every:
            fm = ekf.error_dynamics(s.vel, s.dcm, r, s.lla[:, 2], _rotate(s.dcm, f), self.inv)
            noise = ekf.imu_noise(s.vel, s.dcm, qdt, self.walk_dt[i], self.inv)
            p, force, white = ekf.propagate_sample(s.p, fm, noise, dt), s.force, s.white
        else:
            if self.any_opens[i]:
                opens = torch.as_tensor(sched.opens[:, i])
                s = replace(
                    s,
                    step_lla=_pick(opens, s.lla, s.step_lla),
                    step_vel=_pick(opens, s.vel, s.step_vel),
                    step_dcm=_pick(opens, s.dcm, s.step_dcm),
                )
            p, force = s.p, s.force + _rotate(s.dcm, f) * self.dt_col[i]
            white = s.white + qdt
        lla, vel, dcm = strapdown_step(s.lla, s.vel, s.dcm, f, body_half, dt, r)
        self.s = replace(
            s, p=p, force=force, white=white, lla=lla, vel=vel, dcm=dcm, gyro=w, time=self.time[i]
        )
        if self.every:
            self._blocks()
            return
        if self.any_due[i]:
            due = sched.due[:, i]
            rows = _Rows(due)
            self._close(rows, rows.take(as_tensor(sched.span[:, i])), as_tensor(sched.walk[due, i]))

    def _close(self, rows: _Rows, span: Tensor, walk: Tensor) -> None:
        """Close the covariance step (of ``span`` [s], bias walks ``walk``) of the
        sequences ``rows`` (computed on those alone)."""
        s = self.s
        vel, dcm, lla = rows.take(s.step_vel), rows.take(s.step_dcm), rows.take(s.step_lla)
        r = rates(lla, vel)
        f_ned = rows.take(s.force) / span[:, None]
        fm = ekf.error_dynamics(vel, dcm, r, lla[:, 2], f_ned, self.inv)
        noise = ekf.imu_noise(vel, dcm, rows.take(s.white), walk, self.inv)
        p = ekf.propagate_interval(rows.take(s.p), fm, noise, span)
        self.s = replace(
            s,
            p=rows.put(s.p, p),
            force=rows.put(s.force, torch.zeros_like(f_ned)),
            white=rows.put(s.white, torch.zeros_like(walk)),
        )
        self._blocks()
        self.closed_blocks, self.vel_closed = self.blocks, self.s.vel

    def updates(self, k: int) -> None:
        """The DVL rows of epoch k + 1, each an update (where present) and feedback,
        computed on the sequences that have one."""
        b = self.batch
        for j in range(b.dvl_mask.shape[2]):
            if not self.any_row[k - self.k0][j]:
                self._no_row()
                continue
            present = self.present[:, k - self.k0, j]
            mask = b.dvl_mask[:, k, j]
            rows, s = _Rows(present), self.s
            vel, dcm, lla, bias = (rows.take(x) for x in (s.vel, s.dcm, s.lla, s.bias))
            arm = rows.take(b.lever_arm)
            pred, h = ekf.measurement(vel, dcm, rows.take(s.gyro), arm, b.setup.aiding, self.inv)
            nu = rows.take(b.dvl[:, k, j]) - pred
            p_old = rows.take(s.p)
            qdt, dt = self.last_white
            gyro_variance = rows.take(qdt[:, 3:] / (dt * dt)[:, None])
            r = ekf.dvl_noise(rows.take(b.dvl_variance), arm, gyro_variance, dcm, b.setup.aiding)
            p, dx, nis = ekf.kalman_update(p_old, h, nu, r)
            gate = b.setup.innovation_gate
            ok = torch.ones_like(nis, dtype=torch.bool) if gate is None else nis.detach() <= gate
            new = ekf.feedback(lla, vel, dcm, bias, dx, self.inv)
            kept = [
                _pick(ok, a, o)
                for a, o in zip((p, *new), (p_old, lla, vel, dcm, bias), strict=True)
            ]
            self.s = replace(
                s,
                p=rows.put(s.p, kept[0]),
                lla=rows.put(s.lla, kept[1]),
                vel=rows.put(s.vel, kept[2]),
                dcm=rows.put(s.dcm, kept[3]),
                bias=rows.put(s.bias, kept[4]),
            )
            self._blocks()
            self.innovations.append(rows.put(torch.zeros_like(s.vel), nu))
            self.nis.append(rows.put(torch.zeros_like(s.vel[:, 0]), nis))
            self.accepted.append(rows.put(torch.zeros_like(mask), ok))

    def _no_row(self) -> None:
        innovation, nis, accepted = self.no_row
        self.innovations.append(innovation)
        self.nis.append(nis)
        self.accepted.append(accepted)

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


class _Rows:
    """Some of a batch's sequences (a boolean mask ``(B,)``): a covariance step closes
    or an update runs on those alone, the others keep their values."""

    def __init__(self, mask: NDArray[np.bool_]) -> None:
        self.every = bool(mask.all())
        self.index = torch.as_tensor(np.flatnonzero(mask))

    def take(self, x: Tensor) -> Tensor:
        """The rows of ``x`` ``(B, ...)``."""
        return x if self.every else x.index_select(0, self.index)

    def put(self, full: Tensor, part: Tensor) -> Tensor:
        """``full`` with the rows replaced by ``part`` (out of place)."""
        return part if self.every else full.index_copy(0, self.index, part)


def _rotate(dcm: Tensor, v: Tensor) -> Tensor:
    """``C v`` for ``(B, 3, 3)`` and ``(B, 3)``."""
    return matmul(dcm, v.unsqueeze(-1)).squeeze(-1)


def _pick(mask: Tensor, new: Tensor, old: Tensor) -> Tensor:
    """``new`` where ``mask`` ``(B,)``, else ``old``."""
    return torch.where(mask.reshape(-1, *([1] * (new.dim() - 1))), new, old)
