"""Hostile inputs to the Monte Carlo engine: ``monte_carlo`` and the native ``Ensemble``."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import pronet

from .contract import (
    ANY_SCALAR,
    CORE_FORMS,
    CORE_VALID,
    INF,
    SAME,
    VARIANCES,
    any_float,
    attempt,
    counts,
    finite,
    fuzz,
    good,
    hostile,
    in_child,
    one_hostile,
    same,
    short_trajectory,
    split,
    vectors,
    within,
)
from conftest import PAPER_Q

STRAT = pronet.Strategy.constant(PAPER_Q)


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
        # an external strategy's q comes from outside: a Monte Carlo refuses it
        strategy=(
            same(st.sampled_from(["constant", "mehra"])),
            same(st.sampled_from(["x", None, "external"])),
        ),
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
    """The Ensemble with values of the right type (other types: see the end)."""
    values, refs = split(args)

    def make(a):
        a = dict(a)
        prior = a.pop("prior_q")
        return pronet.Ensemble(short_trajectory(), prior, **a)

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
                good((n_runs, 6), VARIANCES, SAME),
                hostile(st.tuples(st.integers(0, 3), st.sampled_from([6, 6, 5])), within(1e3)),
            ),
            label="q",
        )
        taken = attempt(lambda: ens.set_q(value) or True, "q")
        valid = ref is not None and ref.shape == (n_runs, 6) and finite(ref) and (ref >= 0).all()
        # Documented: real arrays or sequences of finite variances >= 0, one row per run.
        assert bool(taken) == valid
    out = ens.finish()
    ok = np.array([f is None for f in out.failure])
    assert out.srmse.shape == (n_runs,) and finite(out.srmse[ok], out.nis[ok])
    assert ens.done and attempt(ens.advance, "ensemble") is None


def test_monte_carlo_and_ensemble_reject_bad_values(paper_trajectory) -> None:
    for kwargs, arg in [
        ({"n_runs": 0}, "n_runs"),
        ({"n_runs": 2.5}, "n_runs"),
        ({"seed": -1}, "seed"),
        ({"record_every": -1}, "record_every"),
        ({"threads": 0}, "threads"),
        ({"sensors": pronet.SensorConfig(dvl_period=0.015)}, "dvl_period"),
    ]:
        with pytest.raises(ValueError, match=rf"^{arg}\b"):
            pronet.monte_carlo(paper_trajectory, STRAT, **{"n_runs": 1, **kwargs})
    with pytest.raises(ValueError, match="^trajectory"):
        pronet.monte_carlo("paper", STRAT)
    cfg = pronet.FilterConfig()
    sens = pronet.SensorConfig()
    with pytest.raises(ValueError, match="^window"):
        pronet.Ensemble(paper_trajectory, PAPER_Q, sensors=sens, config=cfg, n_runs=2, window=0)
    with pytest.raises(ValueError, match="^tuning_period"):
        pronet.Ensemble(paper_trajectory, PAPER_Q, config=cfg, n_runs=2, tuning_period=0.0)
    ens = pronet.Ensemble(paper_trajectory, PAPER_Q, sensors=sens, n_runs=2, tuning_period=5.0)
    ens.advance()
    for q in (
        np.zeros((3, 6)),
        np.full((2, 6), -1.0),
        np.full((2, 6), np.nan),
        np.zeros((2, 6), dtype=np.complex128),
        [["0"] * 6] * 2,
    ):
        with pytest.raises(ValueError, match="^q"):
            ens.set_q(q)
    ens.set_q(np.zeros((2, 6), dtype=np.float32))  # one argument rule: any real array,
    ens.set_q([[0.0] * 6] * 2)  # or a sequence


def test_huge_ensemble_window_does_not_crash() -> None:
    out = in_child(
        """
        try:
            pronet.Ensemble(traj, PAPER_Q, n_runs=1, window=2**40)
            print("ok")
        except ValueError as exc:
            print(exc)
        """,
        timeout=60,
    )
    assert out.startswith(("ok", "window"))


def test_absurd_thread_count_fails_fast() -> None:
    out = in_child(
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


def test_ensemble_refuses_a_huge_run_count() -> None:
    with pytest.raises(ValueError, match=r"^n_runs\b"):
        pronet.Ensemble(short_trajectory(), PAPER_Q, n_runs=2**63)
