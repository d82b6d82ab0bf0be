"""The strapdown step of ``rust/src/mechanization.rs`` (``step_with_rates``) in torch,
batched over B sequences: attitude by two half-turns split at mid-step, velocity with the
specific force resolved at mid-step plus gravity and Coriolis, position by the
trapezoid of the velocities (docs/reference/filter.md, "Strapdown step")."""

from __future__ import annotations

import torch
from torch import Tensor

from pronet.learn.torchfilter.attitude import exp_so3, exp_tiny, matmul, orthonormalize
from pronet.learn.torchfilter.earth import Rates, prime_vertical_radius


def strapdown_step(
    lla: Tensor,
    vel: Tensor,
    dcm: Tensor,
    accel: Tensor,
    body_half: Tensor,
    dt: Tensor,
    r: Rates,
) -> tuple[Tensor, Tensor, Tensor]:
    """One step over ``dt`` ``(B,)`` [s] from ``lla`` ``(B, 3)``, NED ``vel`` ``(B, 3)``
    [m/s] and ``dcm`` ``(B, 3, 3)`` (``C_b^n``) with the bias-corrected specific force
    ``accel`` [m/s², body] and the body's half-turn ``body_half`` ``(B, 3, 3)``
    (:func:`body_half_turns` of the bias-corrected rate), the frame rates ``r`` taken at
    the step's start. Returns the new ``(lla, vel, dcm)``."""
    dt1 = dt.unsqueeze(-1)
    nav_half = exp_tiny(r.nav_rate * (-0.5 * dt1))
    c_mid = matmul(matmul(nav_half, dcm), body_half)
    new_dcm = orthonormalize(matmul(matmul(nav_half, c_mid), body_half))
    coriolis = torch.linalg.cross(2.0 * r.earth + r.transport, vel)
    kinematic = r.gravity_ned - coriolis
    new_vel = vel + matmul(c_mid, accel.unsqueeze(-1)).squeeze(-1) * dt1 + kinematic * dt1
    # advance_position: the trapezoid (the three NED components at once, each as
    # before), radii at the start and at the mid latitude
    travel = 0.5 * (vel + new_vel) * dt1
    h = lla[..., 2]
    h1 = h - travel[..., 2]
    h_mid = 0.5 * (h + h1)
    lat1 = lla[..., 0] + travel[..., 0] / (r.r_n + h_mid)
    mid = 0.5 * (lla[..., 0] + lat1)
    r_e_mid = prime_vertical_radius(torch.sin(mid))
    lon1 = lla[..., 1] + travel[..., 1] / ((r_e_mid + h_mid) * torch.cos(mid))
    return torch.stack([lat1, lon1, h1], dim=-1), new_vel, new_dcm


def body_half_turns(gyro: Tensor, dt: Tensor) -> Tensor:
    """``Exp(ω̂ Δt / 2)`` ``(..., 3, 3)`` of bias-corrected rates ``gyro`` ``(..., 3)``
    [rad/s] over steps ``dt`` ``(...)`` [s]: computed for a stretch of samples at once
    (the biases change only at updates)."""
    return exp_so3(gyro * (0.5 * dt.unsqueeze(-1)))
