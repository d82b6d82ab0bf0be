"""Hostile inputs to strapdown mechanization and the Earth model: ``mechanize``,
``normal_gravity``, ``earth_radii``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

import pronet

from .contract import (
    LLA0,
    NON_FINITE,
    any_float,
    attempt,
    bad_scalars,
    check,
    finite,
    fuzz,
    good,
    hostile,
    one_hostile,
    positions,
    same,
    split,
    vectors,
    within,
)

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


HUGE_MECHANIZE = [
    ((np.full((10, 6), 1e300), 0.01, LLA0, (0, 0, 0)), "imu"),
    ((np.zeros((10, 6)), 1e10, LLA0, (0, 0, 0)), "dt"),
    ((np.zeros((10, 6)), 0.01, LLA0, (1e300, 0, 0)), "vel0"),
    ((np.zeros((10, 6)), 0.01, (0.5, 0.0, 1e300), (0, 0, 0)), "lla0"),
]


@pytest.mark.parametrize(("args", "arg"), HUGE_MECHANIZE, ids=[a for _, a in HUGE_MECHANIZE])
def test_mechanize_refuses_huge_inputs_or_stays_finite(args, arg) -> None:
    imu, dt, lla0, vel0 = args
    # An overflow cannot be pinned on one input: the error names them all; a record of
    # zero specific force (free fall) over seconds is refused naming imu.
    call = lambda: pronet.mechanize(imu, dt, lla0, vel0, (0, 0, 0))  # noqa: E731
    out = attempt(call, "imu, dt, lla0, vel0", "imu")
    assert out is None or finite(out.lla, out.vel, out.rpy)


@pytest.mark.parametrize("h", [1e300, -1e300])
def test_normal_gravity_refuses_heights_far_from_the_surface(h) -> None:
    g = attempt(lambda: pronet.normal_gravity(0.5, h), "h")
    assert g is None or 0 <= g < 10


@pytest.mark.parametrize(
    ("make", "arg"),
    [
        (lambda: pronet.mechanize(np.zeros((3, 6)), 0.0, LLA0, (0, 0, 0), (0, 0, 0)), "dt"),
        (lambda: pronet.mechanize(np.zeros((3, 7)), 0.01, LLA0, (0, 0, 0), (0, 0, 0)), "imu"),
        (lambda: pronet.normal_gravity(math.nan), "lat"),
    ],
)
def test_mechanize_and_gravity_reject_bad_values(make, arg) -> None:
    with pytest.raises(ValueError, match=rf"^{arg}\b"):
        make()


@pytest.mark.parametrize(
    ("make", "arg"),
    [
        (lambda: pronet.normal_gravity("0.5"), "lat"),
        (lambda: pronet.earth_radii(True), "lat"),
    ],
    ids=["str-lat", "bool-lat"],
)
def test_earth_model_scalars_raise_value_error(make, arg) -> None:
    with pytest.raises(ValueError, match=rf"^{arg}\b"):
        make()
