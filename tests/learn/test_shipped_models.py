"""The paper's weights shipped inside the package: they load by name, were trained on
the dataset their card names, and reproduce their card's test scores on a regenerated
test split (the models for real sensor grades: ``test_grade_models.py``)."""

from __future__ import annotations

import numpy as np
import pytest

from pronet.learn import models, training
from pronet.learn.dataset import DatasetParams, dataset_sha256

#: Why no test here is in the fast tier (tests/test_tiers.py).
ALL_SLOW_REASON = "every test scores the shipped nets on the regenerated default dataset (~20 s)"
pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def reports(default_dataset):
    return {
        name: training.test_report(models.load(name), default_dataset)
        for name in models.PAPER_MODELS
    }


@pytest.mark.parametrize("name", models.PAPER_MODELS)
def test_shipped_model_reproduces_its_card(name, default_dataset, reports) -> None:
    model = models.load(name)
    card = model.card
    assert card["kind"] == name.removeprefix("paper-")
    # The card names the dataset by parameters and hash; regenerating it gives those bytes.
    assert DatasetParams(**card["dataset"]["params"]) == DatasetParams()
    assert dataset_sha256(default_dataset) == card["dataset"]["sha256"]
    got, want = reports[name], card["test"]
    assert got["n_test"] == want["n_test"] == 14_400
    for key in ("rmse", "mae", "r2"):
        assert got["model"][key] == pytest.approx(want["model"][key], rel=1e-5), key
        assert got["detrended_variance"][key] == pytest.approx(
            want["detrended_variance"][key], rel=1e-12
        )
    assert got["cramer_rao_rmse"] == pytest.approx(want["cramer_rao_rmse"], rel=1e-12)


def test_detrend_net_meets_the_reference(reports) -> None:
    detrend, baseline = reports["paper-detrend"]["model"], reports["paper-baseline"]["model"]
    reference = reports["paper-detrend"]["detrended_variance"]
    assert detrend["rmse"] <= 1.2 * reference["rmse"]
    assert detrend["rmse"] < baseline["rmse"]


def test_predictions_track_the_labels(default_dataset) -> None:
    test = ~default_dataset.train
    for name in models.PAPER_MODELS:
        pred = models.load(name).predict(default_dataset.windows[test])
        for level in np.unique(default_dataset.q)[[0, 7, 14]]:
            mean = pred[default_dataset.q[test] == level].mean()
            assert mean == pytest.approx(level, rel=0.1, abs=5e-4), (name, level)
