"""Hostile inputs to the trajectory builders: ``builtin_trajectory``,
``trajectory_from_segments`` and ``Segment``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import pronet

from .contract import (
    ALL_FORMS,
    LLA0,
    NON_FINITE,
    SPECIAL,
    any_scalar,
    as_form,
    attempt,
    check,
    finite,
    finite_or_not,
    fuzz,
    good,
    one_hostile,
    positions,
    same,
    split,
    vectors,
)


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


def test_trajectory_from_segments_refuses_a_huge_height() -> None:
    """The core names ``segments`` for whatever makes the trajectory overflow."""
    traj = attempt(
        lambda: pronet.trajectory_from_segments([[1.0, 0, 0, 0]], lla0=(0.5, 0.6, 1e300), speed0=1),
        "lla0",
        "segments",
    )
    assert traj is None or finite(traj.lla, traj.vel_ned, traj.imu)


@settings(max_examples=60, deadline=None)
@given(
    segments=hnp.arrays(
        np.float64, st.tuples(st.integers(0, 4), st.integers(3, 5)), elements=finite_or_not
    ),
    dt=finite_or_not,
    speed0=finite_or_not,
)
def test_hostile_segments_work_or_raise_value_error(segments, dt, speed0) -> None:
    try:
        traj = pronet.trajectory_from_segments(segments, lla0=LLA0, speed0=speed0, dt=dt)
    except ValueError:
        return
    assert np.isfinite(traj.imu).all()


@pytest.mark.parametrize(
    ("make", "arg"),
    [
        (lambda: pronet.builtin_trajectory("nope"), "name"),
        (lambda: pronet.builtin_trajectory("paper", dt=0.0), "dt"),
        (lambda: pronet.builtin_trajectory("paper", dt=-0.01), "dt"),
        (lambda: pronet.trajectory_from_segments([[10, 0, 0]], lla0=LLA0, speed0=1), "segments"),
        (
            lambda: pronet.trajectory_from_segments([[-10, 0, 0, 0]], lla0=LLA0, speed0=1),
            "segments",
        ),
        (
            lambda: pronet.trajectory_from_segments([[10, 0, 0, 0.2]], lla0=LLA0, speed0=1),
            "segments",
        ),
        (
            lambda: pronet.trajectory_from_segments([[10, 0, 0, 0]], lla0=LLA0, speed0=math.nan),
            "speed0",
        ),
    ],
)
def test_trajectory_builders_reject_bad_values(make, arg) -> None:
    with pytest.raises(ValueError, match=rf"^{arg}\b"):
        make()
