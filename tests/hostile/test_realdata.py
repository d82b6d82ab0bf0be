"""Hostile inputs to the recorded-data loop (:mod:`pronet.recorded.real`)."""

from __future__ import annotations

import functools

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

import pronet
from pronet import _core
from pronet.learn import hybrid
from pronet.recorded import alignment, real
from pronet.strategies import Learned

from .contract import (
    CORE_FORMS,
    SPECIAL,
    any_float,
    any_scalar,
    attempt,
    check,
    finite,
    fuzz,
    hostile,
    vectors,
)


@fuzz(60)
@given(imu=hostile(st.tuples(st.integers(0, 6), st.sampled_from([6, 6, 5])), any_float))
def test_white_noise_q(imu) -> None:
    value, ref = imu
    out = check(real.white_noise_q, value, ref, ("imu",))
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
    check(lambda v: real.real_filter_config(v).lever_arm, *lever, ("lever_arm",))
    value, ref = q

    def rows(v):
        return [
            (k, s.kind, s.q) if isinstance(s, _core.Strategy) else (k, "learned", s.prior_q)
            for k, s in real.real_strategies(v, {}, 1.0).items()
        ]

    out = check(rows, value, ref, ("q", "prior_q"))
    if out is not None:  # the paper's four model-based rows, detvar and adaptive
        assert len(out) == 6 and finite(ref) and (ref >= 0).all()


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
    q = real.white_noise_q(sec.imu)
    strategy = Learned(hybrid.ConstantRegressor(q), q) if learned else pronet.Strategy.constant(q)
    cfg = real.real_filter_config(sec.alignment.filter_lever_arm)
    run = attempt(
        lambda: real.run_section(sec, strategy, cfg, duration=duration, use_dvl=use_dvl),
        "duration",
        "use_dvl",
        "section",
    )
    if run is None:
        return
    assert duration is None or duration > 0
    m = run.metrics
    assert finite(m.srmse, m.smae, m.final_horizontal, m.max_horizontal) and m.n_scored >= 1
