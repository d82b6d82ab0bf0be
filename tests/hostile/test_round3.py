"""The third hostile-user probe: 60+ cases a user can cause, none repeated from the
earlier rounds, by class: data loss (an existing output of every writing command),
environment (thread counts from every source), types (strings and booleans where
numbers go, on every input surface), numbers that mislead (intervals leaving their
range, undefined statistics, a strategy that can never act), messages that name the
wrong cause, conflicting options, and records that do not group.

Every refused case must end in exit code 2 with one line ``pronet: <key>: <reason>``
naming the option or key the user gave, before any work, and leave every file that
existed untouched. Every accepted case must give numbers that mean what they say.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

import pronet
from pronet import _core, cli
from pronet.experiments import reproduce, simulation, study, sweep
from pronet.recorded import real

SHORT = """
name = "short"
[trajectory]
segments = [[20, 0, 0, 0]]
"""
GRID = """
scenarios = ["short.toml"]
strategies = ["constant"]
runs = 2
"""
Q = [1e-4] * 3 + [1e-6] * 3
MOST = _core.max_threads()


@pytest.fixture
def where(tmp_path: Path, monkeypatch) -> Path:
    """A folder holding a short scenario, a sweep grid and an empty recording folder;
    every Monte Carlo, study or section run fails the test (nothing may start)."""
    (tmp_path / "short.toml").write_text(SHORT)
    (tmp_path / "grid.toml").write_text(GRID)
    (tmp_path / "data").mkdir()

    def must_not_run(*args, **kwargs):
        raise AssertionError("work started before the input was checked")

    for module, name in (
        (simulation, "run_strategies"),
        (reproduce, "_run_tables"),
        (sweep, "run_sweep"),
        (study, "run_study"),
        (real, "run_sections"),
    ):
        if hasattr(module, name):
            monkeypatch.setattr(module, name, must_not_run)
    return tmp_path


def refused(capsys, argv: list[str], key: str) -> str:
    """Run ``pronet argv``: exit 2, one line on stderr starting ``pronet: <key>``."""
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"pronet: {key}"), err
    return lines[0]


def command(name: str, w: Path, out: Path) -> list[str]:
    """The shortest command line of each command that writes into ``out``."""
    scenario = str(w / "short.toml")
    return {
        "simulate": ["simulate", "--scenario", scenario, "--runs", "2", "--out", str(out)],
        "sweep": ["sweep", str(w / "grid.toml"), "--out", str(out)],
        "study": ["study", "--runs", "2", "--scenarios", "paper", "--out", str(out)],
        "reproduce": ["reproduce", "--runs", "2", "--out", str(out)],
        "real": [
            *("real", "--data", str(w / "data"), "--format", "generic", "--out", str(out)),
            *("--imu-lever-arm=0,0,0", "--dvl-lever-arm=0,0,0"),
        ],
    }[name]


FOLDER_COMMANDS = ("simulate", "sweep", "study", "reproduce", "real")

# --- data loss: no output of any command is overwritten without --force -------------


@pytest.mark.parametrize("name", FOLDER_COMMANDS)
def test_an_existing_result_folder_is_never_touched(where, capsys, name) -> None:
    out = where / "res"
    out.mkdir()
    (out / "mine.txt").write_text("kept")
    refused(capsys, command(name, where, out), "--out")
    assert [p.name for p in out.iterdir()] == ["mine.txt"]


@pytest.mark.parametrize("name", FOLDER_COMMANDS)
def test_a_file_at_the_result_folder_is_never_touched(where, capsys, name) -> None:
    out = where / "res"
    out.write_text("kept")
    refused(capsys, command(name, where, out), "--out")
    assert out.read_text() == "kept"


@pytest.mark.parametrize(
    ("existing", "out"),
    [("X.npz", "X.npz"), ("X.json", "X.npz"), ("X.json", "X.json"), ("X.npz", "X.json")],
)
def test_dataset_overwrites_neither_the_data_nor_its_card(where, capsys, existing, out) -> None:
    """``--out X.npz`` once replaced ``X.json`` beside it without ``--force``."""
    (where / existing).write_text("kept")
    refused(capsys, ["dataset", "--out", str(where / out), "--levels", "1"], "--out")
    assert (where / existing).read_text() == "kept"
    assert sorted(p.name for p in where.iterdir() if p.suffix in (".npz", ".json")) == [existing]


@pytest.mark.parametrize(
    ("model", "existing"),
    [
        ("baseline", "baseline.safetensors"),
        ("baseline", "baseline.json"),
        ("all", "hcf.json"),
        ("all", "detrend.safetensors"),
    ],
)
def test_train_replaces_no_model_of_the_same_name(where, capsys, model, existing) -> None:
    models = where / "models"
    models.mkdir()
    (models / existing).write_text("kept")
    line = refused(capsys, ["train", "--model", model, "--out", str(models)], "--out")
    assert f"{existing} exists; use --force" in line
    assert (models / existing).read_text() == "kept" and len(list(models.iterdir())) == 1


def test_evaluate_replaces_no_figure(where, capsys) -> None:
    figure = where / "fig.png"
    figure.write_text("kept")
    refused(capsys, ["evaluate", "--figure", str(figure)], "--figure")
    assert figure.read_text() == "kept"


# --- environment: thread counts from every source are bounded ------------------------


@pytest.mark.parametrize("value", ["0", "100000", "-1", "abc", "2.5", "", str(MOST + 1)])
def test_the_thread_variable_is_refused_in_process(where, capsys, monkeypatch, value) -> None:
    monkeypatch.setenv("RAYON_NUM_THREADS", value)
    refused(capsys, command("simulate", where, where / "res"), "RAYON_NUM_THREADS")
    assert not (where / "res").exists()


@pytest.mark.parametrize(
    ("name", "threads"),
    # a sweep's --threads is the CPUs of other machines (Ray): there only 1 to 1,024
    [("sweep", "0"), ("sweep", "1025")]
    + [(n, t) for n in ("simulate", "study", "reproduce") for t in ("0", str(MOST + 1))],
)
def test_a_thread_option_beyond_the_machine_is_refused(where, capsys, name, threads) -> None:
    argv = [*command(name, where, where / "res"), "--threads", threads]
    refused(capsys, argv, "--threads")
    assert not (where / "res").exists()


@pytest.mark.parametrize(
    "call",
    [
        lambda t: pronet.monte_carlo(t, pronet.Strategy.constant(Q), n_runs=1, threads=MOST + 1),
        lambda t: pronet.Ensemble(t, Q, n_runs=1, threads=0),
    ],
    ids=["monte_carlo", "Ensemble"],
)
def test_a_thread_argument_beyond_the_machine_is_refused(paper_trajectory, call) -> None:
    with pytest.raises(ValueError, match=rf"^threads: must be 1 to {MOST} "):
        call(paper_trajectory)


# --- types: strings and booleans are not numbers, on any surface ---------------------

TOML_TYPES = [
    ("[trajectory]", 'segments = [["60", 0, 0, 0]]', "[trajectory] segments"),
    ("[trajectory]", "segments = [[60, true, false, 0]]", "[trajectory] segments"),
    ("[trajectory]", "segments = [[true, 0, 0, 0]]", "[trajectory] segments"),
    ("[trajectory]", 'segments = [[20, 0, 0, 0]]\nspeed_mps = "1.5"', "[trajectory] speed_mps"),
    ("[trajectory]", "segments = [[20, 0, 0, 0]]\nlat_deg = true", "[trajectory] lat_deg"),
    ("[trajectory]", 'segments = [[20, 0, 0, 0]]\ndt_s = "0.01"', "[trajectory] dt_s"),
    ("[sensors]", 'dvl_period = "1"', "[sensors] dvl_period"),
    ("[sensors]", "dvl_variance = [true, 0.01, 0.01]", "[sensors] dvl_variance"),
    ("[sensors]", 'imu_variance = ["1e-4", 1e-4, 1e-4, 1e-6, 1e-6, 1e-6]', "[sensors] imu_var"),
    ("[sensors]", "lever_arm = [true, 0, 0]", "[sensors] lever_arm"),
    ("[sensors]", "dvl_outages = [[true, 5]]", "[sensors] dvl_outages"),
    ("[filter]", 'innovation_gate = "16"', "[filter] innovation_gate"),
    ("[filter]", "imu_dt = true", "[filter] imu_dt"),
]


@pytest.mark.parametrize(("table", "line", "key"), TOML_TYPES)
def test_a_scenario_file_takes_numbers_only(where, capsys, table, line, key) -> None:
    body = SHORT if table != "[trajectory]" else 'name = "short"\n'
    (where / "bad.toml").write_text(f"{body}\n{table}\n{line}\n")
    argv = ["simulate", "--scenario", str(where / "bad.toml"), "--out", str(where / "res")]
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"pronet: {where / 'bad.toml'}: {key}") and err.count("\n") == 1, err


PYTHON_TYPES: list[tuple[str, Callable[[], object], str]] = [
    ("segments", lambda: pronet.trajectory_from_segments([[True, 0, 0, 0]], **ORIGIN), "segments"),
    ("segments", lambda: pronet.trajectory_from_segments([["60", 0, 0, 0]], **ORIGIN), "segments"),
    (
        "lla0",
        lambda: pronet.trajectory_from_segments([[9, 0, 0, 0]], lla0=[True, 0, 0], speed0=1.0),
        "lla0",
    ),
    (
        "speed0",
        lambda: pronet.trajectory_from_segments([[9, 0, 0, 0]], lla0=[0.5, 0, 0], speed0="1"),
        "speed0",
    ),
    ("q", lambda: pronet.Strategy.constant([True] * 6), "q"),
    ("window", lambda: pronet.Strategy.mehra(True, Q), "window"),
    ("imu_variance", lambda: pronet.SensorConfig(imu_variance=np.ones(6, bool)), "imu_variance"),
    ("dvl_period", lambda: pronet.SensorConfig(dvl_period=True), "dvl_period"),
    ("innovation_gate", lambda: pronet.FilterConfig(innovation_gate=True), "innovation_gate"),
]
ORIGIN = {"lla0": [0.5, 0.0, 0.0], "speed0": 1.0}


@pytest.mark.parametrize(("name", "call", "key"), PYTHON_TYPES, ids=[c[0] for c in PYTHON_TYPES])
def test_python_arguments_take_numbers_only(name, call, key) -> None:
    with pytest.raises(ValueError, match=rf"^{key}: expected"):
        call()


@pytest.mark.parametrize(
    ("keyword", "value"),
    [("n_runs", True), ("n_runs", 2.0), ("seed", "1"), ("record_every", True)],
)
def test_monte_carlo_counts_are_whole_numbers(paper_trajectory, keyword, value) -> None:
    args = {"n_runs": 1, keyword: value}
    with pytest.raises(ValueError, match=rf"^{keyword}: expected a whole number"):
        pronet.monte_carlo(paper_trajectory, pronet.Strategy.constant(Q), **args)


# --- numbers that mislead --------------------------------------------------------------


def test_a_two_run_simulation_gives_intervals_within_range(tmp_path, capsys) -> None:
    """Two runs: every interval of an RMS, error, NIS or NEES stays at or above zero,
    every share within [0, 1], and the ``scenario`` column holds the scenario's name."""
    (tmp_path / "short.toml").write_text(SHORT)
    argv = ["simulate", "--scenario", str(tmp_path / "short.toml"), "--runs", "2"]
    argv += ["--strategies", "constant,mehra:5", "--no-plots", "--quiet"]
    assert cli.main([*argv, "--out", str(tmp_path / "res")]) == 0
    rows = json.loads((tmp_path / "res" / "metrics.json").read_text())
    assert {r["scenario"] for r in rows} == {"short"}
    for row in rows:
        for name in pronet.MonteCarloResult.SUMMARIZED:
            low, high = row[f"{name}_low"], row[f"{name}_high"]
            assert 0 <= low <= row[name] <= high, (name, row)
            if name.endswith("_3sigma"):
                assert high <= 1


def test_a_run_without_a_dvl_update_has_an_undefined_mean_nis() -> None:
    short = pronet.trajectory_from_segments([[0.5, 0, 0, 0]], **ORIGIN)
    res = pronet.monte_carlo(short, pronet.Strategy.constant(Q), n_runs=2)
    assert np.isnan(res.mean_nis).all() and np.isfinite(res.srmse).all()
    assert str(res.summary()["mean_nis"]) == "undefined"


def test_a_strategy_that_can_never_act_is_refused(paper_trajectory) -> None:
    with pytest.raises(ValueError, match="^strategy: an external strategy"):
        pronet.monte_carlo(paper_trajectory, pronet.Strategy.external(Q), n_runs=1)


# --- messages that name the cause the user gave -------------------------------------


@pytest.mark.parametrize(
    ("call", "key"),
    [
        (lambda: pronet.FilterConfig(lever_arm=[1e9, 0, 0]), "lever_arm"),
        (lambda: pronet.SensorConfig(lever_arm=[0, 0, -5000]), "lever_arm"),
    ],
)
def test_a_lever_arm_beyond_any_vehicle_is_named(call, key) -> None:
    with pytest.raises(ValueError, match=rf"^{key}: must be within ±1000 m"):
        call()


@pytest.mark.parametrize(
    ("line", "message"),
    [
        (
            "lat_deg = 89.5",
            "[trajectory] lat_deg: must be within ±89° (NED is singular at the poles), got 89.5°",
        ),
        ("lat_deg = -90", "[trajectory] lat_deg: must be within ±89°"),
    ],
)
def test_a_latitude_is_answered_in_degrees(where, capsys, line, message) -> None:
    trajectory = "[trajectory]\nsegments = [[20, 0, 0, 0]]"
    (where / "bad.toml").write_text(f'name = "x"\n{trajectory}\n{line}\n')
    argv = ["simulate", "--scenario", str(where / "bad.toml"), "--out", str(where / "res")]
    line_out = refused(capsys, argv, str(where / "bad.toml"))
    assert message in line_out


@pytest.mark.parametrize("period", ["1e-9", "0.015"])
def test_a_dvl_period_names_the_file_and_table(where, capsys, period) -> None:
    (where / "bad.toml").write_text(f"{SHORT}\n[sensors]\ndvl_period = {period}\n")
    argv = ["simulate", "--scenario", str(where / "bad.toml"), "--out", str(where / "res")]
    line = refused(capsys, argv, f"{where / 'bad.toml'}: [sensors] dvl_period")
    assert "whole multiple of the IMU period" in line


@pytest.mark.parametrize("length", [250, 255])
def test_an_out_name_the_file_system_allows_works(tmp_path, capsys, length) -> None:
    """A legal 250-character ``--out`` once failed on pronet's own hidden lock name."""
    (tmp_path / "short.toml").write_text(SHORT)
    out = tmp_path / ("r" * length)
    argv = ["simulate", "--scenario", str(tmp_path / "short.toml"), "--runs", "1", "--quiet"]
    assert cli.main([*argv, "--strategies", "constant", "--no-plots", "--out", str(out)]) == 0
    assert (out / "metrics.csv").is_file()
    assert [p.name for p in tmp_path.iterdir()] != [] and all(
        len(p.name.encode()) <= 255 for p in tmp_path.iterdir()
    )
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([out.name, "short.toml"])


# --- conflicting options ----------------------------------------------------------------


def test_quick_and_runs_together_are_a_conflict(where, capsys) -> None:
    """``reproduce --quick --runs 5`` once ran 10 runs."""
    line = refused(capsys, ["reproduce", "--quick", "--runs", "5"], "--quick and --runs")
    assert "--quick is --runs 10" in line


def test_an_undefined_r2_is_null_in_json_and_undefined_in_text() -> None:
    from pronet.learn import training

    equal = np.full(50, 0.1)  # every label the same: rounding of the mean is not 0
    scores = training.scores(equal + 1e-3, equal)
    assert math.isnan(scores["r2"])
    report = {"model": scores, "detrended_variance": scores, "cramer_rao_rmse": 1e-3}
    assert "| undefined |" in training.scores_table({"m": report})
