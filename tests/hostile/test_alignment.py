"""Hostile clocks, attitudes and lever arms (:mod:`pronet.recorded.alignment`)."""

from __future__ import annotations

import functools

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from pronet.recorded import alignment

from .contract import (
    NON_FINITE,
    any_scalar,
    attempt,
    check,
    finite,
    fuzz,
    good,
    hostile,
    one_hostile,
    same,
    split,
    vectors,
    within,
)


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
