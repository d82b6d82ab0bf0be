"""pronet.stats' intervals and bands: exact quantiles (scipy.stats), checked against
published tables and by simulation where the approximations they replaced were off."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pronet import stats
from pronet.montecarlo import chance_bound


@pytest.mark.parametrize(
    ("df", "table"),
    # Student's t, 97.5 % (e.g. Abramowitz & Stegun table 26.10, to the digits shown)
    [(1, 12.7062047), (3, 3.1824463), (4, 2.7764451), (9, 2.2621572), (99, 1.9842169)],
)
def test_t_quantile_is_the_tables(df: int, table: float) -> None:
    assert stats.t_quantile_975(df) == pytest.approx(table, abs=1e-6)


def test_chi2_band_is_the_tables() -> None:
    # χ²(3): 2.5 % and 97.5 % quantiles 0.2157953 and 9.3484036; the band of a mean over
    # two runs is χ²(6)/2: 1.2373442/2 and 14.4493753/2.
    assert stats.chi2_mean_band(3, 1) == pytest.approx((0.2157953, 9.3484036), abs=1e-6)
    assert stats.chi2_mean_band(3, 2) == pytest.approx((0.6186721, 7.2246877), abs=1e-6)


@pytest.mark.parametrize(("dof", "runs"), [(1, 1), (3, 1), (1, 3)])
def test_chi2_band_holds_95_percent_of_means(dof: int, runs: int) -> None:
    # Few degrees of freedom, where an approximation of the quantiles is worst (the
    # Wilson-Hilferty band this replaced put χ²(1)'s lower edge below zero).
    rng = np.random.default_rng(7)
    means = rng.chisquare(dof, size=(400_000, runs)).mean(axis=1)
    low, high = stats.chi2_mean_band(dof, runs)
    assert np.mean(means < low) == pytest.approx(0.025, abs=0.0015)
    assert np.mean(means > high) == pytest.approx(0.025, abs=0.0015)


def test_t_interval_covers_the_mean_95_percent_of_the_time() -> None:
    rng = np.random.default_rng(3)
    samples = rng.normal(5.0, 2.0, size=(20_000, 4))
    covered = 0
    for x in samples:
        ci = stats.mean_ci(x)
        assert ci.method == "t"
        covered += ci.low <= 5.0 <= ci.high
    assert covered / len(samples) == pytest.approx(0.95, abs=0.005)


def test_bootstrap_interval_stays_in_range_and_is_reproducible() -> None:
    shares = np.array([1.0, 1.0, 0.98, 1.0, 0.5])  # a t-interval would pass 1
    ci = stats.mean_ci(shares, within=stats.SHARE)
    assert ci.method == "bootstrap" and ci.low <= ci.mean <= ci.high <= 1.0
    assert ci.low >= shares.min()
    assert stats.mean_ci(shares, within=stats.SHARE) == ci  # a fixed seed


@pytest.mark.parametrize("n", [1, 2, 10, 100, 1000])
def test_chance_bound_is_the_smallest_k_at_the_level(n: int) -> None:
    def cdf(k: int) -> float:
        return sum(math.comb(n, i) * 0.05**i * 0.95 ** (n - i) for i in range(k + 1))

    k = chance_bound(n)
    assert cdf(k) >= 0.99 and (k == 0 or cdf(k - 1) < 0.99)


def test_bools_are_not_counts() -> None:
    assert stats.t_quantile_975(1) > 12
    with pytest.raises(ValueError, match="df"):
        stats.t_quantile_975(True)


def test_the_divergence_read_from_the_arrays_names_the_first_epoch_and_bound() -> None:
    # Each bound broken alone, at a random epoch, and NaN σ (not computed) beside them.
    rng = np.random.default_rng(11)
    n = 500
    breaks = [
        ("lla", (0,), np.nan), ("vel", (2,), np.inf), ("vel", (0,), 150.0),
        ("lla", (2,), -3e4), ("sigma", (1,), 2e6), ("sigma", (0,), np.nan),
    ]  # fmt: skip
    for trial in range(60):
        arrays = {
            "lla": rng.normal(size=(n, 3)),
            "vel": rng.normal(size=(n, 3)),
            "sigma": np.abs(rng.normal(size=(n, 15))),
        }
        for name, (col,), value in [breaks[i] for i in rng.choice(6, size=trial % 3)]:
            arrays[name][rng.integers(n), col] = value
        lla, vel, sigma = arrays["lla"], arrays["vel"], arrays["sigma"]
        masks = (
            ~np.isfinite(lla).all(axis=1) | ~np.isfinite(vel).all(axis=1),
            np.linalg.norm(vel, axis=1) > stats.MAX_SPEED,
            np.abs(lla[:, 2]) > stats.MAX_ABS_HEIGHT,
            np.hypot(sigma[:, 0], sigma[:, 1]) > stats.MAX_POSITION_SIGMA,
        )
        broken = any(m.any() for m in masks)
        time = np.arange(n) * 0.1
        message = stats.divergence(stats.Extent.of(lla, vel, sigma, time))
        assert (message != "") == broken, (trial, message)
        if broken:
            first, bound = min((int(np.argmax(m)), i) for i, m in enumerate(masks) if m.any())
            what = list(stats.BOUNDS.values())[bound]
            assert f"its solution {what} from t = {time[first]:.6g} s:" in message
