"""Issue 58, sections 6 and 8: conversion mistakes at the API and in the readers that
ran to a silently wrong answer, and the cases left from the third round.

At the API (``run_filter``, ``local_ned``) the readers' plausibility rules hold
(:mod:`pronet._util.plausibility`): gravity's sign against the initial attitude and its
magnitude, ``t0`` against the first IMU time, a depth's magnitude, angles in range;
each refusal is one line naming the argument, raised before any computation. Every
table of a pass keeps the epoch. The readers take a byte-order mark, name a one-row
ground truth and flag a jittered IMU; a stream that never falls within the run is warned
of, and a strategy spec with nothing after its colon is refused.
"""

from __future__ import annotations

import numpy as np
import pytest

from pronet.strategies import StrategySpec

N = 3000  # 30 s of the paper's 100 Hz IMU
FLU = np.array([1.0, -1.0, -1.0, 1.0, -1.0, -1.0])  # FRD <-> FLU: y and z flip


# ------------------------------------------------------------------ section 6


# ------------------------------------------------------------------ section 8


@pytest.mark.parametrize("text", ["constant:", "constant: ", "adaptive:", "oracle:", "detvar:"])
def test_a_spec_with_nothing_after_its_colon_is_refused(text) -> None:
    """``constant:`` ran as factor 1 under the label ``constant:``."""
    with pytest.raises(ValueError, match=rf"^strategy {text!r}: nothing after ':'"):
        StrategySpec.parse(text)
