"""``pronet train``'s options: each one is applied or refused in
one line naming it, before any work; ``--recorded --format generic`` runs with the lever
arms it takes; ``--out FOLDER/`` writes into the folder."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import pytest

from pronet import cli
from pronet.recorded.recordings import write_recording

from synthetic_recording import DVL_LEVER_ARM, IMU_LEVER_ARM, synthetic_recording

ARMS = [
    "--imu-lever-arm=" + ",".join(map(str, IMU_LEVER_ARM)),
    "--dvl-lever-arm=" + ",".join(map(str, DVL_LEVER_ARM)),
]


@pytest.fixture(scope="module")
def generic(tmp_path_factory) -> Path:
    """Two 30 s sections in the generic format."""
    data = tmp_path_factory.mktemp("generic")
    for seed in (0, 1):
        rec = synthetic_recording(seed=seed, duration=30.0, name=f"sec{seed}").recording
        write_recording(data / f"sec{seed}", rec)
    return data


def _refused(capsys, argv: list[str], start: str) -> str:
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"pronet: {start}") and len(err.splitlines()) == 1, err
    return err


def test_the_generic_format_trains_with_the_lever_arms_train_takes(generic, tmp_path, capsys):
    """It asked for --imu-lever-arm or --filter, which train did not take."""
    out = tmp_path / "scale"
    argv = ["train", "--recorded", str(generic), "--format", "generic", "--quiet"]
    assert cli.main([*argv, *ARMS, "--out", str(out)]) == 0
    card = json.loads((tmp_path / "scale.json").read_text())
    assert card["training"]["sections"] == ["sec0", "sec1"]
    capsys.readouterr()
    err = _refused(capsys, [*argv, "--out", str(tmp_path / "x")], "--format generic: needs")
    assert "--imu-lever-arm" in err and "--dvl-lever-arm" in err and "--filter" not in err
    assert not list(tmp_path.glob("x*"))


def test_a_long_lever_arm_is_one_warning_line_naming_the_option(generic, tmp_path, capsys):
    """It was Python's two lines, the source file and line of the library's call and the
    code under it, naming dvl_lever_arm. It is said though Python's filters ignore
    warnings (``-W ignore``)."""
    argv = ["train", "--recorded", str(generic), "--format", "generic", "--quiet"]
    argv += ["--imu-lever-arm=0,0,0", "--dvl-lever-arm=-185,-3,12"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert cli.main([*argv, "--out", str(tmp_path / "m")]) == 0
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("pronet: warning: --dvl-lever-arm: -185,-3,12 m (185 m long)")


def test_out_naming_a_folder_writes_the_model_into_it(generic, tmp_path, capsys):
    """``--out mymodels/`` wrote ``mymodels.safetensors`` beside the folder."""
    argv = ["train", "--recorded", str(generic), "--format", "generic", "--quiet", *ARMS]
    assert cli.main([*argv, "--out", f"{tmp_path / 'mymodels'}/"]) == 0
    assert sorted(p.name for p in (tmp_path / "mymodels").iterdir()) == [
        "recorded-a.json",
        "recorded-a.safetensors",
    ]
    (tmp_path / "existing").mkdir()  # an existing folder, no slash: the same
    assert cli.main([*argv, "--model", "a", "--out", str(tmp_path / "existing")]) == 0
    assert (tmp_path / "existing" / "recorded-a.safetensors").is_file()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["existing", "mymodels"]
    capsys.readouterr()


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--dataset", "d.npz"], "--dataset: only without --recorded/--simulated"),
        (["--data-seed", "3"], "--data-seed: only with --simulated"),
        (["--max-epochs", "3"], "--max-epochs: only without --recorded/--simulated"),
        (["--models", "cnn"], "--models: only with --cross-validate or --held-out"),
        (["--ledger", "l.jsonl"], "--ledger: only with --cross-validate or --held-out"),
        (["--held-out", "0"], "--held-out: must be at least 1, got 0"),
        (["--cross-validate", "--held-out", "1"], "--cross-validate, --held-out: give one"),
        (["--cross-validate", "--force"], "--force: only when training one model"),
        (["--epochs", "2"], "--epochs: only with a cnn or akit model"),
        (["--cross-validate", "--models", "a", "--steps", "2"], "--steps: only with a cnn"),
    ],
)
def test_options_that_do_not_apply_to_a_recorded_run_are_refused(
    generic, tmp_path, capsys, extra, message
):
    """Each was silently ignored (``--held-out 0`` taken as not given)."""
    out = tmp_path / "out"
    argv = ["train", "--recorded", str(generic), "--format", "generic", *ARMS, "--out", str(out)]
    _refused(capsys, [*argv, *extra], message)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--format", "generic"], "--format: only with --recorded DIR"),
        (["--held-out", "2", "--epochs", "1"], "--held-out, --epochs: only with --recorded"),
        (["--imu-lever-arm=0,0,0"], "--imu-lever-arm: only with --recorded DIR"),
        (["--simulated", "100000", "--sections", "a"], "--sections: only with --recorded DIR"),
        (["--simulated", "100000", "--format", "snapir"], "--format: only with --recorded DIR"),
    ],
)
def test_options_of_another_kind_of_training_are_refused(tmp_path, capsys, argv, message):
    """Refused before the dataset is read (here: none) or a recording simulated (here:
    too many to hold)."""
    if "--simulated" not in argv:
        argv = [*argv, "--dataset", str(tmp_path / "none.npz")]
    _refused(capsys, ["train", *argv, "--out", str(tmp_path / "out")], message)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    ("seconds", "reason"),
    [("1e9", "no pass is long enough for a window of 1"), ("1e-9", "must be at least one")],
)
def test_a_window_no_section_holds_names_the_option(generic, tmp_path, seconds, reason, capsys):
    """It was named ``seconds``, the library's argument."""
    argv = ["train", "--recorded", str(generic), "--format", "generic", "--quiet", *ARMS]
    argv += ["--model", "cnn", "--window-seconds", seconds, "--out", str(tmp_path / "m")]
    _refused(capsys, argv, f"--window-seconds: {reason}")
    assert not list(tmp_path.iterdir())
