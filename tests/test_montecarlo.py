"""Monte Carlo behaviour: DVL aiding, statistical consistency, determinism, ensemble."""

from __future__ import annotations

import dataclasses
import inspect

import numpy as np
import pytest
from scipy.stats import chi2

import pronet
from pronet.montecarlo import STATE_BLOCKS

from conftest import PAPER_Q

# A filter whose bias random walk matches an IMU with (almost) no bias drift.
MATCHED = pronet.FilterConfig(accel_bias_psd=1e-10, gyro_bias_psd=1e-14)


#: Bias random-walk PSDs (accel, gyro) of a simulated IMU, and a filter told them.
TOLD_EPS = (1e-8, 1e-12)
TOLD = pronet.FilterConfig(accel_bias_psd=TOLD_EPS[0], gyro_bias_psd=TOLD_EPS[1])


def matched_monte_carlo(
    trajectory: pronet.Trajectory,
    n_runs: int,
    imu_bias: list[float] | None = None,
    sample_initial_error: bool = True,
) -> pronet.MonteCarloResult:
    """Constant true q, white noise q, bias walks of :data:`TOLD_EPS` in both the
    simulated IMU and the filter (:data:`TOLD`), seed 11."""
    eps_a, eps_g = TOLD_EPS
    sensors = pronet.SensorConfig(
        imu_variance=PAPER_Q,
        imu_bias_psd=[eps_a] * 3 + [eps_g] * 3,
        imu_bias=[0.0] * 6 if imu_bias is None else imu_bias,
    )
    return pronet.monte_carlo(
        trajectory, pronet.Strategy.constant(PAPER_Q), sensors=sensors, config=TOLD,
        n_runs=n_runs, seed=11, sample_initial_error=sample_initial_error,
    )  # fmt: skip


def test_dvl_aiding_keeps_velocity_error_below_the_dvl_alone(paper_trajectory) -> None:
    r = pronet.monte_carlo(
        paper_trajectory, pronet.Strategy.constant(PAPER_Q), config=MATCHED, n_runs=20, seed=3
    )
    assert r.n_failed == 0
    # The DVL alone would give sqrt(3 * 0.01) = 0.17 m/s.
    assert r.summary()["srmse"].high < 0.1
    # The paper's epsilon = 0.001 lets the gyro biases wander at 0.03 rad/s/sqrt(s):
    # the filter trusts its IMU far less and is much worse on the same noise.
    paper = pronet.monte_carlo(
        paper_trajectory, pronet.Strategy.constant(PAPER_Q), n_runs=20, seed=3
    )
    assert paper.summary()["srmse"].mean > 2 * r.summary()["srmse"].mean


@pytest.mark.slow
def test_filter_is_consistent_when_sensors_match_its_model(paper_trajectory) -> None:
    """100 runs with white noise q, bias random walk of the filter's epsilon, DVL
    noise R and initial errors from P0: the run-averaged NIS and velocity NEES lie in
    their 95 % chi-square bands at >= 90 % of the DVL epochs."""
    n = 100
    r = matched_monte_carlo(paper_trajectory, n)
    assert r.n_failed == 0
    lo, hi = chi2.ppf([0.025, 0.975], 3 * n) / n
    nis = r.nis.mean(axis=0)
    nees_v = r.nees[:, :, 1].mean(axis=0)
    inside_nis = np.mean((nis > lo) & (nis < hi))
    inside_nees = np.mean((nees_v > lo) & (nees_v < hi))
    assert inside_nis >= 0.9, f"NIS inside band at {inside_nis:.0%} of epochs"
    assert inside_nees >= 0.9, f"velocity NEES inside band at {inside_nees:.0%} of epochs"


def test_same_seed_is_bit_identical_with_one_and_two_threads(paper_trajectory) -> None:
    strategy = pronet.Strategy.mehra(5, PAPER_Q)
    a = pronet.monte_carlo(
        paper_trajectory, strategy, n_runs=4, seed=5, threads=1, record_every=100
    )
    b = pronet.monte_carlo(
        paper_trajectory, strategy, n_runs=4, seed=5, threads=2, record_every=100
    )
    for name in ("srmse", "smae", "final_horizontal_error", "nis", "nees", "error", "sigma"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)
    c = pronet.monte_carlo(paper_trajectory, strategy, n_runs=4, seed=6, threads=2)
    assert not np.array_equal(a.srmse, c.srmse)


def test_histories_have_documented_shapes(paper_trajectory) -> None:
    r = pronet.monte_carlo(
        paper_trajectory, pronet.Strategy.constant(PAPER_Q), n_runs=3, seed=0, record_every=100
    )
    assert r.record_time.shape == (331,)
    assert r.error.shape == (3, 331, 15) and r.sigma.shape == (3, 331, 15)
    np.testing.assert_array_equal(r.q[:, :, 0], 1e-4)
    assert r.nis.shape == (3, 330) and r.nees.shape == (3, 330, 5)
    np.testing.assert_allclose(r.dvl_time, np.arange(1, 331))


def test_ensemble_round_trip_and_outside_tuning(paper_trajectory) -> None:
    ens = pronet.Ensemble(
        paper_trajectory,
        PAPER_Q,
        sensors=pronet.SensorConfig(),
        config=MATCHED,
        n_runs=3,
        seed=2,
        window=200,
        tuning_period=10.0,
        record_every=1000,
    )
    first = ens.advance()
    assert first is not None and first.dtype == np.float32 and first.shape == (3, 6, 200)
    assert ens.steps == 1000 and ens.time == pytest.approx(10.0)
    # The windows are the noisy samples: ideal IMU plus noise of the scenario's variance.
    noise = first - paper_trajectory.imu[800:1000].T[None].astype(np.float32)
    assert noise[:, :3].std() == pytest.approx(0.01, rel=0.1)
    ens.set_q(np.full((3, 6), 4e-4))
    stops = 1
    while ens.advance() is not None:
        stops += 1
    assert stops == 32 and ens.done
    res = ens.finish()
    assert isinstance(res, pronet.MonteCarloResult) and res.n_runs == 3
    q = res.q
    assert q.shape == (3, 34, 6)
    np.testing.assert_array_equal(q[:, 1, 0], 1e-4)  # prior until the first tuning
    np.testing.assert_array_equal(q[:, -1, 0], 4e-4)
    with pytest.raises(ValueError, match="already finished"):
        ens.advance()


def test_ensemble_takes_monte_carlos_arguments_and_returns_its_result(paper_trajectory) -> None:
    mc = inspect.signature(pronet.monte_carlo).parameters
    ens = inspect.signature(pronet.Ensemble).parameters
    shared = [name for name in mc if name != "strategy"]
    assert [n for n in ens if n in shared] == shared
    for name in shared:
        assert (ens[name].kind, ens[name].default) == (mc[name].kind, mc[name].default), name
    assert ens["n_runs"].default == 100 and ens["sensors"].default is None
    # Never tuned, the ensemble's runs are a constant strategy's at its prior, run by run.
    tuned = pronet.Ensemble(paper_trajectory, PAPER_Q, n_runs=2, seed=3).finish()
    const = pronet.monte_carlo(
        paper_trajectory, pronet.Strategy.constant(PAPER_Q), n_runs=2, seed=3
    )
    assert isinstance(tuned, pronet.MonteCarloResult)
    for name in ("srmse", "nis", "nees", "final_horizontal_error"):
        np.testing.assert_array_equal(getattr(tuned, name), getattr(const, name), err_msg=name)


def test_a_covariance_step_keeps_every_strategy_and_recording_changes_no_run(
    paper_trajectory,
) -> None:
    """At a 0.07 s covariance step (seven samples, so that the DVL updates and the
    tunings fall inside intervals): the history samples are brought up to date on a
    copy, so a run with them is the run without; an untuned ensemble is a constant
    strategy run for run; q set from outside between two tunings takes effect; Mehra
    and the adaptive strategy run to the end."""
    step = pronet.FilterConfig(accel_bias_psd=1e-10, gyro_bias_psd=1e-14, covariance_step=0.07)
    args = dict(config=step, n_runs=2, seed=3)
    const = pronet.Strategy.constant(PAPER_Q)
    plain = pronet.monte_carlo(paper_trajectory, const, **args)
    recorded = pronet.monte_carlo(paper_trajectory, const, record_every=37, **args)
    assert recorded.sigma is not None and np.isfinite(recorded.sigma).all()
    untuned = pronet.Ensemble(paper_trajectory, PAPER_Q, **args).finish()
    for name in ("srmse", "nis", "nees", "final_horizontal_error"):
        np.testing.assert_array_equal(getattr(recorded, name), getattr(plain, name), name)
        np.testing.assert_array_equal(getattr(untuned, name), getattr(plain, name), name)
    ens = pronet.Ensemble(paper_trajectory, PAPER_Q, window=100, tuning_period=5.0, **args)
    while ens.advance() is not None:
        ens.set_q(np.full((2, 6), 16.0) * np.asarray(PAPER_Q))
    tuned = ens.finish()
    assert np.isfinite(tuned.nis).all() and not np.array_equal(tuned.nis, plain.nis)
    for strategy in (pronet.Strategy.mehra(5, PAPER_Q), pronet.Strategy.adaptive(60, PAPER_Q)):
        r = pronet.monte_carlo(paper_trajectory, strategy, **args)
        assert r.n_failed == 0 and np.isfinite(r.nees).all()


def test_shards_concat_and_results_convert_to_dataframes(paper_trajectory) -> None:
    from pronet import results, run
    from pronet.sim import paper, scenarios

    strategy = pronet.Strategy.mehra(5, PAPER_Q)
    whole = pronet.monte_carlo(paper_trajectory, strategy, n_runs=5, seed=2, record_every=500)
    parts = [
        pronet.monte_carlo(
            paper_trajectory, strategy, n_runs=n, seed=2, first_run=first, record_every=500
        )
        for first, n in ((0, 2), (2, 3))
    ]
    joined = pronet.MonteCarloResult.concat(parts)
    for name in ("srmse", "nis", "nees", "error", "sigma", "q", "diverged_at"):
        np.testing.assert_array_equal(getattr(joined, name), getattr(whole, name))
    assert joined.failure == whole.failure
    other = pronet.monte_carlo(paper_trajectory, strategy, n_runs=1, seed=2)  # no history
    with pytest.raises(ValueError, match="different scenarios or histories"):
        pronet.MonteCarloResult.concat([parts[0], other])

    runs = whole.to_dataframe()
    assert list(runs.columns) == ["run", *pronet.MonteCarloResult.PER_RUN, "failure"]
    np.testing.assert_array_equal(runs["srmse"], whole.srmse)
    row = whole.summary_row()
    assert row["srmse"] == pytest.approx(whole.srmse.mean())
    assert row["srmse_low"] < row["srmse"] < row["srmse_high"] and row["runs"] == 5

    sc = scenarios.paper_scenario()
    rows = run.run_strategies(paper.model_based_strategies(sc.q_nominal), sc, n_runs=3, seed=1)
    table = results.rows_dataframe({"paper": rows})
    assert list(table["strategy"]) == [r.label for r in rows]
    assert table.loc[2, "srmse"] == pytest.approx(rows[2].srmse.mean)
    per_run = results.rows_dataframe({"paper": rows}, per_run=True)
    assert len(per_run) == 4 * 3 and tuple(per_run.columns) == results.RUN_COLUMNS


def test_the_turn_on_bias_is_the_configured_one_and_the_filter_stays_consistent(
    paper_trajectory,
) -> None:
    """The filter starts its bias estimates at zero (its prior mean), so the IMU's
    turn-on bias ``SensorConfig(imu_bias=)`` is an error it must estimate: it changes
    the result. A bias of 1σ of P0 per axis (a typical one), with the navigation
    solution started at the truth: the velocity and bias NEES stay inside their 95 %
    bands at >= 90 % of the DVL epochs (measured 98 %, 100 %, 95 %)."""
    n = 50

    def run(bias: list[float]) -> pronet.MonteCarloResult:
        return matched_monte_carlo(paper_trajectory, n, imu_bias=bias, sample_initial_error=False)

    sigma = np.array(TOLD.p0_sigma[9:15])
    biased, unbiased = run(list(sigma * [1, -1, 1, -1, 1, -1])), run([0.0] * 6)
    assert biased.n_failed == 0
    assert biased.srmse.mean() > unbiased.srmse.mean()
    assert not np.array_equal(biased.nees, unbiased.nees)
    lo, hi = chi2.ppf([0.025, 0.975], 3 * n) / n
    for block in ("velocity", "accel_bias", "gyro_bias"):
        nees = biased.nees[:, :, STATE_BLOCKS.index(block)].mean(axis=0)
        inside = np.mean((nees > lo) & (nees < hi))
        assert inside >= 0.9, f"{block} NEES inside its band at {inside:.0%} of epochs"


def _with_nees(
    nees: np.ndarray, failure: list[str | None] | None = None
) -> pronet.MonteCarloResult:
    """A result whose only content is its per-epoch NEES ``(runs, epochs, 5)``."""
    runs, epochs, _ = nees.shape
    per_run = np.full(runs, 0.1)
    return pronet.MonteCarloResult(
        srmse=per_run, smae=per_run, final_horizontal_error=per_run,
        max_horizontal_error=per_run, mean_nis=np.full(runs, 3.0),
        rejected_updates=np.zeros(runs, dtype=np.int64), diverged_at=np.full(runs, np.nan),
        failure=failure or [None] * runs, dvl_time=np.arange(1.0, epochs + 1),
        nis=np.full((runs, epochs), 3.0), nees=nees,
    )  # fmt: skip


def test_nees_in_band_is_the_share_of_epochs_a_consistent_filter_keeps_inside() -> None:
    from pronet.results import OUT_OF_BAND, consistency_cells

    rng = np.random.default_rng(4)
    honest = rng.chisquare(3, size=(20, 400, 5))
    r = _with_nees(honest)
    for block in STATE_BLOCKS:
        assert 0.9 < r.nees_in_band(block) < 0.99, block
    np.testing.assert_allclose(r.attitude_nees, honest[:, :, 2].mean(axis=1))
    assert OUT_OF_BAND not in "".join(consistency_cells(r))
    # An attitude block four times overconfident leaves its band and is flagged.
    bold = honest.copy()
    bold[:, :, 2] *= 4
    flagged = _with_nees(bold)
    assert flagged.nees_in_band("attitude") < 0.05
    vel, att, _ = consistency_cells(flagged)
    assert att.endswith(OUT_OF_BAND) and not vel.endswith(OUT_OF_BAND)
    # Failed runs are left out (their NEES is NaN), an unknown block is an error.
    broken = honest.copy()
    broken[0] = np.nan
    partial = _with_nees(broken, ["diverged"] + [None] * 19)
    assert 0.9 < partial.nees_in_band("velocity") < 0.99
    with pytest.raises(ValueError, match="^block: expected one of"):
        r.nees_in_band("heading")
    assert "attitude_nees" in r.summary() and "attitude_nees" in r.to_dataframe()


def test_summary_reports_every_blocks_nees_with_its_band() -> None:
    rng = np.random.default_rng(7)
    honest = rng.chisquare(3, size=(20, 300, 5))
    scale = np.array([1.0, 1.0, 4.0, 0.25, 1.0])  # attitude overconfident, accel bias shy
    r = _with_nees(honest * scale, ["diverged"] + [None] * 19)
    r = dataclasses.replace(r, nees=np.where(np.arange(20)[:, None, None] == 0, np.nan, r.nees))
    summary, row = r.summary(), r.summary_row()
    low, high = chi2.ppf([0.025, 0.975], 3 * 19) / 19  # the band of 19 runs' mean
    assert row["nees_band_low"] == pytest.approx(low, rel=2e-3)
    assert row["nees_band_high"] == pytest.approx(high, rel=2e-3)
    for i, block in enumerate(STATE_BLOCKS):
        per_run = (honest * scale)[1:, :, i].mean(axis=1)
        assert summary[f"{block}_nees"].mean == pytest.approx(per_run.mean()), block
        assert summary[f"{block}_nees"].n == 19
        assert row[f"{block}_nees"] == pytest.approx(3.0 * scale[i], rel=0.05), block
        inside = row[f"{block}_nees_in_band"]
        assert (0.9 < inside < 0.99) if scale[i] == 1.0 else inside < 0.05, block
    # The same names in the per-run table and the result schema.
    assert {f"{b}_nees" for b in STATE_BLOCKS} <= set(r.to_dataframe().columns)
    from pronet.results import SUMMARY_COLUMNS

    assert list(row) == [c for c in SUMMARY_COLUMNS if c in row]
    assert {f"{b}_nees_in_band" for b in STATE_BLOCKS} <= set(SUMMARY_COLUMNS)
