"""What the differentiable filter runs on and carries: the filter's setup
(:class:`Setup`), B sequences of sensor rows (:class:`Batch`), the filter's state
between calls (:class:`State`).

Shapes: B sequences of T IMU samples; sample k covers ``(time[k-1], time[k]]`` and
epoch k + 1 is the estimate after it (epoch 0: the start). Everything is float64."""

from __future__ import annotations

from dataclasses import dataclass, fields, replace

import numpy as np
import torch
from numpy.typing import ArrayLike
from torch import Tensor

from pronet import _core
from pronet.learn.torchfilter.attitude import dcm_from_euler
from pronet.learn.torchfilter.ekf import to_invariant

DTYPE = torch.float64


def as_tensor(x: ArrayLike | Tensor) -> Tensor:
    """``x`` as a float64 tensor (a tensor keeps its graph)."""
    if isinstance(x, Tensor):
        return x.to(DTYPE)
    return torch.as_tensor(np.asarray(x, dtype=np.float64))


@dataclass(frozen=True)
class Setup:
    """The filter settings shared by a whole batch (from a ``FilterConfig``):
    ``formulation`` ``"invariant"`` or ``"classic"``, ``aiding`` ``"body"`` or
    ``"nav"``, ``covariance_step`` [s] (below 1.5 IMU periods: every sample) and the
    chi-square ``innovation_gate`` (None: none)."""

    formulation: str = "invariant"
    aiding: str = "body"
    covariance_step: float = 0.1
    innovation_gate: float | None = None

    @classmethod
    def from_config(cls, config: _core.FilterConfig) -> Setup:
        """The setup of ``config``; the DVL calibration states and the second-order
        heading term are not implemented here (a ``ValueError`` naming ``config``)."""
        if config.formulation not in ("invariant", "classic"):
            raise ValueError(
                f"config: the differentiable filter runs the invariant and classic "
                f"formulations, not {config.formulation!r}"
            )
        if config.dvl_calibration:
            raise ValueError(
                "config: the differentiable filter has no DVL calibration states "
                "(dvl_calibration=True)"
            )
        if config.heading_second_order:
            raise ValueError(
                "config: the differentiable filter has no second-order heading term "
                "(heading_second_order=True)"
            )
        return cls(
            config.formulation, config.aiding, config.covariance_step, config.innovation_gate
        )

    @property
    def invariant(self) -> bool:
        return self.formulation == "invariant"


@dataclass(frozen=True)
class Batch:
    """B sensor sequences of T IMU samples each, with what varies per sequence.

    Attributes:
        imu: ``(B, T, 6)`` raw samples ``[f (m/s²), ω (rad/s)]``, body FRD.
        dt: ``(B, T)`` each sample's step [s] (``time[k] − time[k-1]``, the first from
            the start time).
        time: ``(B, T)`` the time [s] of epoch k + 1 (sample k's end).
        dvl: ``(B, T, K, 3)`` the DVL rows applied at epoch k + 1 (up to K), [m/s] body
            (or NED with ``aiding="nav"``); ``dvl_mask`` ``(B, T, K)`` which are there.
        last: ``(B, T)`` True at the pass's last sample, where the core closes its
            covariance step (a window cut from inside a pass has none).
        imu_dt: ``(B,)`` nominal IMU period [s] (``FilterConfig.imu_dt``).
        dvl_variance: ``(B, 3)`` R [(m/s)²]; ``lever_arm``: ``(B, 3)`` [m, body];
        bias_psd: ``(B, 6)`` bias random-walk PSDs ``[ε_a ×3, ε_g ×3]``.
        setup: the shared :class:`Setup`.
    """

    imu: Tensor
    dt: Tensor
    time: Tensor
    dvl: Tensor
    dvl_mask: Tensor
    last: Tensor
    imu_dt: Tensor
    dvl_variance: Tensor
    lever_arm: Tensor
    bias_psd: Tensor
    setup: Setup

    @property
    def size(self) -> int:
        """B."""
        return int(self.imu.shape[0])

    @property
    def length(self) -> int:
        """T."""
        return int(self.imu.shape[1])

    def every_sample(self) -> bool:
        """Whether P moves at every sample (covariance step < 1.5 IMU periods); the
        sequences must agree."""
        every = self.setup.covariance_step < 1.5 * self.imu_dt
        if bool(every.any()) != bool(every.all()):
            raise ValueError("batch: sequences disagree on propagating P at every sample")
        return bool(every.all())

    def select(self, rows: slice | Tensor) -> Batch:
        """The sequences ``rows`` (a slice or an index tensor) of the batch."""
        values = {f.name: getattr(self, f.name)[rows] for f in fields(self) if f.name != "setup"}
        return Batch(**values, setup=self.setup)

    @classmethod
    def stack(cls, parts: list[Batch]) -> Batch:
        """One batch of several (same T and setup; K padded)."""
        if not parts:
            raise ValueError("parts: needs at least one batch")
        if len({p.length for p in parts}) != 1 or len({p.setup for p in parts}) != 1:
            raise ValueError("parts: batches must share their length T and setup")
        k = max(int(p.dvl.shape[2]) for p in parts)

        def pad(p: Batch) -> Batch:
            extra = k - int(p.dvl.shape[2])
            if not extra:
                return p
            dvl = torch.cat([p.dvl, p.dvl.new_zeros(p.size, p.length, extra, 3)], 2)
            mask = torch.cat([p.dvl_mask, p.dvl_mask.new_zeros(p.size, p.length, extra)], 2)
            return replace(p, dvl=dvl, dvl_mask=mask)

        padded = [pad(p) for p in parts]
        values = {
            f.name: torch.cat([getattr(p, f.name) for p in padded])
            for f in fields(cls)
            if f.name != "setup"
        }
        return cls(**values, setup=parts[0].setup)


def dvl_epochs(imu_time: np.ndarray, t0: float, dvl_time: np.ndarray) -> np.ndarray:
    """The epoch (1..n) each DVL row is applied at, as the core places it (the first
    epoch with ``t ≥ t_dvl − Δt/2``); 0 for a row before the run, n + 1 after it."""
    dt = np.diff(np.concatenate([[t0], imu_time]))
    reach = np.maximum.accumulate(imu_time + 0.5 * dt)
    epoch = np.searchsorted(reach, dvl_time, side="left") + 1
    epoch[dvl_time < t0 - 0.5 * dt[0]] = 0
    return epoch


def sensor_batch(
    imu: ArrayLike,
    imu_time: ArrayLike,
    dvl: ArrayLike,
    dvl_time: ArrayLike,
    t0: float,
    config: _core.FilterConfig,
    *,
    ends_pass: bool = True,
) -> Batch:
    """One sequence (B = 1) from a pass's arrays as :func:`pronet.run_filter` takes them
    (``imu`` ``(n, 6)``, ``imu_time`` ``(n,)`` [s], the DVL stream's ``dvl`` ``(m, 3)``
    at ``dvl_time`` [s], start time ``t0`` [s]) filtered with ``config``; ``ends_pass``:
    the last sample is the pass's last (the core closes its covariance step there)."""
    t = np.asarray(imu_time, dtype=np.float64)
    rows = np.asarray(dvl, dtype=np.float64).reshape(-1, 3)
    epoch = dvl_epochs(t, float(t0), np.asarray(dvl_time, dtype=np.float64))
    inside = (epoch >= 1) & (epoch <= len(t))
    counts = np.bincount(epoch[inside], minlength=len(t) + 1)
    k = max(1, int(counts.max(initial=0)))
    z = np.zeros((len(t), k, 3))
    mask = np.zeros((len(t), k), dtype=bool)
    slot = np.zeros(len(t) + 1, dtype=int)
    for row in np.flatnonzero(inside):  # few rows (one per DVL reading)
        e = int(epoch[row])
        z[e - 1, slot[e]] = rows[row]
        mask[e - 1, slot[e]] = True
        slot[e] += 1
    last = np.zeros(len(t), dtype=bool)
    last[-1] = ends_pass
    psd = [config.accel_bias_psd] * 3 + [config.gyro_bias_psd] * 3
    return Batch(
        imu=as_tensor(imu)[None],
        dt=as_tensor(np.diff(np.concatenate([[t0], t])))[None],
        time=as_tensor(t)[None],
        dvl=as_tensor(z)[None],
        dvl_mask=torch.as_tensor(mask)[None],
        last=torch.as_tensor(last)[None],
        imu_dt=as_tensor([config.imu_dt]),
        dvl_variance=as_tensor(config.dvl_variance)[None],
        lever_arm=as_tensor(config.lever_arm)[None],
        bias_psd=as_tensor(psd)[None],
        setup=Setup.from_config(config),
    )


@dataclass(frozen=True)
class State:
    """The filter between two calls of :func:`~pronet.learn.torchfilter.advance`, B
    sequences.

    Attributes:
        lla: ``(B, 3)`` latitude, longitude [rad], height [m, up].
        vel: ``(B, 3)`` NED velocity [m/s]; dcm: ``(B, 3, 3)`` ``C_b^n``.
        bias: ``(B, 6)`` ``[b_a (m/s²), b_g (rad/s)]``.
        p: ``(B, 15, 15)`` the covariance in the filter's own error coordinates (the
            invariant ones under ``formulation="invariant"``), standing at the start of
            the covariance step under way if any.
        gyro: ``(B, 3)`` the last bias-corrected rate [rad/s] (the lever-arm term).
        time: ``(B,)`` the epoch's time [s].
        step_lla, step_vel, step_dcm, elapsed, force, white, walk: the covariance step
            under way (``elapsed`` ``(B,)`` [s], 0: none): its start's navigation state,
            ``Σ Ĉ f̂ Δt`` [m/s, NED], ``Σ q Δt_imu Δt`` and ``Σ ε Δt`` per channel.
        var_current, time_current: ``(B, 15)`` the classic variances reported at the
            last epoch whose P was up to date and ``(B,)`` its time [s] (the reported σ
            inside a covariance step is interpolated from there).
    """

    lla: Tensor
    vel: Tensor
    dcm: Tensor
    bias: Tensor
    p: Tensor
    gyro: Tensor
    time: Tensor
    step_lla: Tensor
    step_vel: Tensor
    step_dcm: Tensor
    elapsed: Tensor
    force: Tensor
    white: Tensor
    walk: Tensor
    var_current: Tensor
    time_current: Tensor

    def select(self, rows: slice | Tensor) -> State:
        """The sequences ``rows`` (a slice or an index tensor) of the state."""
        return State(**{f.name: getattr(self, f.name)[rows] for f in fields(self)})

    def detach(self) -> State:
        """The same state cut from the graph (the start of a truncated window)."""
        return State(**{f.name: getattr(self, f.name).detach() for f in fields(self)})


def start_state(
    lla0: ArrayLike | Tensor,
    vel0: ArrayLike | Tensor,
    rpy0: ArrayLike | Tensor,
    p0: ArrayLike | Tensor,
    t0: ArrayLike | Tensor,
    setup: Setup,
    bias0: ArrayLike | Tensor | None = None,
) -> State:
    """The state at the start of a pass, B sequences: ``lla0``, ``vel0``, ``rpy0``
    ``(B, 3)`` as :func:`pronet.run_filter` takes them, ``p0`` ``(B, 15, 15)`` the
    covariance in the classic coordinates (``diag(p0_sigma²)`` for a pass's start, or the
    core's at an epoch), ``t0`` ``(B,)`` [s], ``bias0`` ``(B, 6)`` (default zeros).
    Tensors keep their graph: the start is differentiable."""
    lla, vel, rpy = as_tensor(lla0), as_tensor(vel0), as_tensor(rpy0)
    p_classic, time = as_tensor(p0), as_tensor(t0)
    batch = lla.shape[0]
    bias = lla.new_zeros(batch, 6) if bias0 is None else as_tensor(bias0)
    dcm = dcm_from_euler(rpy)
    p = to_invariant(p_classic, vel) if setup.invariant else p_classic
    var = torch.diagonal(p_classic, dim1=-2, dim2=-1)
    zero3 = lla.new_zeros(batch, 3)
    return State(
        lla, vel, dcm, bias, p, zero3, time, lla, vel, dcm,
        lla.new_zeros(batch), zero3, lla.new_zeros(batch, 6), lla.new_zeros(batch, 6),
        var, time,
    )  # fmt: skip
