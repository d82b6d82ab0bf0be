"""Hostile inputs to :mod:`pronet.learn.windowstats`: window statistics and the Cramér-Rao
bound."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from pronet.learn import windowstats

from .contract import (
    NON_FINITE,
    SAME,
    as_form,
    check,
    finite,
    fuzz,
    hostile,
)

#: Window samples: no amplitude where the fourth moment over- or underflows (pinned at
#: the end), and no subnormals.
WINDOW_VALUES = st.one_of(
    st.just(0.0),
    st.floats(1e-30, 1e30),
    st.floats(-1e30, -1e-30),
    NON_FINITE,
)


@fuzz(80)
@given(
    windows=hostile(hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=7), WINDOW_VALUES)
)
def test_window_statistics(windows) -> None:
    value, ref = windows
    calls = {
        "as_windows": windowstats.as_windows,
        "detrend": windowstats.detrend,
        "detrended_variance": windowstats.detrended_variance,
        "features": windowstats.features,
    }
    numeric = isinstance(value, np.ndarray) and value.dtype.kind in "iuf"
    before = value.copy() if numeric else None
    scale = 1.0 if ref is None else np.abs(ref[np.isfinite(ref)]).max(initial=1.0)
    # skewness and kurtosis of a window that is constant to rounding are rounding noise
    # (the layouts give the same bits: test_window_statistics_layouts_agree)
    tolerance = {
        "as_windows": {},
        "detrend": {"rtol": 1e-9, "atol": 1e-12 * scale},
        "detrended_variance": {"rtol": 1e-9, "atol": 1e-12 * scale**2},
        "features": {"compare": False},
    }
    for name, call in calls.items():
        out = check(call, value, ref, ("windows",), **tolerance[name])
        if out is None:
            assert ref is None or ref.ndim == 0 or ref.shape[-1] < 3, name
            continue
        rows = np.isfinite(ref).all(axis=-1)
        want = {"features": (*ref.shape[:-1], 14), "detrended_variance": ref.shape[:-1]}
        assert out.shape == want.get(name, ref.shape), name
        kept = out[rows]  # the windows without NaN or inf
        assert finite(kept), name
        if name == "detrended_variance":  # against an independent least-squares fit
            assert (kept >= 0).all()
            row_scale = np.abs(ref[rows]).max(axis=-1, initial=0.0) ** 2
            n = ref.shape[-1]
            t = np.arange(n) - (n - 1) / 2
            resid = [np.linalg.lstsq(np.c_[np.ones(n), t], w, rcond=None)[1] for w in ref[rows]]
            exact = np.array([r[0] if r.size else 0.0 for r in resid]) / (n - 2)
            assert np.all(np.abs(kept - exact) <= 1e-9 * row_scale + 1e-300)
        if name == "features":  # variances, spreads and ranges
            assert (kept[..., [0, 1, 2, 3, 4, 7, 8, 9, 10, 11]] >= 0).all()
    # the statistics work in place, on arrays of their own, never on the caller's
    if before is not None:
        np.testing.assert_array_equal(value, before)


@fuzz(40)
@given(
    windows=hnp.arrays(
        np.float64,
        st.tuples(st.integers(1, 3), st.integers(3, 40)),
        elements=st.one_of(st.integers(-1000, 1000).map(float), st.floats(-1e3, 1e3)),
    ),
    form=st.sampled_from(SAME),
)
def test_window_statistics_layouts_agree(windows, form) -> None:
    # bit for bit: the statistics work on a C-ordered float64 copy whatever the layout
    value, ref = as_form(windows, form)
    for call in (windowstats.detrend, windowstats.detrended_variance, windowstats.features):
        np.testing.assert_array_equal(call(value), call(ref))


def test_windows_cut_from_a_log_give_the_bits_of_their_c_ordered_copy() -> None:
    # windows as views of a (time, channel) log: transposed, and sliding along time
    log = np.random.default_rng(1).normal(size=(1000, 6)) + np.linspace(0, 3, 1000)[:, None]
    sliding = np.lib.stride_tricks.sliding_window_view(log, 200, axis=0)[::25]
    for view in (log[-200:].T, sliding, log[-200:].T.astype(np.float32)):
        twin = np.ascontiguousarray(view)
        for call in (windowstats.detrend, windowstats.detrended_variance, windowstats.features):
            out = call(view)
            np.testing.assert_array_equal(out, call(twin))
            assert out.flags.c_contiguous


@fuzz(40)
@given(
    q=hnp.arrays(np.float64, st.integers(1, 6), elements=st.floats(-1e100, 1e100)),
    n=st.integers(1, 10**6),
)
def test_cramer_rao_rmse_on_valid_input(q, n) -> None:
    out = windowstats.cramer_rao_rmse(q, n)
    assert math.isfinite(out) and out >= 0


@pytest.mark.parametrize(
    ("call", "w"),
    [
        (windowstats.detrended_variance, np.full((1, 5), 1e308)),
        (windowstats.features, np.array([[1e80, -1e80, 1e80, -1e80, 2e80]])),
        (windowstats.features, np.array([[1e-160, 0.0, 1e-160, 0.0, 3e-160]])),
    ],
    ids=["variance-1e308", "features-1e80", "features-1e-160"],
)
def test_window_statistics_do_not_overflow(call, w) -> None:
    with np.errstate(all="ignore"):
        out = call(w)
    assert finite(out[..., [5, 6, 12, 13]] if out.shape[-1] == 14 else out)


@pytest.mark.parametrize(
    ("q", "n", "arg"),
    [([1e-3], 0, "n"), ([1e-3], -1, "n"), ([], 200, "q"), ([1j], 200, "q"), ([1e-3], "200", "n")],
    ids=["n0", "n-1", "empty", "complex", "str-n"],
)
@pytest.mark.filterwarnings("ignore::RuntimeWarning", "ignore::numpy.exceptions.ComplexWarning")
def test_cramer_rao_rmse_refuses_bad_input(q, n, arg) -> None:
    with np.errstate(all="ignore"):
        with pytest.raises(ValueError, match=rf"^{arg}\b"):
            windowstats.cramer_rao_rmse(q, n)
