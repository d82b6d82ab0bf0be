"""The contract every hostile-input test checks, and the hostile values they draw from.

Random shapes, dtypes (int, bool, complex, object, str), NaN, inf, negative, zero, huge
and subnormal values, empty arrays, Fortran-ordered, strided and reversed arrays: each
call either works, with finite and correctly shaped output (and, for another layout or
real dtype, the same answer as the C-contiguous float64 array), or raises a
``ValueError`` whose message starts with the argument's name. Never a crash, a hang, a
PanicException, another exception type or a silent wrong answer.

Elementwise array helpers (the window statistics, the regressors, ``dcm_from_euler``,
``Clock``, ``white_noise_q``) propagate NaN and inf to the outputs they touch, as NumPy
does (documented for the regressors in :mod:`pronet.learn.models`); finite input must give
finite output wherever the exact result is representable.

The ``*_refuses_*`` and ``*_does_not_*`` cases of each test module pin the defects this
suite found in the native core, the nets and the window statistics, each fixed since
(huge scalars, bools, bytes and complex values into the core; overflow in mechanization,
filtering and window statistics; absurd windows and thread counts; heights beyond the
normal-gravity model). The nets answer NaN beyond ``models.MAX_SAMPLE``, by design.

A helper module, not a test module: ``tests/hostile/test_*.py`` import it.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import re
import subprocess
import sys
import textwrap

import numpy as np
from hypothesis import HealthCheck, currently_in_test_context, event, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import pronet

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


def check(call, value, ref, args, *, rtol=0.0, atol=0.0, compare=True):
    """Outcome of ``call(value)``, checked against ``call(ref)`` (``ref``: the same
    numbers as a C-contiguous float64 array; None when only a ValueError is right).
    Both must raise or both give the same answer (the one argument rule: any layout,
    real dtype or sequence of the same numbers is taken alike); ``rtol``, ``atol``: for
    results NumPy may round differently in another memory layout; ``compare=False``:
    only the outcomes must agree."""
    got = attempt(lambda: call(value), *args)
    if ref is None:
        assert got is None, f"accepted {type(value).__name__} {getattr(value, 'dtype', '')}"
        return None
    want = attempt(lambda: call(ref), *args)
    if got is None:
        assert want is None, "refused an array whose float64 twin works"
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


VARIANCES = st.one_of(st.floats(0.0, 1.0), st.sampled_from([0.0, 5e-324, 1e300]))

counts = st.one_of(
    st.integers(-2, 0),
    st.sampled_from([2**63, 2**64, 2**70, True, 2.0, 1.5, "1", None]),
)

ANY_SCALAR = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=3),
    st.complex_numbers(max_magnitude=10, allow_nan=False),
)

finite_or_not = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e300, -1e300, 1e-300, 5e-324]),
)


@functools.cache
def windowstats_regressor():
    from pronet.learn.models import DetrendedVariance

    return DetrendedVariance()


@functools.cache
def regressor(name: str):
    from pronet.learn import models

    return windowstats_regressor() if name == "reference" else models.load(name)


def in_child(code: str, timeout: float, memory: int | None = 4 << 30) -> str:
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
