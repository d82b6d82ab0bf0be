"""The RTS smoother on simulated passes: consistent, and better than the filter.

Forty passes over the first 120 s of the ``paper`` trajectory, each with its own IMU
noise, turn-on biases, DVL noise and initial error drawn from what the filter is told
(so a consistent filter's velocity NEES is 3, with 3 degrees of freedom). The NumPy
reference check of the same smoother is ``tests/test_numpy_reference_smoother.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

import pronet
from pronet.config import filter_config
from pronet.recorded.alignment import dcm_from_euler

Q = (1e-4,) * 3 + (1e-6,) * 3
P0 = np.array([1, 1, 1, 0.1, 0.1, 0.1, 1e-3, 1e-3, 5e-3, 1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-4])
DVL_SIGMA = 0.02
RUNS, SECONDS = 40, 120.0


def _passes(formulation: str) -> tuple[np.ndarray, ...]:
    """Velocity errors and their σ of the filter and the smoother, ``(runs, epochs, 3)``."""
    truth = pronet.builtin_trajectory("paper")
    n = int(round(SECONDS / truth.dt))
    k = np.arange(100, n + 1, 100)  # a 1 Hz DVL
    body = np.einsum("kji,kj->ki", dcm_from_euler(truth.rpy[k]), truth.vel_ned[k])
    cfg = pronet.FilterConfig(
        p0_sigma=P0, dvl_variance=[DVL_SIGMA**2] * 3, accel_bias_psd=1e-10,
        gyro_bias_psd=1e-14, formulation=formulation,
    )  # fmt: skip
    out: list[list[np.ndarray]] = [[], [], [], []]
    for seed in range(RUNS):
        rng = np.random.default_rng(seed)
        imu = truth.imu[:n] + rng.normal(size=6) * P0[9:] + rng.normal(size=(n, 6)) * np.sqrt(Q)
        dvl = body + rng.normal(size=body.shape) * DVL_SIGMA
        d = rng.normal(size=9) * P0[:9]
        start = pronet.lla_from_ned(d[:3], truth.lla[0])
        res = pronet.run_filter(
            imu, truth.time[1 : n + 1], [pronet.Dvl(truth.time[k], dvl)], t0=0.0, lla0=start,
            vel0=truth.vel_ned[0] + d[3:6], rpy0=truth.rpy[0] + d[6:9], config=cfg,
            strategy=pronet.Strategy.constant(Q), smooth=True,
        )  # fmt: skip
        s = res.smoothed
        assert s is not None
        v = truth.vel_ned[: n + 1]
        for i, part in enumerate((res.vel - v, res.sigma[:, 3:6], s.vel - v, s.sigma[:, 3:6])):
            out[i].append(part)
    return tuple(np.array(x) for x in out)


@pytest.mark.slow
@pytest.mark.parametrize("formulation", ["invariant", "classic"])
def test_the_smoother_is_consistent_and_beats_the_filter(formulation) -> None:
    ef, sf, es, ss = _passes(formulation)
    nees_f = np.mean(np.sum((ef / sf) ** 2, axis=2))
    nees_s = np.mean(np.sum((es / ss) ** 2, axis=2))
    # Both consistent: a mean NEES of 3 over 40 runs × 12,001 correlated epochs.
    assert 2.5 < nees_f < 3.6 and 2.5 < nees_s < 3.6, (nees_f, nees_s)
    rms_f = np.sqrt(np.mean(np.sum(ef**2, axis=2), axis=0))
    rms_s = np.sqrt(np.mean(np.sum(es**2, axis=2), axis=0))
    # Never worse beyond the noise of 40 runs, and well better on the whole.
    assert (rms_s <= 1.15 * rms_f).all()
    assert rms_s.mean() < 0.85 * rms_f.mean(), (rms_s.mean(), rms_f.mean())


@pytest.fixture(scope="module")
def matched():
    from pronet.sim.scenarios import SCENARIOS

    return SCENARIOS["matched"](0)


def _assert_consistent(s: pronet.MonteCarloResult, velocity_share: float) -> None:
    """The smoothed NEES as a consistent smoother gives it: the velocity's, the fastest
    block's, in band at most DVL epochs; every block's, averaged over the runs and then
    over the epochs, inside the 99 % band of an average over the runs. (A slow block's
    share of epochs in band is nearly all or nothing, a consistent smoother's included:
    docs/results/smoother.md, "One draw of 100 runs".)"""
    from scipy.stats import chi2

    assert s.nees_in_band("velocity") >= velocity_share, s.nees_in_band("velocity")
    low, high = chi2.ppf([0.005, 0.995], 3 * s.n_runs) / s.n_runs
    for i, block in enumerate(pronet.STATE_BLOCKS):
        nees = float(np.nanmean(np.nanmean(s.nees[:, :, i], axis=0)))
        assert low < nees < high, (block, nees, low, high)


def _mc(sc, **kw):
    return pronet.monte_carlo(
        sc.trajectory, pronet.Strategy.constant(sc.q_nominal), sensors=sc.sensors,
        config=sc.config, seed=0, record_every=100, **kw,
    )  # fmt: skip


@pytest.mark.slow
def test_monte_carlo_smooths_every_run_and_leaves_the_filter_as_it_was(matched) -> None:
    """The filter's numbers are bit-identical with and without ``smooth``; the smoothed
    result has the same shapes, a consistent NEES in every block, and a velocity error
    below the filter's at every recorded epoch (a filter told the simulated model)."""
    plain = _mc(matched, n_runs=30)
    both = _mc(matched, n_runs=30, smooth=True)
    assert plain.smoothed is None
    for name in ("srmse", "final_horizontal_error", "nis", "nees", "error", "sigma"):
        np.testing.assert_array_equal(getattr(both, name), getattr(plain, name), err_msg=name)
    s = both.smoothed
    assert s is not None and s.smoothed is None and s.q is None
    assert s.nees.shape == both.nees.shape and s.error.shape == both.error.shape
    np.testing.assert_array_equal(s.nis, both.nis)  # the filter's, kept
    _assert_consistent(s, 0.85)
    rms = lambda r: np.sqrt(np.mean(np.sum(r.error[:, :, 3:6] ** 2, axis=2), axis=0))  # noqa: E731
    assert (rms(s)[1:-1] < rms(both)[1:-1]).all()
    assert s.summary()["srmse"].mean < 0.7 * both.summary()["srmse"].mean
    # The last epoch has nothing after it: smoothed = filtered there.
    np.testing.assert_allclose(s.error[:, -1], both.error[:, -1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(s.final_horizontal_error, both.final_horizontal_error, rtol=1e-12)


@pytest.mark.parametrize("step", [0.1, 0.2])
def test_monte_carlo_smooths_over_a_covariance_step(matched, step) -> None:
    """With the covariance propagated over 0.1 s or 0.2 s steps (the smoother's grid
    then the steps' closes) the smoothed runs are consistent in every block, below the
    filter at every recorded epoch, and within 1 % of the every-sample smoother's
    SRMSE."""
    every = _mc(matched, n_runs=20, smooth=True)
    stepped = pronet.monte_carlo(
        matched.trajectory, pronet.Strategy.constant(matched.q_nominal), sensors=matched.sensors,
        config=filter_config({"covariance_step": step}, "step", matched.config), seed=0,
        record_every=100, n_runs=20, smooth=True,
    )  # fmt: skip
    s, e = stepped.smoothed, every.smoothed
    assert s is not None and e is not None
    _assert_consistent(s, 0.85)
    rms = lambda r: np.sqrt(np.mean(np.sum(r.error[:, :, 3:6] ** 2, axis=2), axis=0))  # noqa: E731
    assert (rms(s)[1:-1] < rms(stepped)[1:-1]).all()
    srmse = s.summary()["srmse"].mean, e.summary()["srmse"].mean
    assert abs(srmse[0] / srmse[1] - 1) < 0.01, srmse


@pytest.mark.slow
@pytest.mark.parametrize("name", ["regimes", "outage"])
def test_told_the_true_noise_the_smoother_is_consistent(name) -> None:
    """Where the IMU noise switches regimes (and the DVL falls silent), a filter told the
    true variance at every step (the oracle) is consistent, and so is the smoother
    (``_assert_consistent``; told the nominal q instead, the velocity NEES is in band at
    a third of the epochs); never worse than the filter beyond noise, and the velocity
    error well below it (docs/results/smoother.md, "Told the true IMU noise")."""
    from pronet.sim.scenarios import SCENARIOS

    sc, runs = SCENARIOS[name](0), 50
    r = pronet.monte_carlo(
        sc.trajectory, pronet.Strategy.oracle(), sensors=sc.sensors, config=sc.config,
        n_runs=runs, seed=0, record_every=100, smooth=True,
    )  # fmt: skip
    s = r.smoothed
    assert s is not None
    _assert_consistent(s, 0.7)
    rms = lambda x: np.sqrt(np.mean(np.sum(x.error[:, :, 3:6] ** 2, axis=2), axis=0))  # noqa: E731
    assert (rms(s) <= 1.05 * rms(r)).all()
    assert s.summary()["srmse"].mean < 0.7 * r.summary()["srmse"].mean


def test_the_ensemble_smooths_as_monte_carlo_does(matched) -> None:
    """An untuned ensemble is a constant strategy's Monte Carlo, smoothed too, the
    19-state filter (DVL calibration states) as well."""
    ens = pronet.Ensemble(
        matched.trajectory, matched.q_nominal, sensors=matched.sensors, config=matched.config,
        n_runs=3, seed=0, record_every=100, smooth=True,
    ).finish()  # fmt: skip
    mc = _mc(matched, n_runs=3, smooth=True)
    assert ens.smoothed is not None and mc.smoothed is not None
    np.testing.assert_array_equal(ens.smoothed.srmse, mc.smoothed.srmse)
    np.testing.assert_array_equal(ens.smoothed.error, mc.smoothed.error)
    from pronet.config import FILTER_KEYS

    kw = {k: getattr(matched.config, k) for k in FILTER_KEYS}
    calibrated = pronet.FilterConfig(**kw, dvl_calibration=True)
    r = pronet.monte_carlo(
        matched.trajectory, pronet.Strategy.constant(matched.q_nominal), n_runs=3,
        sensors=matched.sensors, config=calibrated, seed=0, smooth=True,
    )  # fmt: skip
    assert r.smoothed is not None
    assert r.smoothed.summary()["srmse"].mean < 0.7 * r.summary()["srmse"].mean


@pytest.mark.slow
def test_the_smoother_cuts_the_drift_of_each_dvl_outage() -> None:
    """The ``outage`` scenario (DVL silent 60–120, 150–210, 240–300 s), 100 runs: the
    smoothed horizontal error at each outage's middle is below the filter's, and the
    part of it gathered since the outage began is cut to 0.44–0.49 of the filter's
    (asserted: below 0.6). The error from before the outage, unobservable from
    velocity alone, stays (docs/reference/smoother.md, "The RTS smoother")."""
    from pronet.sim.scenarios import SCENARIOS

    sc = SCENARIOS["outage"](0)
    r = _mc(sc, n_runs=100, smooth=True)
    s = r.smoothed
    assert s is not None
    for start, end in sc.sensors.dvl_outages:
        a, m = (int(np.argmin(np.abs(r.record_time - t))) for t in (start, (start + end) / 2))

        def rms(e: np.ndarray) -> float:
            return float(np.sqrt(np.mean(np.sum(e**2, axis=1))))

        assert rms(s.error[:, m, :2]) < rms(r.error[:, m, :2])
        drift = [rms(x.error[:, m, :2] - x.error[:, a, :2]) for x in (r, s)]
        assert drift[1] < 0.6 * drift[0], (start, drift)


def test_smoothing_with_lost_dvl_readings_keeps_the_epochs_aligned(matched) -> None:
    """With bottom-lock loss (``dvl_dropout``) the smoothed NEES has the filter's shape
    and its NaN at the same lost epochs."""
    from dataclasses import replace

    sensors = pronet.SensorConfig(
        imu_variance=matched.sensors.imu_variance[0], dvl_variance=matched.sensors.dvl_variance,
        dvl_dropout=(30.0, 10.0),
    )  # fmt: skip
    r = _mc(replace(matched, sensors=sensors), n_runs=4, smooth=True)
    s = r.smoothed
    assert s is not None and r.missed_updates is not None and r.missed_updates.sum() > 0
    assert s.nees.shape == r.nees.shape
    lost = np.isnan(r.nis)
    np.testing.assert_array_equal(np.isnan(s.nees[:, :, 1]), lost)
    assert s.summary()["srmse"].mean < r.summary()["srmse"].mean


def test_smoothed_shards_concat_as_the_whole(matched) -> None:
    """Shards of a smoothed Monte Carlo (``first_run``) join into the whole, smoothed
    part included; smoothed and plain shards do not mix."""
    whole = _mc(matched, n_runs=4, smooth=True)
    parts = [_mc(matched, n_runs=2, smooth=True, first_run=k) for k in (0, 2)]
    joined = pronet.MonteCarloResult.concat(parts)
    assert joined.smoothed is not None and whole.smoothed is not None
    np.testing.assert_array_equal(joined.smoothed.srmse, whole.smoothed.srmse)
    np.testing.assert_array_equal(joined.smoothed.error, whole.smoothed.error)
    with pytest.raises(ValueError, match="some shards were smoothed"):
        pronet.MonteCarloResult.concat([parts[0], _mc(matched, n_runs=2, first_run=2)])


def test_nees_in_band_with_lost_readings_uses_each_epochs_run_count() -> None:
    """A consistent filter's NEES (χ² with 3 dof) with 40 % of the readings lost is in
    band at about 95 % of the epochs, each epoch judged against the band of the runs
    that had it (against the band of all runs it scored 0.875)."""
    rng = np.random.default_rng(0)
    runs, epochs = 100, 400
    nees = rng.chisquare(3, size=(runs, epochs, 5))
    nees[rng.random((runs, epochs)) < 0.4] = np.nan
    empty = np.zeros(runs)
    result = pronet.MonteCarloResult(
        srmse=empty, smae=empty, final_horizontal_error=empty, max_horizontal_error=empty,
        mean_nis=empty, rejected_updates=np.zeros(runs, np.int64), diverged_at=empty + np.nan,
        failure=[None] * runs, dvl_time=np.arange(epochs, dtype=float),
        nis=nees[:, :, 0], nees=nees,
    )  # fmt: skip
    assert 0.92 <= result.nees_in_band("velocity") <= 0.98


@pytest.fixture(scope="module")
def dive():
    """60 s of the synthetic recording (IMU at 100 Hz), a 1 Hz body DVL from its truth,
    and depth readings every 0.5 s and fixes every 10 s on the IMU's clock."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from synthetic_recording import synthetic_recording, with_aiding

    syn = synthetic_recording(seed=3, duration=60.0)
    traj, n = syn.trajectory, len(syn.recording.imu_time)
    k = np.arange(100, n + 1, 100)
    body = np.einsum("kji,kj->ki", dcm_from_euler(traj.rpy[k]), traj.vel_ned[k])
    dvl = body + np.random.default_rng(1).normal(size=body.shape) * 0.01
    return syn, dvl, traj.time[k], with_aiding(syn, seed=3, fix_every=10.0)


@pytest.mark.parametrize("output_step", [None, 1.0])
@pytest.mark.parametrize("measured", ["nothing", "dvl", "aided"])
@pytest.mark.parametrize("covariance_step", [0.1, 0.0])
@pytest.mark.parametrize("formulation", ["invariant", "classic"])
def test_the_smoothed_sigma_is_never_above_the_forward_one(
    dive, formulation, covariance_step, measured, output_step
) -> None:
    """At every kept epoch and state, those inside a covariance step too (the API reference,
    ``SmoothedResult.sigma``); with no measurement at all the smoothed σ is the forward
    σ, bit for bit."""
    syn, dvl, dvl_time, aided = dive
    rec, traj = syn.recording, syn.trajectory
    no_dvl = measured == "nothing"
    streams = [] if no_dvl else [pronet.Dvl(dvl_time, dvl)]
    if measured == "aided":
        depth, fixes = aided.depth, aided.fixes
        streams += [pronet.Depth(depth.time, depth.depth, sigma=0.05),
                    pronet.Fix(fixes.time, fixes.lla, sigma=fixes.sigma)]  # fmt: skip
    r = pronet.run_filter(
        rec.imu, traj.time[1:], streams, t0=0.0, lla0=traj.lla[0], vel0=traj.vel_ned[0],
        rpy0=traj.rpy[0], strategy=pronet.Strategy.constant([1e-4] * 3 + [1e-8] * 3),
        config=pronet.FilterConfig(formulation=formulation, covariance_step=covariance_step),
        smooth=True, output_step=output_step,
    )  # fmt: skip
    s = r.smoothed
    assert s is not None and np.isfinite(s.sigma).all()
    if no_dvl:
        np.testing.assert_array_equal(s.sigma, r.sigma)
        return
    assert (s.sigma <= r.sigma * (1 + 1e-12)).all(), (s.sigma / r.sigma).max(axis=0)
    assert (s.sigma[:, 3:6] < 0.9 * r.sigma[:, 3:6]).any()  # the smoother did something


@pytest.mark.parametrize("covariance_step", [0.1, 0.0])
@pytest.mark.parametrize("formulation", ["invariant", "classic"])
def test_the_monte_carlo_smoothed_sigma_is_never_above_the_forward_one(
    formulation, covariance_step
) -> None:
    """Recorded every 7 samples, mostly inside a 0.1 s step, where the run's forward σ
    is its covariance brought up to date there (not interpolated)."""
    r = pronet.monte_carlo(
        pronet.builtin_trajectory("paper"), pronet.Strategy.constant([1e-4] * 3 + [1e-8] * 3),
        config=pronet.FilterConfig(formulation=formulation, covariance_step=covariance_step),
        n_runs=2, seed=0, record_every=7, smooth=True,
    )  # fmt: skip
    s = r.smoothed
    assert s is not None and np.isfinite(s.sigma).all()
    assert (s.sigma <= r.sigma * (1 + 1e-12)).all(), (s.sigma / r.sigma).max(axis=(0, 1))
    assert (s.sigma[..., 3:6] < 0.9 * r.sigma[..., 3:6]).any()


@pytest.mark.parametrize("formulation", ["invariant", "classic"])
def test_a_monte_carlo_ending_off_the_step_grid_has_smoothed_sigma_to_its_end(
    formulation,
) -> None:
    """A run of 30.37 s (off the DVL's and the 0.1 s step's grid) recorded at every
    sample: the close that brings its last step up to date is kept with the others, so
    σ is finite at its last epochs too (they were NaN: that close was lost)."""
    segments = [pronet.Segment(20.0), pronet.Segment(10.37, yaw_rate=0.02)]
    trajectory = pronet.trajectory_from_segments(segments, lla0=(0.5, 0.1, -10.0), speed0=1.0)
    r = pronet.monte_carlo(
        trajectory, pronet.Strategy.constant([1e-4] * 3 + [1e-6] * 3),
        config=pronet.FilterConfig(formulation=formulation, covariance_step=0.1),
        n_runs=1, seed=0, record_every=1, smooth=True,
    )  # fmt: skip
    s = r.smoothed
    assert s is not None and s.sigma.shape[1] == trajectory.n_samples + 1
    assert np.isfinite(s.sigma).all()
    assert (s.sigma <= r.sigma * (1 + 1e-12)).all()
