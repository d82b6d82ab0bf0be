"""Rotations in torch, batched over leading dimensions: the skew matrix, the SO(3)
exponential, Euler angles and the re-orthonormalization of the core's
``rust/src/attitude.rs`` (same formulas, same branches).

Frames: a DCM ``C_b^n`` takes FRD body vectors to NED; Euler angles are ZYX
``[roll, pitch, yaw]`` [rad]."""

from __future__ import annotations

import torch
from torch import Tensor


def skew(v: Tensor) -> Tensor:
    """``(..., 3, 3)`` cross-product matrix ``[v×]`` of ``(..., 3)`` vectors."""
    x, y, z = v.unbind(-1)
    o = torch.zeros_like(x)
    return torch.stack([o, -z, y, z, o, -x, -y, x, o], dim=-1).unflatten(-1, (3, 3))


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
    return torch.stack(rows, dim=-1).unflatten(-1, (3, 3))


def exp_tiny(rv: Tensor) -> Tensor:
    """``Exp(rv)`` for rotation vectors all below 1e-5 rad (the frame's turn over half an
    IMU step, about 1e-7 rad): ``I + K + K²/2``, whose omitted terms (``|rv|³/6`` and
    ``|rv|²·|K|/6``) are below 1e-16 there; :func:`exp_so3` otherwise."""
    if not bool(((rv * rv).sum(-1) < 1e-10).all()):
        return exp_so3(rv)
    k = skew(rv)
    return torch.eye(3, dtype=rv.dtype, device=rv.device) + k + k @ k * 0.5


def orthonormalize(c: Tensor) -> Tensor:
    """One step of ``C ← C (1.5 I − ½ CᵀC)``, the core's re-orthonormalization."""
    eye = torch.eye(3, dtype=c.dtype, device=c.device)
    return c @ (eye * 1.5 - c.transpose(-1, -2) @ c * 0.5)


def dcm_from_euler(rpy: Tensor) -> Tensor:
    """``(..., 3, 3)`` ``C_b^n = Rz(yaw) Ry(pitch) Rx(roll)`` of ``(..., 3)`` [rad]."""
    sr, sp, sy = torch.sin(rpy).unbind(-1)
    cr, cp, cy = torch.cos(rpy).unbind(-1)
    rows = [
        cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr,
        sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr,
        -sp, cp * sr, cp * cr,
    ]  # fmt: skip
    return torch.stack(rows, dim=-1).unflatten(-1, (3, 3))


def euler_from_dcm(c: Tensor) -> Tensor:
    """``(..., 3)`` ZYX ``[roll, pitch, yaw]`` [rad] of ``(..., 3, 3)`` DCMs (yaw in
    (−π, π])."""
    roll = torch.atan2(c[..., 2, 1], c[..., 2, 2])
    pitch = torch.asin((-c[..., 2, 0]).clamp(-1.0, 1.0))
    yaw = torch.atan2(c[..., 1, 0], c[..., 0, 0])
    return torch.stack([roll, pitch, yaw], dim=-1)
