"""Q models learned from recorded missions, as model files ``learned:PATH`` runs.

- :class:`SectionScale` (kind ``"section-scale"``, model (a) of docs/how-to/learning-q.md):
  one scale per channel group, ``q = [s_a·q̂_f, s_g·q̂_ω]`` on the section's own
  constant-row q ``q̂`` (:func:`pronet.recorded.tuning.white_noise_q` on recorded
  data): a constant over the section, so ``learned:PATH`` runs it as the native
  constant strategy (:func:`pronet.strategies.strategy`). Needs no torch.
- The windowed CNN (model (b)) is a scale-free :class:`pronet.learn.models.DetrendNet`
  (``scaling="spread"``: ``ln q = ln s² + z(window)``, s² the detrended window's mean
  square), saved as that kind: it runs frozen in the core like the shipped nets.
- The A-KIT-like model (c) (kind ``"akit"``, :mod:`pronet.learn.akit`) also reads the
  filter's velocity: on recorded data its schedule comes from a stepped core run
  (``recorded_schedule``), which :func:`pronet.run.run` calls instead of the windows-only
  schedule; it needs torch and cannot run in the simulated hybrid loop.

:func:`load_model_file` opens any of them by path (or a shipped name).
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from pronet.learn import modelfile

#: The card kind of :class:`SectionScale`.
SECTION_SCALE = "section-scale"


@dataclass(frozen=True)
class SectionScale:
    """Model (a): the constant row's q times ``scales`` ``(s_a, s_g)`` (accelerometer,
    gyro), positive and finite; ``card``: the model card when read from a file."""

    scales: tuple[float, float]
    card: dict[str, Any] | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        if len(self.scales) != 2 or not all(0 < s < math.inf for s in self.scales):
            raise ValueError(f"scales: two finite values > 0, got {self.scales}")

    def q_for(self, q_nominal: Sequence[float]) -> tuple[float, ...]:
        """The section's q [(m/s²)², (rad/s)²] from its constant row's ``q_nominal`` (6,)."""
        q = np.asarray(q_nominal, dtype=np.float64)
        if q.shape != (6,):
            raise ValueError(f"q_nominal: expected 6 variances, got shape {q.shape}")
        return tuple(float(v) for v in q * np.repeat(self.scales, 3))

    def save(self, path: str | os.PathLike[str], card: dict[str, Any]) -> Path:
        """Write the safetensors weights (``log_scales``) and the JSON card."""
        tensors = {"log_scales": np.log(np.asarray(self.scales, dtype=np.float64))}
        return modelfile.write(path, tensors, {"kind": SECTION_SCALE, **card})

    @classmethod
    def from_tensors(
        cls, tensors: dict[str, Any], card: dict[str, Any], weights: Path
    ) -> SectionScale:
        """The model of a checked model file (``ModelFileError`` naming ``weights``)."""
        modelfile.check_tensors(weights, tensors, {"log_scales": (2,)})
        s = np.exp(np.asarray(tensors["log_scales"], dtype=np.float64))
        try:
            return cls((float(s[0]), float(s[1])), card)
        except ValueError as exc:
            raise modelfile.ModelFileError(f"{weights}: {exc}") from None


def load_model_file(name_or_path: str | os.PathLike[str]) -> Any:
    """A model by path or shipped name: a :class:`SectionScale`, else the regressor
    :func:`pronet.learn.frozen.load_frozen` opens (the nets frozen in the core, no
    torch). ``ModelFileError`` (a ``ValueError``) naming the file otherwise."""
    from pronet.learn.frozen import load_frozen, read_model

    tensors, card, weights, _ = read_model(name_or_path)
    if card.get("kind") == SECTION_SCALE:
        return SectionScale.from_tensors(tensors, card, weights)
    if card.get("kind") == "akit":  # torch: it runs the filter's velocity through a net
        from pronet.learn.akit import akit_from_tensors

        return akit_from_tensors(tensors, card, weights)
    return load_frozen(name_or_path)
