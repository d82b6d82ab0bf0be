"""The command line: `pronet info` and `pronet reproduce` end to end (few runs)."""

from __future__ import annotations

import json

import pytest

from pronet import cli


def test_info_lists_trajectories(capsys) -> None:
    assert cli.main(["info"]) == 0
    assert "paper" in capsys.readouterr().out


PNG = b"\x89PNG\r\n\x1a\n"


def test_reproduce_writes_a_complete_result_folder(tmp_path, capsys) -> None:
    out = tmp_path / "res"
    args = ["reproduce", "--runs", "2", "--out", str(out), "--threads", "2", "--quiet"]
    assert cli.main(args) == 0
    printed = capsys.readouterr().out
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
        "table.md",
        "trajectory.png",
        "velocity_error_paper.png",
        "velocity_error_varying-noise.png",
    ]
    for png in out.glob("*.png"):
        assert png.read_bytes()[:8] == PNG and png.stat().st_size > 20_000, png.name
    metrics = json.loads((out / "metrics.json").read_text())
    assert len(metrics) == 2  # both scenarios
    for rows in metrics.values():
        assert list(rows) == [
            "constant (true q)",
            "constant (20 x q)",
            "adaptive xi=1",
            "adaptive xi=5",
            "HCF-ensemble",
            "baseline net",
            "detrend net",
        ]
        assert rows["constant (true q)"]["srmse"]["n"] == 2
        assert rows["detrend net"]["tunings"] == 328
        assert rows["detrend net"]["srmse_diff_vs_first"]["n"] == 2
    table = (out / "table.md").read_text()
    assert table.count("| detrend net |") == 2
    assert len((out / "metrics.csv").read_text().splitlines()) == 1 + 2 * 7 * 2
    # No temporary folder is left behind, and an existing folder is never overwritten.
    assert [p.name for p in tmp_path.iterdir()] == ["res"]
    assert cli.main(["reproduce", "--runs", "2", "--out", str(out)]) == 2


def test_reproduce_rejects_bad_run_count(capsys) -> None:
    assert cli.main(["reproduce", "--runs", "0"]) == 2
    assert cli.main(["reproduce", "--tuning-period", "0"]) == 2
    with pytest.raises(SystemExit):
        cli.main(["reproduce", "--runs", "many"])
