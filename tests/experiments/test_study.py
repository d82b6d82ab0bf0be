"""``pronet study``: the folder it writes, its statistics and its refusals."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from pronet import cli, results
from pronet.experiments.study import (
    STUDY_COLUMNS,
    STUDY_ROWS,
    oracle_share,
    run_study,
    study_dataframe,
)

ROWS = "constant (true q),oracle,adaptive,detvar"


def test_pronet_study_writes_table_metrics_figure_and_config(tmp_path) -> None:
    out = tmp_path / "study"
    args = ["study", "--runs", "3", "--scenarios", "regimes,outage", "--strategies", ROWS]
    assert cli.main([*args, "--out", str(out), "--quiet"]) == 0
    files = {p.name for p in out.iterdir()}
    assert {"table.md", "study.csv", "summary.csv", "metrics.csv", "metrics.json"} <= files
    assert {"config.json", "study.png"} <= files
    assert not list(tmp_path.glob(".study*"))  # nothing left of the atomic write
    table = pd.read_csv(out / "study.csv")
    assert tuple(table.columns) == STUDY_COLUMNS
    assert list(table["strategy"].unique()) == ROWS.split(",")
    assert tuple(pd.read_csv(out / "metrics.csv").columns) == results.RUN_COLUMNS
    outage = table[table["scenario"] == "outage"]["outage_end_error"]
    assert outage.notna().all() and (outage > 0).all()
    assert table[table["scenario"] == "regimes"]["outage_end_error"].isna().all()
    assert (table["seconds"] > 0).all() and (table["runs"] == 3).all()
    config = json.loads((out / "config.json").read_text())
    assert config["scenarios"]["regimes"]["schedule_seed"] == 0
    assert config["strategies"]["adaptive"] == "adaptive"
    text = (out / "table.md").read_text()
    assert "### regimes: 3 runs per row" in text and "| reference |" in text


def test_the_oracle_share_is_paired_and_undefined_without_a_gain() -> None:
    rng = np.random.default_rng(0)
    ref = 1.0 + 0.1 * rng.standard_normal(50)
    oracle = ref - 0.2 - 0.01 * rng.standard_normal(50)
    half = ref - 0.1
    share, low, high = oracle_share(ref, half, oracle)
    assert share == pytest.approx(0.1 / np.mean(ref - oracle))
    assert low < share < high and high - low < 0.1  # paired: the common noise cancels
    assert oracle_share(ref, oracle, oracle)[0] == pytest.approx(1.0)
    assert all(math.isnan(v) for v in oracle_share(ref, half, ref))  # the oracle gains 0


def test_the_study_table_pairs_every_row_with_the_reference() -> None:
    rows = run_study(4, 2, scenarios=["matched"], labels=["oracle", "constant (0.1 x q)"])
    assert [r.label for r in rows] == ["constant (true q)", "oracle", "constant (0.1 x q)"]
    table = study_dataframe(rows)
    ref = rows[0].result.srmse
    np.testing.assert_allclose(table["srmse_diff"], [np.mean(r.result.srmse - ref) for r in rows])
    assert table["srmse_diff"].iloc[0] == 0.0


def test_pronet_study_smooth_adds_a_smoothed_row_beside_each(tmp_path) -> None:
    """``--smooth``: each row followed by its smoothed one, the same runs smoothed (its
    outage-end error from the smoothed solution), the forward rows as without it."""
    out = tmp_path / "study"
    args = [
        "study",
        "--runs",
        "3",
        "--scenarios",
        "outage",
        "--strategies",
        "constant (true q),oracle",
    ]
    assert cli.main([*args, "--smooth", "--out", str(out), "--quiet"]) == 0
    table = pd.read_csv(out / "study.csv")
    labels = ["constant (true q)", "constant (true q), smoothed", "oracle", "oracle, smoothed"]
    assert list(table["strategy"]) == labels
    plain = run_study(3, 0, scenarios=["outage"], labels=["oracle"])
    np.testing.assert_array_equal(
        table["srmse"].iloc[[0, 2]], [r.result.srmse.mean() for r in plain]
    )
    forward, smoothed = table.iloc[0], table.iloc[1]
    assert smoothed["srmse"] < forward["srmse"]
    assert smoothed["outage_end_error"] != forward["outage_end_error"]
    config = json.loads((out / "config.json").read_text())
    assert config["smooth"] is True and config["strategies"]["oracle, smoothed"] == "oracle"


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--scenarios", "lake"], "--scenarios: unknown"),
        (["--strategies", "kalman"], "--strategies: unknown"),
        (["--runs", "0"], "--runs: must be at least 1"),
        (["--strategies", "oracle,oracle"], "listed twice"),
        (["--tuning-period", "0"], "--tuning-period: must be a finite number of seconds > 0"),
        (["--tuning-period", "inf"], "--tuning-period: must be a finite number of seconds > 0"),
    ],
)
def test_pronet_study_refuses_bad_arguments(tmp_path, capsys, args, message) -> None:
    assert cli.main(["study", *args, "--out", str(tmp_path / "s"), "--quiet"]) == 2
    assert message in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


def test_the_tuning_period_reaches_the_estimators_and_the_config(tmp_path) -> None:
    """``--tuning-period``: detvar estimates q at those instants (its result moves from
    the default's, the constant's does not), and config.json records it."""
    out = tmp_path / "study"
    args = ["study", "--runs", "3", "--scenarios", "regimes", "--strategies", "detvar"]
    assert cli.main([*args, "--tuning-period", "4", "--out", str(out), "--quiet"]) == 0
    assert json.loads((out / "config.json").read_text())["tuning_period_s"] == 4.0
    at_4 = pd.read_csv(out / "study.csv").set_index("strategy")["srmse"]
    labels = ["constant (true q)", "detvar"]
    at_1 = {r.label: r.result.srmse.mean() for r in run_study(3, 0, scenarios=["regimes"],
                                                             labels=labels)}  # fmt: skip
    assert at_4["constant (true q)"] == pytest.approx(at_1["constant (true q)"], rel=1e-12)
    assert at_4["detvar"] != pytest.approx(at_1["detvar"], rel=1e-6)


def test_a_tuning_period_longer_than_a_scenario_is_refused_before_any_run() -> None:
    done: list[str] = []
    with pytest.raises(ValueError, match=r"^matched: detvar: tuning_period: 400 s leaves no"):
        run_study(2, 0, scenarios=["matched"], labels=["detvar"], tuning_period=400.0,
                  on_done=done.append)  # fmt: skip
    assert done == []  # not even the reference row ran


def test_every_study_row_is_a_spec() -> None:
    from pronet.strategies import StrategySpec

    for spec in STUDY_ROWS.values():
        StrategySpec.parse(spec)


@pytest.mark.slow
def test_the_adaptive_and_learned_rows_meet_the_study_bars() -> None:
    """At the study's 100 runs, adaptive never diverges on a study scenario and is no
    worse than the constant told 10x the truth on matched and regimes; on 30 paired runs
    (the study's 100 take a minute of inference) the regressors for real sensor grades
    stay within 5 % of the constant told the truth on matched."""
    labels = ["constant (10 x q)", "adaptive"]
    for name in ("matched", "varying-matched", "regimes", "outage"):
        rows = {r.label: r.result for r in run_study(100, 0, scenarios=[name], labels=labels)}
        assert rows["adaptive"].n_diverged == 0 and rows["adaptive"].n_failed == 0, name
        if name in ("matched", "regimes"):
            assert np.mean(rows["adaptive"].srmse) <= np.mean(rows["constant (10 x q)"].srmse)
    learned = ["HCF-ensemble", "baseline net", "detrend net"]
    rows = {r.label: r.result for r in run_study(30, 0, scenarios=["matched"], labels=learned)}
    reference = np.mean(rows["constant (true q)"].srmse)
    for label in learned:
        assert np.mean(rows[label].srmse) <= 1.05 * reference, label
