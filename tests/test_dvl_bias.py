"""The DVL's correlated velocity error (``FilterConfig(dvl_bias_sigma=...)``): a
first-order Gauss–Markov error per DVL axis, three states beside the calibration's.

Told the true model, the filter and the RTS smoother are consistent where the DVL's
error is correlated: their velocity and the correlated error's estimate lie within 1σ
and 3σ of the truth as often as a Gaussian does. Told only a white R of the same total
variance, the classic failure: the velocity's σ is too small for the error it makes
(the DVL's slow error taken as averaging out)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import pronet

from synthetic_recording import gauss_markov

SIGMA_B, TAU, WHITE = 0.03, 60.0, 0.01  # [m/s], [s], [m/s]
Q = np.array([1e-6] * 3 + [1e-10] * 3)  # per-sample IMU variances
RUNS = 12


def _run(seed: int, cfg: pronet.FilterConfig, smooth: bool = False, **kw: object):
    """One pass on the paper's trajectory with a 5 Hz DVL whose error is correlated and
    a position fix every 30 s (1 m σ): the result and the truth's velocity and DVL
    error."""
    truth = pronet.builtin_trajectory("paper")
    n = len(truth.time) - 1
    rng = np.random.default_rng(seed)
    imu = truth.imu[:n] + rng.normal(size=(n, 6)) * np.sqrt(Q)
    k = np.arange(20, n + 1, 20)
    body_to_ned = Rotation.from_euler("ZYX", truth.rpy[k][:, ::-1]).as_matrix()
    body = np.einsum("kji,kj->ki", body_to_ned, truth.vel_ned[k])
    b = gauss_markov(truth.time[k], (SIGMA_B,) * 3, TAU, rng)
    dvl = body + b + rng.normal(size=body.shape) * WHITE
    f = np.arange(3000, n + 1, 3000)
    fix_lla = np.array([pronet.lla_from_ned(rng.normal(size=3), p) for p in truth.lla[f]])
    fixes = pronet.Fix(truth.time[f], fix_lla, sigma=[1.0, 1.0, 1.0])
    res = pronet.run_filter(
        imu, truth.time[1 : n + 1], [pronet.Dvl(truth.time[k], dvl), fixes], t0=0.0,
        lla0=truth.lla[0], vel0=truth.vel_ned[0], rpy0=truth.rpy[0], config=cfg,
        strategy=pronet.Strategy.constant(Q), smooth=smooth, warn=False, **kw,
    )  # fmt: skip
    return res, truth.vel_ned[: n + 1], k, b


def _config(correlated: bool) -> pronet.FilterConfig:
    common = dict(accel_bias_psd=1e-12, gyro_bias_psd=1e-16)
    if correlated:
        return pronet.FilterConfig(
            dvl_variance=[WHITE**2] * 3, dvl_bias_sigma=[SIGMA_B] * 3,
            dvl_bias_time_constant=TAU, **common,
        )  # fmt: skip
    return pronet.FilterConfig(dvl_variance=[WHITE**2 + SIGMA_B**2] * 3, **common)


def _shares(correlated: bool) -> tuple[float, float]:
    """Share of (run, DVL epoch, axis) whose velocity error, and correlated-error
    estimate's error, lie within 3σ."""
    vel, bias = [], []
    for seed in range(RUNS):
        res, v, k, b = _run(seed, _config(correlated))
        vel.append(np.abs(res.vel[k] - v[k]) <= 3 * res.sigma[k, 3:6])
        if correlated:
            bias.append(np.abs(res.calibration[k, 4:7] - b) <= 3 * res.calibration_sigma[k, 4:7])
    return float(np.mean(vel)), float(np.mean(bias)) if bias else math.nan


def test_told_the_correlated_error_the_filter_is_consistent_and_a_white_r_is_not() -> None:
    vel, bias = _shares(True)
    assert vel >= 0.95 and bias >= 0.95, (vel, bias)
    white, _ = _shares(False)
    assert white < 0.9, white  # overconfident: the slow error taken as averaging out


def test_the_correlated_error_is_estimated_and_reported_in_the_dvl_states() -> None:
    res, v, k, b = _run(0, _config(True))
    assert res.calibration.shape == (len(res.time), 7)
    # the scale and mounting are not estimated: held at their nominal values
    assert np.all(res.calibration[:, :4] == 0.0) and np.all(res.calibration_sigma[:, :4] == 0.0)
    err = res.calibration[k, 4:7] - b
    assert np.mean(np.abs(err) <= 3 * res.calibration_sigma[k, 4:7]) >= 0.95
    # σ starts at the prior, its stationary σ, and falls as the fixes make it observable
    assert res.calibration_sigma[0, 4:7] == pytest.approx([SIGMA_B] * 3)
    assert np.all(res.calibration_sigma[-1, 4:7] < SIGMA_B)
    frame = res.to_dataframe()
    assert {"dvl_bias_x", "sigma_dvl_bias_z"} <= set(frame.columns)


def test_the_configuration_says_what_it_models() -> None:
    c = pronet.FilterConfig(dvl_bias_sigma=[0.02, 0.02, 0.01], dvl_bias_time_constant=30)
    assert (c.dvl_bias_sigma, c.dvl_bias_time_constant, c.dvl_calibration) == (
        [0.02, 0.02, 0.01], 30.0, False,
    )  # fmt: skip
    assert "dvl_bias_sigma=[0.02, 0.02, 0.01]" in repr(c)
    both = pronet.FilterConfig(dvl_calibration=True, dvl_bias_sigma=[0.01] * 3)
    assert both.dvl_calibration and both.dvl_bias_time_constant == 60.0
    plain = pronet.FilterConfig()
    assert plain.dvl_bias_sigma is None and plain.dvl_bias_time_constant is None
    for kw, name in [
        (dict(dvl_bias_time_constant=30.0), "dvl_bias_time_constant"),
        (dict(dvl_bias_sigma=[0.1, 0.1]), "dvl_bias_sigma"),
        (dict(dvl_bias_sigma=[0.1, -0.1, 0.1]), "dvl_bias_sigma"),
        (dict(dvl_bias_sigma=[0.1] * 3, dvl_bias_time_constant=0.0), "dvl_bias_time_constant"),
        (dict(dvl_bias_sigma=[0.1] * 3, aiding="nav"), "dvl_bias_sigma"),
    ]:
        with pytest.raises(ValueError, match=f"^{name}"):
            pronet.FilterConfig(**kw)


def test_the_smoother_takes_the_correlated_error_and_stays_consistent() -> None:
    # 1σ and 3σ shares of (run, DVL epoch, axis): forward and smoothed velocity and b̂.
    shares: dict[str, list[np.ndarray]] = {}
    rms = []
    for seed in range(6):
        res, v, k, b = _run(100 + seed, _config(True), smooth=True)
        s = res.smoothed
        assert s is not None
        assert np.all(s.calibration_sigma[:, 4:7] <= res.calibration_sigma[:, 4:7] * (1 + 1e-12))
        for name, err, sigma in [
            ("vel", res.vel[k] - v[k], res.sigma[k, 3:6]),
            ("vel smoothed", s.vel[k] - v[k], s.sigma[k, 3:6]),
            ("b", res.calibration[k, 4:7] - b, res.calibration_sigma[k, 4:7]),
            ("b smoothed", s.calibration[k, 4:7] - b, s.calibration_sigma[k, 4:7]),
        ]:
            shares.setdefault(name, []).append(np.abs(err) / sigma)
        rms.append([np.sqrt(np.mean(e**2)) for e in (res.calibration[k, 4:7] - b,
                                                     s.calibration[k, 4:7] - b)])  # fmt: skip
    for name, ratios in shares.items():
        r = np.concatenate(ratios)
        # a Gaussian: 68 % within 1σ, 99.7 % within 3σ (the runs' epochs are correlated:
        # a band, not a test at the binomial's width)
        assert 0.6 <= np.mean(r <= 1) <= 0.8 and np.mean(r <= 3) >= 0.98, (name, np.mean(r <= 1))
    forward, smoothed = np.mean(rms, axis=0)
    assert smoothed < 0.6 * forward, (forward, smoothed)  # the data after each epoch helps


def test_a_thinned_smoothed_pass_is_the_every_epoch_one_and_a_monte_carlo_smooths_it() -> None:
    every, *_ = _run(3, _config(True), smooth=True)
    thin, *_ = _run(3, _config(True), smooth=True, output_step=1.0)
    assert every.smoothed is not None and thin.smoothed is not None
    for name in ("vel", "sigma", "calibration", "calibration_sigma"):
        kept = getattr(every.smoothed, name)[thin.epoch]
        np.testing.assert_array_equal(getattr(thin.smoothed, name), kept, err_msg=name)
    # a Monte Carlo's backward pass carries Λ as a product where σ is read at few epochs
    sc = pronet.builtin_trajectory("paper")
    mc = pronet.monte_carlo(
        sc, pronet.Strategy.constant(Q), sensors=pronet.SensorConfig(imu_variance=Q),
        config=_config(True), n_runs=3, seed=1, record_every=1000, smooth=True,
    )  # fmt: skip
    assert mc.smoothed is not None
    assert np.all(mc.smoothed.sigma <= mc.sigma * (1 + 1e-12))
    assert np.all(np.isfinite(mc.smoothed.error))
    # the scale and mounting held: no calibration error or NEES reported for them
    assert mc.calibration_error is None and mc.calibration_nees is None
