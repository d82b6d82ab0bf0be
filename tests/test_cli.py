"""The command line: `pronet info` and `pronet reproduce` end to end (few runs)."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from pronet import cli


def test_info_lists_versions_weights_and_trajectories(capsys) -> None:
    assert cli.main(["info"]) == 0
    text = capsys.readouterr().out
    assert "paper" in text and "torch" in text and "detrend" in text
    assert cli.main(["info", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert Path(info["weights"], "detrend.safetensors").is_file()
    assert "paper" in info["trajectories"] and info["cores"] >= 1


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
    assert [p.name for p in out.parent.iterdir()] == ["res"]
    assert cli.main(["reproduce", "--runs", "2", "--out", str(out)]) == 2


def test_reproduce_rejects_bad_run_count(capsys) -> None:
    assert cli.main(["reproduce", "--runs", "0"]) == 2
    assert cli.main(["reproduce", "--tuning-period", "0"]) == 2
    with pytest.raises(SystemExit):
        cli.main(["reproduce", "--runs", "many"])


def test_ctrl_c_keeps_finished_shards_and_resume_redoes_none_of_them(
    tmp_path, capsys, monkeypatch, reproduced
) -> None:
    """Ctrl-C after 5 of the 14 Monte Carlos: exit 130, no result folder, the 5 kept in
    <out>.partial. --resume computes only the other 9, and the results equal an
    uninterrupted run's."""
    from pronet import experiment

    calls: list[str] = []
    real_mc, real_hybrid = experiment.monte_carlo, experiment.run_hybrid

    def counting(real, interrupt_at=None):
        def wrapped(*a, **kw):
            if interrupt_at is not None and len(calls) == interrupt_at:
                raise KeyboardInterrupt
            calls.append(real.__name__)
            return real(*a, **kw)

        return wrapped

    monkeypatch.setattr(experiment, "monte_carlo", counting(real_mc, interrupt_at=5))
    monkeypatch.setattr(experiment, "run_hybrid", counting(real_hybrid, interrupt_at=5))
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
    monkeypatch.setattr(experiment, "monte_carlo", counting(real_mc))
    monkeypatch.setattr(experiment, "run_hybrid", counting(real_hybrid))
    assert cli.main([*args, "--resume"]) == 0
    assert len(calls) == 14 - 5
    assert not partial.exists()
    whole, _ = reproduced  # the same settings, uninterrupted (2 threads there: same numbers)
    assert (out / "metrics.csv").read_text() == (whole / "metrics.csv").read_text()
