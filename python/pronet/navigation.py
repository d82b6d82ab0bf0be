"""Strapdown mechanization of IMU arrays."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet import _core
from pronet._util.validate import float_array, scalar


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
    """
    out = _core.mechanize(
        float_array(imu, "imu", (None, 6)),
        scalar(dt, "dt"),
        float_array(lla0, "lla0", (3,)),
        float_array(vel0, "vel0", (3,)),
        float_array(rpy0, "rpy0", (3,)),
    )
    return NavSolution(lla=out["lla"], vel=out["vel"], rpy=out["rpy"])
