"""Strapdown mechanization of IMU arrays, and geodetic positions as local NED metres.

:func:`local_ned` and its inverse :func:`lla_from_ned` use the core's WGS-84 ellipsoid
(``_core.WGS84_A``, ``_core.WGS84_F``), exactly (through Earth-centred, Earth-fixed
coordinates, no small-offset approximation): ``ned`` is the vector from ``origin`` to the
point in the NED frame at ``origin`` (north, east, down [m]; a tangent plane, so
``down`` grows with the distance as the Earth curves away).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet import _core
from pronet._util.plausibility import angles_beyond, check_imu_start
from pronet._util.validate import float_array, real_array, scalar


@dataclass(frozen=True)
class NavSolution:
    """A navigation solution at n + 1 epochs (the initial state first).

    Attributes:
        lla: ``(n+1, 3)`` geodetic latitude, longitude [rad] and height [m, up].
        vel: ``(n+1, 3)`` velocity, NED [m/s].
        rpy: ``(n+1, 3)`` roll, pitch, yaw (ZYX) [rad], yaw in (−π, π].
    """

    lla: NDArray[np.float64]
    vel: NDArray[np.float64]
    rpy: NDArray[np.float64]


def mechanize(
    imu: ArrayLike, dt: float, lla0: ArrayLike, vel0: ArrayLike, rpy0: ArrayLike
) -> NavSolution:
    """Integrate IMU samples with the NED strapdown equations (no aiding).

    Args:
        imu: ``(n, 6)`` samples ``[f_x, f_y, f_z, w_x, w_y, w_z]``: specific force [m/s²]
            and angular rate [rad/s], body frame FRD, each the mean over its interval.
        dt: sample period [s].
        lla0: initial ``[lat rad, lon rad, h m]``.
        vel0: initial NED velocity [m/s].
        rpy0: initial roll, pitch, yaw [rad].

    More states than this process can still take are a ``ValueError`` naming ``imu``
    (docs/results/performance.md, "Memory"). So are a unit or frame slip the samples show
    (:func:`pronet._util.plausibility.check_imu_start`: a mean specific force that is
    not gravity's, or that points away from where ``rpy0`` puts it, as in an IMU left
    in FLU) and a ``lla0`` in degrees.
    """
    samples = float_array(imu, "imu", (None, 6))
    step = scalar(dt, "dt")
    start, attitude = float_array(lla0, "lla0", (3,)), float_array(rpy0, "rpy0", (3,))
    if step > 0 and np.isfinite(step):
        check_imu_start(samples, np.arange(len(samples), dtype=np.float64) * step, attitude)
    if (beyond := angles_beyond(start, "lla0")) is not None:
        raise ValueError(beyond)
    out = _core.mechanize(samples, step, start, float_array(vel0, "vel0", (3,)), attitude)
    return NavSolution(lla=out["lla"], vel=out["vel"], rpy=out["rpy"])


def _ecef(lla: NDArray[np.float64]) -> NDArray[np.float64]:
    """``(..., 3)`` geodetic ``[lat, lon, h]`` [rad, rad, m] as ECEF ``[x, y, z]`` [m]."""
    e2 = _core.WGS84_F * (2.0 - _core.WGS84_F)
    lat, lon, h = lla[..., 0], lla[..., 1], lla[..., 2]
    n = _core.WGS84_A / np.sqrt(1.0 - e2 * np.sin(lat) ** 2)
    return np.stack(
        [
            (n + h) * np.cos(lat) * np.cos(lon),
            (n + h) * np.cos(lat) * np.sin(lon),
            (n * (1.0 - e2) + h) * np.sin(lat),
        ],
        axis=-1,
    )


def _ned_rotation(origin: NDArray[np.float64]) -> NDArray[np.float64]:
    """The rotation from ECEF to the NED frame at ``origin`` (rows: N, E, D in ECEF)."""
    sl, cl = np.sin(origin[0]), np.cos(origin[0])
    so, co = np.sin(origin[1]), np.cos(origin[1])
    return np.array([[-sl * co, -sl * so, cl], [-so, co, 0.0], [-cl * co, -cl * so, -sl]])


def _origin(origin: ArrayLike) -> NDArray[np.float64]:
    o = float_array(origin, "origin", (3,))
    if not (np.isfinite(o).all() and abs(o[0]) <= np.pi / 2):
        raise ValueError(f"origin: expected finite [lat, lon, h] with |lat| <= pi/2, got {o}")
    if (beyond := angles_beyond(o, "origin")) is not None:
        raise ValueError(beyond)
    return o


def local_ned(lla: ArrayLike, origin: ArrayLike) -> NDArray[np.float64]:
    """Geodetic positions as local north, east, down metres about ``origin``.

    Args:
        lla: ``(3,)`` or ``(n, 3)`` latitude, longitude [rad] and height [m, up] (WGS-84),
            e.g. :attr:`pronet.FilterResult.lla` or ``Trajectory.lla``.
        origin: ``(3,)`` the origin's latitude, longitude [rad] and height [m].

    Latitudes beyond ±90° and longitudes beyond −180° … 360° (either convention) are
    refused as angles in degrees, naming the argument (and the row).

    Returns:
        ``lla``'s shape: the vector from ``origin`` to each point in the NED frame at
        ``origin`` [m]. :func:`lla_from_ned` is the inverse.
    """
    o = _origin(origin)
    p = _rows(lla, "lla")
    if (beyond := angles_beyond(p, "lla")) is not None:
        raise ValueError(beyond)
    return (_ecef(p) - _ecef(o)) @ _ned_rotation(o).T


def lla_from_ned(ned: ArrayLike, origin: ArrayLike) -> NDArray[np.float64]:
    """Local north, east, down metres about ``origin`` as geodetic positions (the inverse
    of :func:`local_ned`; exact to below a micrometre within 1000 km of ``origin``).

    Args:
        ned: ``(3,)`` or ``(n, 3)`` NED vectors from ``origin`` [m], in its NED frame.
        origin: ``(3,)`` the origin's latitude, longitude [rad] and height [m] (its
            longitude within −180° … 360°, as :func:`local_ned`'s).

    Returns:
        ``ned``'s shape: latitude, longitude [rad] in (−π, π], height [m, up] (WGS-84).
    """
    o = _origin(origin)
    x = _ecef(o) + _rows(ned, "ned") @ _ned_rotation(o)
    a, e2 = _core.WGS84_A, _core.WGS84_F * (2.0 - _core.WGS84_F)
    lon = np.arctan2(x[..., 1], x[..., 0])
    r = np.hypot(x[..., 0], x[..., 1])
    lat = np.arctan2(x[..., 2], r * (1.0 - e2))
    for _ in range(6):  # the fixed point converges by ~e² per step: 1e-15 rad after 6
        n = a / np.sqrt(1.0 - e2 * np.sin(lat) ** 2)
        lat = np.arctan2(x[..., 2] + e2 * n * np.sin(lat), r)
    n = a / np.sqrt(1.0 - e2 * np.sin(lat) ** 2)
    cos_lat, sin_lat = np.cos(lat), np.sin(lat)
    h = r * cos_lat + x[..., 2] * sin_lat - n * (1.0 - e2 * sin_lat**2)
    return np.stack([lat, lon, h], axis=-1)


def _rows(value: ArrayLike, name: str) -> NDArray[np.float64]:
    """``value`` as finite float64 ``(3,)`` or ``(n, 3)``, or ``ValueError`` naming it."""
    shape: tuple[int | None, ...] = (3,) if real_array(value, name).ndim == 1 else (None, 3)
    out = float_array(value, name, shape)
    if not np.isfinite(out).all():
        raise ValueError(f"{name}: must be finite")
    return out
