"""Rotations in torch, batched over leading dimensions: the skew matrix, the SO(3)
exponential, Euler angles and the re-orthonormalization of the core's
``rust/src/attitude.rs`` (same formulas, same branches); and what the filter's other
modules share for speed: the constants it uses at every step (:func:`constant`) and
the product of ``(B, ·, ·)`` matrices (:func:`matmul`).

Frames: a DCM ``C_b^n`` takes FRD body vectors to NED; Euler angles are ZYX
``[roll, pitch, yaw]`` [rad]."""

from __future__ import annotations

from functools import cache

import torch
from torch import Tensor

# [v×] row by row from [x, y, z, 0, −x, −y, −z, −0]: 0, −z, y, z, 0, −x, −y, x, 0
_SKEW_ORDER = (3, 6, 1, 2, 3, 4, 5, 0, 3)


@cache
def constant(name: str, dtype: torch.dtype, device: torch.device) -> Tensor:
    """A constant the filter uses at every step, made once per dtype and device (never
    to be modified in place): ``"eye3"``, ``"eye15"``, ``"eye3x1.5"`` (``1.5 I``) or
    ``"skew_order"`` (for :func:`skew`)."""
    with torch.inference_mode(False):  # usable with autograd whatever the caller's mode
        if name == "skew_order":
            return torch.tensor(_SKEW_ORDER, device=device)
        eye = torch.eye(15 if name == "eye15" else 3, dtype=dtype, device=device)
        return eye * 1.5 if name == "eye3x1.5" else eye


def matmul(a: Tensor, b: Tensor) -> Tensor:
    """``a @ b``; for two ``(B, ·, ·)`` operands of the same B ``torch.bmm``, the same
    product (and the same numbers) without ``matmul``'s broadcasting, a third of its cost
    on the filter's small matrices."""
    if a.dim() == 3 == b.dim() and a.shape[0] == b.shape[0]:
        return torch.bmm(a, b)
    return a @ b


def _matrices(flat: Tensor) -> Tensor:
    """``(..., 9)`` row-major entries as ``(..., 3, 3)`` (a view)."""
    return flat.view(*flat.shape[:-1], 3, 3)


def skew(v: Tensor) -> Tensor:
    """``(..., 3, 3)`` cross-product matrix ``[v×]`` of ``(..., 3)`` vectors."""
    padded = torch.constant_pad_nd(v, (0, 1))  # [x, y, z, 0]: v has one consumer, as before
    signed = torch.cat([padded, -padded], dim=-1)
    return _matrices(signed.index_select(-1, constant("skew_order", torch.int64, v.device)))


def exp_so3(rv: Tensor) -> Tensor:
    """``(..., 3, 3)`` rotation ``Exp(rv)`` of rotation vectors ``(..., 3)`` [rad]:
    ``I + a K + b K²`` with the core's series for ``a = sin t / t`` and ``b = (1 − cos
    t) / t²`` below ``t² = 1e-6`` (so the gradient at 0 is finite)."""
    t2 = (rv * rv).sum(-1)
    small = t2 < 1e-6
    a_series = 1.0 - t2 * (1.0 / 6.0) * (1.0 - t2 * (1.0 / 20.0) * (1.0 - t2 * (1.0 / 42.0)))
    b_series = 0.5 * (
        1.0 - t2 * (1.0 / 12.0) * (1.0 - t2 * (1.0 / 30.0) * (1.0 - t2 * (1.0 / 56.0)))
    )
    if bool(small.all()):
        a, b = a_series, b_series
    else:
        safe = torch.where(small, torch.ones_like(t2), t2)
        t = safe.sqrt()
        a = torch.where(small, a_series, torch.sin(t) / t)
        b = torch.where(small, b_series, (1.0 - torch.cos(t)) / safe)
    x, y, z = rv.unbind(-1)
    ax, ay, az = a * x, a * y, a * z
    bxy, bxz, byz = b * x * y, b * x * z, b * y * z
    rows = [
        1.0 - b * (y * y + z * z), bxy - az, bxz + ay,
        bxy + az, 1.0 - b * (x * x + z * z), byz - ax,
        bxz - ay, byz + ax, 1.0 - b * (x * x + y * y),
    ]  # fmt: skip
    return _matrices(torch.stack(rows, dim=-1))


def exp_tiny(rv: Tensor) -> Tensor:
    """``Exp(rv)`` for rotation vectors all below 1e-5 rad (the frame's turn over half an
    IMU step, about 1e-7 rad): ``I + K + K²/2``, whose omitted terms (``|rv|³/6`` and
    ``|rv|²·|K|/6``) are below 1e-16 there; :func:`exp_so3` otherwise."""
    if not bool(((rv * rv).sum(-1) < 1e-10).all()):
        return exp_so3(rv)
    k = skew(rv)
    return constant("eye3", rv.dtype, rv.device) + k + matmul(k, k) * 0.5


def orthonormalize(c: Tensor) -> Tensor:
    """One step of ``C ← C (1.5 I − ½ CᵀC)``, the core's re-orthonormalization."""
    ctc = matmul(c.transpose(-1, -2), c)
    return matmul(c, constant("eye3x1.5", c.dtype, c.device) - ctc * 0.5)


def dcm_from_euler(rpy: Tensor) -> Tensor:
    """``(..., 3, 3)`` ``C_b^n = Rz(yaw) Ry(pitch) Rx(roll)`` of ``(..., 3)`` [rad]."""
    sr, sp, sy = torch.sin(rpy).unbind(-1)
    cr, cp, cy = torch.cos(rpy).unbind(-1)
    rows = [
        cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr,
        sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr,
        -sp, cp * sr, cp * cr,
    ]  # fmt: skip
    return _matrices(torch.stack(rows, dim=-1))


def euler_from_dcm(c: Tensor) -> Tensor:
    """``(..., 3)`` ZYX ``[roll, pitch, yaw]`` [rad] of ``(..., 3, 3)`` DCMs (yaw in
    (−π, π])."""
    roll = torch.atan2(c[..., 2, 1], c[..., 2, 2])
    pitch = torch.asin((-c[..., 2, 0]).clamp(-1.0, 1.0))
    yaw = torch.atan2(c[..., 1, 0], c[..., 0, 0])
    return torch.stack([roll, pitch, yaw], dim=-1)
