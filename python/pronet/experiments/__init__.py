"""The experiments: compositions of the run path (:func:`pronet.run.run`) that write
one result folder each (:mod:`pronet.results`).

- :mod:`~pronet.experiments.aided_calibration`: the DVL calibration states with
  position fixes and depth (``scripts/aided_calibration.py``, ``docs/results/calibration.md``);
- :mod:`~pronet.experiments.qlearn`: Q models learned from missions with ground truth,
  trained through the differentiable filter and cross-validated
  (``pronet train --recorded``, ``docs/how-to/learning-q.md``);
- :mod:`~pronet.experiments.consistency`: is the filter's σ honest, block by block,
  for every IMU grade (``scripts/consistency.py``, ``docs/results/consistency.md``);
- :mod:`~pronet.experiments.reproduce`: the paper's experiment end to end
  (``pronet reproduce``);
- :mod:`~pronet.experiments.simulation`: chosen strategies on one scenario
  (``pronet simulate``);
- :mod:`~pronet.experiments.study`: when adaptive process noise pays (``pronet study``);
- :mod:`~pronet.experiments.sweep`: grids of Monte Carlos, locally or on Ray
  (``pronet sweep``).

Recorded sections have their own experiment, :mod:`pronet.recorded.real`.
"""

__all__ = [
    "aided_calibration",
    "consistency",
    "qlearn",
    "reproduce",
    "simulation",
    "study",
    "sweep",
]
