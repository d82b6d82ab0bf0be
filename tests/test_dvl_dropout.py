"""The simulated DVL's random bottom-lock loss (``SensorConfig(dvl_dropout=...)``):
missed updates counted, NaN at their epochs, the same for any thread
count, and nothing changed when unset."""

from __future__ import annotations

import numpy as np
import pytest

import pronet
from pronet import _core
from pronet.config import ConfigError, sensor_config

from conftest import PAPER_Q


def _mc(trajectory, sensors, threads=1, n_runs=6):
    return pronet.monte_carlo(
        trajectory,
        _core.Strategy.constant(PAPER_Q),
        sensors=sensors,
        n_runs=n_runs,
        seed=4,
        threads=threads,
    )


def test_dropout_misses_updates_the_same_way_for_any_thread_count(paper_trajectory):
    sensors = _core.SensorConfig(dvl_dropout=(60.0, 20.0))
    assert sensors.dvl_dropout == (60.0, 20.0)
    one, two = _mc(paper_trajectory, sensors, 1), _mc(paper_trajectory, sensors, 2)
    for name in ("srmse", "nis", "missed_updates", "mean_nis"):
        np.testing.assert_array_equal(getattr(one, name), getattr(two, name))
    m = one.nis.shape[1]
    assert (one.missed_updates == np.isnan(one.nis).sum(axis=1)).all()
    # about a quarter of the epochs lost (20 s of every 80 s), run by run different
    share = one.missed_updates.sum() / (one.n_runs * m)
    assert 0.1 < share < 0.45, share
    assert len(set(one.missed_updates.tolist())) > 1
    assert np.isnan(one.nees[np.isnan(one.nis)]).all()
    assert np.isfinite(one.mean_nis).all() and np.isfinite(one.velocity_nees).all()
    assert 0.0 <= one.nees_in_band("velocity") <= 1.0
    assert one.to_dataframe()["missed_updates"].tolist() == one.missed_updates.tolist()


def test_unset_dropout_changes_nothing_and_keeps_the_other_noise(paper_trajectory):
    plain = _mc(paper_trajectory, _core.SensorConfig())
    assert _core.SensorConfig().dvl_dropout is None
    assert (plain.missed_updates == 0).all()
    # the epochs a dropout keeps see the same DVL noise (its stream is its own): until
    # the first lost reading, the runs are bit for bit the same
    lossy = _mc(paper_trajectory, _core.SensorConfig(dvl_dropout=(60.0, 20.0)))
    assert (lossy.missed_updates > 0).any()
    compared = 0
    for run in range(plain.n_runs):
        lost = np.isnan(lossy.nis[run])
        first_lost = int(np.argmax(lost)) if lost.any() else lost.size
        np.testing.assert_array_equal(lossy.nis[run, :first_lost], plain.nis[run, :first_lost])
        compared += first_lost
    assert compared > 0  # some epochs were compared at all


def test_dropout_from_a_scenario_file_and_bad_values_named():
    base = _core.SensorConfig()
    got = sensor_config({"dvl_dropout": [120, 15.5]}, "s.toml: [sensors]", base)
    assert got.dvl_dropout == (120.0, 15.5)
    with pytest.raises(ConfigError, match=r"dvl_dropout: needs \[mean_interval, mean_length\]"):
        sensor_config({"dvl_dropout": [0, 1]}, "s.toml: [sensors]", base)
    with pytest.raises(ValueError, match="dvl_dropout"):
        _core.SensorConfig(dvl_dropout=(1.0, 2.0, 3.0))
