"""Hostile training hyperparameters (:mod:`pronet.learn.training`)."""

from __future__ import annotations

import math

from hypothesis import given, settings
from hypothesis import strategies as st

from .contract import (
    ANY_SCALAR,
    attempt,
)


@settings(max_examples=150, deadline=None)
@given(
    field=st.sampled_from(
        [
            "max_epochs",
            "batch_size",
            "learning_rate",
            "patience",
            "min_improvement",
            "val_fraction",
            "seed",
        ]
    ),
    value=ANY_SCALAR,
)
def test_training_hyperparameters_are_checked_when_made(field, value) -> None:
    from pronet.learn.training import NetTraining

    hp = attempt(lambda: NetTraining(**{field: value}), field)
    if hp is not None:
        v = getattr(hp, field)
        assert not isinstance(v, bool | str | complex) and v is not None and math.isfinite(v)
