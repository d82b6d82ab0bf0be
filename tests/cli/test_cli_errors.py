"""One rule for every failure a user can cause: ``pronet: <path or argument>: <reason>``
on one line, exit code 2, no traceback, and the output checked before any computing.
Also: every JSON pronet writes is strict, and identical runs write identical files."""

from __future__ import annotations

import errno
import json
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from cli_output import one_line

from pronet import cli
from pronet._util import files
from pronet.experiments import simulation

SHORT = """
name = "short"
[trajectory]
segments = [[20, 0, 0, 0]]
"""


@pytest.fixture
def scenario(tmp_path: Path) -> Path:
    path = tmp_path / "short.toml"
    path.write_text(SHORT)
    return path


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if a Monte Carlo starts."""

    def must_not_run(*args, **kwargs):
        raise AssertionError("work started before the output was checked")

    monkeypatch.setattr(simulation, "run_strategies", must_not_run)


def simulate(scenario: Path, out: Path, *extra: str) -> list[str]:
    """``pronet simulate`` of two runs into ``out`` (no plots: only the files matter)."""
    args = ["simulate", "--scenario", str(scenario), "--runs", "2", "--out", str(out)]
    return [*args, "--no-plots", *extra]


def test_out_below_a_file_is_refused_before_any_work(tmp_path, scenario, no_work, capsys):
    (tmp_path / "file").write_text("x")
    assert cli.main(simulate(scenario, tmp_path / "file" / "res")) == 2
    line = one_line(capsys)
    assert line.startswith("pronet: --out: ") and "is a file, not a folder" in line


@pytest.mark.parametrize(
    "command",
    [
        ["navigate", "--data", "rec"],
        ["real", "--data", "rec"],
        ["reproduce"],
        ["simulate"],
        ["study"],
        ["sweep"],
        ["dataset"],
        ["train"],
    ],
)
def test_an_empty_out_is_refused_not_taken_for_the_default(command, monkeypatch, capsys):
    """``--out ''`` (an unset shell variable): ``navigate`` and the experiment commands
    wrote to ``results/<command>-<time>``, ``train`` to ``models/``, without a word;
    refused in one line naming the option, before the command runs at all."""
    for module in cli.COMMANDS:  # no command's handler may start
        monkeypatch.setattr(module, "run", lambda args: pytest.fail("the command ran"))
    with pytest.raises(SystemExit) as refused:
        cli.main([*command, "--out", ""])
    assert refused.value.code == 2
    assert one_line(capsys) == (
        f"pronet: --out: expected a path, got ''; leave the option out for its default "
        f"(see pronet {command[0]} --help)"
    )


@pytest.mark.parametrize("out", ["", "  "])
def test_an_empty_out_from_python_is_refused_not_taken_for_the_default(out, tmp_path, monkeypatch):
    """``new_result_folder("")`` (every experiment's ``out=``, e.g. ``run_real(data,
    "")``) made ``results/<command>-<time>`` and a blank one a folder named by its
    spaces: refused as the command line's empty ``--out`` is, nothing made."""
    from pronet._util.outputs import new_result_folder

    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match=r"^--out: expected a path, got '\s*'; None"):
        new_result_folder(out, "real")
    assert list(tmp_path.iterdir()) == []


def test_an_existing_out_is_refused_before_any_work(tmp_path, scenario, no_work, capsys):
    (tmp_path / "res").mkdir()
    assert cli.main(simulate(scenario, tmp_path / "res")) == 2
    assert "exists; choose another --out" in one_line(capsys)


def _unwritable_folder(tmp_path: Path) -> Path:
    """A folder this process may not write into: a read-only one of its own, or, for
    root (who writes into those), one the kernel refuses even to root (/proc/sys)."""
    if os.geteuid() != 0:
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        return locked
    refused = Path("/proc/sys")
    if os.access(refused, os.W_OK):
        pytest.skip("root, and /proc/sys is writable here: no folder refuses root")
    return refused


def test_an_unwritable_out_is_refused_before_any_work(tmp_path, scenario, no_work, capsys):
    locked = _unwritable_folder(tmp_path)
    assert cli.main(simulate(scenario, locked / "res")) == 2
    line = one_line(capsys)
    assert line.startswith(f"pronet: --out: {locked / 'res'}: ") and "is not writable" in line


def test_an_out_another_run_is_writing_is_refused(tmp_path, scenario, no_work, capsys):
    out = tmp_path / "res"
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            textwrap.dedent(
                f"""
                import sys, time
                from pathlib import Path
                from pronet._util import files
                files.reserve_folder(Path({str(out)!r}))
                print("reserved", flush=True)
                sys.stdin.read()
                """
            ),
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == "reserved"
        assert cli.main(simulate(scenario, out)) == 2
        line = one_line(capsys)
        assert f"being written by another run (process {holder.pid})" in line
    finally:
        holder.communicate("")
    assert holder.returncode == 0
    # Once the other run is gone, the folder is free again, and its lock file goes too.
    assert not (tmp_path / ".res.lock").exists()


def test_a_left_over_temporary_folder_of_a_killed_run_is_removed(tmp_path, scenario, capsys):
    left = tmp_path / ".res.k1ll3d_x"  # what atomic_folder leaves when the process is killed
    left.mkdir()
    (left / "table.md").write_text("half")
    other = tmp_path / ".res.v2.abcd1234"  # another folder's (res.v2): not touched
    other.mkdir()
    out = tmp_path / "res"
    assert cli.main(simulate(scenario, out, "--strategies", "constant", "--quiet")) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == [".res.v2.abcd1234", "res", "short.toml"]


def test_a_missing_input_file_is_one_line(tmp_path, capsys):
    missing = tmp_path / "missing.npz"
    assert cli.main(["evaluate", "--dataset", str(missing)]) == 2
    line = one_line(capsys)
    assert str(missing) in line


def test_a_full_disk_is_one_line_naming_the_file(tmp_path, scenario, monkeypatch, capsys):
    def full(folder, *args, **kwargs):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(folder / "table.md"))

    monkeypatch.setattr("pronet.results.write_tables", full)
    out = tmp_path / "res"
    assert cli.main(simulate(scenario, out, "--strategies", "constant", "--quiet")) == 2
    line = one_line(capsys)
    assert "table.md: No space left on device; free some space" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["short.toml"]  # nothing half-written


def test_a_write_the_system_refuses_is_one_line_and_leaves_nothing(tmp_path, scenario):
    """A real refusal from the operating system, also when running as root: the file
    size limit (``ulimit -f``, 64 bytes) lets the lock file be written but not the
    tables, after the Monte Carlo has run. One line naming the result folder, exit 2,
    nothing half-written beside the scenario."""
    import resource

    def small_files() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (64, 64))

    out = tmp_path / "res"
    args = simulate(scenario, out, "--strategies", "constant", "--quiet")
    done = subprocess.run(
        [sys.executable, "-m", "pronet.cli", *args],
        capture_output=True,
        text=True,
        preexec_fn=small_files,
        env={**os.environ, "PYTHONDONTWRITEBYTECODE": "1"},
    )
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr and len(done.stderr.splitlines()) == 1, done.stderr
    expected = f"pronet: {out}: File too large; " + r".*\(ulimit -f\).*\n"
    assert re.fullmatch(expected, done.stderr), done.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["short.toml"]


def test_running_out_of_memory_is_one_line(tmp_path, scenario, monkeypatch, capsys):
    def huge(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(simulation, "run_strategies", huge)
    assert cli.main(simulate(scenario, tmp_path / "res", "--quiet")) == 2
    assert one_line(capsys).startswith("pronet: out of memory")


def test_a_damaged_shard_on_resume_is_one_line(tmp_path, capsys):
    from pronet.shards import ShardStore

    store = ShardStore(tmp_path / "res.partial", {"n_runs": 2})
    path = store._path("paper", "constant")
    path.write_bytes(b"PK\x03\x04 truncated")
    with pytest.raises(ValueError, match=r"res\.partial/.*is damaged .*remove it"):
        store.load("paper", "constant")


def test_user_error_formats_each_kind() -> None:
    assert cli.user_error(ValueError("--runs: must be at least 1")) == "--runs: must be at least 1"
    assert cli.user_error(ValueError("a\nb")) == "a b"
    # the library's argument names become the options that set them
    assert cli.user_error(ValueError("n_runs: too many")) == "--runs: too many"
    assert cli.user_error(ValueError("n_levelsx: y")) == "n_levelsx: y"
    err = OSError(errno.EACCES, "Permission denied", "/x/y")
    assert cli.user_error(err) == "/x/y: Permission denied"
    assert cli.user_error(OSError(errno.ENOSPC, "No space left on device")).startswith(
        "output: No space left on device; free"
    )
    assert cli.user_error(MemoryError()).startswith("out of memory")


def test_json_is_strict_and_plain() -> None:
    import numpy as np

    data = {"a": float("nan"), "b": [np.float32(1.5), np.int64(2), np.inf], "c": Path("p")}
    text = files.json_bytes(data).decode()
    assert json.loads(text) == {"a": None, "b": [1.5, 2, None], "c": "p"}
    assert "NaN" not in text and "Infinity" not in text and text.endswith("\n")
    with pytest.raises(TypeError, match="object is not a plain value"):
        files.json_bytes({"x": object()})


def test_identical_runs_write_identical_json(tmp_path, scenario, capsys) -> None:
    """Two runs with the same settings (a learned row included, whose description once
    held an object's address) write the same config.json and metrics.json, both strict."""
    folders = []
    for name in ("one", "two"):
        out = tmp_path / name
        args = simulate(scenario, out, "--strategies", "constant,detvar", "--quiet")
        assert cli.main(args) == 0
        folders.append(out)

    def not_strict(token: str) -> None:
        pytest.fail(f"a JSON file holds {token}")

    for file in ("config.json", "metrics.json"):
        texts = [(f / file).read_text() for f in folders]
        assert texts[0] == texts[1], file
        json.loads(texts[0], parse_constant=not_strict)


def test_a_learned_strategy_is_described_without_an_address() -> None:
    """What reproduce's config.json records for a learned row: the model's kind and
    weights, the same for two loads of the same model."""
    from pronet.learn.frozen import load_frozen
    from pronet.learn.windowstats import DetrendedVariance
    from pronet.strategies import Learned

    q = (1e-4,) * 3 + (1e-6,) * 3
    one, two = (repr(Learned(load_frozen("detrend"), q)) for _ in range(2))
    assert one == two and " at 0x" not in one
    assert one.startswith("Learned(detrend, weights sha256 ") and "tuning_period=1.0 s" in one
    assert repr(Learned(DetrendedVariance(), q)).startswith("Learned(DetrendedVariance, prior_q=")


# ------------------------------------------- degenerate settings are errors, never silent


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (
            ["--strategies", "constant,detvar", "--tuning-period", "500"],
            "detvar: tuning_period: 500 s leaves no tuning instant in the 20 s run",
        ),
        (
            ["--strategies", "constant,mehra:500"],
            "mehra:500: window: mehra over 500 DVL updates never fills in the 20 s run (20 ",
        ),
        (
            ["--strategies", "adaptive:21"],
            "adaptive:21: window: adaptive over 21 DVL updates never fills",
        ),
    ],
)
def test_a_strategy_that_could_never_act_is_refused_before_any_run(
    tmp_path, scenario, capsys, monkeypatch, extra, message
) -> None:
    from pronet import run as run_module

    def must_not_run(*args, **kwargs):
        raise AssertionError("a row ran")

    monkeypatch.setattr(run_module, "run", must_not_run)
    assert cli.main(simulate(scenario, tmp_path / "res", *extra, "--quiet")) == 2
    assert message in one_line(capsys)
    assert not (tmp_path / "res").exists()


def test_the_longest_window_that_fills_is_accepted(tmp_path, scenario) -> None:
    """20 DVL updates in the 20 s scenario: a window of 20 fills at the last one."""
    out = tmp_path / "res"
    assert cli.main(simulate(scenario, out, "--strategies", "mehra:20", "--quiet")) == 0


def test_a_recorded_run_too_short_to_tune_is_refused() -> None:
    import numpy as np

    from pronet import _core
    from pronet.learn.windowstats import DetrendedVariance
    from pronet.run import Recorded, run
    from pronet.strategies import Learned

    n = 150  # fewer samples than the 200-sample window
    rec = Recorded(
        imu=np.tile([0.0, 0.0, -9.8, 0.0, 0.0, 0.0], (n, 1)),
        imu_time=np.arange(1, n + 1) * 0.01,
        dvl=np.zeros((1, 3)),
        dvl_time=np.array([1.0]),
        t0=0.0,
        lla0=np.array([0.5, 0.6, 0.0]),
        vel0=np.zeros(3),
        rpy0=np.zeros(3),
        config=_core.FilterConfig(),
    )
    learned = Learned(DetrendedVariance(), (1e-4,) * 3 + (1e-6,) * 3)
    too_short = r"^tuning_period: 1 s leaves no tuning instant in the 1\.5 s"
    with pytest.raises(ValueError, match=too_short):
        run(learned, rec)
    with pytest.raises(ValueError, match="^window: mehra over 2 DVL updates never fills"):
        run(_core.Strategy.mehra(2, learned.prior_q), rec)


def test_a_turn_rate_beyond_any_vehicle_is_refused(tmp_path, capsys) -> None:
    fast = tmp_path / "fast.toml"
    fast.write_text('name = "fast"\n[trajectory]\nsegments = [[20, 0, 1e4, 0]]\n')
    assert cli.main(simulate(fast, tmp_path / "res", "--quiet")) == 2
    line = one_line(capsys)
    assert "segments: row 0: a yaw rate of 174.5" in line  # the file gives °/s
    assert "rad/s (10000°/s) is beyond any vehicle; at most 10 rad/s (573°/s)" in line


@pytest.mark.parametrize("strategies", ["constant", "detvar"])
def test_a_run_count_beyond_memory_is_one_line_before_any_allocation(
    tmp_path, scenario, capsys, strategies
) -> None:
    args = simulate(scenario, tmp_path / "res", "--strategies", strategies, "--quiet")
    args[args.index("--runs") + 1] = "1000000000000"
    assert cli.main(args) == 2
    line = one_line(capsys)
    assert line.startswith("pronet: --runs: 1000000000000 runs of this scenario would hold ")
    assert "split them into shards" in line


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["simulate", "--runs", "1e12"], "pronet: --runs: invalid int value: '1e12'"),
        (["simulate", "--no-such-option"], "pronet: unrecognized arguments: --no-such-option"),
        (["real"], "pronet: the following arguments are required: --data"),
        (["no-such-command"], "pronet: command: invalid choice: 'no-such-command'"),
    ],
)
def test_a_malformed_command_line_is_one_line(args, expected, capsys) -> None:
    with pytest.raises(SystemExit) as stop:
        cli.main(args)
    assert stop.value.code == 2
    line = one_line(capsys)
    assert line.startswith(expected) and line.endswith("--help)"), line


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["--levels", "0"], "pronet: --levels: must be >= 1, got 0"),
        (["--levels", "100000000"], "pronet: --levels: 100000000 levels make "),
        (["--seed", "-1"], "pronet: --seed: must be >= 0, got -1"),
    ],
)
def test_dataset_sizes_name_the_option(tmp_path, args, expected, capsys) -> None:
    assert cli.main(["dataset", *args, "--out", str(tmp_path / "d.npz"), "--quiet"]) == 2
    assert one_line(capsys).startswith(expected)
    assert not list(tmp_path.iterdir())


def test_a_dataset_out_that_is_no_npz_is_refused(tmp_path, capsys) -> None:
    """It wrote an .npz under a .txt name, which train and evaluate then took as it."""
    assert cli.main(["dataset", "--out", str(tmp_path / "x.txt"), "--quiet"]) == 2
    assert one_line(capsys).startswith("pronet: --out: a dataset is an .npz file; got ")
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("name", ["fig.pdf", "fig.txt", "fig"])
def test_an_evaluate_figure_that_is_no_png_is_refused(tmp_path, name, capsys) -> None:
    """It wrote PNG bytes under any name (a .pdf, a .txt), after scoring the models."""
    figure = tmp_path / name
    assert cli.main(["evaluate", "--figure", str(figure), "--quiet"]) == 2
    assert one_line(capsys) == f"pronet: --figure: the figure is a .png file; got {figure}"
    assert not list(tmp_path.iterdir())


def test_study_checks_its_arguments_before_saying_anything(tmp_path, capsys) -> None:
    assert cli.main(["study", "--runs", "0", "--out", str(tmp_path / "s")]) == 2
    assert capsys.readouterr().out == ""  # no "study: ... 0 runs each" first
    assert cli.main(["study", "--runs", "0", "--out", str(tmp_path / "s")]) == 2
    assert one_line(capsys) == "pronet: --runs: must be at least 1, got 0"


def test_evaluate_without_a_model_name_is_one_line(tmp_path, capsys) -> None:
    # "--models ," left no name: the dataset was built, then StopIteration escaped
    assert cli.main(["evaluate", "--models", " , ", "--quiet"]) == 2
    assert one_line(capsys) == "pronet: --models: expected shipped names or model files, got ' , '"


@pytest.mark.parametrize("command", ["evaluate", "train"])
def test_a_bad_dataset_file_names_the_option(command, tmp_path, capsys) -> None:
    junk = tmp_path / "d.npz"
    junk.write_bytes(b"junk")
    assert cli.main([command, "--dataset", str(tmp_path / "none.npz"), "--quiet"]) == 2
    assert one_line(capsys) == f"pronet: --dataset: {tmp_path / 'none.npz'}: no such dataset file"
    assert cli.main([command, "--dataset", str(junk), "--quiet"]) == 2
    card = f"pronet: --dataset: cannot read the dataset card {tmp_path}"
    assert one_line(capsys).startswith(card)
