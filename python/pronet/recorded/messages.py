"""One ROS message at a time in pronet's frames and units: what a node's callbacks hand
an online navigator (:class:`pronet.recorded.online.Navigator`).

:class:`MessageConverter` converts each message exactly as the bag reader
(:mod:`pronet.recorded.bags`) converts a whole topic: the same frames (the world's ENU or
NED into NED, the body's FLU or FRD into FRD, :class:`~pronet.recorded.bags.BagTopics`),
the same units and the same covariances turned into σ (where a message sets them). A
reading without a σ of its own gives None: the vehicle's σ then applies.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from pronet.recorded.bags import (
    BagTopics,
    _dcm,
    _depth_rows,
    _dvl_variance,
    _fix_rows,
    _frames,
    _heading_rows,
    _stamp,
    _xyz,
    euler_from_dcm,
)
from pronet.recorded.solution import F64


class MessageConverter:
    """Converts single messages of the topics ``topics`` describes (its frames, the
    pressure's surface reference and water density, the heading's source)."""

    def __init__(self, topics: BagTopics) -> None:
        self.topics = topics
        self._t_w, self._d_b = _frames(topics)  # world → NED, body FRD → the bag's body

    def stamp(self, msg: Any) -> float:
        """The message's header stamp [s]."""
        return _stamp(msg)

    def _frd(self, vector: Any) -> F64:
        return np.asarray(self._d_b @ _xyz(vector), dtype=np.float64)

    def imu(self, msg: Any) -> tuple[float, F64]:
        """A ``sensor_msgs/Imu``: ``(t [s], [f (m/s²), ω (rad/s)])`` in the body frame FRD."""
        f, w = self._frd(msg.linear_acceleration), self._frd(msg.angular_velocity)
        return _stamp(msg), np.concatenate([f, w])

    def orientation(self, msg: Any) -> tuple[float, F64, F64] | None:
        """A ``sensor_msgs/Imu``'s orientation (an AHRS's): ``(t, rpy [rad], 1σ [rad])``
        of the body FRD in NED, or None where the message sets no attitude variance."""
        variance = np.array(msg.orientation_covariance, dtype=np.float64)[[0, 4, 8]]
        if not (variance > 0).all():
            return None
        rpy = euler_from_dcm(self._t_w @ _dcm(msg.orientation) @ self._d_b)
        return _stamp(msg), np.asarray(rpy, dtype=np.float64), np.sqrt(variance)

    def dvl(self, msg: Any) -> tuple[float, F64, F64 | None]:
        """A DVL's ``TwistStamped`` or ``TwistWithCovarianceStamped``: ``(t, v (m/s,
        body FRD), 1σ per axis or None)``."""
        twist = msg.twist.twist if hasattr(msg.twist, "twist") else msg.twist
        r = _dvl_variance([msg])
        sigma = None if r is None else np.sqrt(np.array(r))
        return _stamp(msg), self._frd(twist.linear), sigma

    def depth(self, msg: Any) -> tuple[float, float, float | None]:
        """A ``sensor_msgs/FluidPressure``: ``(t, depth [m, down], 1σ [m] or None)``."""
        rows, labels = _depth_rows([msg], self.topics)
        sigma = float(rows[0, 2]) if "sigma [m]" in labels else None
        return float(rows[0, 0]), float(rows[0, 1]), sigma

    def fix(self, msg: Any) -> tuple[float, F64, F64 | None] | None:
        """A ``sensor_msgs/NavSatFix``: ``(t, [φ, λ (rad), h (m)], 1σ north, east, down or
        None)``, or None without a fix (``STATUS_NO_FIX``)."""
        (row,), labels = _fix_rows([msg])
        if np.isnan(row[1]):
            return None
        sigma = row[4:7].copy() if len(labels) > 4 else None
        return float(row[0]), row[1:4].copy(), sigma

    def heading(self, msg: Any) -> tuple[float, float, float | None] | None:
        """A heading message of the kind the heading topic holds (``Imu``,
        ``QuaternionStamped``, a pose): ``(t, yaw [rad, from true north], 1σ [rad] or
        None)``, or None where it has no orientation."""
        table = _heading_rows([msg], self.topics)
        if table.reasons and table.reasons[0]:
            return None
        t, yaw = (float(v) for v in table.values[0, :2])
        sigma = float(table.values[0, 2]) if len(table.labels) > 2 else None
        return t, yaw, sigma
