"""The 72,000-window training set: counts, split, labels, determinism, safe loading."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest

import pronet
from pronet import cli
from pronet.learn.dataset import (
    TRAINING_TRAJECTORIES,
    DatasetParams,
    build_dataset,
    load_dataset,
    save_dataset,
)


@pytest.fixture(scope="module")
def ds():
    return build_dataset(DatasetParams(seed=7))


def test_counts_and_split(ds) -> None:
    assert ds.windows.shape == (72_000, 200) and ds.windows.dtype == np.float32
    assert (ds.n_train, ds.n_test) == (57_600, 14_400)
    for t in range(4):
        on = ds.trajectory == t
        assert ds.train[on].sum() == 14_400 and (~ds.train[on]).sum() == 3_600
    levels = np.unique(ds.q)
    np.testing.assert_allclose(levels, np.linspace(0.001, 0.05, 15))
    # Every (trajectory, level, channel) has 200 windows covering the 40,000 samples.
    key = (ds.trajectory.astype(int) * 15 + np.searchsorted(levels, ds.q)) * 6 + ds.channel
    assert np.bincount(key).tolist() == [200] * (4 * 15 * 6)
    assert sorted(np.unique(ds.start).tolist()) == list(range(0, 40_000, 200))


def test_windows_are_ideal_imu_plus_noise_of_the_label_variance(ds) -> None:
    ideal = {t: pronet.builtin_trajectory(n).imu for t, n in enumerate(TRAINING_TRAJECTORIES)}
    rng = np.random.default_rng(0)
    for i in rng.choice(ds.q.size, 20, replace=False):
        s, c, t = ds.start[i], ds.channel[i], ds.trajectory[i]
        noise = ds.windows[i] - ideal[t][s : s + 200, c]
        assert noise.var() == pytest.approx(ds.q[i], rel=0.35)
    # Averaged over a level, the detrended window variance is the label.
    x = np.arange(200.0)
    for q in np.unique(ds.q)[[0, 7, 14]]:
        w = ds.windows[ds.q == q].astype(np.float64)
        coef = np.polynomial.polynomial.polyfit(x, w.T, 1)
        resid = w - np.polynomial.polynomial.polyval(x, coef)
        assert (resid**2).sum(axis=1).mean() / 198 == pytest.approx(q, rel=0.02)


@pytest.mark.slow
def test_same_seed_same_bytes_and_different_seed_differs(tmp_path) -> None:
    a = save_dataset(
        build_dataset(DatasetParams(seed=3)), tmp_path / "a.npz", DatasetParams(seed=3)
    )
    b = save_dataset(
        build_dataset(DatasetParams(seed=3)), tmp_path / "b.npz", DatasetParams(seed=3)
    )
    c = save_dataset(
        build_dataset(DatasetParams(seed=4)), tmp_path / "c.npz", DatasetParams(seed=4)
    )
    assert a.read_bytes() == b.read_bytes()
    assert a.read_bytes() != c.read_bytes()
    card = json.loads(a.with_suffix(".json").read_text())
    assert card["sha256"] == hashlib.sha256(a.read_bytes()).hexdigest()
    assert card["params"]["seed"] == 3 and card["spacing"] == "linear"
    assert (card["n_train"], card["n_test"]) == (57_600, 14_400)
    loaded = load_dataset(a)
    np.testing.assert_array_equal(loaded.windows, build_dataset(DatasetParams(seed=3)).windows)


def test_load_refuses_tampered_or_unlabelled_files(tmp_path) -> None:
    params = DatasetParams(seed=1)
    path = save_dataset(build_dataset(params), tmp_path / "d.npz", params)
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.raises(ValueError, match="hash"):
        load_dataset(path)
    path.with_suffix(".json").unlink()
    with pytest.raises(ValueError, match="card"):
        load_dataset(path)


@pytest.mark.parametrize(
    ("params", "arg"),
    [
        (DatasetParams(seed=-1), "seed"),
        (DatasetParams(n_levels=0), "n_levels"),
        (DatasetParams(q_min=0.0), "q_min"),
        (DatasetParams(window=1), "window"),
        (DatasetParams(train_fraction=1.0), "train_fraction"),
    ],
)
def test_bad_parameters_name_the_argument(params, arg) -> None:
    with pytest.raises(ValueError, match=rf"^{arg}"):
        build_dataset(params)


def test_cli_writes_dataset_and_card(tmp_path, capsys) -> None:
    out = tmp_path / "ds.npz"
    assert cli.main(["dataset", "--out", str(out), "--seed", "5"]) == 0
    assert out.exists() and out.with_suffix(".json").exists()
    assert "72000 examples" in capsys.readouterr().out
    assert cli.main(["dataset", "--out", str(out)]) == 2  # never overwrites


def test_dataset_size_is_bounded_before_anything_is_built(monkeypatch) -> None:
    from pronet import _core
    from pronet.learn import dataset

    for name in dataset.TRAINING_TRAJECTORIES:  # the bound's arithmetic holds
        assert _core.builtin_trajectory(name, 0.01).n_samples == dataset.TRAJECTORY_SAMPLES

    def must_not_build(*args, **kwargs):
        raise AssertionError("a trajectory was generated")

    monkeypatch.setattr(dataset._core, "builtin_trajectory", must_not_build)
    too_many = r"^n_levels: 100000 levels make 357\.6 GiB .* \(1118 levels\)"
    with pytest.raises(ValueError, match=too_many):
        dataset.build_dataset(dataset.DatasetParams(n_levels=100_000))
    dataset.DatasetParams(n_levels=1118).validate()
