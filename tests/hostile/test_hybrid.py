"""Hostile inputs to the hybrid loop: ``run_hybrid``, ``q_schedule``, guardrails and the
constant regressor."""

from __future__ import annotations

import dataclasses

import numpy as np
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from pronet.learn import hybrid

from .contract import (
    INF,
    SPECIAL,
    any_float,
    any_scalar,
    as_form,
    attempt,
    check,
    counts,
    finite,
    fuzz,
    good,
    hostile,
    one_hostile,
    same,
    short_trajectory,
    vectors,
    windowstats_regressor,
    within,
)


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
