"""What :func:`~pronet.learn.torchfilter.advance` returns per epoch, and the σ the core
reports there (inside a covariance step, interpolated in variance up to the step's
close, ``docs/reference/filter.md``, "Covariance step")."""

from __future__ import annotations

from dataclasses import dataclass, fields

import torch
from torch import Tensor

from pronet.learn.torchfilter.attitude import euler_from_dcm, skew


@dataclass(frozen=True)
class Outputs:
    """The estimate at each epoch of a call (n epochs, B sequences) and its DVL updates.

    Attributes:
        time: ``(B, n)`` epoch times [s].
        lla: ``(B, n, 3)`` [rad, rad, m]; vel: ``(B, n, 3)`` NED velocity [m/s];
        dcm: ``(B, n, 3, 3)`` ``C_b^n``; bias: ``(B, n, 6)`` ``[b_a, b_g]``; all after
            the epoch's updates.
        var_stale: ``(B, n, 15)`` the classic variances of P as it stands at the epoch
            (inside a covariance step: its start's P, at the epoch's velocity).
        var_closed: ``(B, n, 15)`` where ``closed``, the variances at the step's close
            (before the epoch's updates).
        closed, current: ``(B, n)`` a step closed at the epoch; P is up to date there.
        innovation: ``(B, n, K, 3)`` ``z − h(x̂)`` [m/s] of the DVL rows (0 where none);
        nis: ``(B, n, K)``; dvl_mask: ``(B, n, K)`` which rows were there; accepted:
            ``(B, n, K)`` which the gate let through.
        var_start, time_start: ``(B, 15)``, ``(B,)`` the last up-to-date variances and
            their time before the call.
    """

    time: Tensor
    lla: Tensor
    vel: Tensor
    dcm: Tensor
    bias: Tensor
    var_stale: Tensor
    var_closed: Tensor
    closed: Tensor
    current: Tensor
    innovation: Tensor
    nis: Tensor
    dvl_mask: Tensor
    accepted: Tensor
    var_start: Tensor
    time_start: Tensor

    @property
    def rpy(self) -> Tensor:
        """``(B, n, 3)`` roll, pitch, yaw [rad]."""
        return euler_from_dcm(self.dcm)

    @property
    def sigma(self) -> Tensor:
        """``(B, n, 15)`` the 1σ the core reports (classic coordinates): at an epoch
        inside a covariance step whose close falls within these outputs, the variance
        interpolated linearly in time from the last up-to-date epoch to the close; after
        the last close, P's at the step's start (:meth:`cat` the chunks of a run first)."""
        return interpolated_variance(self).clamp_min(0.0).sqrt()

    @property
    def settled(self) -> Tensor:
        """``(B, n)`` whether :attr:`sigma` at the epoch is the core's: P up to date
        there, or the step under way closes within these outputs (the epochs after the
        last close are not, until the next chunk is joined by :meth:`cat`)."""
        after = self.current.flip(1).cummax(dim=1).values.flip(1)
        return self.current | after

    @classmethod
    def cat(cls, chunks: list[Outputs]) -> Outputs:
        """The outputs of consecutive calls as one (the first call's start kept)."""
        if not chunks:
            raise ValueError("chunks: needs at least one")
        keep = ("var_start", "time_start")
        k = max(int(c.nis.shape[2]) for c in chunks)
        values = {}
        for f in fields(cls):
            if f.name in keep:
                values[f.name] = getattr(chunks[0], f.name)
                continue
            parts = [getattr(c, f.name) for c in chunks]
            if f.name in ("innovation", "nis", "dvl_mask", "accepted"):
                parts = [_pad_rows(x, k) for x in parts]
            values[f.name] = torch.cat(parts, dim=1)
        return cls(**values)


def _pad_rows(x: Tensor, k: int) -> Tensor:
    """``x`` with its third dimension (the rows per epoch) padded with zeros to ``k``."""
    extra = k - int(x.shape[2])
    if extra <= 0:
        return x
    shape = list(x.shape)
    shape[2] = extra
    return torch.cat([x, x.new_zeros(shape)], dim=2)


def classic_variance(diag: Tensor, p_aa: Tensor, p_av: Tensor, vel: Tensor) -> Tensor:
    """The diagonal of an invariant P in the classic coordinates at ``vel``: P's
    ``diag`` ``(..., 15)`` but the velocity errors' ``diag(P_vv + S P_av + P_va Sᵀ +
    S P_aa Sᵀ)`` with ``S = [v̂×]`` (``p_aa``, ``p_av`` the (attitude, attitude) and
    (attitude, velocity) blocks ``(..., 3, 3)``)."""
    s = skew(vel)
    cross = torch.diagonal(s @ p_av, dim1=-2, dim2=-1)
    quad = torch.diagonal(s @ p_aa @ s.transpose(-1, -2), dim1=-2, dim2=-1)
    v = diag[..., 3:6] + 2.0 * cross + quad
    return torch.cat([diag[..., :3], v, diag[..., 6:]], dim=-1)


def interpolated_variance(out: Outputs) -> Tensor:
    """The variances :attr:`Outputs.sigma` reports (see there), ``(B, n, 15)``."""
    batch, n = out.current.shape
    idx = torch.arange(n).expand(batch, n)
    cur = out.current
    # the last up-to-date epoch before each (-1: the start), the first at or after it
    before = torch.cummax(torch.where(cur, idx, -1), dim=1).values
    before = torch.cat([before.new_full((batch, 1), -1), before[:, :-1]], dim=1)
    after = torch.where(cur, idx, n).flip(1).cummin(dim=1).values.flip(1)
    pending = ~cur & (after < n)
    var_all = torch.cat([out.var_start[:, None], out.var_stale], dim=1)
    time_all = torch.cat([out.time_start[:, None], out.time], dim=1)
    a = (before + 1)[..., None].expand(batch, n, 15)
    c = after.clamp_max(n - 1)
    var_a = torch.gather(var_all, 1, a)
    t_a = torch.gather(time_all, 1, before + 1)
    var_c = torch.gather(out.var_closed, 1, c[..., None].expand(batch, n, 15))
    t_c = torch.gather(out.time, 1, c)
    span = torch.where(pending, t_c - t_a, torch.ones_like(t_a))
    w = ((out.time - t_a) / span)[..., None]
    return torch.where(pending[..., None], var_a + w * (var_c - var_a), out.var_stale)
