"""The command line: `pronet info` and `pronet reproduce` end to end (few runs)."""

from __future__ import annotations

import json

import pytest

from pronet import cli


def test_info_lists_trajectories(capsys) -> None:
    assert cli.main(["info"]) == 0
    assert "paper" in capsys.readouterr().out


def test_reproduce_writes_a_complete_result_folder(tmp_path, capsys) -> None:
    out = tmp_path / "res"
    assert cli.main(["reproduce", "--runs", "2", "--out", str(out), "--threads", "2"]) == 0
    printed = capsys.readouterr().out
    assert "constant (true q)" in printed and "1.082" in printed
    assert sorted(p.name for p in out.iterdir()) == [
        "config.json",
        "metrics.csv",
        "metrics.json",
        "table.md",
    ]
    metrics = json.loads((out / "metrics.json").read_text())
    rows = next(iter(metrics.values()))
    assert set(rows) == {"constant (true q)", "constant (20 x q)", "adaptive xi=1", "adaptive xi=5"}
    assert rows["constant (true q)"]["srmse"]["n"] == 2
    assert len((out / "metrics.csv").read_text().splitlines()) == 1 + 4 * 2
    # No temporary folder is left behind, and an existing folder is never overwritten.
    assert [p.name for p in tmp_path.iterdir()] == ["res"]
    assert cli.main(["reproduce", "--runs", "2", "--out", str(out)]) == 2


def test_reproduce_rejects_bad_run_count(capsys) -> None:
    assert cli.main(["reproduce", "--runs", "0"]) == 2
    with pytest.raises(SystemExit):
        cli.main(["reproduce", "--runs", "many"])
