"""Hostile values for the native types: ``Strategy``, ``FilterConfig`` and ``SensorConfig``
(the contract: :mod:`hostile.contract`)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import pronet

from .contract import (
    ANY_SCALAR,
    CORE_FORMS,
    NON_ARRAYS,
    SAME,
    VARIANCES,
    any_float,
    as_form,
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
from conftest import PAPER_Q


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
        var, var_ref = draw(good((k, 6), VARIANCES, SAME))
        t, t_ref = as_form(times, draw(st.sampled_from(SAME)))
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
    # The schedule (imu_variance with imu_variance_times) too takes any real numbers.
    out = check(make, values, refs, names)
    if out is not None:
        var, times = refs["imu_variance"] if scheduled else (refs["imu_variance"], np.zeros(1))
        var = var.reshape(-1, 6)
        assert var.shape[0] == len(times) >= 1 and times[0] == 0 and (np.diff(times) > 0).all()
        arrays = (var, times, refs["imu_bias"], refs["imu_bias_psd"], refs["dvl_variance"])
        # a period of 0 is no DVL (a GNSS/INS or depth-only run); a negative one is refused
        assert finite(*arrays, refs["dvl_period"], refs["lever_arm"]) and refs["dvl_period"] >= 0
        assert (var >= 0).all() and (refs["imu_bias_psd"] >= 0).all()
        assert (refs["dvl_variance"] >= 0).all()
        np.testing.assert_array_equal(out[0], var)
        assert out[1] == times.tolist()


@settings(max_examples=80, deadline=None)
@given(gate=ANY_SCALAR)
def test_innovation_gate_takes_a_positive_real_or_none(gate) -> None:
    config = attempt(lambda: pronet.FilterConfig(innovation_gate=gate), "innovation_gate")
    if config is not None:
        assert config.innovation_gate is None or 0 < config.innovation_gate < math.inf


@pytest.mark.parametrize(
    ("make", "arg"),
    [
        (lambda: pronet.Strategy.constant([1e-4] * 5), "q"),
        (lambda: pronet.Strategy.constant([-1e-4] * 6), "q"),
        (lambda: pronet.Strategy.constant([math.nan] * 6), "q"),
        (lambda: pronet.Strategy.mehra(0, PAPER_Q), "window"),
        (lambda: pronet.Strategy.mehra(3, [-1.0] * 6), "prior_q"),
        (lambda: pronet.FilterConfig(dvl_variance=(0.01, -0.01, 0.01)), "dvl_variance"),
        (lambda: pronet.FilterConfig(dvl_variance=(0.01, 0.0, 0.01)), "dvl_variance"),
        (lambda: pronet.FilterConfig(accel_bias_psd=-1.0), "accel_bias_psd"),
        (lambda: pronet.FilterConfig(gyro_bias_psd=math.nan), "gyro_bias_psd"),
        (lambda: pronet.FilterConfig(p0_sigma=[1.0] * 14), "p0_sigma"),
        (lambda: pronet.FilterConfig(p0_sigma=[-1.0] * 15), "p0_sigma"),
        (lambda: pronet.FilterConfig(imu_dt=0.0), "imu_dt"),
        (lambda: pronet.FilterConfig(imu_dt=-0.01), "imu_dt"),
        (lambda: pronet.FilterConfig(aiding="sideways"), "aiding"),
        (lambda: pronet.SensorConfig(imu_variance=[-1.0] * 6), "imu_variance"),
        (lambda: pronet.SensorConfig(dvl_variance=[-1.0] * 3), "dvl_variance"),
        (lambda: pronet.SensorConfig(dvl_period=-1.0), "dvl_period"),
        (lambda: pronet.SensorConfig(dvl_period=math.inf), "dvl_period"),
        (
            lambda: pronet.SensorConfig(imu_variance=[[1e-3] * 6] * 2, imu_variance_times=[0, 0]),
            "imu_variance_times",
        ),
        (lambda: pronet.SensorConfig(imu_bias_psd=[-1.0] * 6), "imu_bias_psd"),
    ],
)
def test_configs_reject_bad_values(make, arg) -> None:
    with pytest.raises(ValueError, match=rf"^{arg}\b"):
        make()


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
    ],
    ids=[
        "str-float",
        "bool-float",
        "int-str",
        "complex-float",
        "float-int",
        "bool-int",
        "huge-int",
    ],
)
def test_core_scalars_raise_value_error(make, arg) -> None:
    with pytest.raises(ValueError, match=rf"^{arg}\b"):
        make()
