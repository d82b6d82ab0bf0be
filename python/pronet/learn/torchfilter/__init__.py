"""The differentiable filter: pronet's INS/DVL error-state EKF in torch (float64),
batched over B independent sequences, the same algorithm as the core's recorded pass
(``rust/src/ekf/``; docs/reference/filter.md), differentiable in the per-sample IMU variances q and
in the start state. It is how a model of q is trained through the filter on recorded
missions (docs/reference/learning.md, "The differentiable filter"), checked against the core to
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
- :func:`windows.windows`: the core over whole sections with a q schedule, cut into windows of
  a given length that start right after a DVL update, with the start states from the
  core's run (truncated back-propagation: gradients within a window only).

Frames: NED navigation, FRD body; positions ``[lat, lon (rad), h (m, up)]``.

Modules: :mod:`~pronet.learn.torchfilter.attitude` (rotations),
:mod:`~pronet.learn.torchfilter.earth` (WGS-84), :mod:`~pronet.learn.torchfilter.mechanization`
(the strapdown step), :mod:`~pronet.learn.torchfilter.ekf` (F, the noise, the
transitions, the update and feedback), :mod:`~pronet.learn.torchfilter.state` (setup,
batch, state), :mod:`~pronet.learn.torchfilter.loop` (:func:`advance`),
:mod:`~pronet.learn.torchfilter.outputs` (what it returns, the reported σ),
:mod:`~pronet.learn.torchfilter.windows` (windows from the core's passes). The names
above are re-exported here.
"""

from pronet.learn.torchfilter.loop import advance as advance
from pronet.learn.torchfilter.outputs import Outputs as Outputs
from pronet.learn.torchfilter.state import Batch as Batch
from pronet.learn.torchfilter.state import Setup as Setup
from pronet.learn.torchfilter.state import State as State
from pronet.learn.torchfilter.state import sensor_batch as sensor_batch
from pronet.learn.torchfilter.state import start_state as start_state

__all__ = [
    "attitude",
    "earth",
    "ekf",
    "loop",
    "mechanization",
    "outputs",
    "state",
    "windows",
]
