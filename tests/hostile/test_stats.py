"""Hostile inputs to :mod:`pronet.stats`: confidence intervals and t quantiles."""

from __future__ import annotations

import math
from statistics import NormalDist

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
    assert NormalDist().inv_cdf(0.975) - 1e-15 <= t <= 12.7063 and math.isfinite(t)
    # decreasing in df (to scipy's last few ulps, where it is not exactly monotone)
    assert stats.t_quantile_975(df + 1) <= t * (1 + 1e-14)


@fuzz(80)
@given(
    values=hnp.arrays(
        np.float64,
        st.integers(0, 12),
        elements=st.floats(0.0, 1.0, allow_nan=False) | st.just(math.nan),
    ),
    bounded=st.booleans(),
)
def test_an_interval_stays_within_its_quantity_range(values, bounded) -> None:
    """A t-interval over two runs reached below zero for an RMS and above one for a
    share: the interval of a quantity with a range never leaves it, and is the t one
    wherever that one stays inside."""
    within = stats.SHARE if bounded else stats.NON_NEGATIVE
    out = stats.mean_ci(values, within)
    plain = stats.mean_ci(values)
    assert out.n == plain.n and (out.mean == plain.mean or math.isnan(plain.mean))
    if out.n < 2:
        assert out.method == "none" and math.isnan(out.low) and math.isnan(out.high)
        return
    x = values[np.isfinite(values)]
    assert within[0] <= out.low <= out.mean <= out.high <= within[1]
    if within[0] <= plain.low and plain.high <= within[1]:
        assert (out.low, out.high, out.method) == (plain.low, plain.high, "t")
    else:
        assert out.method == "bootstrap"
        assert x.min() <= out.low and out.high <= x.max()


def test_the_two_run_example_and_undefined_statistics_print_as_such() -> None:
    """The probe's example: two runs of an RMS, 0.6788 [-1.4844, 2.8420] as a t-interval."""
    two = [0.0012, 1.3564]
    t = stats.mean_ci(two)
    assert t.low < 0 and t.method == "t"  # the t-interval leaves the range...
    rms = stats.mean_ci(two, stats.NON_NEGATIVE)
    assert rms.method == "bootstrap" and (rms.low, rms.high) == (min(two), max(two))
    assert str(rms) == "0.6788 [0.0012, 1.3564]"
    # the same values and seed give the same interval every time
    assert stats.mean_ci(two, stats.NON_NEGATIVE) == rms
    assert str(stats.mean_ci([0.5])) == "0.5000 [CI undefined]"
    assert str(stats.mean_ci([math.nan])) == "undefined"
    assert stats.format_number(math.nan) == "undefined" == stats.format_number(math.inf)
    assert stats.format_number(0.25, "{:.2f}") == "0.25"
    # many runs: the t-interval, as before
    many = np.random.default_rng(3).exponential(size=200)
    assert stats.mean_ci(many, stats.NON_NEGATIVE) == stats.mean_ci(many)
