"""Sweeps: the plan, shards that join into the whole Monte Carlo, resume, the result
folder and DataFrames, and the Ray engine giving exactly the local engine's numbers."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pandas as pd
import pytest
import ray  # noqa: F401 - in the test extras: CI must run the Ray tests, never skip them

import pronet
from pronet import config
from pronet.experiments import sweep
from pronet.shards import ShardStore

#: A 40 s scenario keeps every sweep here to seconds.
SHORT = """
[trajectory]
segments = [[20, 0, 0, 0], [20, 0, 3, 0]]
"""

GRID = """
scenarios = ["short.toml"]
strategies = ["constant", "mehra:5", "learned:detrend"]
tuning_periods_s = [1.0, 2.0]
noise_levels = [1, 4]
runs = 5
shard_runs = 2
seed = 11
"""


@pytest.fixture(scope="module")
def grid(tmp_path_factory) -> config.SweepGrid:
    folder = tmp_path_factory.mktemp("grid")
    (folder / "short.toml").write_text(SHORT)
    (folder / "grid.toml").write_text(GRID)
    return config.load_sweep(folder / "grid.toml")


@pytest.fixture(scope="module")
def local(grid) -> sweep.SweepResult:
    return sweep.run_sweep(grid, engine="local", threads=2)


def arrays_equal(a: pronet.MonteCarloResult, b: pronet.MonteCarloResult) -> bool:
    names = ("srmse", "smae", "final_horizontal_error", "mean_nis", "nis", "nees", "diverged_at")
    return all(np.array_equal(getattr(a, n), getattr(b, n), equal_nan=True) for n in names)


def test_a_grid_too_big_for_memory_is_refused_before_it_is_planned(grid) -> None:
    huge = dataclasses.replace(grid, runs=10**9, shard_runs=1)  # 8e9 shards if planned
    with pytest.raises(ValueError, match=r"^grid: 8 grid points x 1000000000 runs of short: "):
        sweep.plan(huge)
    sweep.check_size(dataclasses.replace(grid, runs=1000))  # a big but sane grid passes


def test_the_plan_covers_every_grid_point_and_run_once(grid) -> None:
    shards = sweep.plan(grid)
    points = list(dict.fromkeys(s.point for s in shards))
    # 2 noise levels x (constant, mehra:5, learned:detrend at 2 tuning periods)
    assert len(points) == 2 * 4
    assert {p.tuning_period for p in points if p.strategy != "learned:detrend"} == {None}
    assert {p.tuning_period for p in points if p.strategy == "learned:detrend"} == {1.0, 2.0}
    for point in points:
        mine = [s for s in shards if s.point == point]
        runs = [r for s in mine for r in range(s.first_run, s.first_run + s.n_runs)]
        assert runs == list(range(5))  # shards of 2, 2, 1 in order
    assert len({s.point.key for s in shards}) == len(points)


def test_shards_join_into_the_whole_monte_carlo(grid, local) -> None:
    sc = grid.scenarios[0].build()
    for pr in local.points:
        if pr.point.strategy != "mehra:5" or pr.point.noise_level != 4:
            continue
        whole = pronet.monte_carlo(
            sc.trajectory,
            pronet.Strategy.mehra(5, sc.q_nominal),
            sensors=sweep.noisier(sc.sensors, 4.0),
            config=sc.config,
            n_runs=5,
            seed=11,
        )
        assert arrays_equal(pr.result, whole)
        break
    else:
        pytest.fail("no mehra:5 point at noise level 4")


def test_noise_levels_scale_what_the_imu_draws_not_what_the_filter_is_told(local) -> None:
    by_point = {(p.point.strategy, p.point.noise_level): p.result for p in local.points}
    # the constant row keeps the nominal q, so at 4x the noise it is told too little
    assert not arrays_equal(by_point[("constant", 1.0)], by_point[("constant", 4.0)])
    nis_1 = np.nanmean(by_point[("constant", 1.0)].mean_nis)
    nis_4 = np.nanmean(by_point[("constant", 4.0)].mean_nis)
    assert nis_4 > nis_1


def test_noisier_keeps_a_schedule_and_everything_else() -> None:
    base = pronet.sim.scenarios.varying_noise_scenario().sensors
    louder = sweep.noisier(base, 3.0)
    np.testing.assert_allclose(louder.imu_variance, 3.0 * np.asarray(base.imu_variance))
    assert louder.imu_variance_times == base.imu_variance_times
    assert (louder.dvl_variance, louder.dvl_period) == (base.dvl_variance, base.dvl_period)


def test_results_convert_to_dataframes(grid, local) -> None:
    summary = local.to_dataframe()
    assert len(summary) == 8
    assert list(summary.columns[:4]) == ["scenario", "strategy", "noise_level", "tuning_period_s"]
    for metric in ("srmse", "smae", "final_horizontal_error", "mean_nis"):
        assert (summary[f"{metric}_low"] <= summary[metric]).all()
        assert (summary[metric] <= summary[f"{metric}_high"]).all()
    assert (summary["runs"] == 5).all()
    first = local.points[0]
    assert summary.loc[0, "srmse"] == pytest.approx(np.mean(first.result.srmse))
    per_run = local.to_dataframe(per_run=True)
    assert len(per_run) == 8 * 5
    np.testing.assert_array_equal(per_run["srmse"][:5], first.result.srmse)
    assert per_run["run"].tolist()[:5] == list(range(5))
    runs = first.result.to_dataframe()
    assert isinstance(runs, pd.DataFrame) and list(runs["srmse"]) == list(first.result.srmse)


def test_a_resumed_sweep_runs_only_what_is_missing(grid, local, tmp_path, monkeypatch) -> None:
    store = ShardStore(tmp_path / "partial", sweep.settings(grid))
    todo = sweep.plan(grid)
    # half the shards finished before an interruption
    for shard in todo[::2]:
        store.save(shard.point.key, shard.label, *sweep.run_shard(shard, 2))
    ran: list[sweep.Shard] = []
    real = sweep.run_shard

    def counting(shard, threads=None):
        ran.append(shard)
        return real(shard, threads)

    monkeypatch.setattr(sweep, "run_shard", counting)
    seen: list[sweep.Shard] = []
    resumed = sweep.run_sweep(grid, threads=2, store=store, on_shard=seen.append)
    assert ran == todo[1::2] and len(seen) == len(todo)
    for a, b in zip(resumed.points, local.points, strict=True):
        assert a.point == b.point and arrays_equal(a.result, b.result)
    # another grid's shards are refused, not mixed in
    other = sweep.settings(config.SweepGrid(grid.scenarios, grid.strategies, seed=12))
    with pytest.raises(ValueError, match="different settings"):
        ShardStore(tmp_path / "partial", other)


def test_the_result_folder_holds_tables_csvs_and_plots(grid, local, tmp_path) -> None:
    out = sweep.write_result_folder(tmp_path / "res", local, sweep.settings(grid))
    names = sorted(p.name for p in out.iterdir())
    assert names == [
        "config.json",
        "metrics.csv",
        "metrics.json",
        "srmse_vs_noise_level.png",
        "srmse_vs_tuning_period.png",
        "summary.csv",
        "table.md",
    ]
    assert pd.read_csv(out / "summary.csv").shape[0] == 8
    assert pd.read_csv(out / "metrics.csv").shape[0] == 40
    assert json.loads((out / "config.json").read_text())["grid"]["seed"] == 11
    table = (out / "table.md").read_text()
    assert table.count("| learned:detrend |") == 4 and "| mehra:5 | 4 |" in table
    for png in out.glob("*.png"):
        assert png.read_bytes()[:4] == b"\x89PNG" and png.stat().st_size > 20_000
    with pytest.raises(FileExistsError):
        sweep.write_result_folder(out, local, {})


def test_bad_engine_arguments_fail_before_any_run(grid, monkeypatch) -> None:
    def must_not_run(shard, threads=None):
        raise AssertionError("a shard ran")

    monkeypatch.setattr(sweep, "run_shard", must_not_run)
    with pytest.raises(ValueError, match="engine: expected one of local, ray"):
        sweep.run_sweep(grid, engine="dask")
    with pytest.raises(ValueError, match="address: only the ray engine"):
        sweep.run_sweep(grid, address="auto")
    with pytest.raises(ValueError, match="threads: expected 1 to "):
        sweep.run_sweep(grid, threads=0)


def test_close_grid_values_stay_separate_points(grid, tmp_path) -> None:
    """Levels that print alike with a few digits are still two points with two sets of
    shards, also through a resume (shard files are named by the full numbers)."""
    close = config.SweepGrid(
        grid.scenarios, grid.strategies[:1], noise_levels=(1.0000001, 1.0000004), runs=2
    )
    points = {s.point for s in sweep.plan(close)}
    assert len(points) == 2 and len({p.key for p in points}) == 2
    store = ShardStore(tmp_path / "p", sweep.settings(close))
    first = sweep.run_sweep(close, threads=2, store=store)
    assert len(store) == 2
    again = sweep.run_sweep(close, threads=2, store=store)  # all loaded
    a, b = (p.result.srmse for p in again.points)
    assert not np.array_equal(a, b)
    for x, y in zip(first.points, again.points, strict=True):
        np.testing.assert_array_equal(x.result.srmse, y.result.srmse)
    twice = config.SweepGrid(grid.scenarios, grid.strategies[:1], noise_levels=(1.0, 1.0))
    with pytest.raises(ValueError, match="two grid points are the same"):
        sweep.plan(twice)


@pytest.mark.slow
def test_the_ray_engine_gives_exactly_the_local_numbers(grid, local) -> None:
    on_ray = sweep.run_sweep(grid, engine="ray", threads=1)
    assert [p.point for p in on_ray.points] == [p.point for p in local.points]
    for a, b in zip(on_ray.points, local.points, strict=True):
        assert arrays_equal(a.result, b.result), a.point.key
        if a.hybrid is not None:
            assert b.hybrid is not None
            np.testing.assert_array_equal(a.hybrid.clipped, b.hybrid.clipped)
            assert a.hybrid.n_tunings == b.hybrid.n_tunings
    pd.testing.assert_frame_equal(on_ray.to_dataframe(), local.to_dataframe())


@pytest.mark.slow
def test_a_failing_shard_on_ray_names_the_shard(tmp_path) -> None:
    """A model file the workers cannot read (say, absent on a cluster node): the error
    names the shard, and finished shards stay in the store for a resume."""
    import pickle
    import shutil

    from pronet.learn import modelfile

    (tmp_path / "short.toml").write_text(SHORT)
    for suffix in (".safetensors", ".json"):
        shutil.copy(modelfile.SHIPPED_DIR / f"baseline{suffix}", tmp_path)
    text = 'scenarios = ["short.toml"]\nstrategies = ["constant", "learned:baseline.json"]\n'
    (tmp_path / "grid.toml").write_text(text + "runs = 2\n")
    grid = config.load_sweep(tmp_path / "grid.toml")  # the model is there when checked
    shard = sweep.plan(grid)[0]
    assert pickle.loads(pickle.dumps(shard)) == shard  # plain data, fit to travel
    (tmp_path / "baseline.safetensors").unlink()
    message = r"shard short: learned:baseline.json, noise x1.0, tuning 1.0 s, runs 0-1: .*baseline"
    with pytest.raises(ValueError, match=message) as err:
        sweep.run_sweep(grid, engine="ray")
    assert "\x1b[" not in str(err.value)  # the task's error, not Ray's coloured report
    # shard after shard here: the constant row's shard finishes first and is kept; the
    # plan read the model and kept it (sweep._model), so it is forgotten after that
    # shard, as a worker that never read it would not have it
    store = ShardStore(tmp_path / "partial", {"test": 1})
    with pytest.raises(ValueError, match="baseline"):
        sweep.run_sweep(grid, engine="local", store=store,
                        on_shard=lambda _: sweep._model.cache_clear())  # fmt: skip
    assert len(store) == 1
