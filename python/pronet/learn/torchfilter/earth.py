"""The WGS-84 Earth of ``rust/src/earth.rs`` in torch, batched: radii of curvature,
normal gravity, Earth and transport rates, NED offsets to geodetic ones.

Positions are ``[lat, lon, h]`` (geodetic latitude and longitude [rad], height above
the ellipsoid [m, up]); vectors in the navigation frame are NED."""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor

A = 6378137.0  #: semi-major axis [m]
F = 1.0 / 298.257223563  #: flattening
E2 = F * (2.0 - F)  #: first eccentricity squared
B = A * (1.0 - F)  #: semi-minor axis [m]
OMEGA_IE = 7.292115e-5  #: Earth rotation rate [rad/s]
GM = 3.986004418e14  #: gravitational constant [m³/s²]
GAMMA_EQUATOR = 9.7803253359  #: normal gravity at the equator [m/s²]
GAMMA_POLE = 9.8321849378  #: normal gravity at the poles [m/s²]


def _root(sin_lat: Tensor) -> tuple[Tensor, Tensor]:
    """``d = 1 − e² sin²φ`` and its square root."""
    d = 1.0 - E2 * sin_lat * sin_lat
    return d, d.sqrt()


def radii(sin_lat: Tensor) -> tuple[Tensor, Tensor]:
    """Meridian and prime-vertical radii of curvature ``(R_N, R_E)`` [m] from the sine
    of the latitude."""
    d, sqrt_d = _root(sin_lat)
    return A * (1.0 - E2) / (d * sqrt_d), A / sqrt_d


def prime_vertical_radius(sin_lat: Tensor) -> Tensor:
    """``R_E`` of :func:`radii` alone (the same operations)."""
    return A / _root(sin_lat)[1]


def gravity(sin_lat: Tensor, h: Tensor) -> Tensor:
    """Normal gravity [m/s², down] at the latitude of sine ``sin_lat`` and height ``h``
    [m]: Somigliana with the second-order height term (as the core)."""
    s2 = sin_lat * sin_lat
    k = (1.0 - F) * GAMMA_POLE / GAMMA_EQUATOR - 1.0
    gamma0 = GAMMA_EQUATOR * (1.0 + k * s2) / (1.0 - E2 * s2).sqrt()
    m = OMEGA_IE * OMEGA_IE * A * A * B / GM
    return gamma0 * (1.0 - 2.0 * h / A * (1.0 + F + m - 2.0 * F * s2) + 3.0 * h * h / (A * A))


@dataclass(frozen=True)
class Rates:
    """What a step evaluates at its start (``FrameRates`` of the core), each ``(B, ...)``:
    Earth rate and transport rate [rad/s, NED], gravity [m/s², down], the latitude's
    sine and cosine and the radii of curvature [m]."""

    earth: Tensor
    transport: Tensor
    gravity: Tensor
    sin: Tensor
    cos: Tensor
    r_n: Tensor
    r_e: Tensor

    @property
    def nav_rate(self) -> Tensor:
        """``ω_in = ω_ie + ω_en`` [rad/s, NED]."""
        return self.earth + self.transport

    @property
    def gravity_ned(self) -> Tensor:
        """``(B, 3)`` gravity vector [m/s², NED]."""
        z = torch.zeros_like(self.gravity)
        return torch.stack([z, z, self.gravity], dim=-1)


def rates(lla: Tensor, vel: Tensor) -> Rates:
    """The frame rates at positions ``lla`` ``(B, 3)`` and NED velocities ``vel``
    ``(B, 3)`` [m/s]."""
    lat, h = lla[..., 0], lla[..., 2]
    sin, cos = torch.sin(lat), torch.cos(lat)
    r_n, r_e = radii(sin)
    zero = torch.zeros_like(lat)
    earth = torch.stack([OMEGA_IE * cos, zero, -OMEGA_IE * sin], dim=-1)
    transport = torch.stack(
        [
            vel[..., 1] / (r_e + h),
            -vel[..., 0] / (r_n + h),
            -vel[..., 1] * (sin / cos) / (r_e + h),
        ],
        dim=-1,
    )
    return Rates(earth, transport, gravity(sin, h), sin, cos, r_n, r_e)


def ned_to_lla_delta(lla: Tensor, d: Tensor) -> Tensor:
    """The geodetic change ``(B, 3)`` [rad, rad, m] of a NED offset ``d`` [m] at
    ``lla``."""
    lat, h = lla[..., 0], lla[..., 2]
    r_n, r_e = radii(torch.sin(lat))
    return torch.stack(
        [d[..., 0] / (r_n + h), d[..., 1] / ((r_e + h) * torch.cos(lat)), -d[..., 2]], dim=-1
    )
