"""Reliability: the innovation gate against DVL outliers, divergence detection from the
NIS, and Monte Carlo shards identical to the whole."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import pronet
from pronet.run import run
from pronet.sim.scenarios import SCENARIOS

from conftest import PAPER_Q

DVL_SIGMA = 0.1  # [m/s], R = 0.01 (m/s)², the paper's
GATE = 16.27  # χ²(3) 99.9 % quantile
#: A filter whose bias walk matches an IMU with almost none, so that a good DVL matters.
MATCHED = dict(accel_bias_psd=1e-10, gyro_bias_psd=1e-14, dvl_variance=(DVL_SIGMA**2,) * 3)


def _recording(seed: int, spike_every: int):
    """120 s of the paper trajectory: noisy IMU, 1 Hz NED DVL with a 10σ spike on one
    axis every ``spike_every``-th reading. Returns the run_filter arguments and the
    truth velocity at each epoch."""
    traj = pronet.builtin_trajectory("paper")
    n = 12_000
    rng = np.random.default_rng(seed)
    imu = traj.imu[:n] + rng.normal(size=(n, 6)) * np.sqrt(PAPER_Q)
    k = np.arange(100, n + 1, 100)
    dvl = traj.vel_ned[k] + rng.normal(size=(k.size, 3)) * DVL_SIGMA
    spikes = np.arange(spike_every - 1, k.size, spike_every)
    axis = rng.integers(0, 3, spikes.size)
    dvl[spikes, axis] += 10 * DVL_SIGMA * rng.choice([-1.0, 1.0], spikes.size)
    args = dict(
        imu=imu,
        imu_time=traj.time[1 : n + 1],
        streams=[pronet.Dvl(traj.time[k], dvl)],  # NED: the configs' aiding="nav"
        t0=traj.time[0],
        lla0=traj.lla[0],
        vel0=traj.vel_ned[0],
        rpy0=traj.rpy[0],
        strategy=pronet.Strategy.constant(PAPER_Q),
    )
    return args, traj.vel_ned[: n + 1], spikes


def _velocity_rmse(out: pronet.FilterResult, truth: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((out.vel - truth) ** 2, axis=1))))


def test_innovation_gate_rejects_ten_sigma_spikes_and_keeps_the_error_bounded() -> None:
    args, truth, spikes = _recording(seed=5, spike_every=7)
    clean_args, _, _ = _recording(seed=5, spike_every=10**6)  # same noise, no spikes

    def run(data, gate):
        config = pronet.FilterConfig(aiding="nav", innovation_gate=gate, **MATCHED)
        return pronet.run_filter(**data, config=config)

    clean = _velocity_rmse(run(clean_args, None), truth)
    gated_out = run(args, GATE)
    gated = _velocity_rmse(gated_out, truth)
    ungated = _velocity_rmse(run(args, None), truth)
    # The gate rejects (nearly) every spike and (nearly) nothing else.
    rejected = np.flatnonzero(~gated_out.accepted)
    assert np.isin(spikes, rejected).mean() >= 0.9
    assert np.setdiff1d(rejected, spikes).size <= 2
    # Bounded: the spikes barely move the gated error off the clean one; without the
    # gate it is measurably worse.
    assert gated < 1.2 * clean, (clean, gated)
    assert ungated > 1.5 * gated, (gated, ungated)
    # Off by default: every reading is applied.
    assert pronet.FilterConfig().innovation_gate is None
    assert run(args, None).accepted.all()


def test_the_gate_is_counted_in_a_monte_carlo(paper_trajectory) -> None:
    """A tight gate rejects consistent readings too; the count is reported per run."""
    common = dict(n_runs=3, seed=1)
    loose = pronet.monte_carlo(paper_trajectory, pronet.Strategy.constant(PAPER_Q), **common)
    tight = pronet.monte_carlo(
        paper_trajectory,
        pronet.Strategy.constant(PAPER_Q),
        config=pronet.FilterConfig(innovation_gate=0.5),
        **common,
    )
    assert (loose.rejected_updates == 0).all()
    assert (tight.rejected_updates > 0).all()
    assert tight.nis.shape == loose.nis.shape  # rejected epochs keep their NIS


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_gate_is_a_value_error(bad) -> None:
    with pytest.raises(ValueError, match="innovation_gate"):
        pronet.FilterConfig(innovation_gate=bad)


def test_divergence_is_detected_from_the_nis_and_reported(paper_trajectory) -> None:
    """A filter that believes its DVL 100× better than it is (σ 1 mm/s against 0.1 m/s)
    sees innovations ~100 of its σ: every run is flagged, early. The matched filter is
    never flagged."""
    common = dict(n_runs=4, seed=2)
    strategy = pronet.Strategy.constant(PAPER_Q)
    healthy = pronet.monte_carlo(paper_trajectory, strategy, **common)
    overconfident = pronet.monte_carlo(
        paper_trajectory, strategy, config=pronet.FilterConfig(dvl_variance=(1e-6,) * 3), **common
    )
    assert healthy.n_diverged == 0 and np.isnan(healthy.diverged_at).all()
    assert overconfident.n_diverged == 4
    assert (overconfident.diverged_at <= 25.0).all()  # 20 updates at 1 Hz, and a few
    # run_filter reports it too.
    args, _, _ = _recording(seed=3, spike_every=10**6)
    out = pronet.run_filter(
        **args, config=pronet.FilterConfig(aiding="nav", dvl_variance=(1e-6,) * 3)
    )
    assert out.diverged_at is not None and out.diverged_at <= 25.0
    ok = pronet.run_filter(**args, config=pronet.FilterConfig(aiding="nav", **MATCHED))
    assert ok.diverged_at is None


def test_shards_are_bit_identical_to_the_whole(paper_trajectory) -> None:
    strategy = pronet.Strategy.mehra(5, PAPER_Q)
    whole = pronet.monte_carlo(paper_trajectory, strategy, n_runs=5, seed=11, threads=2)
    parts = [
        pronet.monte_carlo(
            paper_trajectory, strategy, n_runs=n, seed=11, first_run=first, threads=1
        )
        for first, n in ((0, 2), (2, 1), (3, 2))
    ]
    for name in ("srmse", "smae", "mean_nis", "max_horizontal_error", "nis", "nees"):
        joined = np.concatenate([getattr(p, name) for p in parts])
        assert np.array_equal(joined, getattr(whole, name), equal_nan=True), name


def test_bad_first_run_is_a_value_error(paper_trajectory) -> None:
    for bad in (-1, 2**64, 1.5):
        with pytest.raises(ValueError, match="first_run"):
            pronet.monte_carlo(
                paper_trajectory, pronet.Strategy.constant(PAPER_Q), n_runs=1, first_run=bad
            )


def test_a_shard_round_trips_exactly_and_other_settings_are_refused(
    tmp_path, paper_trajectory
) -> None:
    from pronet.learn.hybrid import ConstantRegressor, run_hybrid
    from pronet.shards import ShardStore

    store = ShardStore(tmp_path / "s", {"n_runs": 2, "seed": 4})
    mc = pronet.monte_carlo(
        paper_trajectory, pronet.Strategy.mehra(1, PAPER_Q), n_runs=2, seed=4, record_every=500
    )
    hybrid = run_hybrid(
        ConstantRegressor(PAPER_Q), paper_trajectory, prior_q=PAPER_Q, n_runs=2, seed=4
    )
    store.save("paper", "mehra xi=1", mc, None)
    store.save("paper", "net / 1 s", hybrid.result, hybrid)
    again = ShardStore(tmp_path / "s", {"n_runs": 2, "seed": 4})
    assert len(again) == 2 and again.load("paper", "other") is None
    loaded, none = again.load("paper", "mehra xi=1")
    assert none is None and loaded.failure == mc.failure
    for name, value in vars(mc).items():
        if isinstance(value, np.ndarray):
            assert np.array_equal(getattr(loaded, name), value, equal_nan=True), name
    result, h = again.load("paper", "net / 1 s")
    assert h.n_tunings == hybrid.n_tunings and np.array_equal(h.clipped, hybrid.clipped)
    assert np.array_equal(result.srmse, hybrid.result.srmse)
    with pytest.raises(ValueError, match="^resume"):
        ShardStore(tmp_path / "s", {"n_runs": 3, "seed": 4})


def test_smooth_takes_numpy_bools_and_refuses_ints_in_one_line() -> None:
    """``smooth=np.True_`` was "expected a bool, got bool" in run_filter, ``smooth=1`` a
    bare TypeError in monte_carlo: a NumPy bool is a bool, a number is refused naming
    ``smooth`` (:func:`pronet._util.validate.flag`), in every call that takes it."""
    traj = pronet.trajectory_from_segments(
        np.array([[3.0, 0.0, 0.0, 0.0]]), lla0=(0.56, 0.59, -5.0), speed0=1.0
    )
    args, _, _ = _recording(0, 1000)
    dvl = args["streams"][0]
    short = {**args, "imu": args["imu"][:300], "imu_time": args["imu_time"][:300]}
    short["streams"] = [pronet.Dvl(dvl.time[:3], dvl.velocity[:3])]
    scenario = replace(SCENARIOS["paper"](0), trajectory=traj)
    calls = {
        "run_filter": lambda s: pronet.run_filter(**short, smooth=s),
        "monte_carlo": lambda s: pronet.monte_carlo(
            traj, pronet.Strategy.constant(PAPER_Q), n_runs=1, smooth=s
        ),
        "Ensemble": lambda s: pronet.Ensemble(traj, PAPER_Q, n_runs=1, window=10, smooth=s),
        "run": lambda s: run(pronet.Strategy.constant(PAPER_Q), scenario, n_runs=1, smooth=s),
    }
    for name, call in calls.items():
        call(np.True_)
        call(np.False_)
        for wrong in (1, 0, "yes", None, np.int64(1)):
            with pytest.raises(ValueError, match=r"^smooth: expected True or False, got ") as e:
                call(wrong)
            assert "\n" not in str(e.value), name
