"""The noise regressors: window statistics, the two CNNs, the HCF ensemble, training."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch
from scipy import stats

from pronet.learn import windowstats
from pronet.learn.dataset import Dataset
from pronet.learn.hcf import HCFEnsemble, TreeSet
from pronet.learn.models import BaselineNet, DetrendedVariance, DetrendNet, Regressor
from pronet.learn.training import NetTraining, scores, train_net


def test_detrend_removes_exactly_a_line_and_the_variance_is_unbiased() -> None:
    rng = np.random.default_rng(1)
    t = np.arange(200.0)
    line = 3.0 - 0.02 * t
    np.testing.assert_allclose(windowstats.detrend(line), 0.0, atol=1e-12)
    noise = rng.standard_normal((20_000, 200)) * np.sqrt(0.02)
    # A line added to the noise changes nothing after detrending.
    np.testing.assert_allclose(
        windowstats.detrend(noise + line), windowstats.detrend(noise), atol=1e-12
    )
    v = windowstats.detrended_variance(noise + line)
    assert v.mean() / 0.02 == pytest.approx(1.0, abs=4 * np.sqrt(2 / 198 / 20_000))
    # Its spread is the N − 2 dof chi-square one: q·√(2/(N − 2)).
    assert v.std() / 0.02 == pytest.approx(np.sqrt(2 / 198), rel=0.03)
    assert windowstats.cramer_rao_rmse([0.02], 200) == pytest.approx(0.02 * np.sqrt(2 / 200))


def test_features_agree_with_scipy_and_numpy() -> None:
    w = np.random.default_rng(2).standard_normal((5, 200)) + np.linspace(0, 1, 200)
    f = windowstats.features(w)
    assert f.shape == (5, 14) == (5, len(windowstats.FEATURE_NAMES))
    for block, x in ((f[:, :7], w), (f[:, 7:], windowstats.detrend(w))):
        np.testing.assert_allclose(block[:, 0], x.var(axis=1, ddof=1))
        np.testing.assert_allclose(block[:, 1], x.std(axis=1, ddof=1))
        np.testing.assert_allclose(block[:, 2], np.ptp(x, axis=1))
        mad = np.abs(x - x.mean(axis=1, keepdims=True)).mean(axis=1)
        np.testing.assert_allclose(block[:, 3], mad)
        np.testing.assert_allclose(block[:, 4], np.sqrt((np.diff(x, axis=1) ** 2).mean(axis=1)))
        np.testing.assert_allclose(block[:, 5], stats.skew(x, axis=1))
        np.testing.assert_allclose(block[:, 6], stats.kurtosis(x, axis=1))
    # A constant window has no shape: zeros, not NaN.
    assert np.all(np.isfinite(windowstats.features(np.ones((1, 200)))))


@pytest.mark.parametrize("cls", [BaselineNet, DetrendNet])
def test_nets_are_small_and_map_any_batch_shape(cls) -> None:
    torch.manual_seed(0)
    net = cls()
    assert net.n_parameters() < 100_000
    q = net.predict(np.random.default_rng(0).standard_normal((3, 6, 200)) * 0.1)
    assert q.shape == (3, 6) and q.dtype == np.float64 and np.all(q > 0)
    with pytest.raises(ValueError, match="windows: this model reads windows of 200"):
        net.predict(np.zeros((6, 100)))
    with pytest.raises(ValueError, match="windows: expected real numbers"):
        net.predict(np.full((6, 200), "a"))


def test_detrend_happens_inside_forward() -> None:
    torch.manual_seed(0)
    noise = np.random.default_rng(3).standard_normal((8, 200)) * 0.1
    line = 9.81 + 0.004 * np.arange(200)  # an offset and a ramp of 0.8 over the window
    detrend, baseline = DetrendNet(), BaselineNet()
    detrend.load_state_dict(baseline.state_dict())  # the same weights
    # The detrend net is the baseline net on detrended windows, and blind to the line.
    np.testing.assert_allclose(
        detrend.predict(noise + line), baseline.predict(windowstats.detrend(noise)), rtol=1e-4
    )
    np.testing.assert_allclose(detrend.predict(noise + line), detrend.predict(noise), rtol=1e-4)
    # The baseline net centres its input (an offset is invisible) but sees the ramp.
    x = torch.from_numpy(noise + line).float()
    np.testing.assert_allclose(
        baseline.prepare(x).numpy(),
        noise - noise.mean(axis=1, keepdims=True) + line - line.mean(),
        atol=1e-5,
    )


def test_every_regressor_fits_the_protocol() -> None:
    for model in (BaselineNet(), DetrendNet(), DetrendedVariance()):
        assert isinstance(model, Regressor)


def test_hcf_tree_walk_equals_scikit_learn() -> None:
    from sklearn.ensemble import GradientBoostingRegressor, RandomForestRegressor

    rng = np.random.default_rng(4)
    q = rng.choice(np.linspace(0.001, 0.05, 15), 600)
    w = rng.standard_normal((600, 200)) * np.sqrt(q)[:, None]
    model = HCFEnsemble.fit(w, q, gb_trees=20, rf_trees=10, rf_depth=6)
    x = windowstats.features(w)
    gb = GradientBoostingRegressor(n_estimators=20, max_depth=3, random_state=0).fit(x, q)
    rf = RandomForestRegressor(
        n_estimators=10, max_depth=6, min_samples_leaf=10, random_state=0, n_jobs=1
    ).fit(x, q)
    np.testing.assert_allclose(
        model.predict(w), 0.5 * gb.predict(x) + 0.5 * rf.predict(x), rtol=1e-12
    )
    assert isinstance(model, Regressor)
    assert model.predict(w.reshape(2, 300, 200)).shape == (2, 300)
    bad = w[:2].copy()
    bad[0, 5] = np.nan
    out = model.predict(bad)
    assert np.isnan(out[0]) and np.isfinite(out[1])


def test_tree_check_rejects_a_cycle(tmp_path) -> None:
    trees = TreeSet(
        left=np.array([1, -1, -1], np.int32),
        right=np.array([2, -1, -1], np.int32),
        feature=np.zeros(3, np.int32),
        threshold=np.zeros(3),
        value=np.arange(3.0),
        roots=np.array([0], np.int32),
    )
    trees.check(14, tmp_path / "m")  # valid
    looped = dataclasses.replace(trees, right=np.array([0, -1, -1], np.int32))
    with pytest.raises(ValueError, match="not valid trees"):
        looped.check(14, tmp_path / "m")


def _subset(ds: Dataset, idx: np.ndarray) -> Dataset:
    return Dataset(*(getattr(ds, f.name)[idx] for f in dataclasses.fields(Dataset)))


@pytest.mark.slow
def test_small_training_run_lowers_the_loss(default_dataset) -> None:
    rng = np.random.default_rng(5)
    small = _subset(
        default_dataset, np.sort(rng.choice(default_dataset.q.size, 400, replace=False))
    )
    hp = NetTraining(max_epochs=2, patience=10, batch_size=32)
    net, history = train_net("detrend", small, hp, progress=False)
    assert len(history) == 2
    assert history[1]["train_loss"] < history[0]["train_loss"]
    # Deterministic: the same seed trains the same weights.
    again, _ = train_net("detrend", small, hp, progress=False)
    for a, b in zip(net.state_dict().values(), again.state_dict().values(), strict=True):
        assert torch.equal(a, b)


def test_scores() -> None:
    q = np.array([1.0, 2.0, 3.0])
    s = scores(q + np.array([0.1, -0.1, 0.0]), q)
    assert s["rmse"] == pytest.approx(np.sqrt(0.02 / 3))
    assert s["mae"] == pytest.approx(0.2 / 3)
    assert s["r2"] == pytest.approx(1 - 0.02 / 2)


@pytest.mark.slow
def test_training_refuses_bad_hyperparameters_and_leaves_torch_as_it_was(default_dataset) -> None:
    before = torch.are_deterministic_algorithms_enabled()
    with pytest.raises(ValueError, match="max_epochs: must be at least 1"):
        NetTraining(max_epochs=0)  # refused when made, before any training
    with pytest.raises(ValueError, match="kind: expected one of"):
        train_net("cnn", default_dataset, progress=False)
    assert torch.are_deterministic_algorithms_enabled() == before
