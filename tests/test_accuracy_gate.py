"""The accuracy gate (``tests/accuracy_gate.py``): fresh runs against the pinned
baselines, in both directions, and the tables of ``docs/results/accuracy.md`` generated from the
same file."""

from __future__ import annotations

import copy
import subprocess
import sys
from pathlib import Path

import pytest

import accuracy_gate as baselines
from accuracy_gate import FILE, PAGE, SNAPIR

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def fresh() -> baselines.Rows:
    return baselines.fresh_rows(SNAPIR)


@pytest.mark.slow
def test_fresh_runs_match_the_recorded_baselines(fresh):
    recorded = baselines.load(FILE)
    assert {"paper, 8 runs", "varying-noise, 8 runs"} <= set(recorded)
    assert len(recorded["paper, 8 runs"]) == 7
    assert baselines.compare(recorded, fresh) == []


def test_the_accuracy_page_tables_are_generated_from_the_file():
    page = PAGE.read_text()
    assert baselines.BEGIN in page and baselines.END in page
    assert baselines.page_with_tables(page, baselines.load(FILE)) == page


def test_a_page_without_markers_is_refused():
    with pytest.raises(ValueError, match="^page: has no accuracy-baselines markers"):
        baselines.page_with_tables("# no tables here\n", baselines.load(FILE))


@pytest.mark.slow
def test_the_gate_fails_both_ways(fresh):
    recorded = baselines.load(FILE)
    row = ("paper, 8 runs", "constant (true q)")

    def with_recorded(key: str, factor: float) -> list[str]:
        changed = copy.deepcopy(recorded)
        changed[row[0]][row[1]][key] *= factor
        return baselines.compare(changed, fresh)

    # Recorded better than now: the fresh run is a regression.
    (problem,) = with_recorded("srmse", 0.999)
    assert "srmse worse" in problem and "constant (true q)" in problem
    # Recorded worse than now: an improvement nobody recorded.
    (problem,) = with_recorded("max_horizontal", 1.01)
    assert "improved beyond" in problem
    # Inside the tolerances nothing is reported.
    assert with_recorded("srmse", 1 - 1e-7) == []
    assert with_recorded("smae", 1 + 1e-4) == []
    # NIS is judged by its distance from 3, the consistent value.
    nis = recorded[row[0]][row[1]]["mean_nis"]
    (problem,) = with_recorded("mean_nis", (3 + (3 - nis) * 0.5) / nis)
    assert "mean_nis worse" in problem
    # Counts match exactly; a row that is computed but not recorded fails.
    changed = copy.deepcopy(recorded)
    changed[row[0]][row[1]]["n_scored"] += 1
    assert any("n_scored" in p for p in baselines.compare(changed, fresh))
    del changed[row[0]][row[1]]
    assert any("not recorded" in p for p in baselines.compare(changed, fresh))


def test_blessing_without_the_data_keeps_the_recorded_real_rows():
    real = {"real: s1": {"a": {"srmse": 1.0}}}
    recorded = {"paper, 8 runs": {"a": {}}, **real}
    simulated = {"paper, 8 runs": {"a": {"srmse": 2.0}}}
    assert baselines.rows_to_bless(recorded, simulated) == {**simulated, **real}
    # With the data, the fresh real rows replace the recorded ones; a vanished section goes.
    fresh = {**simulated, "real: s2": {"a": {"srmse": 3.0}}}
    assert baselines.rows_to_bless(recorded, fresh) == fresh


def test_baseline_file_is_checked():
    with pytest.raises(ValueError, match="not a pronet accuracy-baselines file"):
        baselines.load(ROOT / "python" / "pronet" / "learn" / "weights" / "detrend.json")


@pytest.mark.slow
def test_the_gate_script_checks_and_blesses(fresh, tmp_path, monkeypatch, capsys):
    """``main`` on the rows computed above: it passes against the file, fails (exit 1)
    against an altered copy, and --bless rewrites the file and the page's tables from
    fresh rows."""
    monkeypatch.setattr(baselines, "fresh_rows", lambda data: fresh)
    data = ["--data", str(SNAPIR)]
    assert baselines.main(["--file", str(FILE), *data]) == 0
    assert "0 departures" in capsys.readouterr().out
    altered = baselines.load(FILE)
    altered["paper, 8 runs"]["constant (true q)"]["srmse"] *= 0.9
    copy_file, page = tmp_path / "baselines.json", tmp_path / "accuracy.md"
    baselines.save(copy_file, altered)
    assert baselines.main(["--file", str(copy_file), *data]) == 1
    assert "srmse worse" in capsys.readouterr().out
    page.write_text(PAGE.read_text())
    bless = ["--bless", "--file", str(copy_file), "--page", str(page)]
    assert baselines.main([*bless, *data]) == 0
    assert baselines.main(["--file", str(copy_file), *data]) == 0
    assert page.read_text() == baselines.page_with_tables(
        page.read_text(), baselines.load(copy_file)
    )
    row = ("paper, 8 runs", "constant (true q)")
    assert baselines.load(copy_file)[row[0]][row[1]]["srmse"] == fresh[row[0]][row[1]]["srmse"]


def test_bless_changes_both_files_or_neither(tmp_path, monkeypatch):
    """A page that cannot take the tables, or cannot be written, leaves the baselines
    file as it was."""
    file, page = tmp_path / "baselines.json", tmp_path / "accuracy.md"
    recorded = baselines.load(FILE)
    baselines.save(file, recorded)
    before = file.read_bytes()
    changed = copy.deepcopy(recorded)
    changed["paper, 8 runs"]["constant (true q)"]["srmse"] *= 0.5
    page.write_text("no markers here\n")
    with pytest.raises(ValueError, match="no accuracy-baselines markers"):
        baselines.bless(file, page, changed)
    assert file.read_bytes() == before and page.read_text() == "no markers here\n"

    page.write_text(PAGE.read_text())
    real_write = baselines.atomic_write

    def failing_page(path, data):
        if Path(path) == page:
            raise OSError(28, "No space left on device", str(path))
        real_write(path, data)

    monkeypatch.setattr(baselines, "atomic_write", failing_page)
    with pytest.raises(OSError, match="No space left"):
        baselines.bless(file, page, changed)
    assert file.read_bytes() == before and page.read_text() == PAGE.read_text()
    monkeypatch.undo()
    baselines.bless(file, page, changed)
    srmse = changed["paper, 8 runs"]["constant (true q)"]["srmse"]
    assert baselines.load(file)["paper, 8 runs"]["constant (true q)"]["srmse"] == srmse
    assert "| constant (true q) |" in page.read_text() and page.read_text() != PAGE.read_text()


def test_bless_takes_no_partial_gate(capsys):
    with pytest.raises(SystemExit) as exit_:
        baselines.main(["--bless", "--strategies", "constant (true q)"])
    assert exit_.value.code == 2
    assert "takes no --strategies" in capsys.readouterr().err


def test_the_gate_runs_as_a_script():
    """``python tests/accuracy_gate.py`` is the documented entry point: it parses its
    arguments there (and the package no longer ships the gate)."""
    out = subprocess.run(
        [sys.executable, str(ROOT / "tests" / "accuracy_gate.py"), "--help"],
        capture_output=True,
        text=True,
        check=True,
    )
    assert "--bless" in out.stdout and "docs/results/accuracy.md" in out.stdout
    assert not (ROOT / "python" / "pronet" / "baselines.py").exists()


def test_the_gate_is_a_developer_tool_not_a_user_command(capsys):
    from pronet import cli

    with pytest.raises(SystemExit):
        cli.main(["--help"])
    listed = capsys.readouterr().out
    assert "reproduce" in listed and "baselines" not in listed
    package = ROOT / "python" / "pronet"
    gates = [*package.rglob("*accuracy_gate*.py"), *package.rglob("gate.py")]
    assert not list(package.rglob("baselines.py")) and not gates
