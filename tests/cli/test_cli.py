"""The command line: `pronet info` and `pronet reproduce` end to end (few runs)."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from pronet import cli
from pronet.results import RUN_COLUMNS


def test_info_lists_versions_weights_and_trajectories(capsys) -> None:
    assert cli.main(["info"]) == 0
    text = capsys.readouterr().out
    assert "paper" in text and "torch" in text and "detrend" in text
    assert cli.main(["info", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert Path(info["weights"], "detrend.safetensors").is_file()
    assert "paper" in info["trajectories"] and info["cores"] >= 1
    assert info["ray"]  # the test extras install it
    assert 1 <= info["threads"] <= info["max_threads"] <= 1024


def test_info_reports_the_thread_count_the_environment_sets(monkeypatch, capsys) -> None:
    monkeypatch.setenv("RAYON_NUM_THREADS", "3")
    assert cli.main(["info", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["threads"] == 3
    monkeypatch.setenv("RAYON_NUM_THREADS", "100000")
    assert cli.main(["info"]) == 2
    assert capsys.readouterr().err.startswith("pronet: RAYON_NUM_THREADS: must be 1 to ")


PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def reproduced(tmp_path_factory) -> tuple[Path, str]:
    """One uninterrupted ``reproduce --runs 2``: its folder and what it printed."""
    out = tmp_path_factory.mktemp("reproduce") / "res"
    args = ["reproduce", "--runs", "2", "--out", str(out), "--threads", "2", "--quiet"]
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert cli.main(args) == 0
    return out, printed.getvalue()


@pytest.mark.slow
def test_reproduce_writes_a_complete_result_folder(reproduced) -> None:
    out, printed = reproduced
    assert "constant (true q)" in printed and "1.082" in printed and "detrend net" in printed
    names = sorted(p.name for p in out.iterdir())
    assert names == [
        "config.json",
        "metrics.csv",
        "metrics.json",
        "predicted_vs_true_q.png",
        "q_paper.png",
        "q_varying-noise.png",
        "srmse_smae.png",
        "summary.csv",
        "table.md",
        "trajectory.png",
        "velocity_error_paper.png",
        "velocity_error_varying-noise.png",
    ]
    for png in out.glob("*.png"):
        assert png.read_bytes()[:8] == PNG and png.stat().st_size > 20_000, png.name
    metrics = json.loads((out / "metrics.json").read_text())
    scenarios = list(dict.fromkeys(r["scenario"] for r in metrics))
    assert scenarios == ["paper", "varying-noise"]
    for scenario in scenarios:
        rows = {r["strategy"]: r for r in metrics if r["scenario"] == scenario}
        assert list(rows) == [
            "constant (true q)",
            "constant (20 x q)",
            "mehra xi=1",
            "mehra xi=5",
            "HCF-ensemble",
            "baseline net",
            "detrend net",
        ]
        assert rows["constant (true q)"]["runs"] == 2
        assert rows["detrend net"]["tunings"] == 328 and rows["detrend net"]["tuning_period_s"] == 1
        diff = rows["detrend net"]
        assert diff["srmse_diff_low"] <= diff["srmse_diff"] <= diff["srmse_diff_high"]
        assert rows["constant (true q)"]["srmse_diff"] == 0
    table = (out / "table.md").read_text()
    assert table.count("| detrend net |") == 2
    # Mehra's rows carry the paper's name beside ours in the paper scenario's table;
    # no row of any table is called "adaptive xi" (pronet's adaptive is another row).
    assert table.count("| mehra xi=5 |") == 2 and table.count("| Adaptive ξ=5 |") == 1
    assert "adaptive xi" not in table.lower()
    lines = (out / "metrics.csv").read_text().splitlines()
    assert lines[0] == ",".join(RUN_COLUMNS) and len(lines) == 1 + 2 * 7 * 2
    # No temporary folder is left behind, and an existing folder is never overwritten.
    assert [p.name for p in out.parent.iterdir()] == ["res"]
    assert cli.main(["reproduce", "--runs", "2", "--out", str(out)]) == 2


def test_reproduce_rejects_bad_run_count(capsys, tmp_path) -> None:
    assert cli.main(["reproduce", "--runs", "0"]) == 2
    assert cli.main(["reproduce", "--tuning-period", "0"]) == 2
    # Under half an IMU period: no whole step, a regressor call at every sample (the
    # probe's 1e-9 ran 100 times the default's calls); refused before any run, by name.
    capsys.readouterr()
    out = tmp_path / "res"
    assert cli.main(["reproduce", "--tuning-period", "1e-9", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("pronet: --tuning-period: must be at least one IMU period"), err
    # nothing written (the folder's lock goes with the process, as after any refusal)
    assert [p.name for p in tmp_path.iterdir()] in ([], [".res.lock"])
    with pytest.raises(SystemExit):
        cli.main(["reproduce", "--runs", "many"])


@pytest.mark.slow
def test_ctrl_c_keeps_finished_shards_and_resume_redoes_none_of_them(
    tmp_path, capsys, monkeypatch, reproduced
) -> None:
    """Ctrl-C after 5 of the 14 Monte Carlos: exit 130, no result folder, the 5 kept in
    <out>.partial. --resume computes only the other 9, and the results equal an
    uninterrupted run's."""
    from pronet import run

    calls: list[str] = []
    real_mc, real_hybrid = run.monte_carlo, run.run_hybrid

    def counting(real, interrupt_at=None):
        def wrapped(*a, **kw):
            if interrupt_at is not None and len(calls) == interrupt_at:
                raise KeyboardInterrupt
            calls.append(real.__name__)
            return real(*a, **kw)

        return wrapped

    monkeypatch.setattr(run, "monte_carlo", counting(real_mc, interrupt_at=5))
    monkeypatch.setattr(run, "run_hybrid", counting(real_hybrid, interrupt_at=5))
    out = tmp_path / "res"
    args = ["reproduce", "--runs", "2", "--out", str(out), "--quiet"]
    assert cli.main(args) == 130
    err = capsys.readouterr().err
    assert "5 finished Monte Carlos kept" in err and "--resume" in err
    assert not out.exists()
    partial = tmp_path / "res.partial"
    assert len(list(partial.glob("*.npz"))) == 5
    # Without --resume the interrupted run is not silently overwritten or ignored.
    assert cli.main(args) == 2
    assert "--resume" in capsys.readouterr().err
    # Other settings do not mix with the kept shards.
    assert cli.main([*args, "--seed", "7", "--resume"]) == 2

    calls.clear()
    monkeypatch.setattr(run, "monte_carlo", counting(real_mc))
    monkeypatch.setattr(run, "run_hybrid", counting(real_hybrid))
    assert cli.main([*args, "--resume"]) == 0
    assert len(calls) == 14 - 5
    assert not partial.exists()
    whole, _ = reproduced  # the same settings, uninterrupted (2 threads there: same numbers)
    assert (out / "metrics.csv").read_text() == (whole / "metrics.csv").read_text()


SHORT_SCENARIO = """
name = "short"
[trajectory]
segments = [[20, 0, 0, 0], [20, 0, 3, 0]]
[filter]
innovation_gate = 16.27
"""


@pytest.mark.slow
def test_simulate_runs_chosen_strategies_on_a_scenario_file(tmp_path, capsys) -> None:
    scenario = tmp_path / "short.toml"
    scenario.write_text(SHORT_SCENARIO)
    out = tmp_path / "sim"
    args = ["simulate", "--scenario", str(scenario), "--runs", "3", "--out", str(out)]
    strategies = ["--strategies", "constant,constant:20,mehra:5,learned:detrend"]
    assert cli.main([*args, *strategies, "--json", "--quiet"]) == 0
    captured = capsys.readouterr()
    printed = json.loads(captured.out)  # stdout is exactly one JSON document
    # stderr: what the runs say of the filter (its notes), also with --quiet and --json
    notes = json.loads((out / "config.json").read_text())["notes"]
    assert notes and captured.err.splitlines() == [f"pronet: {n}" for n in notes]
    assert printed["folder"] == str(out)
    rows = {r["strategy"]: r for r in printed["metrics"]}
    assert list(rows) == ["constant", "constant:20", "mehra:5", "learned:detrend"]
    assert rows["mehra:5"]["runs"] == 3 and rows["learned:detrend"]["tunings"] == 38
    assert {r["scenario"] for r in printed["metrics"]} == {"short"}
    names = sorted(p.name for p in out.iterdir())
    assert names == [
        "config.json",
        "metrics.csv",
        "metrics.json",
        "q.png",
        "srmse_smae.png",
        "summary.csv",
        "table.md",
        "trajectory.png",
        "velocity_error.png",
    ]
    config = json.loads((out / "config.json").read_text())
    assert "16.27" in config["filter"] and config["strategies"][2] == "mehra:5"
    # without --json: the table for people; --no-plots: no figures, the same tables
    again = tmp_path / "again"
    bare = [*args[:-1], str(again), "--strategies", "mehra:5", "--quiet", "--no-plots"]
    assert cli.main(bare) == 0
    text = capsys.readouterr().out
    assert "| mehra:5 |" in text and f"results written to {again}" in text
    assert not list(again.glob("*.png")) and (again / "summary.csv").exists()
    # the same seed and strategy: the same numbers
    (repeat,) = json.loads((again / "metrics.json").read_text())
    for key in ("srmse", "srmse_low", "srmse_high", "smae"):
        assert rows["mehra:5"][key] == repeat[key]
    # --formulation classic reaches the filter: recorded, and other numbers
    assert 'formulation="invariant"' in config["filter"]
    classic = tmp_path / "classic"
    argv = [*args[:-1], str(classic), "--strategies", "mehra:5", "--quiet", "--no-plots"]
    assert cli.main([*argv, "--formulation", "classic"]) == 0
    assert 'formulation="classic"' in json.loads((classic / "config.json").read_text())["filter"]
    (old,) = json.loads((classic / "metrics.json").read_text())
    assert old["srmse"] != repeat["srmse"]
    # --covariance-step reaches the filter too: recorded, and other numbers
    assert "covariance_step=0)" in config["filter"]
    stepped = tmp_path / "stepped"
    argv[argv.index(str(classic))] = str(stepped)
    assert cli.main([*argv, "--covariance-step", "0.1"]) == 0
    assert "covariance_step=0.1" in json.loads((stepped / "config.json").read_text())["filter"]
    (step,) = json.loads((stepped / "metrics.json").read_text())
    assert step["srmse"] != repeat["srmse"]
    # --smooth: each row followed by its smoothed one, recorded (Mehra's Q on the paper's
    # filter is no model the smoother can trust: its row may come out either way)
    smoothed = tmp_path / "smoothed"
    argv[argv.index(str(stepped))] = str(smoothed)
    assert cli.main([*argv, "--smooth"]) == 0
    rows = json.loads((smoothed / "metrics.json").read_text())
    assert [r["strategy"] for r in rows] == ["mehra:5", "mehra:5, smoothed"]
    assert rows[0]["srmse"] == repeat["srmse"] and rows[1]["srmse"] != rows[0]["srmse"]
    assert json.loads((smoothed / "config.json").read_text())["smooth"] is True
    assert "| mehra:5, smoothed |" in (smoothed / "table.md").read_text()


def test_simulate_help_lists_every_built_in_scenario(capsys) -> None:
    from pronet.sim.scenarios import SCENARIOS

    with pytest.raises(SystemExit):
        cli.main(["simulate", "--help"])
    text = " ".join(capsys.readouterr().out.split())  # argparse wraps the lines
    assert all(name in text for name in SCENARIOS), text


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--strategies", "mehra:0"], "mehra needs a window >= 1 [DVL updates], e.g."),
        (["--strategies", "adaptive:1e12"], "updates] (a whole number, not '1e12')"),
        (["--strategies", "constant,constant"], "distinct"),
        (["--strategies", "constant,constant:1"], "'constant' and 'constant:1' are the same"),
        (["--strategies", "detvar,learned:detvar"], "'detvar' and 'learned:detvar' are the"),
        (["--strategies", "learned:no/such/model"], "no/such/model"),
        (["--scenario", "lake"], "neither a built-in scenario"),
        (["--filter", "missing.toml"], "missing.toml: no such file"),
        (["--runs", "0"], "--runs: must be at least 1"),
        (["--tuning-period", "-1"], "--tuning-period: must be a finite number of seconds"),
        (["--record-every", "nan"], "--record-every: must be a finite number of seconds"),
        (["--threads", "0"], "--threads: expected 1 to "),
        (["--covariance-step", "-1"], "--covariance-step: covariance_step: must be a finite"),
        (["--covariance-step", "nan"], "--covariance-step: covariance_step: must be a finite"),
    ],
)
def test_simulate_refuses_bad_input_before_any_work(
    tmp_path, capsys, monkeypatch, extra, message
) -> None:
    from pronet import run

    def must_not_run(*args, **kwargs):
        raise AssertionError("a Monte Carlo ran")

    monkeypatch.setattr(run, "run", must_not_run)
    out = tmp_path / "sim"
    assert cli.main(["simulate", "--runs", "2", "--out", str(out), *extra]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


SWEEP_GRID = """
scenarios = ["short.toml"]
strategies = ["constant", "mehra:5"]
noise_levels = [1, 9]
runs = 3
shard_runs = 2
"""


def test_sweep_writes_one_merged_result_folder_and_resumes(tmp_path, capsys, monkeypatch) -> None:
    from pronet.experiments import sweep

    (tmp_path / "short.toml").write_text(SHORT_SCENARIO)
    (tmp_path / "grid.toml").write_text(SWEEP_GRID)
    out = tmp_path / "sweep"
    args = ["sweep", str(tmp_path / "grid.toml"), "--out", str(out), "--quiet", "--threads", "2"]
    real = sweep.run_shard
    calls: list[str] = []

    def interrupt_after_three(shard, threads=None):
        if len(calls) == 3:
            raise KeyboardInterrupt
        calls.append(shard.label)
        return real(shard, threads)

    monkeypatch.setattr(sweep, "run_shard", interrupt_after_three)
    assert cli.main(args) == 130
    assert "3 finished shards kept" in capsys.readouterr().err and not out.exists()
    assert cli.main(args) == 2  # the interrupted sweep is not silently replaced
    assert "--resume" in capsys.readouterr().err
    calls.clear()
    monkeypatch.setattr(sweep, "run_shard", lambda shard, threads=None: real(shard, threads))
    assert cli.main([*args, "--resume", "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    summary = printed["summary"]
    assert [(r["strategy"], r["noise_level"]) for r in summary] == [
        ("constant", 1.0),
        ("mehra:5", 1.0),
        ("constant", 9.0),
        ("mehra:5", 9.0),
    ]
    assert all(r["runs"] == 3 and r["tuning_period_s"] is None for r in summary)
    assert sorted(p.name for p in out.iterdir()) == [
        "config.json",
        "metrics.csv",
        "metrics.json",
        "srmse_vs_noise_level.png",
        "summary.csv",
        "table.md",
    ]
    assert not (tmp_path / "sweep.partial").exists()
    # the same grid uninterrupted gives the same numbers
    assert cli.main([*args[:3], str(tmp_path / "whole"), "--quiet"]) == 0
    assert "| mehra:5 | 9 |" in capsys.readouterr().out
    assert (tmp_path / "whole" / "metrics.csv").read_text() == (out / "metrics.csv").read_text()


def test_sweep_errors_name_the_file_and_key(tmp_path, capsys) -> None:
    (tmp_path / "short.toml").write_text(SHORT_SCENARIO)
    grid = tmp_path / "grid.toml"
    grid.write_text(SWEEP_GRID.replace("runs = 3", "runs = 'three'"))
    assert cli.main(["sweep", str(grid), "--out", str(tmp_path / "o")]) == 2
    assert f"{grid}: runs: expected a whole number" in capsys.readouterr().err
    grid.write_text('scenarios = ["paper"]\nstrategies = ["constant"]\n')
    assert cli.main(["sweep", str(grid), "--address", "auto"]) == 2
    assert "--address: only with --engine ray" in capsys.readouterr().err
    # a bad thread count is refused before anything is saved: the next run is not blocked
    out = tmp_path / "sw"
    assert cli.main(["sweep", str(grid), "--out", str(out), "--threads", "0"]) == 2
    assert "threads: expected 1 to " in capsys.readouterr().err
    assert not out.exists() and not (tmp_path / "sw.partial").exists()


@pytest.mark.slow
def test_dataset_train_and_evaluate_on_a_small_dataset(tmp_path, capsys) -> None:
    data = tmp_path / "small.npz"
    assert cli.main(["dataset", "--out", str(data), "--levels", "1", "--json"]) == 0
    made = json.loads(capsys.readouterr().out)
    assert made["examples"] == 4800 and made["train"] + made["test"] == 4800
    models = tmp_path / "models"
    train = ["train", "--dataset", str(data), "--model", "baseline", "--max-epochs", "1"]
    assert cli.main([*train, "--out", str(models), "--quiet", "--json"]) == 0
    report = json.loads(capsys.readouterr().out)["models"]["baseline"]
    assert report["n_test"] == made["test"] and report["model"]["rmse"] > 0
    # one noise level: every label is the same, so R² is undefined (null), not -3e29
    assert report["model"]["r2"] is None
    assert (models / "baseline.safetensors").is_file() and (models / "baseline.json").is_file()
    # a model of the same name is not replaced without --force
    weights = (models / "baseline.safetensors").read_bytes()
    assert cli.main([*train, "--out", str(models), "--quiet"]) == 2
    assert "baseline.safetensors exists; use --force" in capsys.readouterr().err
    assert (models / "baseline.safetensors").read_bytes() == weights
    figure = tmp_path / "fig.png"
    evaluate = ["evaluate", "--dataset", str(data), "--figure", str(figure)]
    assert cli.main([*evaluate, "--models", f"{models / 'baseline'},hcf"]) == 0
    text = capsys.readouterr().out
    assert "hcf" in text and "figure written" in text and "| undefined |" in text
    assert figure.read_bytes()[:4] == b"\x89PNG"
    # the figure is not replaced without --force; a bad model file fails before any
    # work, naming the file
    assert cli.main([*evaluate, "--models", "hcf"]) == 2
    assert "--figure: " in capsys.readouterr().err
    (tmp_path / "bad.json").write_text("{")
    assert cli.main([*evaluate, "--force", "--models", str(tmp_path / "bad")]) == 2
    assert "bad" in capsys.readouterr().err


def test_simulate_library_reports_through_callbacks_and_never_prints(tmp_path, capsys) -> None:
    from pronet import config
    from pronet.experiments.simulation import simulate

    (tmp_path / "short.toml").write_text(SHORT_SCENARIO)
    events: list[tuple[object, ...]] = []
    folder = simulate(
        config.load_scenario(tmp_path / "short.toml"),
        ["constant", " mehra:5 "],
        tmp_path / "out",
        n_runs=2,
        say=lambda text: events.append(("say", text)),
        on_start=lambda total, unit, desc: events.append(("start", total, unit, desc)),
        on_done=lambda label: events.append(("done", label)),
    )
    assert folder == tmp_path / "out" and (folder / "table.md").is_file()
    settings = json.loads((folder / "config.json").read_text())
    # then one "say" per note: a row whose runs leave their NIS band (the short scenario's
    # filter is not told its sensors' model)
    notes = [("say", line) for line in settings["notes"]]
    assert [e[0] for e in events] == ["say", "start", "done", "done"] + ["say"] * len(notes)
    assert events[1:4] == [
        ("start", 2, "strategy", None),
        ("done", "constant"),
        ("done", "mehra:5"),
    ]
    assert events[4:] == notes
    assert capsys.readouterr() == ("", "")
    assert settings["scenario"] == "short" and settings["strategies"] == ["constant", "mehra:5"]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"n_runs": 0}, "--runs: must be at least 1, got 0"),
        ({"tuning_period": float("nan")}, "--tuning-period: must be a finite number"),
        ({"threads": 0}, "--threads: expected 1 to "),
        ({"resume": True, "retrain": True}, "--resume: needs the --out"),
        ({"exists": True}, "exists; choose another --out"),
        ({"partial": True}, "add --resume to continue"),
    ],
)
def test_reproduce_library_checks_arguments_before_any_work(
    tmp_path, monkeypatch, kwargs, message
) -> None:
    from pronet import run
    from pronet.experiments.reproduce import reproduce
    from pronet.learn import models

    def must_not_run(*args, **kwargs):
        raise AssertionError("work started")

    monkeypatch.setattr(run, "run", must_not_run)
    monkeypatch.setattr(models, "load", must_not_run)
    out = tmp_path / "res"
    if kwargs.pop("exists", False):
        out.mkdir()
    if kwargs.pop("partial", False):
        (tmp_path / "res.partial").mkdir()
    with pytest.raises(ValueError, match=message):
        reproduce(out, **kwargs)
    assert not (tmp_path / "res.partial").exists() or message.startswith("add --resume")
