"""Hostile panels for the plots (:mod:`pronet.plots`)."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from .contract import (
    attempt,
)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    q_true=hnp.arrays(
        st.sampled_from([np.float64, np.float32, np.int64, np.complex128, np.bool_]),
        hnp.array_shapes(min_dims=0, max_dims=2, max_side=6),
    ),
    q_pred=hnp.arrays(np.float64, st.integers(0, 6), elements=st.floats(allow_nan=True)),
)
def test_predicted_vs_true_plots_or_refuses_the_panel(tmp_path_factory, q_true, q_pred) -> None:
    from pronet import plots

    path = tmp_path_factory.mktemp("plot") / "fig.png"
    out = attempt(lambda: plots.predicted_vs_true({"m": (q_true, q_pred)}, path), "panels")
    if out is not None:
        assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
