"""The DVL noise estimators (:mod:`pronet.recorded.dvlnoise`) against known noise: the
second-difference estimate of the sensor, the innovation matching's fixed point, and
both through ``pronet real``'s rows on a simulated recording whose DVL noise is known."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

import pronet
from pronet.filter import FilterResult
from pronet.recorded import real
from pronet.recorded.alignment import Alignment, align
from pronet.recorded.dvlnoise import (
    DVL_VARIANCE_FLOOR,
    innovation_ratio,
    lag_one,
    match_correlated,
    match_innovations,
    second_difference_variance,
)
from pronet.recorded.passes import section_recorded
from pronet.recorded.tuning import REAL_DVL_VARIANCE, real_filter_config
from pronet.run import run

from synthetic_recording import (
    DVL_CLOCK,
    DVL_LEVER_ARM,
    GT_CLOCK,
    IMU_LEVER_ARM,
    synthetic_recording,
)

TRUE_SIGMA = (0.01, 0.03, 0.005)


def test_second_differences_recover_white_noise_on_a_moving_sensor() -> None:
    """2,000 rows of a slowly turning velocity plus white noise of a different σ per
    axis: var(Δ²v)/6 is within 10 % of each σ² (its sampling error is about 4 %)."""
    rng = np.random.default_rng(1)
    t = np.arange(2000.0)
    smooth = np.column_stack(
        [1.5 + 0.2 * np.sin(t / 40), 0.3 * np.cos(t / 25), 0.05 * np.sin(t / 60)]
    )
    dvl = smooth + rng.normal(size=smooth.shape) * TRUE_SIGMA
    got = np.array(second_difference_variance(dvl))
    np.testing.assert_allclose(got, np.square(TRUE_SIGMA), rtol=0.10)
    # Missing rows break runs of three, they are not read as data.
    holes = dvl.copy()
    holes[::7] = np.nan
    np.testing.assert_allclose(second_difference_variance(holes), got, rtol=0.10)
    # A noiseless constant velocity: the floor, not zero.
    assert second_difference_variance(np.ones((50, 3))) == (DVL_VARIANCE_FLOOR,) * 3
    with pytest.raises(ValueError, match="dvl: needs at least ten"):
        second_difference_variance(np.ones((11, 3)))
    with pytest.raises(ValueError, match=r"dvl: expected shape \(n, 3\)"):
        second_difference_variance(np.ones((50, 2)))


def _fake_pass(true_r: np.ndarray, share: float, rng: np.random.Generator):
    """A stand-in for a filter pass: the filter's own share of S grows with R as
    ``share·√R`` (P shrinks as the DVL is trusted more), and the innovations have the
    variance of that share plus the true R. Like a pass over one recording, it is
    deterministic: the same draws every pass."""
    m = 4000
    draws = rng.normal(size=(m, 3))

    def one_pass(r: tuple[float, float, float]) -> FilterResult:
        hph = share * np.sqrt(np.asarray(r))
        nu = draws * np.sqrt(hph + true_r)
        s = np.zeros((m, 3, 3))
        s[:, [0, 1, 2], [0, 1, 2]] = hph + np.asarray(r)
        nis = np.einsum("ki,ki->k", nu, nu / np.diagonal(s, axis1=1, axis2=2))
        empty = np.zeros((0,))
        unused = ("time", "lla", "vel", "rpy", "bias", "sigma", "calibration",
                  "calibration_sigma", "covariance", "covariance_epoch", "covariances", "gain",
                  "adaptive_q")  # fmt: skip
        return FilterResult(
            **dict.fromkeys(unused, empty),
            dvl_epoch=np.zeros(m, dtype=np.int64),
            innovation=nu,
            innovation_cov=s,
            nis=nis,
            accepted=np.ones(m, dtype=bool),
            diverged_at=None,
        )

    return one_pass


def test_matching_finds_the_r_whose_innovations_the_filter_predicts() -> None:
    """From a start 30× too large or too small, each axis settles where the mean
    innovation square equals the predicted S: R = true R (up to the sampling error of
    4,000 innovations), in a few passes; the floor holds where the data asks for less."""
    true_r = np.square(TRUE_SIGMA)
    for start in (30 * true_r, true_r / 30):
        got = match_innovations(_fake_pass(true_r, 0.02, np.random.default_rng(2)), start)
        assert got.converged and got.passes < 30, got
        np.testing.assert_allclose(got.variance, true_r, rtol=0.15)
        assert got.start == tuple(start)
        assert 2.5 < got.mean_nis < 3.5
    floored = match_innovations(
        _fake_pass(np.zeros(3), 0.02, np.random.default_rng(3)), true_r, floor=1e-5
    )
    assert min(floored.variance) == 1e-5
    for bad, match in [
        (dict(start=(0.0, 1.0, 1.0)), "start: must be finite and > 0"),
        (dict(start=true_r, tolerance=0.0), "tolerance: must be > 0"),
        (dict(start=true_r, max_passes=0), "max_passes: must be at least 1"),
        (dict(start=true_r, floor=-1.0), "floor: must be > 0"),
    ]:
        with pytest.raises(ValueError, match=match):
            match_innovations(_fake_pass(true_r, 0.02, np.random.default_rng(0)), **bad)


def test_innovation_ratio_reads_applied_updates_only() -> None:
    one = _fake_pass(np.full(3, 1e-4), 0.0, np.random.default_rng(4))((1e-4,) * 3)
    rejected = replace(one, accepted=np.zeros_like(one.accepted))
    with pytest.raises(ValueError, match="no DVL update was applied"):
        innovation_ratio(rejected)
    np.testing.assert_allclose(innovation_ratio(one), 1.0, atol=0.1)


@pytest.fixture(scope="module")
def known_noise():
    """A 400 s simulated section (true clocks and lever arms) whose DVL noise σ per
    axis is :data:`TRUE_SIGMA`."""
    synthetic = synthetic_recording(seed=5, duration=400.0, dvl_sigma=TRUE_SIGMA)
    true = Alignment(
        gt_clock=GT_CLOCK,
        dvl_clock=DVL_CLOCK,
        imu_lever_arm=IMU_LEVER_ARM,
        dvl_lever_arm=DVL_LEVER_ARM,
    )
    return align(synthetic.recording, true)


def test_both_estimates_find_a_known_dvl_noise_and_the_rows_use_it(known_noise) -> None:
    """On the simulated section, with the filter told the true IMU noise: the
    second-difference and the innovation-matched R are each within 25 % of the true
    σ² per axis, the matched filter's mean NIS is near 3, and the plan's rows use the
    datasheet R or the matched one as asked."""
    section = known_noise
    strategy = pronet.Strategy.constant([1e-4] * 3 + [1e-8] * 3)
    noise = real.estimate_dvl_noise(section, strategy, section.alignment.filter_lever_arm)
    true_r = np.square(TRUE_SIGMA)
    np.testing.assert_allclose(noise.second_difference, true_r, rtol=0.25)
    np.testing.assert_allclose(noise.matched.variance, true_r, rtol=0.25)
    assert noise.matched.converged and 2.4 < noise.matched.mean_nis < 3.6

    datasheet = real.plan_section(section, {}, 1.0)
    assert datasheet.dvl_variance == (REAL_DVL_VARIANCE,) * 3
    assert tuple(datasheet.config.dvl_variance) == datasheet.dvl_variance
    variants = datasheet.variants
    assert list(variants) == list(real.REAL_VARIANT_ROWS)
    noise = datasheet.dvl_noise
    from_data = variants[real.R_FROM_DATA]
    assert tuple(from_data.dvl_variance) == noise.matched.variance
    assert not from_data.dvl_calibration
    calibrated = variants[real.DVL_CALIBRATION]
    assert calibrated.dvl_calibration
    assert tuple(calibrated.dvl_variance) == datasheet.dvl_variance
    both = variants[real.BOTH]
    assert both.dvl_calibration
    assert tuple(both.dvl_variance) == noise.matched_calibrated.variance
    # An ideal simulated DVL: the states explain nothing, R comes out alike.
    np.testing.assert_allclose(noise.matched_calibrated.variance, true_r, rtol=0.25)
    from_data = real.plan_section(section, {}, 1.0, dvl_noise="data")
    assert from_data.dvl_variance == from_data.dvl_noise.matched.variance
    assert tuple(from_data.config.dvl_variance) == from_data.dvl_variance
    with pytest.raises(ValueError, match="--dvl-noise: must be one of datasheet, data"):
        real.plan_section(section, {}, 1.0, dvl_noise="sheet")


def test_a_section_too_short_for_the_dvl_noise_runs_without_the_variant_rows() -> None:
    """Eleven DVL rows give nine second differences, too few to estimate R: the
    strategy rows still run with the datasheet R, the variant rows are left out and
    the reason is kept; asked to use R from the data, the section fails, naming why."""
    synthetic = synthetic_recording(seed=6, duration=12.0)
    section = align(synthetic.recording, Alignment(how="none"))
    assert len(section.dvl) == 11
    plan = real.plan_section(section, {}, 1.0)
    assert plan.variants == {} and isinstance(plan.dvl_noise, str)
    assert "dvl: needs at least ten" in plan.dvl_noise
    constant = dict(list(plan.strategies.items())[:1])  # the adaptive rows need longer
    runs, _ = real.evaluate_section(section, constant, plan.config, variants=plan.variants)
    assert [r.label for r in runs] == list(constant)
    with pytest.raises(ValueError, match="DVL noise: dvl: needs at least ten"):
        real.plan_section(section, {}, 1.0, dvl_noise="data")


def test_calibration_agreement_weights_by_variance_and_counts_outliers() -> None:
    from pronet.recorded.tables import calibration_agreement

    values = np.array([1.0, 1.2, 0.9, 5.0, 7.0])
    sigmas = np.array([0.1, 0.2, 0.1, 0.1, 0.0])  # the last: no σ, left out
    mean, sigma, off = calibration_agreement(values, sigmas)
    w = 1 / sigmas[:4] ** 2
    assert mean == pytest.approx(np.sum(w * values[:4]) / np.sum(w))
    assert sigma == pytest.approx(1 / np.sqrt(np.sum(w)))
    assert off == 4  # the weighted mean sits between the two clusters; none within 3σ
    assert calibration_agreement(np.array([1.0, 1.1]), np.array([0.1, 0.1]))[2] == 0
    assert np.isnan(calibration_agreement(np.array([1.0]), np.array([0.0]))[0])


def test_the_matching_passes_keep_only_their_last_epoch(known_noise, monkeypatch) -> None:
    """The matching reads the updates alone, so its passes ask the core for no epoch
    arrays (``epochs="last"``: about a third of ``pronet real``'s passes, and the bytes
    they no longer write): every pass, without and with the calibration states."""
    section = known_noise
    asked = []
    run = real.run

    def spy(strategy, target):
        asked.append((target.epochs, target.config.dvl_calibration))
        return run(strategy, target)

    monkeypatch.setattr(real, "run", spy)
    strategy = pronet.Strategy.constant([1e-4] * 3 + [1e-8] * 3)
    noise = real.estimate_dvl_noise(section, strategy, section.alignment.filter_lever_arm)
    passes = noise.matched.passes + noise.matched_calibrated.passes
    assert len(asked) == passes and {epochs for epochs, _ in asked} == {"last"}
    assert sum(calibrated for _, calibrated in asked) == noise.matched_calibrated.passes


def _joint_fit(seed: int, bias: tuple[tuple[float, float, float], float] | None, tau: float):
    """A 1,200 s simulated section whose DVL has white noise of (0.01, 0.01, 0.005) m/s
    and, with ``bias = (σ, τ)``, a Gauss–Markov error on top; R matched alone, then
    fitted with the correlated error at ``tau``. Returns (white fit, joint fit, passes
    run)."""
    synthetic = synthetic_recording(
        seed=seed, duration=1200.0, dvl_sigma=(0.01, 0.01, 0.005), dvl_bias=bias
    )
    truth = Alignment(GT_CLOCK, DVL_CLOCK, IMU_LEVER_ARM, DVL_LEVER_ARM)
    section = align(synthetic.recording, truth)
    strategy = pronet.Strategy.constant([1e-4] * 3 + [1e-8] * 3)
    arm = section.alignment.filter_lever_arm
    made = []

    def one_pass(r, sigma=None):
        made.append(sigma)
        config = real_filter_config(arm, r, correlated=None if sigma is None else (sigma, tau))
        return run(strategy, section_recorded(section, config, epochs="last")).result

    white = match_innovations(one_pass, second_difference_variance(section.dvl))
    return white, match_correlated(one_pass, white, tau, 1.0), len(made)


def test_r_and_a_correlated_dvl_error_are_fitted_together_at_its_time_constant() -> None:
    """A DVL error of 0.02 m/s per axis, τ 60 s, beside white noise: R matched alone
    takes part of it (its σ above the white noise's), the innovations are correlated
    at lag one beyond their band, and the joint fit at the true τ finds the white σ
    within 15 % and the correlated σ within 25 % on every axis, its innovations
    uncorrelated at lag one and its mean NIS near 3. At another τ the fit finds
    another σ: the innovations identify the error's power where the filter sees it,
    not its correlation time."""
    white, joint, made = _joint_fit(1, ((0.02, 0.02, 0.02), 60.0), 60.0)
    assert np.all(np.sqrt(white.variance) > 1.15 * np.array([0.01, 0.01, 0.005]))
    assert joint.converged and joint.correlated is not None and joint.time_constant == 60.0
    np.testing.assert_allclose(np.sqrt(joint.variance), [0.01, 0.01, 0.005], rtol=0.15)
    np.testing.assert_allclose(joint.correlated, 0.02, rtol=0.25)
    assert 2.8 < joint.mean_nis < 3.2 and made == joint.passes
    shorter = _joint_fit(1, ((0.02, 0.02, 0.02), 60.0), 20.0)[1]
    assert shorter.correlated is not None and max(shorter.correlated) < 0.015


def test_white_dvl_noise_shows_no_correlated_error_to_fit() -> None:
    """White DVL noise alone: the innovations' lag-one autocorrelation is inside its
    band on every axis, so the joint fit returns the white fit, one pass more."""
    white, joint, made = _joint_fit(1, None, 60.0)
    assert joint.correlated is None and joint.time_constant is None
    assert joint.variance == white.variance and joint.passes == white.passes + 1 == made
    for tau, step, match in [
        (0.0, 1.0, "time_constant: must be > 0"),
        (60.0, math.inf, "dvl_step"),
    ]:
        with pytest.raises(ValueError, match=match):
            match_correlated(lambda r, s=None: None, white, tau, step)
    for kwargs, match in [
        ({"max_passes": 0}, "max_passes: must be at least 1, got 0"),
        ({"tolerance": math.nan}, "tolerance: must be > 0"),
        ({"floor": 0.0}, "floor: must be > 0"),
    ]:
        with pytest.raises(ValueError, match=match):
            match_correlated(lambda r, s=None: None, white, 60.0, 1.0, **kwargs)


def test_a_correlated_error_on_one_axis_is_fitted_on_that_axis_alone() -> None:
    """The Gauss–Markov error on the DVL's x axis only (0.03 m/s, τ 60 s): the fit
    finds it there, within 25 %, and on y and z under a quarter of it (as the section
    turns, the velocity error the filter took from x shows on y: 0.006 m/s here), and
    the white σ within 15 % of the white noise's on every axis (R alone took 0.012 m/s
    on y)."""
    white, joint, _ = _joint_fit(2, ((0.03, 0.0, 0.0), 60.0), 60.0)
    assert joint.correlated is not None
    assert joint.correlated[0] == pytest.approx(0.03, rel=0.25)
    assert max(joint.correlated[1:]) < 0.25 * joint.correlated[0]
    np.testing.assert_allclose(np.sqrt(joint.variance), [0.01, 0.01, 0.005], rtol=0.15)
    assert math.sqrt(white.variance[1]) > 0.0115


def test_lag_one_reads_consecutive_applied_updates() -> None:
    """An innovation sequence built as an AR(1) with φ 0.5 on x, white on y and z, S
    the identity: the lag-one autocorrelation is φ on x and 0 on the others (within
    twice the 95 % band, whatever the draws), its covariance φ·var on x, and too few
    updates are refused."""
    one = _fake_pass(np.full(3, 1.0), 0.0, np.random.default_rng(6))((1.0,) * 3)
    nu = np.random.default_rng(7).normal(size=one.innovation.shape)
    for k in range(1, len(nu)):
        nu[k, 0] = 0.5 * nu[k - 1, 0] + math.sqrt(0.75) * nu[k, 0]
    s = np.broadcast_to(np.eye(3), one.innovation_cov.shape).copy()
    cov, rho, band = lag_one(replace(one, innovation=nu, innovation_cov=s))
    assert band == pytest.approx(1.96 / math.sqrt(len(nu) - 1))
    assert abs(rho[0] - 0.5) < 0.05 and np.all(np.abs(rho[1:]) < 2 * band)
    assert cov[0] == pytest.approx(0.5, abs=0.05)
    few = replace(one, accepted=np.arange(len(nu)) < 10)
    with pytest.raises(ValueError, match="at least ten pairs"):
        lag_one(few)
