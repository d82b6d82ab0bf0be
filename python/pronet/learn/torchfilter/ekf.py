"""The error-state EKF's pieces in torch, batched over B sequences: the error dynamics
F, the IMU noise mapped through Γ, the per-sample and covariance-step transitions, the
DVL update (body velocity with the lever arm, or NED velocity) in Joseph form and the
feedback of the error estimate, in the classic or the invariant formulation
(``rust/src/ekf/``, docs/reference/filter.md).

Error state (15): ``[δp (NED m), δv (m/s), ψ (rad), δb_a (m/s²), δb_g (rad/s)]``,
estimate minus truth. In the invariant formulation the velocity error is ``δV = δv −
[v̂×]ψ`` and P lives in those coordinates (``x_inv = T x_classic``, ``T`` the identity
but ``−[v̂×]`` at (velocity, attitude))."""

from __future__ import annotations

import torch
from torch import Tensor

from pronet.learn.torchfilter.attitude import constant, exp_so3, matmul, skew
from pronet.learn.torchfilter.earth import Rates, ned_to_lla_delta

POS, VEL, ATT, ACC_BIAS, GYRO_BIAS = 0, 3, 6, 9, 12


def eye15(like: Tensor) -> Tensor:
    """The 15 × 15 identity in ``like``'s dtype and device (shared: not to be modified)."""
    return constant("eye15", like.dtype, like.device)


def _pad(x: Tensor, widths: tuple[int, ...]) -> Tensor:
    """``x`` padded with zeros, ``widths`` as ``torch.nn.functional.pad`` takes them
    (the same operation without its Python wrapper)."""
    return torch.constant_pad_nd(x, widths)


def error_dynamics(
    vel: Tensor, dcm: Tensor, r: Rates, h: Tensor, f_ned: Tensor, invariant: bool
) -> Tensor:
    """``(B, 15, 15)`` F at the navigation state ``vel`` ``(B, 3)``, ``dcm``, height
    ``h`` ``(B,)`` [m] with the frame rates ``r`` there and the NED specific force
    ``f_ned`` ``(B, 3)`` [m/s²] (docs/reference/filter.md; the core's ``ErrorDynamics``)."""
    batch = vel.shape[0]
    zero = vel.new_zeros(batch, 3, 3)
    eye = constant("eye3", vel.dtype, vel.device).expand(batch, 3, 3)
    schuler = r.gravity / ((r.r_n * r.r_e).sqrt() + h)
    transport = -skew(r.transport)
    gravity = torch.diag_embed(torch.stack([-schuler, -schuler, 2.0 * schuler], -1))
    coriolis = -skew(2.0 * r.earth + r.transport)
    accel_bias = -dcm
    # joined in the order the blocks are made (dcm and [v̂×] read in the same order:
    # their gradients summed in the same order)
    attitude = torch.cat([zero, zero, -skew(r.nav_rate), zero, dcm], -1)
    if invariant:
        v = skew(vel)
        position = torch.cat([transport, eye, v, zero, zero], -1)
        velocity_attitude = -skew(r.gravity_ned) - matmul(v, skew(r.earth))
        velocity_gyro = matmul(-v, dcm)
    else:
        position = torch.cat([transport, eye, zero, zero, zero], -1)
        velocity_attitude, velocity_gyro = skew(f_ned), zero
    velocity = torch.cat([gravity, coriolis, velocity_attitude, accel_bias, velocity_gyro], -1)
    return _pad(torch.cat([position, velocity, attitude], -2), (0, 0, 0, 6))


def imu_noise(vel: Tensor, dcm: Tensor, white: Tensor, walk: Tensor, invariant: bool) -> Tensor:
    """``(B, 15, 15)`` ``Γ diag(white) Γᵀ`` plus ``diag(walk)`` on the bias states: the
    discrete noise of IMU white-noise variances ``white`` ``(B, 6)`` (``q Δt_imu Δt``
    summed, [(m/s)², rad²]) and bias walks ``walk`` ``(B, 6)`` (``ε Δt`` summed), Γ at
    ``vel``, ``dcm`` (accelerometer noise into δv, gyro noise into −ψ; the invariant
    formulation also ``[v̂×] C`` of the gyro noise into δV)."""
    ct = dcm.transpose(-1, -2)
    qa = matmul(dcm, white[:, 0:3, None] * ct)  # C diag(q_a) Cᵀ
    qg = matmul(dcm, white[:, 3:6, None] * ct)
    if invariant:
        v = skew(vel)
        vg = matmul(v, qg)
        velocity = [qa + matmul(vg, v.transpose(-1, -2)), -vg]
        attitude = [-vg.transpose(-1, -2), qg]
    else:
        zero = vel.new_zeros(vel.shape[0], 3, 3)
        velocity, attitude = [qa, zero], [zero, qg]
    # (velocity, attitude) × (velocity, attitude) at [3:9, 3:9], the walks on 9..14
    middle = torch.cat([torch.cat(velocity, -1), torch.cat(attitude, -1)], -2)
    walks = torch.diag_embed(walk)
    return torch.cat([_pad(middle, (3, 6, 3, 0)), _pad(walks, (9, 0))], -2)


def symmetric(p: Tensor) -> Tensor:
    """``(P + Pᵀ) / 2``."""
    return (p + p.transpose(-1, -2)) * 0.5


def propagate_sample(p: Tensor, fm: Tensor, q: Tensor, dt: Tensor) -> Tensor:
    """Per-sample propagation ``P ← Φ P Φᵀ + Q_d`` with ``Φ = I + F Δt``."""
    phi = eye15(p) + fm * dt[:, None, None]
    return symmetric(matmul(matmul(phi, p), phi.transpose(-1, -2)) + q)


def propagate_interval(p: Tensor, fm: Tensor, q: Tensor, elapsed: Tensor) -> Tensor:
    """A covariance step's close: ``Φ = I + F ΔT + ½(F ΔT)²``, ``P ← Φ (P + ½Q) Φᵀ +
    ½Q`` (``q`` the accumulated noise)."""
    ft = fm * elapsed[:, None, None]
    phi = eye15(p) + ft + matmul(ft, ft) * 0.5
    half = q * 0.5
    return symmetric(matmul(matmul(phi, p + half), phi.transpose(-1, -2)) + half)


def coordinates(vel: Tensor, sign: float) -> Tensor:
    """``(B, 15, 15)`` T with ``sign · [v̂×]`` at (velocity, attitude): ``sign = −1``
    maps classic errors to invariant ones, ``+1`` back."""
    t = eye15(vel).expand(vel.shape[0], 15, 15).clone()
    t[:, 3:6, 6:9] = sign * skew(vel)
    return t


def to_invariant(p_classic: Tensor, vel: Tensor) -> Tensor:
    """A classic covariance in the invariant coordinates at ``vel``: ``T P Tᵀ``."""
    t = coordinates(vel, -1.0)
    return symmetric(matmul(matmul(t, p_classic), t.transpose(-1, -2)))


def to_classic(p: Tensor, vel: Tensor) -> Tensor:
    """An invariant covariance in the classic coordinates at ``vel``."""
    t = coordinates(vel, 1.0)
    return symmetric(matmul(matmul(t, p), t.transpose(-1, -2)))


def measurement(
    vel: Tensor, dcm: Tensor, gyro: Tensor, arm: Tensor, aiding: str, invariant: bool
) -> tuple[Tensor, Tensor]:
    """The predicted DVL reading ``(B, 3)`` and its Jacobian H ``(B, 3, 15)``: body
    aiding ``Ĉᵀ v̂ + ω̂ × r`` (``gyro`` the last bias-corrected rate, ``arm`` the lever
    arm [m, body]), NED aiding ``v̂ + Ĉ (ω̂ × r)`` (the core's
    ``measurement::velocity``)."""
    batch = vel.shape[0]
    h = vel.new_zeros(batch, 3, 15)
    if aiding == "body":
        ct = dcm.transpose(-1, -2)
        h[:, :, 3:6] = ct
        if not invariant:
            h[:, :, 6:9] = matmul(-ct, skew(vel))
        h[:, :, 12:15] = skew(arm)
        pred = matmul(ct, vel.unsqueeze(-1)).squeeze(-1) + torch.linalg.cross(gyro, arm)
        return pred, h
    h[:, :, 3:6] = constant("eye3", vel.dtype, vel.device)
    if invariant:
        h[:, :, 6:9] = skew(vel)
    if not bool((arm != 0).any()):
        return vel, h
    at_arm = matmul(dcm, torch.linalg.cross(gyro, arm).unsqueeze(-1)).squeeze(-1)
    h[:, :, 6:9] += skew(at_arm)
    h[:, :, 12:15] = matmul(dcm, skew(arm))
    return vel + at_arm, h


def dvl_noise(
    variance: Tensor, arm: Tensor, gyro_variance: Tensor, dcm: Tensor, aiding: str
) -> Tensor:
    """The DVL update's noise ``(B, 3, 3)``: ``diag(variance)`` and what the gyro's
    white noise (``gyro_variance`` ``(B, 3)`` per axis [(rad/s)²]) puts on the lever
    arm's ``ω̂ × r``: ``[r×] Σ_ω [r×]ᵀ`` in body aiding, ``Ĉ [r×] Σ_ω [r×]ᵀ Ĉᵀ`` in
    NED aiding (``dcm`` Ĉ, body to NED; the core's)."""
    r = torch.diag_embed(variance)
    if aiding != "body" and not bool((arm != 0).any()):
        return r
    a = skew(arm) if aiding == "body" else matmul(dcm, skew(arm))
    return r + matmul(a * gyro_variance[:, None, :], a.transpose(-1, -2))


def kalman_update(p: Tensor, h: Tensor, nu: Tensor, r: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """The Joseph-form update of ``p`` by innovations ``nu`` ``(B, 3)`` with Jacobian
    ``h`` and noise ``r`` ``(B, 3, 3)``: the new P (symmetrized), the error estimate
    ``δx̂ = −K ν`` ``(B, 15)`` and the NIS ``νᵀ S⁻¹ ν`` ``(B,)``."""
    pht = matmul(p, h.transpose(-1, -2))
    s = matmul(h, pht) + r
    s_inv = torch.cholesky_inverse(torch.linalg.cholesky(s))
    gain = matmul(pht, s_inv)
    nis = matmul(matmul(nu.unsqueeze(-2), s_inv), nu.unsqueeze(-1))[:, 0, 0]
    ikh = eye15(p) - matmul(gain, h)
    joseph = matmul(matmul(ikh, p), ikh.transpose(-1, -2))
    new_p = joseph + matmul(matmul(gain, r), gain.transpose(-1, -2))
    return symmetric(new_p), -matmul(gain, nu.unsqueeze(-1)).squeeze(-1), nis


def feedback(
    lla: Tensor, vel: Tensor, dcm: Tensor, bias: Tensor, dx: Tensor, invariant: bool
) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """Remove the error estimate ``dx`` ``(B, 15)`` from the solution (the core's
    ``correct``): position in NED metres, velocity (invariant: ``v̂ ← Exp(ψ̂)(v̂ −
    δV̂)``), attitude ``Ĉ ← Exp(ψ̂) Ĉ`` and the biases."""
    rotation = exp_so3(dx[:, ATT : ATT + 3])
    new_lla = lla - ned_to_lla_delta(lla, dx[:, POS : POS + 3])
    moved = vel - dx[:, VEL : VEL + 3]
    new_vel = matmul(rotation, moved.unsqueeze(-1)).squeeze(-1) if invariant else moved
    return new_lla, new_vel, matmul(rotation, dcm), bias - dx[:, ACC_BIAS:]
