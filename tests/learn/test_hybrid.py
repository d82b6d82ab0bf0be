"""The ProNet hybrid loop across the Rust/Python boundary."""

from __future__ import annotations

import numpy as np
import pytest

import pronet
from pronet.learn.hybrid import (
    ConstantRegressor,
    Guardrails,
    apply_guardrails,
    guard_schedule,
    run_hybrid,
)
from pronet.montecarlo import MonteCarloResult

from conftest import PAPER_Q


def _assert_same(a: MonteCarloResult, b: MonteCarloResult) -> None:
    for name in ("srmse", "smae", "final_horizontal_error", "nis", "nees", "error", "sigma"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_constant_regressor_is_bit_identical_to_the_constant_strategy(paper_trajectory) -> None:
    kw = dict(n_runs=4, seed=3, record_every=100)
    direct = pronet.monte_carlo(paper_trajectory, pronet.Strategy.constant(PAPER_Q), **kw)
    hybrid = run_hybrid(ConstantRegressor(PAPER_Q), paper_trajectory, prior_q=PAPER_Q, **kw)
    _assert_same(hybrid.result, direct)
    # Every second from t = 2 s (200 samples) to 329 s; the end (330 s) needs no q.
    assert hybrid.n_tunings == 329 - 2 + 1
    assert hybrid.clipped.sum() == 0 and hybrid.non_finite.sum() == 0
    np.testing.assert_array_equal(hybrid.result.q[:, -1], np.tile(PAPER_Q, (4, 1)))


def test_predicted_q_reaches_the_filter(paper_trajectory) -> None:
    # A small bias walk in the filter, so that the white-noise part dominates Q.
    kw = dict(
        n_runs=2,
        seed=0,
        record_every=100,
        prior_q=PAPER_Q,
        config=pronet.FilterConfig(accel_bias_psd=1e-10, gyro_bias_psd=1e-14),
    )
    q = [1e-3] * 6
    once = run_hybrid(ConstantRegressor(q), paper_trajectory, **kw).result
    twice = run_hybrid(ConstantRegressor([2 * v for v in q]), paper_trajectory, **kw).result
    vel_sigma = slice(3, 6)
    # Same before the first prediction at 2 s, larger velocity σ after it.
    np.testing.assert_array_equal(once.sigma[:, :2], twice.sigma[:, :2])
    ratio = twice.sigma[:, 3:, vel_sigma] / once.sigma[:, 3:, vel_sigma]
    assert np.all(ratio > 1.0)
    assert ratio[:, 10:].min() > 1.02  # once the filter has settled on the new Q
    np.testing.assert_array_equal(twice.q[:, -1], np.full((2, 6), 2e-3))


class _Hostile:
    """Run 0: NaN on channel 0; run 1: negative on channel 1; run 2: 1e9 on channel 5."""

    def predict(self, windows):
        q = np.tile(PAPER_Q, (windows.shape[0], 1))
        q[0, 0] = np.nan
        q[1, 1] = -1.0
        q[2, 5] = 1e9
        return q


def test_guardrails_keep_runs_alive_and_count(paper_trajectory) -> None:
    out = run_hybrid(_Hostile(), paper_trajectory, prior_q=PAPER_Q, n_runs=4, record_every=1000)
    n = out.n_tunings
    np.testing.assert_array_equal(out.non_finite, [n, 0, 0, 0])
    np.testing.assert_array_equal(out.clipped, [0, n, n, 0])
    assert out.result.n_failed == 0 and np.all(np.isfinite(out.result.srmse))
    q_end = out.result.q[:, -1]
    assert q_end[0, 0] == PAPER_Q[0]  # NaN kept the previous (prior) q
    assert q_end[1, 1] == Guardrails().q_min and q_end[2, 5] == Guardrails().q_max


def test_apply_guardrails_unit() -> None:
    q, bad, clip = apply_guardrails(
        np.array([[np.inf, 0.5, -2.0]]), np.array([[0.1, 0.1, 0.1]]), Guardrails(1e-3, 1.0)
    )
    np.testing.assert_array_equal(q, [[0.1, 0.5, 1e-3]])
    assert bad.tolist() == [1] and clip.tolist() == [1]
    with pytest.raises(ValueError, match="q_min, q_max"):
        Guardrails(1.0, 0.1)


@pytest.mark.parametrize("seed", range(20))
def test_a_whole_schedule_is_guarded_as_instant_after_instant(seed) -> None:
    """guard_schedule (recorded data, whole arrays) equals apply_guardrails applied one
    instant after another, the previous guarded row as q_prev, bit for bit and in its
    counts: NaN and inf runs, values out of range, a prior out of range."""
    rng = np.random.default_rng(seed)
    g = Guardrails(1e-6, 1.0)
    q = 10.0 ** rng.uniform(-8, 2, (rng.integers(1, 40), 6))
    q[rng.random(q.shape) < 0.3] = rng.choice([np.nan, np.inf, -np.inf])
    prior = 10.0 ** rng.uniform(-8, 2, 6)
    guarded, non_finite, clipped = guard_schedule(q, prior, g)
    prev, want_bad, want_clip = prior, 0, 0
    for i in range(len(q)):
        row, bad, clip = apply_guardrails(q[i : i + 1], prev[None, :], g)
        np.testing.assert_array_equal(guarded[i], row[0])
        prev, want_bad, want_clip = row[0], want_bad + int(bad[0]), want_clip + int(clip[0])
    assert (non_finite, clipped) == (want_bad, want_clip)


def test_bad_regressors_are_refused(paper_trajectory) -> None:
    with pytest.raises(ValueError, match="regressor: needs a predict"):
        run_hybrid(object(), paper_trajectory, prior_q=PAPER_Q, n_runs=1)

    class WrongShape:
        def predict(self, windows):
            return np.ones(windows.shape[0])

    with pytest.raises(ValueError, match=r"regressor: predict returned shape \(2,\)"):
        run_hybrid(WrongShape(), paper_trajectory, prior_q=PAPER_Q, n_runs=2)
    with pytest.raises(ValueError, match="seed: must be >= 0"):
        run_hybrid(ConstantRegressor(PAPER_Q), paper_trajectory, prior_q=PAPER_Q, seed=-1)
    with pytest.raises(ValueError, match="prior_q: expected shape"):
        run_hybrid(ConstantRegressor(PAPER_Q), paper_trajectory, prior_q=[1.0], n_runs=2)


@pytest.mark.slow
def test_shipped_models_plug_in(paper_trajectory) -> None:
    from pronet.learn import models

    for name in models.SHIPPED:
        out = run_hybrid(
            models.load(name), paper_trajectory, prior_q=PAPER_Q, n_runs=2, record_every=1000
        )
        assert out.result.n_failed == 0 and out.non_finite.sum() == 0
        # The paper's IMU noise (1e-4, 1e-6) lies below the paper models' training range
        # [1e-3, 5e-2]: they answer near its lower end; every model answers q > 0.
        assert np.all(out.result.q[:, -1] > 0)
