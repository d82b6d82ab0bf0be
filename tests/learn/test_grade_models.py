"""Regressors for real sensor grades: the log-uniform dataset, scale-free nets and HCF
ensemble, log10 scores, and the shipped models (``baseline``, ``detrend``, ``hcf``)
against the detrended variance in every decade."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from pronet.learn import models, training
from pronet.learn.dataset import GRADES, DatasetParams, build_dataset, dataset_sha256
from pronet.learn.hcf import HCFEnsemble
from pronet.learn.windowstats import detrended_variance


@pytest.fixture(scope="module")
def grades():
    return build_dataset(GRADES)


def test_the_grade_dataset_spans_each_sensors_decades(grades) -> None:
    accel, gyro = grades.q[grades.channel < 3], grades.q[grades.channel >= 3]
    assert 1e-7 <= accel.min() and accel.max() <= 1e-1
    assert 1e-10 <= gyro.min() and gyro.max() <= 1e-2
    # log-uniform: every decade holds about its share of the windows
    counts = np.histogram(np.log10(accel), bins=np.arange(-7, 0))[0]
    assert counts.min() > 0.8 * accel.size / 6
    # one window, one label: the window's sample variance follows its own q
    quiet = (grades.channel == 3) & (grades.q < 1e-9)
    assert np.median(detrended_variance(grades.windows[quiet]) / grades.q[quiet]) < 100
    with pytest.raises(ValueError, match="spacing"):
        DatasetParams(spacing="cubic").validate()
    with pytest.raises(ValueError, match="gyro_q_min"):
        DatasetParams(gyro_q_min=0.0).validate()


def test_the_paper_dataset_is_unchanged() -> None:
    card = models.load("paper-detrend").card
    assert dataset_sha256(build_dataset(DatasetParams())) == card["dataset"]["sha256"]


@pytest.mark.parametrize("kind", ["baseline", "detrend"])
def test_a_spread_net_is_scale_free_and_starts_at_the_windows_variance(kind) -> None:
    torch.manual_seed(0)
    net = models.NETS[kind](scaling="spread")
    w = np.random.default_rng(1).standard_normal((4, 200)).astype(np.float32)
    prepared = net.prepare(torch.from_numpy(w)).numpy()
    np.testing.assert_allclose(net.predict(w), (prepared**2).mean(axis=1), rtol=1e-5)
    with torch.no_grad():  # any head: q scales with the window's square
        net.head[-1].weight.normal_()
        net.head[-1].bias.fill_(0.3)
    for c in (1e-4, 1e3):
        np.testing.assert_allclose(net.predict(w * c), c * c * net.predict(w), rtol=1e-4)
    assert net.architecture()["scaling"] == "spread"
    with pytest.raises(ValueError, match="scaling"):
        models.NETS[kind](scaling="loud")


def test_log_scores_count_a_miss_by_decade() -> None:
    q = np.array([1e-8, 2e-8, 1e-3])
    s = training.log_scores(np.array([1e-7, 2e-8, np.nan]), q)
    assert s["log10_rmse_by_decade"] == pytest.approx({"-8": np.sqrt(0.5), "-3": 10.0})
    assert s["log10_rmse"] == pytest.approx(np.sqrt(101 / 3))


def test_a_log_ratio_hcf_regresses_over_decades_and_round_trips(tmp_path, grades) -> None:
    take = np.flatnonzero(grades.train)[:3000]
    model = HCFEnsemble.fit(
        grades.windows[take], grades.q[take], gb_trees=20, rf_trees=5, target="log-ratio"
    )
    test = np.flatnonzero(~grades.train)[:2000]
    pred = model.predict(grades.windows[test])
    assert np.median(np.abs(np.log10(pred / grades.q[test]))) < 0.2
    model.save(tmp_path / "h", {})
    back = models.load(tmp_path / "h")
    assert back.target == "log-ratio"
    np.testing.assert_array_equal(back.predict(grades.windows[test]), pred)
    assert models.load("paper-hcf").target == "q"  # a card without a target regresses q


@pytest.mark.slow
@pytest.mark.parametrize("name", models.GRADE_MODELS)
def test_shipped_grade_models_beat_the_detrended_variance_in_every_decade(name, grades) -> None:
    model = models.load(name)
    card = model.card
    assert DatasetParams(**card["dataset"]["params"]) == GRADES
    assert dataset_sha256(grades) == card["dataset"]["sha256"]
    got = training.test_report(model, grades)
    want = card["test"]
    assert got["model"]["log10_rmse"] == pytest.approx(want["model"]["log10_rmse"], rel=1e-4)
    mine, ref = got["model"], got["detrended_variance"]
    assert mine["log10_rmse"] <= ref["log10_rmse"]
    for decade, rmse in mine["log10_rmse_by_decade"].items():
        assert rmse <= 1.2 * ref["log10_rmse_by_decade"][decade], (name, decade)
