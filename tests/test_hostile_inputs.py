"""Hostile inputs to every public entry point that test_bad_input.py does not fuzz yet.

Random shapes, dtypes (int, bool, complex, object, str), NaN, inf, negative, zero, huge
and subnormal values, empty arrays, Fortran-ordered, strided and reversed arrays: each
call either works, with finite and correctly shaped output (and, for another layout or
real dtype, the same answer as the C-contiguous float64 array), or raises a
``ValueError`` whose message starts with the argument's name. Never a crash, a hang, a
PanicException, another exception type or a silent wrong answer.

Elementwise array helpers (the window statistics, the regressors, ``dcm_from_euler``,
``Clock``, ``white_noise_q``) propagate NaN and inf to the outputs they touch, as NumPy
does (documented for the regressors in :mod:`pronet.models`); finite input must give
finite output wherever the exact result is representable.

The cases at the end pin the defects this suite found in the native core, the nets and
the window statistics, each fixed since (huge scalars, bools, bytes and complex values
into the core; overflow in mechanization, filtering and window statistics; absurd
windows and thread counts; heights beyond the normal-gravity model). The nets answer NaN
beyond ``models.MAX_SAMPLE``, by design.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, currently_in_test_context, event, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import pronet
from pronet import alignment, dataset, hybrid, realdata, stats, windowstats
from pronet.experiment import Learned

from conftest import PAPER_Q

LLA0 = (math.radians(32), math.radians(34), -5.0)
NAN, INF = math.nan, math.inf


def fuzz(n: int = 40):
    return settings(max_examples=n, deadline=None, suppress_health_check=list(HealthCheck))


# ---------------------------------------------------------------- the contract


def attempt(call, *args: str):
    """``call()``, or None when it raised a ValueError whose message starts with one of
    ``args``; any other exception (PanicException and RuntimeError included) fails."""
    try:
        with np.errstate(all="ignore"):
            out = call()
    except ValueError as exc:
        if not args:
            raise
        pattern = "|".join(re.escape(a) for a in args)
        assert re.match(rf"({pattern})\b", str(exc)), f"ValueError not naming {args}: {exc}"
        label(f"refused: {str(exc).split(':')[0]}")
        return None
    label("works")
    return out


def label(text: str) -> None:
    """Count outcomes in ``--hypothesis-show-statistics`` (inside a Hypothesis test)."""
    if currently_in_test_context():
        event(text)


def parts(value) -> list:
    """The arrays and numbers of an output, flattened for comparison."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return parts([getattr(value, f.name) for f in dataclasses.fields(value)])
    if isinstance(value, dict):
        return parts([value[k] for k in sorted(value)])
    if isinstance(value, list | tuple):
        try:  # numbers, however nested: one array (a list and its array twin agree)
            return [np.asarray(value, dtype=np.float64)]
        except (TypeError, ValueError):
            return [p for v in value for p in parts(v)]
    return [value]


def assert_same(got, want, rtol: float = 0.0, atol: float = 0.0) -> None:
    a, b = parts(got), parts(want)
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        if x is None or isinstance(x, str):
            assert x == y
        elif rtol or atol:
            np.testing.assert_allclose(x, y, rtol=rtol, atol=atol, equal_nan=True)
        else:
            np.testing.assert_array_equal(x, y)


def check(call, value, ref, args, *, lenient=False, rtol=0.0, atol=0.0, compare=True):
    """Outcome of ``call(value)``, checked against ``call(ref)`` (``ref``: the same
    numbers as a C-contiguous float64 array; None when only a ValueError is right).
    Both must raise or both give the same answer; ``lenient``: ``value`` may also be
    refused while ``ref`` works (entry points documented to take float64 arrays only);
    ``rtol``, ``atol``: for results NumPy may round differently in another memory layout;
    ``compare=False``: only the outcomes must agree."""
    got = attempt(lambda: call(value), *args)
    if ref is None:
        assert got is None, f"accepted {type(value).__name__} {getattr(value, 'dtype', '')}"
        return None
    want = attempt(lambda: call(ref), *args)
    if got is None:
        assert want is None or lenient, "refused an array whose float64 twin works"
        return None
    assert want is not None, "accepted an array whose float64 twin is refused"
    if compare:
        assert_same(got, want, rtol, atol)
    return want


# ---------------------------------------------------------------- hostile values

SPECIAL = [0.0, -0.0, -1.0, 1e-300, 5e-324, 1e300, -1e300, 1.7e308, NAN, INF, -INF]
any_float = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(SPECIAL))
NON_FINITE = st.sampled_from([NAN, INF, -INF])


def within(limit: float, low: float | None = None):
    """Floats in ``[low or -limit, limit]`` plus zero and the non-finite ones."""
    lo = -limit if low is None else low
    return st.one_of(st.floats(lo, limit), st.sampled_from([0.0, -0.0]), NON_FINITE)


#: Layouts and real dtypes: the answer must be the float64 twin's.
SAME = ("C", "F", "strided", "reversed", "list", "int64", "uint8", "float32")
#: Not real numbers: only a ValueError is right.
WRONG = ("bool", "complex", "str")
#: What sequences of numbers handed to the Rust core directly are tried with; bool and
#: complex are pinned as defects at the end (the core takes them as numbers).
CORE_FORMS = (*SAME, "object", "str")
ALL_FORMS = (*SAME, "object", *WRONG)
#: Valid sequences for the Rust core, which reads object arrays of floats correctly.
CORE_VALID = (*SAME, "object")
#: Layouts of float64 arrays: what the core's (n, k) array arguments take.
F64_LAYOUTS = ("C", "F", "strided", "reversed")


def as_form(base: np.ndarray, form: str, object_ok: bool = False):
    """``(value, ref)``: ``base`` in ``form`` and its C-contiguous float64 twin (None
    when only a ValueError is right)."""
    if form in ("int64", "uint8"):
        lo, hi = (-1e6, 1e6) if form == "int64" else (0, 255)
        value = np.clip(np.nan_to_num(base), lo, hi).astype(form)
        return value, value.astype(np.float64)
    if form == "float32":
        with np.errstate(over="ignore"):
            value = base.astype(np.float32)
        return value, value.astype(np.float64)
    if form in WRONG:
        value = {"bool": base != 0, "complex": base + 1j, "str": base.astype(str)}[form]
        return value, None
    if form == "object":
        return base.astype(object), (base if object_ok else None)
    if base.ndim == 0 or form == "C" or (form == "list" and base.size == 0 and base.ndim > 1):
        return (base.tolist() if form == "list" and base.ndim == 0 else base), base
    value = {
        "F": np.asfortranarray(base),
        "strided": np.repeat(base, 2, axis=-1)[..., ::2],
        "reversed": np.flip(np.flip(base).copy()),
        "list": base.tolist(),
    }[form]
    return value, base


@st.composite
def hostile(draw, shape, elements=any_float, forms=ALL_FORMS, object_ok=False):
    """``(value, ref)`` for an array of ``shape`` (a tuple or a strategy of tuples)."""
    if not isinstance(shape, tuple):
        shape = draw(shape)
    base = draw(hnp.arrays(np.float64, shape, elements=elements))
    return as_form(base, draw(st.sampled_from(forms)), object_ok)


def vectors(n: int, elements=any_float, forms=ALL_FORMS, object_ok=False):
    """``(value, ref)`` mostly of shape ``(n,)``, sometimes of a wrong shape."""
    shapes = st.one_of(
        st.just((n,)),
        st.sampled_from([(), (0,), (n - 1,), (n + 1,), (n, 1), (1, n)]),
    )
    return hostile(shapes, elements, forms, object_ok)


@st.composite
def positions(draw, valid: bool = False):
    """``(value, ref)`` for ``lla0``: latitude (the core takes ±89°), longitude, height."""
    if valid:
        base = np.array(
            [draw(st.floats(-1.5, 1.5)), draw(st.floats(-10, 10)), draw(st.floats(-1e4, 1e4))]
        )
        return as_form(base, draw(st.sampled_from(SAME)))
    lat = draw(st.one_of(st.floats(-1.6, 1.6), NON_FINITE))
    lon = draw(st.one_of(st.floats(-10.0, 10.0), st.just(1e300), NON_FINITE))
    base = np.array([lat, lon, draw(within(1e4))])
    if draw(st.integers(0, 4)) == 0:
        base = draw(st.sampled_from([base[:2], np.append(base, 0.0), base[None]]))
    return as_form(base, draw(st.sampled_from(ALL_FORMS)))


def good(shape, elements, forms=SAME):
    """``(value, ref)`` of valid numbers in a layout or real dtype of ``forms``."""
    return hostile(shape, elements, forms, object_ok=True)


def same(strategy):
    """A non-array argument as ``(value, ref)``: the same object on both sides."""
    return strategy.map(lambda x: (x, x))


@st.composite
def one_hostile(draw, **spec):
    """``{name: (value, ref)}``: each argument from its valid strategy except at most one
    (a random one, or none) from its hostile strategy, so that most cases get past the
    other arguments' checks. ``spec``: ``name=(valid, hostile)``."""
    target = draw(st.sampled_from([None, *spec]))
    return {k: draw(bad if k == target else ok) for k, (ok, bad) in spec.items()}


def split(args: dict):
    """``(values, refs)`` of ``{name: (value, ref)}``; refs None if any must be refused."""
    refs = {k: r for k, (_, r) in args.items()}
    refs = None if any(r is None for r in refs.values()) else refs
    return {k: v for k, (v, _) in args.items()}, refs


NON_ARRAYS = [None, "abcdef", {"q": 1}, 3.0, object(), [[1.0, 2.0], [3.0]]]
#: Scalars of every kind for arguments taken by the Python wrappers.
any_scalar = st.one_of(
    any_float,
    st.integers(-(2**70), 2**70),
    st.sampled_from(
        [True, "1", b"1", 1 + 1j, None, np.float32(0.5), np.int64(3), np.array(0.5), 10**400]
    ),
)


#: Anything but a usable real number (non-finite floats, wrong types, beyond float64).
bad_scalars = st.one_of(
    NON_FINITE, st.sampled_from([True, "1", b"1", 1 + 1j, None, 10**400, np.array([0.5])])
)


def finite(*arrays) -> bool:
    return all(bool(np.isfinite(np.asarray(a, dtype=np.float64)).all()) for a in arrays)


@functools.cache
def short_trajectory() -> pronet.Trajectory:
    """1 s straight at 1 m/s, 100 IMU samples: Monte Carlo runs cost about a millisecond."""
    return pronet.trajectory_from_segments([[1.0, 0, 0, 0]], lla0=LLA0, speed0=1.0)


# ---------------------------------------------------------------- strategies, configs

VARIANCES = st.one_of(st.floats(0.0, 1.0), st.sampled_from([0.0, 5e-324, 1e300]))


@fuzz(80)
@given(
    kind=st.sampled_from(["constant", "external", "mehra"]),
    q=st.one_of(
        good((6,), VARIANCES),
        vectors(6, forms=CORE_FORMS, object_ok=True),
        st.sampled_from(NON_ARRAYS).map(lambda x: (x, None)),
    ),
    window=st.one_of(st.integers(-3, 5), st.sampled_from([2**62, 2**63 - 1])),
)
def test_strategies_take_six_finite_non_negative_numbers(kind, q, window) -> None:
    arg = "q" if kind == "constant" else "prior_q"

    def make(v):
        s = (
            pronet.Strategy.mehra(window, v)
            if kind == "mehra"
            else getattr(pronet.Strategy, kind)(v)
        )
        return s.kind, s.q, s.window

    out = check(make, *q, (arg, "window"))
    if out is not None:
        ref = q[1]
        assert ref.shape == (6,) and finite(ref) and (ref >= 0).all()
        assert out[0] == kind and out[1] == ref.tolist()
        assert out[2] == (window if kind == "mehra" else None) and (kind != "mehra" or window >= 1)


@fuzz(60)
@given(
    args=one_hostile(
        p0_sigma=(good((15,), st.floats(0, 10)), vectors(15, forms=CORE_FORMS, object_ok=True)),
        dvl_variance=(
            good((3,), st.floats(1e-6, 1.0)),
            vectors(3, forms=CORE_FORMS, object_ok=True),
        ),
        lever_arm=(good((3,), st.floats(-10, 10)), vectors(3, forms=CORE_FORMS, object_ok=True)),
        accel_bias_psd=(same(st.floats(0, 1)), same(any_float)),
        gyro_bias_psd=(same(st.floats(0, 1)), same(any_float)),
        imu_dt=(same(st.floats(1e-4, 1.0)), same(any_float)),
        aiding=(
            same(st.sampled_from(["body", "nav"])),
            same(st.sampled_from(["side", "", "Body"])),
        ),
    )
)
def test_filter_config_checks_every_field(args) -> None:
    def make(a):
        cfg = pronet.FilterConfig(**a)
        return [getattr(cfg, k) for k in a]

    values, refs = split(args)
    out = check(make, values, refs, tuple(args))
    if out is not None:
        r = refs
        assert r["p0_sigma"].shape == (15,)
        assert r["dvl_variance"].shape == r["lever_arm"].shape == (3,)
        assert finite(*(r[k] for k in r if k != "aiding")) and r["aiding"] in ("body", "nav")
        assert (r["p0_sigma"] >= 0).all() and (r["dvl_variance"] > 0).all() and r["imu_dt"] > 0
        assert r["accel_bias_psd"] >= 0 and r["gyro_bias_psd"] >= 0
        assert out == [v.tolist() if isinstance(v, np.ndarray) else v for v in r.values()]


@st.composite
def schedules(draw, valid: bool):
    """``((variance, times), refs)``: a piecewise-constant IMU variance schedule."""
    if valid:
        k = draw(st.integers(1, 3))
        steps = draw(hnp.arrays(np.float64, k - 1, elements=st.floats(0.01, 100.0)))
        times = np.concatenate([[0.0], np.cumsum(steps)])
        if not (np.diff(times) > 0).all():  # a tiny step lost to rounding
            times = np.arange(k, dtype=float)
        var, var_ref = draw(good((k, 6), VARIANCES, F64_LAYOUTS))
        t, t_ref = as_form(times, draw(st.sampled_from(F64_LAYOUTS)))
        return (var, t), (var_ref, t_ref)
    var = draw(hostile(st.tuples(st.integers(0, 3), st.sampled_from([6, 6, 5])), forms=CORE_FORMS))
    t = draw(hostile(st.tuples(st.integers(0, 3)), within(100.0), CORE_FORMS))
    refs = None if var[1] is None or t[1] is None else (var[1], t[1])
    return (var[0], t[0]), refs


@fuzz(60)
@given(
    args=one_hostile(
        imu_variance=(
            st.one_of(good((6,), VARIANCES), schedules(True)),
            st.one_of(vectors(6, forms=CORE_FORMS, object_ok=True), schedules(False)),
        ),
        imu_bias=(good((6,), st.floats(-1, 1)), vectors(6, forms=CORE_FORMS, object_ok=True)),
        imu_bias_psd=(good((6,), VARIANCES), vectors(6, forms=CORE_FORMS, object_ok=True)),
        dvl_variance=(good((3,), VARIANCES), vectors(3, forms=CORE_FORMS, object_ok=True)),
        dvl_period=(same(st.sampled_from([0.01, 0.5, 1.0, 1e300])), same(any_float)),
        lever_arm=(good((3,), st.floats(-10, 10)), vectors(3, forms=CORE_FORMS, object_ok=True)),
    )
)
def test_sensor_config_checks_every_field(args) -> None:
    values, refs = split(args)
    scheduled = isinstance(values["imu_variance"], tuple)

    def make(a):
        a = dict(a)
        if scheduled:
            a["imu_variance"], a["imu_variance_times"] = a["imu_variance"]
        cfg = pronet.SensorConfig(**a)
        keys = ("imu_variance_times", "imu_bias", "imu_bias_psd", "dvl_variance", "dvl_period")
        return [cfg.imu_variance, *(getattr(cfg, k) for k in keys), cfg.lever_arm]

    names = (*args, "imu_variance_times")
    # The schedule (imu_variance with imu_variance_times) takes float64 arrays only.
    out = check(make, values, refs, names, lenient=scheduled)
    if out is not None:
        var, times = refs["imu_variance"] if scheduled else (refs["imu_variance"], np.zeros(1))
        var = var.reshape(-1, 6)
        assert var.shape[0] == len(times) >= 1 and times[0] == 0 and (np.diff(times) > 0).all()
        arrays = (var, times, refs["imu_bias"], refs["imu_bias_psd"], refs["dvl_variance"])
        assert finite(*arrays, refs["dvl_period"], refs["lever_arm"]) and refs["dvl_period"] > 0
        assert (var >= 0).all() and (refs["imu_bias_psd"] >= 0).all()
        assert (refs["dvl_variance"] >= 0).all()
        np.testing.assert_array_equal(out[0], var)
        assert out[1] == times.tolist()


@fuzz(80)
@given(lat=any_float, h=within(1e5, low=-1e4))
def test_normal_gravity_and_earth_radii(lat, h) -> None:
    """Near the surface (-10 km to 100 km); far heights are pinned at the end."""
    g = attempt(lambda: pronet.normal_gravity(lat, h), "lat", "h")
    radii = attempt(lambda: pronet.earth_radii(lat), "lat")
    assert (g is None) == (not finite(lat, h)) and (radii is None) == (not finite(lat))
    if g is not None:
        assert 9.4 < g < 9.9
    if radii is not None:
        assert 6.33e6 < radii[0] <= radii[1] < 6.40e6


# ---------------------------------------------------------------- navigation

IMU_ROWS = st.tuples(st.integers(0, 12), st.just(6))


@fuzz(60)
@given(
    args=one_hostile(
        imu=(
            good(IMU_ROWS, st.floats(-50, 50)),
            hostile(st.tuples(st.integers(0, 12), st.sampled_from([6, 5, 7])), within(1e3)),
        ),
        dt=(
            same(st.sampled_from([0.01, 0.1, 1.0, 5e-324, np.float32(0.01), 1])),
            # finite dt above ~1e7 s: pinned at the end (the core's defect)
            same(st.one_of(st.sampled_from([0.0, -0.01]), st.floats(-10, 10), bad_scalars)),
        ),
        lla0=(positions(valid=True), positions()),
        vel0=(good((3,), st.floats(-100, 100)), vectors(3, within(1e3))),
        rpy0=(
            good((3,), st.floats(-10, 10)),
            vectors(3, st.one_of(st.floats(-10, 10), st.just(1e300), NON_FINITE)),
        ),
    )
)
def test_mechanize(args) -> None:
    values, refs = split(args)
    out = check(lambda a: pronet.mechanize(**a), values, refs, tuple(args))
    if out is not None:
        n = len(refs["imu"])
        assert refs["imu"].shape == (n, 6)
        assert refs["lla0"].shape == refs["vel0"].shape == refs["rpy0"].shape == (3,)
        assert out.lla.shape == out.vel.shape == out.rpy.shape == (n + 1, 3)
        assert finite(out.lla, out.vel, out.rpy), "finite input, non-finite solution"


def _filter_imu(n: int) -> tuple[np.ndarray, np.ndarray]:
    """n samples at rest (gravity only) at 100 Hz and their times."""
    g = pronet.normal_gravity(LLA0[0], LLA0[2])
    return np.tile([0.0, 0.0, -g, 0.0, 0.0, 0.0], (n, 1)), 0.01 * np.arange(1, n + 1)


@st.composite
def rows_with_times(draw, columns: int, values, valid: bool, t_low: float, t_high: float):
    """``((rows, times), refs)``: DVL or q-schedule rows and their strictly increasing
    times (valid), or both hostile and unrelated."""
    if valid:
        m = draw(st.integers(0 if columns == 3 else 1, 4))
        t = np.unique(draw(hnp.arrays(np.float64, m, elements=st.floats(t_low, t_high))))
        rows = draw(good((len(t), columns), values))
        times = as_form(t, draw(st.sampled_from(SAME)))
    else:
        rows = draw(hostile(st.tuples(st.integers(0, 4), st.sampled_from([columns, 2]))))
        times = draw(hostile(st.tuples(st.integers(0, 4)), within(1.0, low=-0.5)))
    refs = None if rows[1] is None or times[1] is None else (rows[1], times[1])
    return (rows[0], times[0]), refs


@fuzz(60)
@given(
    args=one_hostile(
        dvl=(
            rows_with_times(3, st.floats(-5, 5), True, 0.0, 0.4),
            rows_with_times(3, None, False, 0.0, 0.4),
        ),
        lla0=(positions(valid=True), positions()),
        vel0=(good((3,), st.floats(-5, 5)), vectors(3, within(10.0))),
        rpy0=(good((3,), st.floats(-3, 3)), vectors(3, within(4.0))),
        bias0=(good((6,), st.floats(-0.01, 0.01)), vectors(6, within(1.0))),
        q=(
            rows_with_times(6, VARIANCES, True, -0.1, 0.35),
            rows_with_times(6, None, False, -0.1, 0.35),
        ),
    ),
    kind=st.sampled_from(["constant", "mehra", "external", "external+schedule"]),
)
def test_run_filter_aiding_initial_state_and_q_schedule(args, kind) -> None:
    imu, t = _filter_imu(30)
    strategy = {
        "constant": pronet.Strategy.constant(PAPER_Q),
        "mehra": pronet.Strategy.mehra(1, PAPER_Q),
    }.get(kind, pronet.Strategy.external(PAPER_Q))
    if kind != "external+schedule":
        args = {k: v for k, v in args.items() if k != "q"}
    values, refs = split(args)

    def run(a):
        a = dict(a)
        dvl, dvl_time = a.pop("dvl")
        if "q" in a:
            a["q"], a["q_time"] = a.pop("q")
        return pronet.run_filter(imu, t, dvl, dvl_time, t0=0.0, strategy=strategy, **a)

    # DVL rows near 1e300 make the update diverge: the core reports "numerical failure:
    # ... (DVL row i, t = ...)", which names the row.
    names = (*args, "dvl_time", "q_time", "strategy", "numerical failure")
    out = check(run, values, refs, names)
    if out is not None:
        dvl, dvl_time = refs["dvl"]
        m = len(dvl)
        assert dvl.shape == (m, 3) and dvl_time.shape == (m,) and (np.diff(dvl_time) > 0).all()
        arrays = [refs[k] for k in ("lla0", "vel0", "rpy0", "bias0")]
        assert finite(dvl, dvl_time, *arrays) and abs(refs["lla0"][0]) <= math.radians(89)
        epoch = (out.lla, out.vel, out.rpy, out.bias, out.sigma, out.covariance)
        assert out.time.shape == (31,) and out.sigma.shape == (31, 15) and finite(out.time, *epoch)
        assert out.dvl_epoch.shape == out.nis.shape == (m,) and out.innovation.shape == (m, 3)
        used = out.dvl_epoch >= 0
        assert finite(out.innovation[used], out.nis[used], out.gain[used])


# ---------------------------------------------------------------- Monte Carlo, hybrid

counts = st.one_of(
    st.integers(-2, 0),
    st.sampled_from([2**63, 2**64, 2**70, True, 2.0, 1.5, "1", None]),
)
STRATEGIES = {
    "constant": pronet.Strategy.constant(PAPER_Q),
    "mehra": pronet.Strategy.mehra(2, PAPER_Q),
    "external": pronet.Strategy.external(PAPER_Q),
}


@fuzz(50)
@given(
    args=one_hostile(
        n_runs=(same(st.sampled_from([1, 2, np.int64(2)])), same(counts)),
        seed=(same(st.sampled_from([0, 7, 2**63, 2**64 - 1, np.uint64(2**64 - 1)])), same(counts)),
        record_every=(same(st.sampled_from([0, 1, 7, 2**62])), same(counts)),
        threads=(
            same(st.sampled_from([None, 1, 2])),
            same(st.sampled_from([0, -1, 2**63, 2**64, True, 1.5, "2"])),
        ),
        sample_initial_error=(
            same(st.sampled_from([True, False, np.True_])),
            same(st.sampled_from(["no", "False", 0, 1, None])),
        ),
        strategy=(same(st.sampled_from(list(STRATEGIES))), same(st.sampled_from(["x", None]))),
        sensors=(
            same(st.sampled_from([None, "paper"])),
            same(st.sampled_from(["config", {}, 1.0])),
        ),
    )
)
def test_monte_carlo_scalars(args) -> None:
    a = {k: v for k, (v, _) in args.items()}
    strategy = STRATEGIES.get(a["strategy"], a.pop("strategy"))
    a["sensors"] = pronet.SensorConfig() if a["sensors"] == "paper" else a["sensors"]
    out = attempt(lambda: pronet.monte_carlo(short_trajectory(), strategy, **a), *args)
    if out is None:
        return
    n_runs, seed, record_every = a["n_runs"], a["seed"], a["record_every"]
    assert isinstance(strategy, pronet.Strategy) and isinstance(
        a["sensors"], type(None) | pronet.SensorConfig
    )
    assert isinstance(a["sample_initial_error"], bool | np.bool_)
    for v in (n_runs, seed, record_every):
        assert isinstance(v, int | np.integer) and not isinstance(v, bool)
    assert n_runs >= 1 and 0 <= seed < 2**64 and record_every >= 0
    assert out.srmse.shape == out.mean_nis.shape == (n_runs,) and len(out.failure) == n_runs
    assert all(f is None for f in out.failure)
    assert finite(out.srmse, out.smae, out.final_horizontal_error, out.nis)
    if record_every:
        assert out.error.shape == out.sigma.shape == (n_runs, len(out.record_time), 15)
        assert finite(out.error, out.sigma, out.q)
    for ci in out.summary().values():
        assert ci.n == n_runs and (n_runs == 1 or ci.low <= ci.mean <= ci.high)


@fuzz(50)
@given(
    args=one_hostile(
        prior_q=(
            good((6,), st.floats(0, 1e-2), CORE_VALID),
            vectors(6, within(1.0), CORE_FORMS, object_ok=True),
        ),
        n_runs=(same(st.integers(1, 3)), same(st.integers(-2, 0))),
        window=(same(st.integers(1, 150)), same(st.integers(-2, 0))),
        tuning_period=(
            same(st.sampled_from([0.01, 0.05, 0.2, 1e300])),
            same(st.one_of(any_float, st.just(0.005))),
        ),
        record_every=(same(st.integers(0, 30)), same(st.integers(-3, -1))),
    ),
    data=st.data(),
)
def test_ensemble(args, data) -> None:
    """The native Ensemble with values of the right type (other types: see the end)."""
    values, refs = split(args)

    def make(a):
        a = dict(a)
        prior = a.pop("prior_q")
        return pronet.Ensemble(
            short_trajectory(), pronet.SensorConfig(), pronet.FilterConfig(), prior, **a
        )

    ens = attempt(lambda: make(values), *args)
    if refs is None:
        assert ens is None
        return
    assert (ens is None) == (attempt(lambda: make(refs), *args) is None)
    if ens is None:
        return
    n_runs, window = refs["n_runs"], refs["window"]
    prior = refs["prior_q"]
    assert prior.shape == (6,) and finite(prior) and (prior >= 0).all()
    assert n_runs >= 1 and window >= 1 and 0 < refs["tuning_period"] < INF
    assert refs["record_every"] >= 0
    windows = ens.advance()
    if windows is not None:
        assert windows.dtype == np.float32 and windows.shape == (n_runs, 6, window)
        assert finite(windows)
        value, ref = data.draw(
            st.one_of(
                good((n_runs, 6), VARIANCES, F64_LAYOUTS),
                hostile(st.tuples(st.integers(0, 3), st.sampled_from([6, 6, 5])), within(1e3)),
            ),
            label="q",
        )
        taken = attempt(lambda: ens.set_q(value) or True, "q")
        valid = ref is not None and ref.shape == (n_runs, 6) and finite(ref) and (ref >= 0).all()
        # Documented: float64 arrays (any layout) of finite variances >= 0, one row per run.
        float64 = isinstance(value, np.ndarray) and value.dtype == np.float64
        assert bool(taken) == (valid and float64)
    out = ens.finish()
    ok = np.array([f is None for f in out["failure"]])
    assert out["srmse"].shape == (n_runs,) and finite(out["srmse"][ok], out["nis"][ok])
    assert ens.done and attempt(ens.advance, "ensemble") is None


class Fixed:
    """A regressor that answers every batch with ``make(n_runs)``."""

    def __init__(self, make) -> None:
        self.make = make

    def predict(self, windows):
        return self.make(len(windows))


def tiled(pred) -> Fixed:
    """A regressor answering ``pred`` for every run (as given if it is not ``(6,)``)."""
    value = pred[0]
    if isinstance(value, np.ndarray) and value.shape == (6,):
        return Fixed(lambda n: np.tile(value, (n, 1)))
    return Fixed(lambda n: value)


PREDICTIONS = st.one_of(st.floats(1e-12, 10.0), st.sampled_from(SPECIAL))


@fuzz(40)
@given(
    args=one_hostile(
        regressor=(good((6,), PREDICTIONS), vectors(6, PREDICTIONS)),
        prior_q=(good((6,), st.floats(0, 1e-2)), vectors(6, within(1.0))),
        n_runs=(same(st.integers(1, 2)), same(counts)),
        window=(
            same(st.integers(1, 100)),
            same(st.sampled_from([0, -1, 101, 2**40, 2**70, 3.0, True])),
        ),
        tuning_period=(same(st.sampled_from([0.01, 0.1, 0.25, 1e300])), same(any_scalar)),
        guardrails=(
            same(st.sampled_from([None, (1e-12, 1e-6), (1e-3, 10.0), (1e-9, 1.0)])),
            same(st.sampled_from([None, "tight"])),
        ),
    )
)
def test_run_hybrid(args) -> None:
    a = {k: v for k, (v, _) in args.items()}
    regressor, pred_ref = tiled(args["regressor"]), args["regressor"][1]
    bounds = a.pop("guardrails")
    guard = hybrid.Guardrails(*bounds) if isinstance(bounds, tuple) else bounds
    a.pop("regressor")
    out = attempt(
        lambda: hybrid.run_hybrid(
            regressor, short_trajectory(), guardrails=guard, record_every=7, **a
        ),
        *args,
    )
    if out is None:
        return
    n_runs, window, prior = a["n_runs"], a["window"], args["prior_q"][1]
    guard = guard or hybrid.Guardrails()
    assert isinstance(guard, hybrid.Guardrails) and 1 <= window <= short_trajectory().n_samples
    assert out.clipped.shape == out.non_finite.shape == (n_runs,) and out.n_tunings >= 0
    assert (out.clipped >= 0).all() and (out.non_finite >= 0).all()
    if out.n_tunings:
        assert pred_ref is not None
    res = out.result
    assert all(f is None for f in res.failure) and finite(res.srmse, res.nis)
    q = res.q  # the variances in force: the prior, or guarded predictions
    assert finite(q) and (((q >= guard.q_min) & (q <= guard.q_max)) | (q == prior)).all()


@fuzz(60)
@given(
    target=st.sampled_from(
        [None, "imu", "imu_time", "prior_q", "window", "tuning_period", "regressor"]
    ),
    use_reference=st.booleans(),
    data=st.data(),
)
def test_q_schedule(target, use_reference, data) -> None:
    def arg(name, ok, bad):
        return data.draw(bad if name == target else ok, label=name)

    imu = arg(
        "imu",
        good(st.tuples(st.integers(2, 60), st.just(6)), st.floats(-20, 20)),
        hostile(st.tuples(st.integers(0, 60), st.sampled_from([6, 6, 4])), within(1e4)),
    )
    n = len(imu[1] if imu[1] is not None else np.asarray(imu[0]))

    def times(step):
        with np.errstate(all="ignore"):
            return as_form(step * np.arange(1.0, n + 1), "C")

    bad_steps = st.one_of(st.sampled_from([5e-324, 1e300, 0.0, -0.01]), any_float)
    imu_time = arg(
        "imu_time",
        st.sampled_from([0.01, 0.1]).map(times),
        st.one_of(
            bad_steps.map(times),
            hostile(st.tuples(st.sampled_from([n, n, n + 1])), within(10.0)),
        ),
    )
    prior = arg("prior_q", good((6,), st.floats(0, 1e-2)), vectors(6, within(1.0)))
    window = arg("window", st.integers(3, 40), st.sampled_from([0, -1, 2, 2**70, 3.0]))
    period = arg("tuning_period", st.sampled_from([0.01, 0.05, 0.1, 1e300]), any_scalar)
    pred = arg("regressor", good((6,), PREDICTIONS), vectors(6, PREDICTIONS))
    regressor = windowstats_regressor() if use_reference else tiled(pred)

    def run(a):
        s = hybrid.q_schedule(
            regressor, a[0], a[1], prior_q=prior[0], window=window, tuning_period=period
        )
        return dataclasses.replace(s, model_seconds=0.0)

    names = ("imu", "imu_time", "prior_q", "window", "tuning_period", "regressor")
    names += ("windows",) if use_reference else ()  # N < 3: the reference refuses its windows
    refs = None if imu[1] is None or imu_time[1] is None else (imu[1], imu_time[1])
    out = check(run, (imu[0], imu_time[0]), refs, names)
    if out is None:
        return
    k = len(out.time)
    assert out.q.shape == (k, 6) and finite(out.time, out.q) and (np.diff(out.time) > 0).all()
    assert np.isin(out.time, refs[1]).all() and window >= 1 and finite(prior[1])
    assert k == 0 or use_reference or pred[1] is not None
    g = hybrid.Guardrails()
    assert ((out.q >= g.q_min) & (out.q <= g.q_max)).all()
    assert 0 <= out.clipped <= 6 * k and 0 <= out.non_finite <= 6 * k


@functools.cache
def windowstats_regressor():
    from pronet.models import DetrendedVariance

    return DetrendedVariance()


@fuzz(80)
@given(
    q=hnp.arrays(np.float64, st.tuples(st.integers(0, 4), st.just(6)), elements=any_float),
    prev=hnp.arrays(np.float64, (1, 6), elements=st.floats(1e-12, 1.0)),
    bounds=st.one_of(
        st.tuples(st.floats(1e-12, 1e-3), st.floats(1e-3, 1e3)),
        st.tuples(any_scalar, any_scalar),
    ),
)
def test_guardrails(q, prev, bounds) -> None:
    guard = attempt(lambda: hybrid.Guardrails(*bounds), "q_min", "q_max")
    if guard is None:
        return
    assert 0 < guard.q_min < guard.q_max < INF
    prev = np.broadcast_to(prev, q.shape)
    out, bad, clipped = hybrid.apply_guardrails(q, prev, guard)
    assert out.shape == q.shape and finite(out)
    kept = np.where(np.isfinite(q), q, prev)  # the documented rule
    np.testing.assert_array_equal(out, np.clip(kept, guard.q_min, guard.q_max))
    np.testing.assert_array_equal(bad, (~np.isfinite(q)).sum(axis=1))
    np.testing.assert_array_equal(clipped, ((kept < guard.q_min) | (kept > guard.q_max)).sum(1))


@fuzz(40)
@given(
    q=st.one_of(good((6,), PREDICTIONS), vectors(6)), batch=st.integers(0, 3), n=st.integers(1, 5)
)
def test_constant_regressor(q, batch, n) -> None:
    value, ref = q

    def make(v):
        return hybrid.ConstantRegressor(v).predict(np.zeros((batch, 6, n), np.float32))

    out = check(make, value, ref, ("q",))
    if out is not None:
        np.testing.assert_array_equal(out, np.broadcast_to(ref, (batch, 6)))


# ---------------------------------------------------------------- statistics


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
    scale = 1.0 if ref is None else np.abs(ref[np.isfinite(ref)]).max(initial=1.0)
    # rounding differs with the layout; skewness and kurtosis of a window that is constant
    # to rounding are rounding noise (values: test_window_statistics_layouts_agree)
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


@fuzz(40)
@given(
    windows=hnp.arrays(
        np.float64,
        st.tuples(st.integers(1, 3), st.integers(3, 9)),
        elements=st.integers(-1000, 1000).map(float),
    ),
    form=st.sampled_from(SAME),
)
def test_window_statistics_layouts_agree(windows, form) -> None:
    value, ref = as_form(windows, form)
    for call in (windowstats.detrend, windowstats.detrended_variance, windowstats.features):
        np.testing.assert_allclose(call(value), call(ref), rtol=1e-9, atol=1e-9)


@fuzz(40)
@given(
    q=hnp.arrays(np.float64, st.integers(1, 6), elements=st.floats(-1e100, 1e100)),
    n=st.integers(1, 10**6),
)
def test_cramer_rao_rmse_on_valid_input(q, n) -> None:
    out = windowstats.cramer_rao_rmse(q, n)
    assert math.isfinite(out) and out >= 0


# ---------------------------------------------------------------- regressors


@functools.cache
def regressor(name: str):
    from pronet import models

    return windowstats_regressor() if name == "reference" else models.load(name)


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


# ---------------------------------------------------------------- training data


@fuzz(60)
@given(
    fields=st.fixed_dictionaries(
        {},
        optional={
            "seed": st.one_of(st.integers(-3, 2**70), any_scalar),
            "n_levels": st.one_of(st.integers(-2, 20), any_scalar),
            "q_min": st.one_of(st.floats(1e-6, 1.0), any_scalar),
            "q_max": st.one_of(st.floats(1e-6, 1.0), any_scalar),
            "window": st.one_of(st.integers(-2, 500), any_scalar),
            "train_fraction": st.one_of(st.floats(0.0, 1.0), any_scalar),
        },
    ),
    as_card=st.booleans(),
)
def test_dataset_params_and_cards(fields, as_card) -> None:
    names = ("seed", "n_levels", "q_min", "q_max", "window", "train_fraction")
    params = dataset.DatasetParams(**fields)
    if as_card:
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "d.npz"
            card = {"format": dataset.FORMAT, "version": dataset.VERSION, "params": fields}
            try:
                text = json.dumps(card)
            except (TypeError, ValueError):  # not JSON: never in a card
                return
            dataset.card_path(path).write_text(text)
            loaded = attempt(lambda: dataset.load_params(path), "path")
            if loaded is None:
                return
            params = loaded
    if attempt(lambda: params.validate() or True, *names):
        assert isinstance(params.seed, int | np.integer) and params.seed >= 0
        assert isinstance(params.window, int | np.integer) and params.window >= 2
        assert 0 < params.q_min <= params.q_max < INF and 0 < params.train_fraction < 1
        assert params.n_levels >= 1
        if params.n_levels <= 10**4:  # more levels: a legitimately huge request
            assert finite(params.q_levels()) and len(params.q_levels()) == params.n_levels


def _dataset_arrays(m: int = 4, n: int = 5) -> dict[str, np.ndarray]:
    return {
        "windows": np.zeros((m, n), np.float32),
        "q": np.full(m, 1e-3),
        "trajectory": np.zeros(m, np.int8),
        "channel": np.arange(m, dtype=np.int8) % 6,
        "start": np.arange(m, dtype=np.int32) * n,
        "train": np.arange(m) % 2 == 0,
    }


@fuzz(40)
@given(
    mutation=st.sampled_from(
        ["none", "drop", "complex", "object", "ndim", "length", "text", "empty", "bool"]
    ),
    key=st.sampled_from(list(_dataset_arrays())),
)
def test_load_dataset_refuses_malformed_files_even_with_matching_hash(mutation, key) -> None:
    arrays = _dataset_arrays()
    a = arrays[key]
    arrays[key] = {
        "none": a,
        "complex": a.astype(complex),
        "object": a.astype(object),
        "ndim": a[..., None],
        "length": a[:-1],
        "bool": a != 0,
    }.get(mutation, a)
    if mutation == "drop":
        del arrays[key]
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    data = {"text": b"not a dataset", "empty": b""}.get(mutation, buf.getvalue())
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "d.npz"
        path.write_bytes(data)
        card = {
            "format": dataset.FORMAT,
            "version": dataset.VERSION,
            "sha256": hashlib.sha256(data).hexdigest(),
        }
        dataset.card_path(path).write_text(json.dumps(card))
        ds = attempt(lambda: dataset.load_dataset(path), "path")
    if ds is not None:
        m = len(ds.q)
        assert ds.windows.ndim == 2 and len(ds.windows) == m
        for name in ("trajectory", "channel", "start", "train"):
            assert getattr(ds, name).shape == (m,)
        assert ds.windows.dtype.kind == "f" and ds.train.dtype == bool


@pytest.mark.parametrize(
    ("params", "arg"),
    [
        ({"n_levels": 1, "window": 40_001}, "window"),
        ({"n_levels": 1, "window": 10_000, "q_min": 1e300, "q_max": 1e300}, "q_max"),
    ],
)
def test_build_dataset_refuses_params_that_give_no_or_non_finite_windows(params, arg) -> None:
    with pytest.raises(ValueError, match=rf"^{arg}\b"):
        dataset.build_dataset(dataset.DatasetParams(**params))


# ---------------------------------------------------------------- recorded data


@fuzz(60)
@given(imu=hostile(st.tuples(st.integers(0, 6), st.sampled_from([6, 6, 5])), any_float))
def test_white_noise_q(imu) -> None:
    value, ref = imu
    out = check(realdata.white_noise_q, value, ref, ("imu",))
    if out is None:
        assert ref is None or ref.shape[0] < 2 or ref.shape[1:] != (6,)
        return
    assert len(out) == 6
    cols = np.isfinite(ref).all(axis=0) & (np.abs(ref).max(axis=0) < 1e150)
    assert finite(np.array(out)[cols]) and (np.array(out)[cols] >= 0).all()


@fuzz(40)
@given(
    lever=vectors(3, forms=CORE_FORMS, object_ok=True),
    q=vectors(6, st.one_of(st.floats(0.0, 1.0), st.sampled_from(SPECIAL)), forms=CORE_FORMS),
)
def test_real_filter_config_and_strategies(lever, q) -> None:
    check(lambda v: realdata.real_filter_config(v).lever_arm, *lever, ("lever_arm",))
    value, ref = q

    def rows(v):
        return [(k, s.kind, s.q) for k, s in realdata.real_strategies(v, {}, 1.0).items()]

    out = check(rows, value, ref, ("q", "prior_q"))
    if out is not None:
        assert len(out) == 4 and finite(ref) and (ref >= 0).all()


@functools.cache
def section():
    from synthetic_recording import synthetic_recording

    rec = synthetic_recording(duration=20.0).recording
    return alignment.align(rec, alignment.estimate_alignment(rec))


@fuzz(40)
@given(
    duration=st.one_of(st.none(), st.sampled_from([0.005, 0.5, 1.5, 5.0, 1e300]), any_scalar),
    use_dvl=st.sampled_from([True, False, np.False_, "no", 0, None]),
    learned=st.booleans(),
)
def test_run_section(duration, use_dvl, learned) -> None:
    sec = section()
    q = realdata.white_noise_q(sec.imu)
    strategy = Learned(hybrid.ConstantRegressor(q), q) if learned else pronet.Strategy.constant(q)
    cfg = realdata.real_filter_config(sec.alignment.filter_lever_arm)
    run = attempt(
        lambda: realdata.run_section(sec, strategy, cfg, duration=duration, use_dvl=use_dvl),
        "duration",
        "use_dvl",
        "section",
    )
    if run is None:
        return
    assert duration is None or duration > 0
    m = run.metrics
    assert finite(m.srmse, m.smae, m.final_horizontal, m.max_horizontal) and m.n_scored >= 1


# ---------------------------------------------------------------- alignment


@fuzz(60)
@given(
    offset=any_scalar,
    scale=st.one_of(st.floats(1e-3, 10.0), any_scalar),
    stamps=hostile(hnp.array_shapes(min_dims=0, max_dims=2, max_side=5)),
)
def test_clock(offset, scale, stamps) -> None:
    clock = attempt(lambda: alignment.Clock(offset, scale), "offset", "scale")
    if clock is None:
        return
    assert finite(clock.offset, clock.scale) and clock.scale > 0
    value, ref = stamps
    out = check(clock, value, ref, ("stamps",))
    if out is not None:
        with np.errstate(all="ignore"):
            np.testing.assert_array_equal(out, clock.offset + clock.scale * ref)


@fuzz(60)
@given(
    rpy=hostile(
        st.one_of(
            hnp.array_shapes(min_dims=0, max_dims=2, min_side=0, max_side=4).map(lambda s: (*s, 3)),
            hnp.array_shapes(min_dims=0, max_dims=3, max_side=4),
        ),
        st.one_of(st.floats(-1e300, 1e300), NON_FINITE),
    )
)
def test_dcm_from_euler(rpy) -> None:
    value, ref = rpy
    out = check(alignment.dcm_from_euler, value, ref, ("rpy",))
    if out is None:
        assert ref is None or ref.ndim == 0 or ref.shape[-1] != 3
        return
    assert out.shape == (*ref.shape[:-1], 3, 3)
    c = out[np.isfinite(ref).all(axis=-1)]
    eye = np.broadcast_to(np.eye(3), c.shape)
    np.testing.assert_allclose(c @ np.swapaxes(c, -1, -2), eye, atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(c), 1.0, atol=1e-12)


@fuzz(40)
@given(
    args=one_hostile(
        imu_lever_arm=(good((3,), st.floats(-10, 10)), vectors(3, within(1e300))),
        dvl_lever_arm=(good((3,), st.floats(-10, 10)), vectors(3, within(1e6))),
        gt_clock=(
            same(st.just(alignment.Clock(0.1, 1.0))),
            same(st.sampled_from([(0.1, 1.0), None])),
        ),
    ),
    estimate=st.booleans(),
)
def test_alignment_and_lever_arms(args, estimate) -> None:
    rec = section_recording()
    args = dict(args)
    clock = args.pop("gt_clock")[0]
    values, refs = split(args)

    def make(a):
        if estimate:
            return alignment.estimate_alignment(rec, **a)
        return alignment.Alignment(gt_clock=clock, **a)

    al = check(make, values, refs, (*args, "gt_clock"))
    if al is None:
        return
    imu_arm, dvl_arm = refs["imu_lever_arm"], refs["dvl_lever_arm"]
    assert finite(imu_arm, dvl_arm) and imu_arm.shape == dvl_arm.shape == (3,)
    assert estimate or isinstance(clock, alignment.Clock)
    np.testing.assert_array_equal(al.filter_lever_arm, dvl_arm - imu_arm)
    sec = alignment.align(rec, al)
    if np.abs(imu_arm).max() <= 1e6:  # beyond, a longitude offset may overflow
        assert finite(sec.truth_time, sec.truth_lla, sec.truth_vel, sec.dvl_time)


@functools.cache
def section_recording():
    from synthetic_recording import synthetic_recording

    return synthetic_recording(duration=20.0).recording


# ---------------------------------------------------------------- trajectories


@fuzz(40)
@given(
    name=st.sampled_from([*pronet.builtin_trajectory_names(), "nope", "", 3, None, b"paper"]),
    dt=st.one_of(
        st.sampled_from([0.01, 0.1, 1.0, 100.0, 329.9, 400.0, 1e300, 5e-324, 1e-6, 0.0, -0.01]),
        NON_FINITE,
        st.sampled_from([True, "0.01", None, np.float32(0.5), np.array(0.5), 1, 10**400]),
    ),
)
def test_builtin_trajectory(name, dt) -> None:
    traj = attempt(lambda: pronet.builtin_trajectory(name, dt), "name", "dt")
    if traj is None:
        return
    assert name in pronet.builtin_trajectory_names() and not isinstance(dt, bool | str)
    assert traj.n_samples >= 1 and traj.imu.shape == (traj.n_samples, 6)
    assert finite(traj.time, traj.lla, traj.vel_ned, traj.rpy, traj.imu)
    assert traj.dt == pytest.approx(float(dt))


SEGMENT_VALUES = {
    "duration": st.one_of(st.floats(-1.0, 3.0), st.sampled_from(SPECIAL)),
    "accel": st.one_of(st.floats(-1.0, 1.0), st.sampled_from(SPECIAL)),
    "yaw_rate": st.one_of(st.floats(-1.0, 1.0), st.sampled_from(SPECIAL)),
    "pitch_rate": st.one_of(st.floats(-0.1, 0.1), st.sampled_from(SPECIAL)),
}


@st.composite
def segment_rows(draw, valid: bool):
    """``(value, ref)`` for segment rows, as an array in some form, as Segment objects or
    mixed; valid: 1 to 3 gentle segments."""
    if valid:
        k = draw(st.integers(1, 3))
        columns = [(0.05, 2.0), (-0.5, 0.5), (-0.5, 0.5), (-0.02, 0.02)]
        base = np.array(
            [[draw(st.floats(lo, hi)) for lo, hi in columns] for _ in range(k)], dtype=float
        )
        value, ref = as_form(base, draw(st.sampled_from(("C", "F", "strided", "list", "float32"))))
    else:
        shape = (draw(st.integers(0, 3)), draw(st.sampled_from([4, 4, 4, 3])))
        elements = st.one_of(st.floats(-0.1, 1.0), st.sampled_from(SPECIAL))
        base = draw(hnp.arrays(np.float64, shape, elements=elements))
        if shape[1] == 4:
            with np.errstate(all="ignore"):
                base = base * [3.0, 1.0, 0.5, 0.05]
        value, ref = as_form(base, draw(st.sampled_from(ALL_FORMS)))
    kind = draw(st.sampled_from(["array", "segments", "mixed"]))
    if kind != "array" and ref is not None and ref.shape[1:] == (4,) and len(ref):
        segs = [pronet.Segment(*r) for r in ref.tolist()]
        value = segs if kind == "segments" else [*segs[:1], *ref[1:].tolist()]
    return value, ref


@fuzz(60)
@given(
    args=one_hostile(
        segments=(segment_rows(True), segment_rows(False)),
        lla0=(positions(valid=True), positions()),
        speed0=(same(st.floats(0.0, 5.0)), same(st.one_of(st.floats(-5.0, 5.0), any_scalar))),
        rpy0=(
            good((3,), st.floats(-1.0, 1.0)),
            vectors(3, st.one_of(st.floats(-2.0, 2.0), st.just(1e300), NON_FINITE)),
        ),
        dt=(same(st.sampled_from([0.01, 0.1, 0.5])), same(any_scalar)),
        name=(same(st.sampled_from(["custom", ""])), same(st.sampled_from([3, None, b"x"]))),
    )
)
def test_trajectory_from_segments(args) -> None:
    """Heights within ±10 km (1e300: test_trajectory_from_segments_refuses_a_huge_height)."""
    values, refs = split(args)

    def make(a):
        a = dict(a)
        traj = pronet.trajectory_from_segments(a.pop("segments"), **a)
        return traj.time, traj.lla, traj.vel_ned, traj.rpy, traj.imu, traj.name

    out = check(make, values, refs, tuple(args))
    if out is None:
        return
    segs = refs["segments"]
    assert isinstance(refs["name"], str) and segs.shape[1:] == (4,) and len(segs) >= 1
    arrays = (segs, refs["lla0"], refs["rpy0"], refs["speed0"], refs["dt"])
    assert finite(*arrays) and (segs[:, 0] > 0).all()
    time, *states, imu, _ = out
    assert imu.shape == (len(time) - 1, 6) and finite(time, imu, *states)


@fuzz(60)
@given(
    values=st.fixed_dictionaries({k: st.one_of(v, any_scalar) for k, v in SEGMENT_VALUES.items()}),
    degrees=st.booleans(),
)
def test_segment(values, degrees) -> None:
    make = pronet.Segment.degrees if degrees else pronet.Segment
    seg = attempt(lambda: make(**values), *values)
    if seg is not None:
        row = seg.as_row()
        assert all(isinstance(v, int | float | np.floating | np.integer | np.ndarray) for v in row)
        assert not any(isinstance(v, bool) for v in row)


# ---------------------------------------------------------------- defects found here, fixed


@pytest.mark.filterwarnings("ignore::numpy.exceptions.ComplexWarning")
@pytest.mark.parametrize(
    ("make", "arg"),
    [
        (lambda: pronet.Strategy.constant([True] * 6), "q"),
        (lambda: pronet.Strategy.constant(b"abcdef"), "q"),
        (lambda: pronet.Strategy.external(np.full(6, 1e-3) + 1e-3j), "prior_q"),
        (lambda: pronet.FilterConfig(lever_arm=np.array([True, False, True])), "lever_arm"),
        (lambda: pronet.SensorConfig(imu_bias=b"\x00\x01\x02\x03\x04\x05"), "imu_bias"),
        (lambda: pronet.SensorConfig(dvl_variance=np.ones(3, complex)), "dvl_variance"),
    ],
    ids=["bool", "bytes", "complex", "bool-lever-arm", "bytes-bias", "complex-variance"],
)
def test_core_refuses_sequences_of_non_real_numbers(make, arg) -> None:
    with pytest.raises(ValueError, match=rf"^{arg}\b"):
        make()


@pytest.mark.parametrize(
    ("make", "arg"),
    [
        (lambda: pronet.FilterConfig(imu_dt="0.01"), "imu_dt"),
        (lambda: pronet.FilterConfig(accel_bias_psd=True), "accel_bias_psd"),
        (lambda: pronet.FilterConfig(aiding=1), "aiding"),
        (lambda: pronet.SensorConfig(dvl_period=1j), "dvl_period"),
        (lambda: pronet.Strategy.mehra(2.5, PAPER_Q), "window"),
        (lambda: pronet.Strategy.mehra(True, PAPER_Q), "window"),
        (lambda: pronet.Strategy.mehra(2**70, PAPER_Q), "window"),
        (lambda: pronet.normal_gravity("0.5"), "lat"),
        (lambda: pronet.earth_radii(True), "lat"),
        (
            lambda: pronet.Ensemble(
                short_trajectory(),
                pronet.SensorConfig(),
                pronet.FilterConfig(),
                PAPER_Q,
                n_runs=2**63,
            ),
            "n_runs",
        ),
    ],
    ids=[
        "str-float",
        "bool-float",
        "int-str",
        "complex-float",
        "float-int",
        "bool-int",
        "huge-int",
        "str-lat",
        "bool-lat",
        "huge-n_runs",
    ],
)
def test_core_scalars_raise_value_error(make, arg) -> None:
    with pytest.raises(ValueError, match=rf"^{arg}\b"):
        make()


HUGE_MECHANIZE = [
    ((np.full((10, 6), 1e300), 0.01, LLA0, (0, 0, 0)), "imu"),
    ((np.zeros((10, 6)), 1e10, LLA0, (0, 0, 0)), "dt"),
    ((np.zeros((10, 6)), 0.01, LLA0, (1e300, 0, 0)), "vel0"),
    ((np.zeros((10, 6)), 0.01, (0.5, 0.0, 1e300), (0, 0, 0)), "lla0"),
]


@pytest.mark.parametrize(("args", "arg"), HUGE_MECHANIZE, ids=[a for _, a in HUGE_MECHANIZE])
def test_mechanize_refuses_huge_inputs_or_stays_finite(args, arg) -> None:
    imu, dt, lla0, vel0 = args
    # An overflow cannot be pinned on one input: the error names them all.
    out = attempt(lambda: pronet.mechanize(imu, dt, lla0, vel0, (0, 0, 0)), "imu, dt, lla0, vel0")
    assert out is None or finite(out.lla, out.vel, out.rpy)


HUGE_FILTER = [
    ({"imu": np.full((50, 6), 1e300)}, "imu"),
    ({"imu_time": 1e300 * np.arange(1, 51)}, "imu_time"),
    ({"vel0": (1e300, 0, 0)}, "vel0"),
    ({"bias0": (1e300,) * 6}, "bias0"),
    ({"config": pronet.FilterConfig(p0_sigma=[1e300] * 15)}, "p0_sigma"),
]


@pytest.mark.parametrize(("overrides", "arg"), HUGE_FILTER, ids=[a for _, a in HUGE_FILTER])
def test_run_filter_refuses_a_huge_input_or_stays_finite(overrides, arg) -> None:
    """Refused up front naming the argument, or stopped by the filter's own overflow
    check ("numerical failure: ... (t = ... s)": an overflow inside the filter cannot be
    pinned on one input); never NaN rows."""
    imu, t = _filter_imu(50)
    kwargs = {"imu": imu, "imu_time": t, "lla0": LLA0, "vel0": (0, 0, 0), **overrides}
    out = attempt(
        lambda: pronet.run_filter(
            kwargs.pop("imu"),
            kwargs.pop("imu_time"),
            np.empty((0, 3)),
            np.empty(0),
            t0=0.0,
            rpy0=(0, 0, 0),
            strategy=pronet.Strategy.constant(PAPER_Q),
            **kwargs,
        ),
        arg,
        "numerical failure",
    )
    assert out is None or finite(out.lla, out.vel, out.rpy, out.sigma)


def test_trajectory_from_segments_refuses_a_huge_height() -> None:
    """The core names ``segments`` for whatever makes the trajectory overflow."""
    traj = attempt(
        lambda: pronet.trajectory_from_segments([[1.0, 0, 0, 0]], lla0=(0.5, 0.6, 1e300), speed0=1),
        "lla0",
        "segments",
    )
    assert traj is None or finite(traj.lla, traj.vel_ned, traj.imu)


@pytest.mark.parametrize("h", [1e300, -1e300])
def test_normal_gravity_refuses_heights_far_from_the_surface(h) -> None:
    g = attempt(lambda: pronet.normal_gravity(0.5, h), "h")
    assert g is None or 0 <= g < 10


def _in_child(code: str, timeout: float, memory: int | None = 4 << 30) -> str:
    """Run ``code`` (with ``np``, ``pronet``, ``PAPER_Q`` and a 1 s trajectory ``traj``)
    in a fresh interpreter, so that a crash or a hang cannot take pytest down; its
    stdout. AssertionError if it crashed or did not finish within ``timeout`` seconds."""

    def limit() -> None:
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (memory, memory))

    prelude = (
        "import numpy as np, pronet\n"
        "PAPER_Q = (1e-4,) * 3 + (1e-6,) * 3\n"
        "traj = pronet.trajectory_from_segments([[1.0, 0, 0, 0]], lla0=(0.5, 0.6, 0), speed0=1.0)\n"
    )
    try:
        done = subprocess.run(
            [sys.executable, "-c", prelude + textwrap.dedent(code)],
            capture_output=True,
            text=True,
            timeout=timeout,
            preexec_fn=limit if memory else None,
            env={**os.environ, "RUST_BACKTRACE": "0"},
        )
    except subprocess.TimeoutExpired:
        raise AssertionError(f"no answer within {timeout} s") from None
    if re.search(r"^(SyntaxError|IndentationError|NameError|ImportError)", done.stderr, re.M):
        raise RuntimeError(f"the child's code is broken: {done.stderr[-300:]}")
    assert done.returncode == 0, f"crashed ({done.returncode}): {done.stderr[-300:]}"
    return done.stdout


@pytest.mark.parametrize("window", [2**40, 2**62])
def test_huge_mehra_window_does_not_crash(window) -> None:
    out = _in_child(
        f"""
        s = pronet.Strategy.mehra({window}, PAPER_Q)
        imu = np.tile([0, 0, -9.8, 0, 0, 0.0], (20, 1))
        try:
            pronet.run_filter(imu, 0.01 * np.arange(1, 21), np.ones((1, 3)), np.array([0.1]),
                              t0=0.0, lla0=(0.5, 0.6, 0), vel0=(0, 0, 0), rpy0=(0, 0, 0),
                              strategy=s)
            print("ok")
        except ValueError as exc:
            print(exc)
        """,
        timeout=60,
    )
    assert out.startswith(("ok", "window"))


def test_huge_ensemble_window_does_not_crash() -> None:
    out = _in_child(
        """
        try:
            pronet.Ensemble(traj, pronet.SensorConfig(), pronet.FilterConfig(), PAPER_Q,
                            n_runs=1, window=2**40)
            print("ok")
        except ValueError as exc:
            print(exc)
        """,
        timeout=60,
    )
    assert out.startswith(("ok", "window"))


def test_absurd_thread_count_fails_fast() -> None:
    out = _in_child(
        """
        try:
            pronet.monte_carlo(traj, pronet.Strategy.constant(PAPER_Q), n_runs=1, threads=10**6)
            print("ok")
        except ValueError as exc:
            print(exc)
        """,
        timeout=5,
        memory=None,
    )
    assert out.startswith(("ok", "threads"))


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


# ---------------------------------------------------------------- gate, shards

ANY_SCALAR = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=3),
    st.complex_numbers(max_magnitude=10, allow_nan=False),
)


@settings(max_examples=80, deadline=None)
@given(gate=ANY_SCALAR)
def test_innovation_gate_takes_a_positive_real_or_none(gate) -> None:
    config = attempt(lambda: pronet.FilterConfig(innovation_gate=gate), "innovation_gate")
    if config is not None:
        assert config.innovation_gate is None or 0 < config.innovation_gate < math.inf


@settings(max_examples=40, deadline=None)
@given(first_run=ANY_SCALAR)
def test_first_run_takes_a_whole_number_from_zero(first_run) -> None:
    traj = short_trajectory()
    out = attempt(
        lambda: pronet.monte_carlo(
            traj, pronet.Strategy.constant(PAPER_Q), n_runs=1, first_run=first_run
        ),
        "first_run",
    )
    if out is not None:
        assert isinstance(first_run, int) and 0 <= first_run < 2**64
        assert finite(out.srmse)


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
    from pronet.training import NetTraining

    hp = attempt(lambda: NetTraining(**{field: value}), field)
    if hp is not None:
        v = getattr(hp, field)
        assert not isinstance(v, bool | str | complex) and v is not None and math.isfinite(v)


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
