"""The simulation side under hostile input, fifth round: ``pronet simulate`` and
``pronet sweep`` when every run fails, what a failed run may count in the tables, and
what an error before or after the work leaves behind."""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from cli_output import one_line

import pronet
from pronet import cli, config
from pronet._util.plausibility import PlausibilityWarning
from pronet.experiments import simulation
from pronet.montecarlo import STATE_BLOCKS
from pronet.run import run
from pronet.strategies import StrategySpec, strategy

#: A 20 s scenario keeps every command here to about a second.
SHORT = """
name = "short"
[trajectory]
segments = [[20, 0, 0, 0]]
"""
#: A scenario whose filter's covariance overflows in every run, 2 s in: a gyro bias
#: 1σ of 1e150 rad/s (an IMU noise that did so, 1e30, is now refused as past any IMU's
#: full scale, which a sweep's noise level of 1e30 meets too).
OVERFLOWING = SHORT.replace('"short"', '"overflowing"') + (
    "[filter]\np0_sigma = [1.0, 1.0, 1.0, 0.1, 0.1, 0.1, 1e-3, 1e-3, 5e-3, 1e-3, 1e-3, 1e-3, "
    "1e150, 1e150, 1e150]\n"
)


def left_beside(out: Path) -> list[str]:
    """What a command into ``out`` left in its parent folder (lock files aside)."""
    return sorted(p.name for p in out.parent.iterdir() if not p.name.endswith(".lock"))


def test_a_simulation_whose_every_run_fails_exits_non_zero_and_writes_nothing(
    tmp_path, capsys
) -> None:
    """Every run of every strategy a numerical failure: the command wrote a folder of
    NaN and exited 0 before; now one line naming the first failure, exit 2, no folder."""
    scenario = tmp_path / "overflowing.toml"
    scenario.write_text(OVERFLOWING)
    out = tmp_path / "out"
    args = ["simulate", "--scenario", str(scenario), "--strategies", "constant,mehra:5"]
    code = cli.main([*args, "--runs", "2", "--no-plots", "--quiet", "--out", str(out)])
    line = one_line(capsys)
    assert code == 2
    assert line.startswith(
        "pronet: every run failed; the first, overflowing: constant, run 0: t = "
    )
    assert "numerical failure" in line
    assert left_beside(out) == ["overflowing.toml"]


@pytest.fixture
def grid_folder(tmp_path: Path) -> Path:
    (tmp_path / "short.toml").write_text(SHORT)
    return tmp_path


def sweep(folder: Path, scenarios: str, capsys, levels: str = "[1]") -> tuple[int, Path]:
    """``pronet sweep`` of ``constant`` over ``scenarios`` at the noise ``levels`` (TOML
    lists), 2 runs."""
    (folder / "overflowing.toml").write_text(OVERFLOWING)
    grid = folder / "grid.toml"
    grid.write_text(
        f'scenarios = {scenarios}\nstrategies = ["constant"]\nnoise_levels = {levels}\nruns = 2\n'
    )
    out = folder / "out"
    code = cli.main(["sweep", str(grid), "--quiet", "--json", "--out", str(out)])
    return code, out


def test_a_sweep_whose_every_run_fails_exits_non_zero_and_leaves_nothing(
    grid_folder, capsys
) -> None:
    """The known defect: a sweep all of whose runs failed exited 0 with a table of
    "undefined". Now exit 2, one line, no folder and no ``.partial`` to resume."""
    code, out = sweep(grid_folder, '["overflowing.toml"]', capsys)
    line = one_line(capsys)
    assert code == 2
    assert line.startswith("pronet: every run failed; the first, overflowing: constant, noise x1")
    assert left_beside(out) == ["grid.toml", "overflowing.toml", "short.toml"]
    # A noise level that takes the IMU past any full scale: refused before any run.
    code, out = sweep(grid_folder, '["short.toml"]', capsys, levels="[1, 1e30]")
    line = one_line(capsys)
    assert code == 2 and line.startswith(
        "pronet: grid: short, noise x1e+30: imu_variance: element 0 is 1e26 (σ 1e13 m/s²), "
    )
    assert left_beside(out) == ["grid.toml", "overflowing.toml", "short.toml"]  # no .partial


def test_a_failed_grid_point_does_not_take_the_others_with_it(grid_folder, capsys) -> None:
    code, out = sweep(grid_folder, '["short.toml", "overflowing.toml"]', capsys)
    assert code == 0
    summary = pd.read_csv(out / "summary.csv")
    assert summary["failed_runs"].tolist() == [0, 2]
    assert json.loads(capsys.readouterr().out)["folder"] == str(out)


def test_a_failed_run_counts_in_no_nees(tmp_path) -> None:
    """The core keeps the epochs a run had before its numerical failure; their NEES were
    averaged into the run's ``velocity_nees`` ... ``gyro_bias_nees`` and the 3σ share,
    so a row of failed runs read e.g. ``0.00 (100.0 %)`` (or 5e77) in the tables, and
    a failed run weighed in a row's mean NEES. Now a failed run's are NaN, as its
    other metrics."""
    scenario = tmp_path / "overflowing.toml"
    scenario.write_text(OVERFLOWING)
    sc = config.load_scenario(scenario)
    result = run(strategy(StrategySpec.parse("constant"), sc.q_nominal), sc, n_runs=2).result
    assert result.n_failed == 2
    assert np.isfinite(result.nees).any()  # the epochs before the failures are kept
    per_run = result.to_dataframe()
    columns = [f"{b}_nees" for b in STATE_BLOCKS] + ["velocity_nees_3sigma", "srmse"]
    assert per_run[columns].isna().all().all()
    assert all(math.isnan(ci.mean) for ci in result.summary().values())


@pytest.mark.parametrize(
    ("grid", "expected"),
    [
        (
            'strategies = ["detvar"]\ntuning_periods_s = [1e300]',
            "grid: short: detvar, tuning 1e+300 s: tuning_period: 1e+300 s leaves no tuning",
        ),
        ('strategies = ["adaptive:100000"]', "grid: short: adaptive:100000: window: adaptive"),
        ('strategies = ["constant"]\nruns = 100000000000000', "grid: 1 grid points x "),
        (
            'strategies = ["constant", "constant:1"]',
            "grid: strategies: 'constant' and 'constant:1' are the same strategy",
        ),
    ],
)
def test_a_sweep_refused_before_its_work_leaves_no_partial_folder(
    grid_folder, grid, expected, capsys
) -> None:
    """A strategy that could never act (found by the first shard) or a grid beyond
    memory was refused after ``<out>.partial`` was made, so the same command, corrected
    or not, was then refused as ``holds an interrupted run; add --resume``."""
    path = grid_folder / "grid.toml"
    path.write_text(f'scenarios = ["short.toml"]\n{grid}\n')
    out = grid_folder / "out"
    for _ in range(2):  # the second time says the same, not "add --resume"
        assert cli.main(["sweep", str(path), "--quiet", "--out", str(out)]) == 2
        assert one_line(capsys).startswith(f"pronet: {expected}")
        assert left_beside(out) == ["grid.toml", "short.toml"]


def test_reproduce_refused_before_its_work_leaves_no_partial_folder(tmp_path, capsys) -> None:
    out = tmp_path / "out"
    for _ in range(2):
        code = cli.main(["reproduce", "--tuning-period", "1e300", "--quiet", "--out", str(out)])
        assert code == 2
        line = one_line(capsys)
        assert "tuning_period: 1e+300 s leaves no tuning instant" in line
        assert left_beside(out) == []


@pytest.mark.parametrize("imu_dt", [100, 0.001])  # a rate in Hz; ms read as s the other way
def test_a_filter_imu_dt_other_than_the_trajectorys_period_is_warned_of(
    tmp_path, imu_dt, capsys
) -> None:
    """A ``[filter] imu_dt`` (or a ``--filter`` file's) other than the trajectory's IMU
    period mistunes every row's process noise by their ratio; ``imu_dt = 100`` (Hz
    for s) ran 10⁴ times mistuned with only the NIS note to say so. ``run_filter``
    warns of it on recorded data; a simulation now does too, naming the file and key."""
    scenario = tmp_path / "s.toml"
    scenario.write_text(f"{SHORT}\n[filter]\nimu_dt = {imu_dt}\n")
    ratio = f"{imu_dt / 0.01:.3g}×"
    with pytest.warns(PlausibilityWarning, match=rf"s.toml: \[filter\] imu_dt: {imu_dt:g} s, "):
        assert config.load_scenario(scenario).config.imu_dt == imu_dt  # used as given
    filter_file = tmp_path / "f.toml"
    filter_file.write_text(f"imu_dt = {imu_dt}\n")
    plain = tmp_path / "plain.toml"
    plain.write_text(SHORT)
    out = tmp_path / "out"
    args = ["simulate", "--scenario", str(plain), "--filter", str(filter_file), "--runs", "1"]
    assert cli.main([*args, "--strategies", "constant", "--no-plots", "--out", str(out)]) == 0
    said = [line for line in capsys.readouterr().err.splitlines() if "imu_dt" in line]
    assert len(said) == 1 and said[0].startswith(f"pronet: warning: {filter_file}: imu_dt: ")
    assert "is 0.01 s: " in said[0] and ratio in said[0]


def test_a_filter_imu_dt_at_the_trajectorys_period_says_nothing(tmp_path) -> None:
    scenario = tmp_path / "s.toml"
    scenario.write_text(f"{SHORT}\n[filter]\nimu_dt = 0.0105\n")  # within 15 %
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        config.load_scenario(scenario)


@pytest.mark.parametrize("seconds", ["1e20", "1e300"])
def test_a_record_interval_beyond_the_run_keeps_the_first_sample(tmp_path, seconds) -> None:
    """``--record-every`` longer than the run keeps its first history sample, as 100 s
    on a 20 s run did; from 1.8e17 s on the core refused it as ``record_every: must be
    at most 18446744073709551615, got 10000000000000000000000``."""
    scenario = tmp_path / "short.toml"
    scenario.write_text(SHORT)
    folders = {}
    for every in (seconds, "100"):
        folders[every] = simulation.simulate(
            scenario,
            ["constant"],
            tmp_path / every,
            n_runs=1,
            record_every=float(every),
            plots=False,
        )
    files = [(f / "metrics.csv").read_text() for f in folders.values()]
    assert files[0] == files[1]


@pytest.mark.parametrize("dt", ["0", "-0.01", "nan", "inf"])
def test_a_builtin_trajectorys_bad_period_names_the_files_key(tmp_path, dt) -> None:
    """``[trajectory] builtin = "paper"`` with ``dt_s = 0`` was refused as ``[trajectory]
    dt: must be finite and > 0`` (the native argument); ``segments`` said ``dt_s``."""
    for rows in ('builtin = "paper"', "segments = [[20, 0, 0, 0]]"):
        path = tmp_path / "s.toml"
        path.write_text(f"[trajectory]\n{rows}\ndt_s = {dt}\n")
        with pytest.raises(config.ConfigError, match=r"s.toml: \[trajectory\] dt_s: must be a "):
            config.load_scenario(path)


def test_a_heading_sigma_in_degrees_is_warned_of(tmp_path) -> None:
    """A vehicle file's ``heading_sigma`` is in degrees, a scenario's in radians: ``2``
    copied across simulated a 115° compass without a word."""
    path = tmp_path / "s.toml"
    path.write_text(f"{SHORT}\n[sensors]\nheading_sigma = 2\n")
    with pytest.warns(
        PlausibilityWarning, match=r"s.toml: \[sensors\] heading_sigma: 2 rad \(115°\)"
    ):
        assert config.load_scenario(path).sensors.heading_sigma == 2  # used as given
    path.write_text(f"{SHORT}\n[sensors]\nheading_sigma = 0.035\n")  # 2°, in radians
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        config.load_scenario(path)


def test_dvl_outages_over_the_whole_run_are_warned_of(tmp_path) -> None:
    """Outages that hold every DVL epoch of the 20 s run: every row was inertial-only
    with its NIS and NEES "undefined", without a word (found by the probe). Warned of,
    naming the file and key; an outage that leaves one epoch (the last, at 20 s: the
    outage is half-open), no DVL at all (``dvl_period = 0``) or no DVL epoch in the run
    says nothing."""
    path = tmp_path / "s.toml"
    path.write_text(f"{SHORT}\n[sensors]\ndvl_outages = [[0, 5], [5, 20.5]]\n")
    with pytest.warns(
        PlausibilityWarning, match=r"s.toml: \[sensors\] dvl_outages: hold every DVL epoch"
    ):
        assert len(config.load_scenario(path).sensors.dvl_outages) == 2  # used as given
    for table in ("dvl_outages = [[0, 20]]", "dvl_outages = [[0, 30]]\ndvl_period = 0"):
        path.write_text(f"{SHORT}\n[sensors]\n{table}\n")
        with warnings.catch_warnings():
            warnings.simplefilter("error", PlausibilityWarning)
            config.load_scenario(path)
    # No epoch in the run (a file refuses such a period; the API's SensorConfig takes it)
    from pronet._util.plausibility import warn_of_sensors

    sensors = pronet.SensorConfig(dvl_period=400.0, dvl_outages=[[1000.0, 1001.0]])
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        warn_of_sensors(sensors, pronet.builtin_trajectory("paper"), "api:")
