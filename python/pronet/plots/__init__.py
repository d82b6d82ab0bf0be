"""Figures, drawn with matplotlib's Agg canvas (no display, no global pyplot state) and
written as PNG atomically; matplotlib loads only when one is drawn.

- :mod:`~pronet.plots.figures`: one function per figure of the simulated experiments
  and of ``pronet evaluate`` (re-exported here: ``pronet.plots.trajectory(...)``);
- :mod:`~pronet.plots.sections`: the figures of a recorded section (``pronet real``).

``docs/reference/figures.md`` shows each figure and how to read it.
"""

from pronet.plots.figures import (
    metrics_with_ci,
    png_bytes,
    predicted_vs_true,
    q_tracking,
    save_png,
    study_figure,
    sweep_metric,
    trajectory,
    velocity_error,
)

__all__ = [
    "metrics_with_ci",
    "png_bytes",
    "predicted_vs_true",
    "q_tracking",
    "save_png",
    "study_figure",
    "sweep_metric",
    "trajectory",
    "velocity_error",
]
