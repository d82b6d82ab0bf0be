"""The differentiable filter: pronet's INS/DVL error-state EKF in torch (float64),
batched over B independent sequences, the same algorithm as the core's recorded pass
(``rust/src/ekf/``; docs/filter.md), differentiable in the per-sample IMU variances q and
in the start state. It is how a model of q is trained through the filter on recorded
missions (docs/learning.md, "The differentiable filter"), checked against the core to
1e-9 (``tests/learn/test_torchfilter.py``).

The API (shapes: B sequences, T samples, n epochs of a call, K DVL rows per epoch):

- :class:`Setup` (formulation, aiding, covariance step, gate; ``Setup.from_config``),
  :class:`Batch` (``imu (B, T, 6)``, ``dt``, ``time``, the DVL rows mapped to epochs
  ``dvl (B, T, K, 3)`` with ``dvl_mask``, and per-sequence R, lever arm, bias PSDs;
  :func:`sensor_batch` makes one from a pass's arrays, ``Batch.stack`` joins them),
  :class:`State` (navigation solution, biases, P in the filter's own error coordinates
  ``(B, 15, 15)``, the covariance step under way; :func:`start_state`).
- :func:`advance` ``(state, batch, k0, k1, q) -> (state, Outputs)``: samples ``k0..k1``
  with q ``(B, 6)`` (or ``(B, k1 − k0, 6)`` per sample) in force; resumable: chunks
  equal one call. :class:`Outputs` holds per epoch the velocity, position, attitude,
  biases, the reported classic σ (``Outputs.sigma``), and the DVL innovations and NIS.
- :func:`windows`: the core over whole sections with a q schedule, cut into windows of
  a given length that start right after a DVL update, with the start states from the
  core's run (truncated back-propagation: gradients within a window only).

Frames: NED navigation, FRD body; positions ``[lat, lon (rad), h (m, up)]``.
"""

from pronet.learn.torchfilter.advance import advance
from pronet.learn.torchfilter.outputs import Outputs
from pronet.learn.torchfilter.state import Batch, Setup, State, sensor_batch, start_state

__all__ = ["Batch", "Outputs", "Setup", "State", "advance", "sensor_batch", "start_state"]
