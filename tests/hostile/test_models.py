"""Hostile windows into the regressors: the reference statistic and the shipped nets."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from .contract import (
    NON_FINITE,
    check,
    finite,
    fuzz,
    hostile,
    regressor,
)


@fuzz(40)
@given(
    name=st.sampled_from(["reference", "baseline", "detrend", "hcf"]),
    windows=hostile(
        st.tuples(st.integers(1, 3), st.sampled_from([200, 200, 199, 2])),
        st.one_of(st.floats(-1e6, 1e6), NON_FINITE),
    ),
)
def test_regressors(name, windows) -> None:
    """Every row of finite samples gets a finite q >= 0 (empty batches: see the end)."""
    model = regressor(name)
    value, ref = windows
    scale = 1.0 if ref is None else np.abs(ref[np.isfinite(ref)]).max(initial=1.0)
    out = check(model.predict, value, ref, ("windows",), rtol=1e-6, atol=1e-12 * scale**2)
    if out is None:
        return
    assert out.shape == ref.shape[:-1] and out.dtype == np.float64
    rows = np.isfinite(ref).all(axis=-1)
    assert finite(out[rows]) and (out[rows] >= 0).all()


@pytest.mark.parametrize("name", ["baseline", "detrend"])
def test_nets_take_an_empty_batch(name) -> None:
    assert regressor(name).predict(np.zeros((0, 200))).shape == (0,)


@pytest.mark.parametrize("name", ["baseline", "detrend"])
def test_nets_give_nan_beyond_their_range_and_finite_q_inside_it(name) -> None:
    """Beyond models.MAX_SAMPLE the nets' float32 arithmetic overflows: NaN, documented
    (the hybrid loop keeps the previous q and counts it); finite below it."""
    signs = np.where(np.arange(200) % 2, 1.0, -1.0)
    q = regressor(name).predict(np.stack([1e20 * signs, 1e12 * signs, 0.1 * signs]))
    assert np.isnan(q[0]) and finite(q[1:])


def test_hcf_reads_no_noise_in_a_constant_window() -> None:
    """A window with no detrended variance (constant: a sensor at rest with no noise, a
    zero-filled gap) has q = 0, in the core and in the NumPy walk alike; its scale-free
    features are 0/0, which gave NaN (found by test_regressors)."""
    model = regressor("hcf")
    windows = np.vstack([np.zeros(200), np.full(200, -9.8)])  # the second: d ~ 1e-33
    for q in (model.predict(windows), model.predict(windows, native=False)):
        assert q[0] == 0.0 and 0.0 <= q[1] < 1e-20
    noisy = windows + np.random.default_rng(0).normal(scale=0.01, size=windows.shape)
    assert (model.predict(noisy) > 0).all()
