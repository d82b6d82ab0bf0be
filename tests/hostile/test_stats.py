"""Hostile inputs to :mod:`pronet.stats`: confidence intervals and t quantiles."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from pronet import stats

from .contract import (
    INF,
    NAN,
    attempt,
    check,
    finite,
    fuzz,
    hostile,
)


@fuzz(80)
@given(values=hostile(hnp.array_shapes(min_dims=0, max_dims=2, min_side=0, max_side=6)))
def test_mean_ci(values) -> None:
    value, ref = values
    out = check(stats.mean_ci, value, ref, ("values",))
    if out is None:
        assert ref is None
        return
    x = ref[np.isfinite(ref)]
    assert out.n == x.size
    if not x.size:
        return
    e = int(np.frexp(np.abs(x).max())[1])  # an exactly rounded mean, without overflow
    want = math.ldexp(math.fsum(np.ldexp(x, -e)) / x.size, e)
    tol = 4 * x.size * np.finfo(float).eps * np.abs(x).max()  # cancellation in the sum
    assert out.mean == pytest.approx(want, rel=1e-12, abs=tol + 1e-300)
    if x.size >= 2:
        assert out.low <= out.mean <= out.high
        assert np.abs(x).max() > 1e306 or finite(out.low, out.high)


@fuzz(60)
@given(
    df=st.one_of(
        st.integers(-3, 10**30),
        st.sampled_from([1, 2, 3, 10**400, 2.5, 3.0, NAN, INF, True, "3", None, np.int64(9)]),
    )
)
def test_t_quantile(df) -> None:
    t = attempt(lambda: stats.t_quantile_975(df), "df")
    if t is None:
        return
    assert isinstance(df, int | np.integer) and not isinstance(df, bool) and df >= 1
    assert stats._Z975 - 1e-15 <= t <= 12.7063 and math.isfinite(t)
    assert stats.t_quantile_975(df + 1) <= t
