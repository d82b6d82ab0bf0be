"""Hostile inputs to ``run_filter`` and its streams (``Dvl``, ``Depth``, ``Fix``,
``Heading``): bad arrays raise ValueError naming the argument, before any computation;
no Rust panic ever reaches Python."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import pronet
from pronet import _core

from .contract import (
    CORE_FORMS,
    LLA0,
    SAME,
    VARIANCES,
    as_form,
    attempt,
    bad_scalars,
    check,
    finite,
    finite_or_not,
    fuzz,
    good,
    hostile,
    in_child,
    one_hostile,
    positions,
    same,
    split,
    vectors,
    within,
)
from conftest import PAPER_Q

STRAT = pronet.Strategy.constant(PAPER_Q)
#: Scalars that are no σ (a (1,) array is one per row of a one-row stream) and no gate
#: (None is one: the config's).
BAD_SIGMAS = bad_scalars.filter(lambda x: not isinstance(x, np.ndarray))
BAD_GATES = BAD_SIGMAS.filter(lambda x: x is not None)


def _filter_inputs(n: int = 300):
    traj = pronet.builtin_trajectory("paper")
    imu = traj.imu[:n].copy()
    t = traj.time[1 : n + 1].copy()
    dvl = np.tile([1.0, 0.0, 0.0], (n // 100, 1))
    dvl_t = np.arange(1, n // 100 + 1, dtype=float)
    return imu, t, dvl, dvl_t


def _run(**overrides):
    imu, t, dvl, dvl_t = _filter_inputs()
    args = dict(
        imu=imu,
        imu_time=t,
        streams=[pronet.Dvl(dvl_t, dvl)],
        t0=0.0,
        lla0=LLA0,
        vel0=(1.0, 0.0, 0.0),
        rpy0=(0.0, 0.0, 0.0),
        strategy=STRAT,
    )
    args.update(overrides)
    return pronet.run_filter(args.pop("imu"), args.pop("imu_time"), args.pop("streams"), **args)


@pytest.mark.parametrize(
    ("overrides", "arg"),
    [
        ({"imu": np.zeros((300, 5))}, "imu"),
        ({"imu": np.zeros(300)}, "imu"),
        ({"imu": np.full((300, 6), "x")}, "imu"),
        ({"imu": np.zeros((300, 6), dtype=complex)}, "imu"),
        ({"imu": np.where(np.eye(300, 6) > 0, np.nan, 0.0)}, "imu"),
        ({"imu": np.full((300, 6), np.inf)}, "imu"),
        ({"imu_time": np.zeros(300)}, "imu_time"),
        ({"imu_time": np.arange(300.0)[::-1].copy()}, "imu_time"),
        ({"imu_time": np.arange(10.0)}, "imu_time"),
        ({"t0": 0.01}, "imu_time"),
        ({"t0": 5.0}, "imu_time"),
        ({"t0": math.nan}, "t0"),
        ({"t0": "zero"}, "t0"),
        ({"streams": pronet.Dvl([1.0], [[1.0, 0.0, 0.0]])}, "streams"),
        ({"streams": "dvl"}, "streams"),
        ({"streams": [np.zeros((3, 3))]}, r"streams\[0\]"),
        ({"streams": [pronet.Dvl([1.0], [[1.0, 0.0, 0.0]]), None]}, r"streams\[1\]"),
        ({"lla0": (0.1, 0.2)}, "lla0"),
        ({"lla0": (math.nan, 0.2, 0.0)}, "lla0"),
        ({"lla0": (1.6, 0.2, 0.0)}, "lla0"),
        ({"vel0": "fast"}, "vel0"),
        ({"rpy0": (0.0, math.inf, 0.0)}, "rpy0"),
        ({"strategy": "constant"}, "strategy"),
        ({"config": {"aiding": "body"}}, "config"),
        ({"bias0": (0.0,) * 5}, "bias0"),
    ],
)
def test_run_filter_rejects_bad_arrays_naming_the_argument(overrides, arg) -> None:
    with pytest.raises(ValueError, match=rf"^{arg}(\b|:)"):
        _run(**overrides)


T2 = [0.5, 1.5]
V2 = [[1.0, 0.0, 0.0]] * 2
FIX1 = ([1.0], [[0.56, 0.59, math.nan]])


@pytest.mark.parametrize(
    ("make", "arg"),
    [
        (lambda: pronet.Dvl(T2, np.zeros((2, 2))), "velocity"),
        (lambda: pronet.Dvl(T2, [[np.nan, 0, 0]] * 2), "velocity"),
        (lambda: pronet.Dvl([1.0, 1.0], V2), "time"),
        (lambda: pronet.Dvl([0.5], V2), "time"),
        (lambda: pronet.Dvl(T2, V2, sigma=-0.1), "sigma"),
        (lambda: pronet.Dvl(T2, V2, sigma=[0.1, 0.1]), "sigma"),
        (lambda: pronet.Dvl(T2, V2, sigma=[[0.1] * 3] * 3), "sigma"),
        (lambda: pronet.Dvl(T2, V2, sigma=[0.1, math.nan, 0.1]), "sigma"),
        (lambda: pronet.Dvl(T2, V2, sigma="0.1"), "sigma"),
        (lambda: pronet.Dvl(T2, V2, frame="nav"), "frame"),
        (lambda: pronet.Dvl(T2, V2, frame="Body"), "frame"),
        (lambda: pronet.Dvl(T2, V2, lever_arm=[0.0, 1001.0, 0.0]), "lever_arm"),
        (lambda: pronet.Dvl(T2, V2, lever_arm=[0.0, 0.5]), "lever_arm"),
        (lambda: pronet.Dvl(T2, V2, gate=0.0), "gate"),
        (lambda: pronet.Dvl(T2, V2, gate=np.array([16.0])), "gate"),
        (lambda: pronet.Depth(T2, [1.0, 2.0], sigma=math.nan), "sigma"),
        (lambda: pronet.Depth(T2, [1.0, 2.0], sigma=-0.1), "sigma"),
        (lambda: pronet.Depth(T2, [1.0, 2.0], sigma=[0.1, 0.0]), "sigma"),
        (lambda: pronet.Depth(T2, [1.0, 2.0], sigma=[0.1] * 3), "sigma"),
        (lambda: pronet.Depth(T2, [1.0, math.nan], sigma=0.1), "depth"),
        (lambda: pronet.Depth([1.5, 0.5], [1.0, 2.0], sigma=0.1), "time"),
        (lambda: pronet.Depth([0.5], [1.0, 2.0], sigma=0.1), "time"),
        (lambda: pronet.Depth(T2, [1.0, 2.0], sigma=0.1, lever_arm=[0, 0, -2e3]), "lever_arm"),
        (lambda: pronet.Fix(*FIX1, sigma=[[-1.0, 1.0, 1.0]]), "sigma"),
        (lambda: pronet.Fix(*FIX1, sigma=2.0), "sigma"),
        (lambda: pronet.Fix(*FIX1, sigma=[[1.0, 1.0, 1.0]] * 2), "sigma"),
        (lambda: pronet.Fix([1.0], [[0.56, 0.59]], sigma=[2.0] * 3), "lla"),
        (lambda: pronet.Fix([1.0], [[math.inf, 0.59, 0.0]], sigma=[2.0] * 3), "lla"),
        (lambda: pronet.Fix([1.0], [[1.6, 0.59, 0.0]], sigma=[2.0] * 3), "lla"),
        (lambda: pronet.Fix([math.nan], FIX1[1], sigma=[2.0] * 3), "time"),
        (lambda: pronet.Fix(*FIX1, sigma=[2.0] * 3, lever_arm=[math.inf, 0, 0]), "lever_arm"),
        (lambda: pronet.Heading(T2, [0.5, 270.0], sigma=0.01), "heading"),
        (lambda: pronet.Heading(T2, [0.5, math.nan], sigma=0.01), "heading"),
        (lambda: pronet.Heading(T2, [0.5, 0.6], sigma=5.0), "sigma"),
        (lambda: pronet.Heading(T2, [0.5, 0.6], sigma=0.0), "sigma"),
        (lambda: pronet.Heading(T2, [0.5, 0.6], sigma=[0.01, math.inf]), "sigma"),
        (lambda: pronet.Heading(T2, [0.5, 0.6], sigma=[0.01]), "sigma"),
        (lambda: pronet.Heading(T2, [0.5, 0.6], sigma=[[0.01, 0.01]]), "sigma"),
        (lambda: pronet.Heading(T2, [[0.5, 0.6]], sigma=0.01), "heading"),
        (lambda: pronet.Heading([2.0, 1.0], [0.5, 0.6], sigma=0.01), "time"),
        (lambda: pronet.Heading([1.0], [0.5, 0.6], sigma=0.01), "time"),
    ],
)
def test_streams_reject_bad_arrays_naming_the_argument(make, arg) -> None:
    """One ValueError line naming the constructor's argument, when the stream is made."""
    with pytest.raises(ValueError, match=rf"^{arg}: ") as info:
        make()
    assert "\n" not in str(info.value)


def test_a_ned_stream_beside_the_calibration_states_is_refused_naming_it() -> None:
    calibrated = pronet.FilterConfig(dvl_calibration=True)
    body, ned = pronet.Dvl([1.0], [[1.0, 0, 0]]), pronet.Dvl([1.5], [[1.0, 0, 0]], frame="ned")
    with pytest.raises(ValueError, match=r"^streams\[1\]: a NED velocity stream"):
        _run(streams=[body, ned], config=calibrated)
    _run(streams=[body], config=calibrated)
    _run(streams=[ned])


def test_native_core_takes_any_real_numbers_and_refuses_the_rest_naming_the_argument() -> None:
    imu, t, dvl, dvl_t = _filter_inputs()
    kwargs = dict(
        t0=0.0,
        lla0=LLA0,
        vel0=(1, 0, 0),
        rpy0=(0, 0, 0),
        config=pronet.FilterConfig(),
        strategy=STRAT,
    )
    streams = [_core.Dvl(dvl_t, dvl)]
    ref = _core.run_filter(imu, t, streams, **kwargs)
    as_lists = _core.run_filter(
        imu.tolist(), list(t), (_core.Dvl(tuple(dvl_t), dvl.tolist()),), **kwargs
    )
    np.testing.assert_array_equal(as_lists["vel"], ref["vel"])
    narrow = _core.run_filter(imu.astype(np.float32), t, streams, **kwargs)
    exact = _core.run_filter(imu.astype(np.float32).astype(np.float64), t, streams, **kwargs)
    np.testing.assert_array_equal(narrow["vel"], exact["vel"])
    with pytest.raises(ValueError, match="^imu: expected real numbers of shape"):
        _core.run_filter(imu.astype(np.complex128), t, streams, **kwargs)
    with pytest.raises(ValueError, match="^time: expected real numbers of shape"):
        _core.Dvl([str(x) for x in dvl_t], dvl)
    with pytest.raises(ValueError, match="^velocity: expected real numbers of shape"):
        _core.Dvl(dvl_t, dvl != 0)
    with pytest.raises(ValueError, match=r"^streams\[0\]: expected a Dvl, Depth, Fix or Heading"):
        _core.run_filter(imu, t, [dvl], **kwargs)


def test_layouts_are_accepted_and_agree() -> None:
    """Fortran-ordered, strided and integer inputs give the same answer as C float64."""
    imu, t, dvl, dvl_t = _filter_inputs()
    ref = _run(imu=imu, imu_time=t)
    fortran = _run(imu=np.asfortranarray(imu), imu_time=t)
    strided = _run(imu=np.repeat(imu, 2, axis=0)[::2], imu_time=np.repeat(t, 2)[::2])
    np.testing.assert_array_equal(ref.vel, fortran.vel)
    np.testing.assert_array_equal(ref.vel, strided.vel)
    as_int = _run(streams=[pronet.Dvl(dvl_t, dvl.astype(np.int64))])
    np.testing.assert_array_equal(as_int.vel, _run(streams=[pronet.Dvl(dvl_t, dvl)]).vel)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    imu=hnp.arrays(
        np.float64, hnp.array_shapes(min_dims=1, max_dims=3, max_side=12), elements=finite_or_not
    ),
    t_step=finite_or_not,
    t0=finite_or_not,
    q=st.lists(finite_or_not, min_size=0, max_size=8),
)
def test_hostile_filter_inputs_work_or_raise_value_error(imu, t_step, t0, q) -> None:
    """Random shapes and values: the call either returns finite-shaped output or raises
    ValueError; never a panic, a crash or another exception type."""
    try:
        strategy = pronet.Strategy.constant(q)
    except ValueError:
        strategy = STRAT
    n = imu.shape[0] if imu.ndim >= 1 else 0
    with np.errstate(all="ignore"):  # hostile t0 and t_step overflow here on purpose
        times = t0 + t_step * np.arange(1, n + 1) if n else np.empty(0)
    try:
        with np.errstate(all="ignore"):
            out = pronet.run_filter(
                imu,
                times,
                t0=t0,
                lla0=LLA0,
                vel0=(0, 0, 0),
                rpy0=(0, 0, 0),
                strategy=strategy,
            )
    except ValueError:
        return
    assert out.vel.shape == (n + 1, 3)


def test_no_panic_exception_type_is_exposed() -> None:
    """The binding catches panics itself; no call above may raise pyo3's PanicException,
    which derives from BaseException and would slip past `except Exception`."""
    for bad in (
        lambda: _run(imu=np.full((300, 6), 1e308)),
        lambda: _run(imu_time=np.linspace(1e-300, 3e-300, 300)),
    ):
        try:
            bad()
        except ValueError:
            pass
        except BaseException as exc:  # noqa: BLE001 - the point of the test
            pytest.fail(f"{type(exc).__name__}: {exc}")


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
        streams = [pronet.Dvl(dvl_time, dvl)]
        return pronet.run_filter(imu, t, streams, t0=0.0, strategy=strategy, **a)

    # DVL rows near 1e300 make the update diverge: the core reports "numerical failure:
    # ... (DVL row i, t = ...)", which names the row. A roll or pitch beyond 90° turns
    # the IMU at rest upside down: "imu, rpy0" disagree on gravity's sign.
    names = (*args, "time", "velocity", "q_time", "strategy", "numerical failure", "imu, rpy0")
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


@st.composite
def readings(draw, tail: tuple[int, ...], values, valid: bool, sigma=None):
    """``((rows, times[, sigma]), refs)``: depth (``tail`` ``()``) or fix (``(3,)``) rows
    at strictly increasing times inside the 0.3 s run (and the fixes' per-row σ), all
    valid; or each hostile and unrelated in length (NaN, inf, unsorted or repeated
    times, wrong shapes, negative σ)."""
    if valid:
        m = draw(st.integers(0, 3))
        t = np.unique(draw(hnp.arrays(np.float64, m, elements=st.floats(0.0, 0.3))))
        parts = [draw(good((len(t), *tail), values)), as_form(t, draw(st.sampled_from(SAME)))]
        if sigma is not None:
            parts.append(draw(good((len(t), 3), sigma)))
    else:
        rows = st.tuples(st.integers(0, 4), *(st.sampled_from([n, 2]) for n in tail))
        parts = [draw(hostile(rows)), draw(hostile(st.tuples(st.integers(0, 4)), within(1.0)))]
        if sigma is not None:
            shapes = st.tuples(st.integers(0, 4), st.sampled_from([3, 2]))
            parts.append(draw(hostile(shapes, within(10.0, low=-10.0))))
    refs = None if any(r is None for _, r in parts) else tuple(r for _, r in parts)
    return tuple(v for v, _ in parts), refs


#: A fix's latitude, longitude [rad] near LLA0 and height [m] (NaN: a fix without one).
FIX_VALUES = st.one_of(st.floats(0.55, 0.6), st.just(math.nan))


@fuzz(80)
@given(
    args=one_hostile(
        depth=(readings((), st.floats(-10, 100), True), readings((), None, False)),
        depth_sigma=(
            same(st.floats(0.01, 10)),
            # not a (1,) array: one σ per reading of a one-reading stream
            st.one_of(BAD_SIGMAS, st.floats(max_value=-1e-300)).map(lambda x: (x, None)),
        ),
        fix=(
            readings((3,), FIX_VALUES, True, st.floats(0.1, 10)),
            readings((3,), None, False, True),
        ),
    ),
)
def test_run_filter_depth_and_fix_streams(args) -> None:
    """The depth and fix streams' arguments (``Depth(time, depth, sigma=)``,
    ``Fix(time, lla, sigma=)``) in any layout, or one of them hostile (bad shapes and
    lengths, NaN and inf, unsorted or repeated times, a negative or missing σ): the pass
    works with an update at every reading inside it, or raises one ValueError naming the
    argument; never a panic or a crash."""
    imu, t = _filter_imu(30)
    values, refs = split(args)

    def run(a):
        (depth, depth_time), (fix, fix_time, fix_sigma) = a["depth"], a["fix"]
        streams = [
            pronet.Depth(depth_time, depth, sigma=a["depth_sigma"]),
            pronet.Fix(fix_time, fix, sigma=fix_sigma),
        ]
        return pronet.run_filter(
            imu, t, streams, t0=0.0, lla0=LLA0, vel0=(0, 0, 0), rpy0=(0, 0, 0), strategy=STRAT
        )

    names = ("time", "depth", "sigma", "lla")
    out = check(run, values, refs, (*names, "numerical failure"))
    if out is not None:
        (depth, depth_time), (fix, fix_time, fix_sigma) = refs["depth"], refs["fix"]
        assert (np.diff(depth_time) > 0).all() and (np.diff(fix_time) > 0).all()
        assert finite(depth, depth_time, fix[:, :2], fix_time, fix_sigma)
        assert out.depth_epoch.shape == out.depth_nis.shape == depth.shape
        assert out.fix_epoch.shape == out.fix_nis.shape == fix_time.shape
        assert (out.depth_epoch >= 0).all() and (out.fix_epoch >= 0).all()
        assert finite(out.lla, out.vel, out.sigma, out.depth_nis, out.fix_nis)


@fuzz(80)
@given(
    args=one_hostile(
        velocity=(
            readings((3,), st.floats(-5, 5), True, st.floats(0.01, 1)),
            readings((3,), None, False, True),
        ),
        lever_arm=(
            good((3,), st.floats(-10, 10)),
            vectors(3, within(2000.0), forms=CORE_FORMS, object_ok=True),
        ),
        gate=(same(st.floats(0.1, 100)), BAD_GATES.map(lambda x: (x, None))),
    ),
    frame=st.sampled_from([None, "body", "ned"]),
    one_sigma=st.booleans(),
)
def test_run_filter_velocity_streams(args, frame, one_sigma) -> None:
    """A velocity stream's arguments (``Dvl(time, velocity, sigma=, frame=, lever_arm=,
    gate=)``, σ per row or one for all) in any layout, or one of them hostile (bad
    shapes and lengths, NaN and inf, unsorted or repeated times, a negative σ, a lever
    arm beyond ``MAX_LEVER_ARM``, a gate that is no number): the pass works with an
    update at every row inside it, or raises one ValueError naming the argument."""
    imu, t = _filter_imu(30)
    values, refs = split(args)

    def run(a):
        velocity, time, sigma = a["velocity"]
        if one_sigma and len(np.asarray(sigma, dtype=object)):
            sigma = np.asarray(sigma)[0]
        dvl = pronet.Dvl(
            time, velocity, sigma=sigma, frame=frame, lever_arm=a["lever_arm"], gate=a["gate"]
        )
        return pronet.run_filter(
            imu, t, [dvl], t0=0.0, lla0=LLA0, vel0=(0, 0, 0), rpy0=(0, 0, 0), strategy=STRAT
        )

    names = ("time", "velocity", "sigma", "lever_arm", "gate", "numerical failure")
    out = check(run, values, refs, names)
    if out is not None:
        velocity, time, _ = refs["velocity"]
        assert out.nis.shape == time.shape and out.streams[0].nis is out.nis
        assert (out.dvl_epoch >= 0).all() and finite(out.lla, out.vel, out.sigma, out.nis)


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
            t0=0.0,
            rpy0=(0, 0, 0),
            strategy=pronet.Strategy.constant(PAPER_Q),
            **kwargs,
        ),
        arg,
        "numerical failure",
    )
    assert out is None or finite(out.lla, out.vel, out.rpy, out.sigma)


@pytest.mark.parametrize("window", [2**40, 2**62])
def test_huge_mehra_window_does_not_crash(window) -> None:
    out = in_child(
        f"""
        s = pronet.Strategy.mehra({window}, PAPER_Q)
        imu = np.tile([0, 0, -9.8, 0, 0, 0.0], (20, 1))
        try:
            pronet.run_filter(imu, 0.01 * np.arange(1, 21), [pronet.Dvl([0.1], np.ones((1, 3)))],
                              t0=0.0, lla0=(0.5, 0.6, 0), vel0=(0, 0, 0), rpy0=(0, 0, 0),
                              strategy=s)
            print("ok")
        except ValueError as exc:
            print(exc)
        """,
        timeout=60,
    )
    assert out.startswith(("ok", "window"))
