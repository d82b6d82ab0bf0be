"""Files that belong together are replaced together: a model's
weights and card, a dataset and its card, a navigated recording's files. A write that
fails (a file-size limit, an error or Ctrl-C between the renames) leaves the old set;
a process killed between the renames leaves a set the readers still read as the old
one; the hash check of a card against its weights holds throughout."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from pronet.learn import modelfile
from pronet.learn.qmodels import SectionScale, load_model_file

OLD, NEW = (3.0, 0.01), (2.0, 0.5)


def _old_model(path: Path) -> None:
    SectionScale(OLD).save(path, {"training": {"sections": ["old"]}})


def _child(code: str, file_size: int | None = None) -> subprocess.CompletedProcess[str]:
    """Run ``code`` in a fresh Python, its files at most ``file_size`` bytes."""
    import resource

    def limit() -> None:
        if file_size is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (file_size, file_size))

    python = str(Path(__file__).resolve().parents[1] / "python")
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1", "PYTHONPATH": python}
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, preexec_fn=limit, env=env
    )


def _is_old(path: Path) -> None:
    """The model at ``path`` loads (its card's hash matches its weights) and is the old one."""
    assert load_model_file(path).scales == pytest.approx(OLD)


def test_a_file_size_limit_while_a_model_is_replaced_keeps_the_old_pair(tmp_path):
    """The issue's case: the new weights (88 bytes) fit the limit, the new card (4 kB)
    does not. Before, the weights were replaced and the card was not: the old model
    failed its hash check, lost. Now both stay old, and no temporary is left."""
    path = tmp_path / "m"
    _old_model(path)
    card = {"training": {"notes": "x" * 4000}}
    save = (
        f"from pronet.learn.qmodels import SectionScale as S; S({NEW}).save({str(path)!r}, {card})"
    )
    done = _child(save, file_size=2048)
    assert done.returncode == 1 and "OSError: [Errno 27] File too large" in done.stderr
    _is_old(path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.json", "m.safetensors"]


@pytest.mark.parametrize("error", [OSError(errno.EIO, "I/O error"), KeyboardInterrupt()])
def test_an_error_between_the_renames_puts_the_old_pair_back(tmp_path, monkeypatch, error):
    """The weights renamed into place, then the card's rename fails (or Ctrl-C comes):
    the old weights are put back."""
    path = tmp_path / "m"
    _old_model(path)
    rename = os.replace

    def replace(src, dst):
        if str(dst).endswith(".json"):
            raise error
        rename(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(type(error)):
        SectionScale(NEW).save(path, {})
    monkeypatch.undo()
    _is_old(path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.json", "m.safetensors"]


def test_a_process_killed_between_the_renames_leaves_a_readable_pair(tmp_path):
    """Killed (no handler runs) after the weights' rename, before the card's: the old
    card's hash finds the old weights kept beside them; the next write replaces the
    pair and what the killed one left."""
    path = tmp_path / "m"
    _old_model(path)
    code = f"""
import os
rename = os.replace
def replace(src, dst):
    if str(dst).endswith(".json"):
        os._exit(9)
    rename(src, dst)
os.replace = replace
from pronet.learn.qmodels import SectionScale
SectionScale({NEW}).save({str(path)!r}, {{}})
"""
    assert _child(code).returncode == 9
    weights, card = modelfile.paths(path)
    assert json.loads(card.read_text())["training"] == {"sections": ["old"]}  # the old card
    _is_old(path)  # ... with the old weights, kept
    SectionScale(NEW).save(path, {})
    assert load_model_file(path).scales == pytest.approx(NEW)
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".previous")]


def test_a_dataset_and_its_card_are_replaced_together(tmp_path, monkeypatch):
    """The dataset's card failing after its data (before: the new data under the old
    card, refused by its hash check): the old dataset still loads."""
    from pronet.learn.dataset import DatasetParams, build_dataset, load_dataset, save_dataset

    path = tmp_path / "d.npz"
    old = DatasetParams(seed=1, n_levels=2)
    save_dataset(build_dataset(old), path, old)
    new = DatasetParams(seed=2, n_levels=2)
    data = build_dataset(new)
    rename = os.replace

    def replace(src, dst):
        if str(dst).endswith(".json"):
            raise OSError(errno.ENOSPC, "No space left on device")
        rename(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(OSError, match="No space"):
        save_dataset(data, path, new)
    monkeypatch.undo()
    assert (load_dataset(path).windows == build_dataset(old).windows).all()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d.json", "d.npz"]


def test_a_navigated_recordings_files_are_replaced_together(tmp_path, monkeypatch):
    """``write_all`` into a folder holding an earlier run's files, failing at the
    report (the last): every earlier file is put back, none half new."""
    from recorded.test_export import _navigation

    from pronet.recorded import export

    out = tmp_path / "out"
    first = export.write_all(_navigation(n=300), out, figures=False)
    before = {p.name: p.read_bytes() for p in first}
    rename = os.replace

    def replace(src, dst):
        if str(dst).endswith("report.md"):
            raise OSError(errno.EIO, "I/O error")
        rename(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(OSError):
        export.write_all(_navigation(n=320), out, figures=False)
    monkeypatch.undo()
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


@pytest.mark.slow
def test_train_recorded_force_over_a_model_under_a_file_size_limit_keeps_it(tmp_path):
    """The issue's command: ``pronet train --simulated 2 --force`` over an existing model
    file, the file-size limit hit at the card: one line naming the file, exit 2, and
    the old model still loads (``pronet real --model`` reads it so)."""
    path = tmp_path / "m"
    _old_model(path)
    args = ["train", "--simulated", "2", "--model", "a", "--force", "--out", str(path), "--quiet"]
    done = _child(f"import sys; from pronet.cli import main; sys.exit(main({args!r}))", 300)
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith(f"pronet: {path}.json: File too large"), done.stderr
    _is_old(path)
