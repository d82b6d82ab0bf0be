"""One run path: the same strategy through the Python API, ``pronet simulate`` and
``pronet sweep`` gives bit-identical numbers, and every result folder has one schema."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import pronet
from pronet import _core, cli, config, results
from pronet.run import Recorded, run
from pronet.strategies import StrategySpec, strategy

from conftest import PAPER_Q

PACKAGE = Path(__file__).resolve().parents[1] / "python" / "pronet"

SCENARIO = """
name = "short"
[trajectory]
segments = [[20, 0, 0, 0], [20, 0, 3, 0]]
"""

SPECS = ["constant:3", "mehra:5", "oracle", "adaptive:20", "detvar", "learned:detrend"]
GRID = """
scenarios = ["short.toml"]
strategies = ["constant:3", "mehra:5", "oracle", "adaptive:20", "detvar", "learned:detrend"]
runs = 5
shard_runs = 2
seed = 4
"""


def _csv(path: Path) -> pd.DataFrame:
    return pd.read_csv(path)


def test_api_simulate_and_sweep_give_the_same_bits(tmp_path) -> None:
    (tmp_path / "short.toml").write_text(SCENARIO)
    (tmp_path / "grid.toml").write_text(GRID)
    scenario = config.load_scenario(tmp_path / "short.toml")
    specs = SPECS
    api = {
        spec: run(
            strategy(StrategySpec.parse(spec), scenario.q_nominal), scenario, n_runs=5, seed=4
        ).result
        for spec in specs
    }
    sim, swp = tmp_path / "sim", tmp_path / "swp"
    common = ["--quiet", "--threads", "2"]
    simulate_only = ["--no-plots"]
    simulate = ["simulate", "--scenario", str(tmp_path / "short.toml"), "--runs", "5"]
    simulate += ["--seed", "4", "--strategies", ",".join(specs), "--out", str(sim)]
    assert cli.main([*simulate, *common, *simulate_only]) == 0
    assert cli.main(["sweep", str(tmp_path / "grid.toml"), "--out", str(swp), *common]) == 0
    by_sim, by_sweep = _csv(sim / "metrics.csv"), _csv(swp / "metrics.csv")
    for spec in specs:
        for metric in results.METRICS:
            want = getattr(api[spec], metric)
            for table in (by_sim, by_sweep):
                got = table.loc[table["strategy"] == spec, metric].to_numpy()
                np.testing.assert_array_equal(got, want, err_msg=f"{spec} {metric}")


def test_every_result_folder_has_the_same_columns(tmp_path) -> None:
    """simulate and sweep here; reproduce and real check the same header in their own
    tests (test_cli, test_realdata)."""
    (tmp_path / "short.toml").write_text(SCENARIO)
    (tmp_path / "grid.toml").write_text(GRID)
    sim, swp = tmp_path / "sim", tmp_path / "swp"
    simulate = ["simulate", "--scenario", str(tmp_path / "short.toml"), "--runs", "2"]
    simulate += ["--strategies", "constant", "--out", str(sim), "--quiet", "--no-plots"]
    assert cli.main(simulate) == 0
    assert cli.main(["sweep", str(tmp_path / "grid.toml"), "--out", str(swp), "--quiet"]) == 0
    for folder in (sim, swp):
        assert tuple(_csv(folder / "metrics.csv").columns) == results.RUN_COLUMNS
        assert tuple(_csv(folder / "summary.csv").columns) == results.SUMMARY_COLUMNS


def _dispatches_on_learned(tree: ast.AST) -> bool:
    """Whether the module holds ``isinstance(..., Learned)``."""
    return any(
        isinstance(node, ast.Call)
        and getattr(node.func, "id", None) == "isinstance"
        and len(node.args) == 2
        and "Learned" in ast.unparse(node.args[1])
        for node in ast.walk(tree)
    )


def test_one_module_tells_learned_from_native_strategies() -> None:
    dispatching = sorted(
        str(p.relative_to(PACKAGE))
        for p in PACKAGE.rglob("*.py")
        if _dispatches_on_learned(ast.parse(p.read_text()))
    )
    assert dispatching == ["run.py"]


def test_run_refuses_what_its_target_cannot_take() -> None:
    q = (1e-4,) * 3 + (1e-6,) * 3
    native = _core.Strategy.constant(q)
    with pytest.raises(ValueError, match="^target: expected a Scenario or Recorded, got str$"):
        run(native, "paper")  # type: ignore[call-overload]
    rec = Recorded(
        imu=np.tile([0.0, 0.0, -9.8, 0.0, 0.0, 0.0], (3, 1)),  # at rest: a plausible IMU
        imu_time=np.array([0.01, 0.02, 0.03]),
        dvl=np.zeros((0, 3)),
        dvl_time=np.zeros(0),
        t0=0.0,
        lla0=np.array([0.5, 0.6, 0.0]),
        vel0=np.zeros(3),
        rpy0=np.zeros(3),
        config=_core.FilterConfig(),
    )
    with pytest.raises(ValueError, match="a recorded run takes none of them"):
        run(native, rec, n_runs=5)  # type: ignore[call-overload]
    assert run(native, rec).result.time.shape == (4,)
    with pytest.raises(ValueError, match="^strategy: oracle needs the simulated IMU's true var"):
        run(strategy(StrategySpec.parse("oracle"), q), rec)
    # Adaptive runs on recorded data, once its window can fill: never a silent prior.
    adaptive = strategy(StrategySpec.parse("adaptive"), q)
    with pytest.raises(ValueError, match="^window: adaptive over 60 DVL updates never fills"):
        run(adaptive, rec)
    one = dataclasses.replace(rec, dvl=np.zeros((1, 3)), dvl_time=np.array([0.02]))
    assert run(strategy(StrategySpec.parse("adaptive:1"), q), one).result.time.shape == (4,)


def test_filter_result_to_dataframe_has_every_epoch_and_update() -> None:
    from pronet.filter import EPOCH_COLUMNS, UPDATE_COLUMNS

    traj = pronet.builtin_trajectory("paper")
    n = 500
    dvl_t = np.array([1.0, 2.0, 3.0, 99.0])  # the last after the run
    ned = pronet.Dvl(dvl_t, np.tile(traj.vel_ned[0], (4, 1)), frame="ned")
    out = pronet.run_filter(
        traj.imu[:n], traj.time[1 : n + 1], [ned], t0=0.0, lla0=traj.lla[0],
        vel0=traj.vel_ned[0], rpy0=traj.rpy[0], strategy=pronet.Strategy.constant(PAPER_Q),
    )  # fmt: skip
    epochs = out.to_dataframe()
    assert tuple(epochs.columns) == EPOCH_COLUMNS and len(epochs) == n + 1
    np.testing.assert_array_equal(epochs["time"], out.time)
    np.testing.assert_array_equal(epochs[["lat", "lon", "h"]], out.lla)
    np.testing.assert_array_equal(epochs["yaw"], out.rpy[:, 2])
    np.testing.assert_array_equal(epochs["bias_gz"], out.bias[:, 5])
    np.testing.assert_array_equal(epochs["sigma_psi_d"], out.sigma[:, 8])
    updates = out.to_dataframe("updates")
    assert tuple(updates.columns) == UPDATE_COLUMNS and len(updates) == 4
    np.testing.assert_allclose(updates["time"][:3], [1.0, 2.0, 3.0], atol=1e-9)
    assert np.isnan(updates["time"][3]) and updates["dvl_epoch"][3] == -1
    np.testing.assert_array_equal(updates["innovation_z"], out.innovation[:, 2])
    assert list(updates["accepted"]) == [True, True, True, False]
    with pytest.raises(ValueError, match="^rows"):
        out.to_dataframe("runs")


def test_run_filter_keeps_the_covariance_at_the_times_asked_for() -> None:
    """``covariance_time`` keeps the full covariance at the epoch nearest each time,
    after its update (its diagonal the σ there), in every aiding and with every epoch
    kept or the last alone; a time outside the run is -1 and NaN; the pass is otherwise
    the same; a bad time is refused by name."""
    traj = pronet.builtin_trajectory("paper")
    n = 400
    dvl = pronet.Dvl([1.0, 2.0, 3.0], np.tile([1.0, 0, 0], (3, 1)))
    args = (traj.imu[:n], traj.time[1 : n + 1], [dvl])
    kw = dict(t0=0.0, lla0=traj.lla[0], vel0=traj.vel_ned[0], rpy0=traj.rpy[0],
              strategy=pronet.Strategy.mehra(2, PAPER_Q))  # fmt: skip
    plain = pronet.run_filter(*args, **kw)  # type: ignore[arg-type]
    assert plain.covariances.shape == (0, 15, 15) and plain.covariance_epoch.shape == (0,)
    times = [-1.0, 0.0, 1.0, 2.5, 3.996, 4.2]
    out = pronet.run_filter(*args, **kw, covariance_time=times)  # type: ignore[arg-type]
    np.testing.assert_array_equal(out.sigma, plain.sigma)
    np.testing.assert_array_equal(out.covariance_epoch, [-1, 0, 100, 250, n, -1])
    assert np.isnan(out.covariances[[0, -1]]).all()
    for p, k in zip(out.covariances[1:-1], out.covariance_epoch[1:-1], strict=True):
        np.testing.assert_array_equal(p, p.T)
        np.testing.assert_array_equal(np.sqrt(np.diag(p)), out.sigma[k])
        assert np.linalg.eigvalsh(p).min() > 0
    np.testing.assert_array_equal(out.covariances[-2], out.covariance)
    # Off-diagonal terms are kept too: the update correlates velocity with attitude.
    assert np.abs(out.covariances[2][3:6, 6:9]).max() > 0
    last = pronet.run_filter(*args, **kw, epochs="last", covariance_time=times)  # type: ignore[arg-type]
    np.testing.assert_array_equal(last.covariances, out.covariances)
    for bad, message in (([2.0, 1.0], "must increase strictly"), ([np.nan], "finite")):
        with pytest.raises(ValueError, match=f"^covariance_time.*{message}"):
            pronet.run_filter(*args, **kw, covariance_time=bad)  # type: ignore[arg-type]


def test_run_filter_smooths_on_request_and_refuses_what_it_cannot() -> None:
    """``smooth=True`` adds the smoothed solution (a table like the forward one's, with
    the DVL calibration states' columns when they are on) and leaves the forward pass
    as it was; it keeps every epoch and is refused with ``epochs="last"`` or given a
    non-bool."""
    from pronet.filter import EPOCH_COLUMNS

    traj = pronet.builtin_trajectory("paper")
    n = 400
    dvl = pronet.Dvl([1.0, 2.0, 3.0], np.tile([1.0, 0, 0], (3, 1)))
    args = (traj.imu[:n], traj.time[1 : n + 1], [dvl])
    kw = dict(t0=0.0, lla0=traj.lla[0], vel0=traj.vel_ned[0], rpy0=traj.rpy[0],
              strategy=pronet.Strategy.constant(PAPER_Q))  # fmt: skip
    plain = pronet.run_filter(*args, **kw)  # type: ignore[arg-type]
    assert plain.smoothed is None
    out = pronet.run_filter(*args, **kw, smooth=True)  # type: ignore[arg-type]
    np.testing.assert_array_equal(out.vel, plain.vel)
    np.testing.assert_array_equal(out.sigma, plain.sigma)
    s = out.smoothed
    assert isinstance(s, pronet.SmoothedResult)
    table = s.to_dataframe()
    assert tuple(table.columns) == EPOCH_COLUMNS and len(table) == n + 1
    np.testing.assert_array_equal(table["time"], out.time)
    np.testing.assert_array_equal(table["vel_e"], s.vel[:, 1])
    np.testing.assert_array_equal(table["sigma_dv_n"], s.sigma[:, 3])
    assert (s.sigma <= out.sigma * (1 + 1e-12)).all() and (s.sigma[100] < out.sigma[100]).any()
    calibrated = pronet.run_filter(
        *args, **kw, smooth=True, config=pronet.FilterConfig(dvl_calibration=True)
    )  # type: ignore[arg-type]
    assert calibrated.smoothed is not None
    table = calibrated.smoothed.to_dataframe()
    assert tuple(table.columns) == tuple(calibrated.to_dataframe().columns)
    np.testing.assert_array_equal(
        table["sigma_dvl_scale"], calibrated.smoothed.calibration_sigma[:, 0]
    )
    cases = [
        ({"epochs": "last"}, "^epochs: smooth=True keeps the epochs it corrects"),
        ({"smooth": 1}, "^smooth: expected True or False, got 1"),
    ]
    for extra, message in cases:
        with pytest.raises(ValueError, match=message):
            pronet.run_filter(*args, **{**kw, "smooth": True, **extra})  # type: ignore[arg-type]
