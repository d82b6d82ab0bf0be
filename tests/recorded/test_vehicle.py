"""Your own vehicle: ``pronet real --filter FILE.toml`` with a
scenario's ``[filter]`` keys, the grade presets and the lever arms; the generic format
requires the lever arms; ``--data`` takes one ``.npz``."""

from __future__ import annotations

import json
import re
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from pronet.cli import main
from pronet.config import FILTER_KEYS, ConfigError
from pronet.recorded import vehicle
from pronet.recorded.recordings import write_recording
from pronet.recorded.tuning import REAL_P0_SIGMA, real_filter_config

from synthetic_recording import DVL_LEVER_ARM, IMU_LEVER_ARM, synthetic_recording, with_aiding


def _toml(path, text):
    path.write_text(text)
    return str(path)


def _arms_toml() -> str:
    return f"imu_lever_arm = {list(IMU_LEVER_ARM)}\ndvl_lever_arm = {list(DVL_LEVER_ARM)}\n"


def _within_3sigma(table_md: str, label: str) -> float:
    """``label``'s share of velocity errors within 3σ in table.md's first (summary)
    table, found by its column's header."""
    header: list[str] = []
    for line in table_md.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if line.startswith("| strategy |"):
            header = cells
        elif line.startswith(f"| {label} |") and header:
            return float(cells[header.index("vel. error within 3σ (share)")])
    raise AssertionError(f"no row {label!r}")


def test_pronet_real_with_mems_toml_is_consistent_on_a_simulated_mems_recording(tmp_path, capsys):
    """The acceptance case: a MEMS recording simulated with the mems grade's turn-on
    bias (drawn from its P0) and bias walks, written in the generic format, run with
    ``--filter mems.toml`` telling the filter that model: the velocity error lies within
    its 3σ at >= 95 % of the truth rows."""
    grade = vehicle.GRADES["mems"]
    rng = np.random.default_rng(11)
    bias = tuple(rng.normal(size=6) * np.array(grade["p0_sigma"][9:]))
    psd = (grade["accel_bias_psd"],) * 3 + (grade["gyro_bias_psd"],) * 3
    rec = synthetic_recording(
        seed=11, duration=200.0, name="mems", imu_bias=bias, bias_psd=psd
    ).recording
    write_recording(tmp_path / "mems.npz", rec)
    toml = _toml(
        tmp_path / "mems.toml", 'grade = "mems"\ndvl_variance = [1e-4, 1e-4, 1e-4]\n' + _arms_toml()
    )
    out = tmp_path / "out"
    argv = ["real", "--data", str(tmp_path / "mems.npz"), "--format", "generic"]
    assert main([*argv, "--filter", toml, "--out", str(out), "--quiet", "--no-plots"]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["filter_file"] == toml and config["sections"] == ["mems"]
    assert "dvl_variance=[0.0001, 0.0001, 0.0001]" in config["filter"]
    assert config["dvl_variance"]["mems"]["used"] == [1e-4] * 3
    table = (out / "table.md").read_text()
    within = _within_3sigma(table, "constant (estimated q)")
    assert within >= 0.95, table
    # the FOG tuning, told nothing of the MEMS biases, is not consistent on it
    fog = tmp_path / "fog"
    assert main([*argv, *_arms(), "--out", str(fog), "--quiet", "--no-plots", "--no-models"]) == 0
    fog_within = _within_3sigma((fog / "table.md").read_text(), "constant (estimated q)")
    assert fog_within < within
    capsys.readouterr()


def _arms() -> list[str]:
    return [
        "--imu-lever-arm=" + ",".join(map(str, IMU_LEVER_ARM)),
        "--dvl-lever-arm=" + ",".join(map(str, DVL_LEVER_ARM)),
    ]


def test_the_grades_and_the_keys_of_a_filter_file(tmp_path):
    fog = vehicle.load_vehicle("fog").base
    default = real_filter_config((0.0, 0.0, 0.0))
    assert repr(fog) == repr(default)  # the fog grade is the default tuning
    mems = vehicle.load_vehicle("mems").base
    assert mems.p0_sigma[:9] == list(REAL_P0_SIGMA[:9])
    assert mems.p0_sigma[9] == pytest.approx(9.80665e-3) and mems.gyro_bias_psd > 1e-10
    tactical = vehicle.load_vehicle(
        _toml(tmp_path / "t.toml", 'grade = "tactical"\ngyro_bias_psd = 1e-13\n')
    )
    assert tactical.base.gyro_bias_psd == 1e-13  # a key over its grade
    assert tactical.base.p0_sigma[12] == pytest.approx(5 * np.pi / 180 / 3600)
    assert tactical.imu_lever_arm is None and tactical.dvl_lever_arm is None
    scenario = _toml(
        tmp_path / "s.toml", '[trajectory]\nbuiltin = "paper"\n[filter]\ngrade = "tactical"\n'
    )
    assert repr(vehicle.load_vehicle(scenario).base) == repr(vehicle.load_vehicle("tactical").base)
    own = vehicle.load_vehicle(
        _toml(tmp_path / "o.toml", "imu_lever_arm = [1, 0, 0]\nlever_arm = [0, 0, 0.5]\n")
    )
    assert own.dvl_lever_arm == (1.0, 0.0, 0.5)


def test_every_key_of_a_filter_file_reaches_the_sections_filter(tmp_path):
    # a key the file sets must not be dropped on its way to each section's tuning
    text = "dvl_bias_sigma = [0.02, 0.03, 0.01]\ndvl_bias_time_constant = 45.0\n"
    text += 'innovation_gate = 30.0\naiding = "body"\n'
    base = vehicle.load_vehicle(_toml(tmp_path / "b.toml", text)).base
    arm = (0.1, -0.2, 0.3)
    section = real_filter_config(arm, base=base, calibration=True, covariance_step=0.0)
    for key in FILTER_KEYS:
        expected = getattr(base, key)
        if key == "lever_arm":
            expected = list(arm)
        elif key == "covariance_step":
            expected = 0.0
        assert getattr(section, key) == expected, key
    assert section.dvl_calibration and section.dvl_bias_time_constant == 45.0


def test_the_second_order_heading_term_of_a_filter_file_reaches_all_but_the_calibration_rows(
    tmp_path,
):
    """pronet real's DVL calibration rows run without the term, which their states do not
    take (FilterConfig refuses both: every such row failed); every other row keeps it."""
    base = vehicle.load_vehicle(_toml(tmp_path / "b.toml", "heading_second_order = true\n")).base
    arm = (0.1, -0.2, 0.3)
    assert base.heading_second_order
    assert real_filter_config(arm, base=base).heading_second_order
    calibrated = real_filter_config(arm, base=base, calibration=True)
    assert calibrated.dvl_calibration and not calibrated.heading_second_order
    with pytest.raises(ValueError, match="^heading_second_order: .* se23"):
        real_filter_config(arm, base=base, formulation="se23")


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ('grade = "nav"\n', r"grade: must be one of fog, tactical, mems, got 'nav'"),
        ("imu_dt = 0.005\n", r"imu_dt: pronet real uses each section's own IMU step"),
        ("p0 = 1\n", r"unknown key 'p0'"),
        ("accel_bias_psd = -1\n", r"accel_bias_psd"),
        ("lever_arm = [0, 0, 1]\n", r"lever_arm: the DVL from the IMU needs imu_lever_arm"),
        ("dvl_lever_arm = [1800, 0, 0]\n", r"dvl_lever_arm: must be within"),
        ("fix_sigma = [1e-9, 1e-9, 1e-9]\n", r"fix_sigma: .* at least 0\.001 m"),
    ],
)
def test_a_bad_filter_file_is_one_line_naming_file_and_key(tmp_path, capsys, text, message):
    path = _toml(tmp_path / "bad.toml", text)
    with pytest.raises(ConfigError, match=message):
        vehicle.load_vehicle(path)
    argv = ["real", "--data", str(tmp_path), "--filter", path, "--out", str(tmp_path / "o")]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bad.toml" in err


def test_the_generic_format_requires_the_lever_arms(tmp_path, capsys):
    rec = synthetic_recording(seed=1, duration=70.0, name="s").recording
    write_recording(tmp_path / "s", rec)
    argv = ["real", "--data", str(tmp_path / "s"), "--format", "generic", "--quiet"]
    out = tmp_path / "o"
    assert main([*argv, "--out", str(out), "--dvl-lever-arm=0,0,0"]) == 2
    err = capsys.readouterr().err
    assert "--format generic: needs the IMU's lever arm (--imu-lever-arm" in err
    assert not out.exists()
    # a recording with DVL readings needs the DVL's arm too: the section's one line
    assert main([*argv, "--out", str(out), "--imu-lever-arm=0,0,0"]) == 2
    err = capsys.readouterr().err
    assert "has DVL readings: needs the DVL's lever arm (--dvl-lever-arm" in err
    assert err.count("\n") == 1 and not out.exists()
    # an explicit 0,0,0 is an answer: it runs (on a folder of CSVs as one section)
    zero = ["--imu-lever-arm=0,0,0", "--dvl-lever-arm=0,0,0", "--no-plots", "--no-models"]
    assert main([*argv, "--out", str(out), *zero]) == 0
    config = json.loads((out / "config.json").read_text())
    assert config["imu_lever_arm_m"] == [0, 0, 0] and config["sections"] == ["s"]
    metrics = pd.read_csv(out / "metrics.csv")
    assert set(metrics.scenario.str.split(" ").str[0]) == {"s"}
    capsys.readouterr()


def test_without_dvl_readings_the_generic_format_needs_no_dvl_lever_arm(tmp_path, capsys):
    """A depth/fix-only recording, or ``--no-dvl`` on one with a DVL, runs without
    ``--dvl-lever-arm`` (the DVL's arm is never used there), and the two give the same
    rows."""
    aided = with_aiding(synthetic_recording(seed=1, duration=70.0, name="s"), seed=1)
    with_dvl = write_recording(tmp_path / "dvl" / "s", aided)
    no_dvl = replace(aided, dvl=np.empty((0, 3)), dvl_time=np.empty(0))
    without = write_recording(tmp_path / "none" / "s", no_dvl)
    argv = ["real", "--format", "generic", "--quiet", "--no-plots", "--no-models",
            "--imu-lever-arm=0,0,0"]  # fmt: skip
    assert main([*argv, "--data", str(without), "--out", str(tmp_path / "a")]) == 0
    assert main([*argv, "--data", str(with_dvl), "--no-dvl", "--out", str(tmp_path / "b")]) == 0
    capsys.readouterr()
    a, b = (pd.read_csv(tmp_path / o / "metrics.csv") for o in ("a", "b"))
    assert len(a) and a.strategy.tolist() == b.strategy.tolist()
    assert np.array_equal(a.srmse.to_numpy(), b.srmse.to_numpy(), equal_nan=True)
    assert json.loads((tmp_path / "a" / "config.json").read_text())["dvl_lever_arm_m"] is None


def test_both_levels_of_a_vehicle_file_obey_one_rule(tmp_path):
    """A vehicle's keys may sit at the top level, in a ``[filter]`` table, or both: a
    top-level ``dvl_variance`` beside ``[filter]`` was ignored and top-level lever arms
    reported missing. A key at both levels, or an unknown one at either, is refused; a
    scenario file's own keys beside ``[filter]`` are not read, as before."""
    split = vehicle.load_vehicle(
        _toml(
            tmp_path / "split.toml",
            'name = "auv"\ndvl_variance = [2e-4, 2e-4, 2e-4]\n' + _arms_toml()
            + '[trajectory]\nbuiltin = "paper"\n[filter]\ngrade = "tactical"\n',
        )
    )  # fmt: skip
    assert split.base.dvl_variance == [2e-4] * 3
    assert split.imu_lever_arm == IMU_LEVER_ARM and split.dvl_lever_arm == DVL_LEVER_ARM
    assert repr(split.base.p0_sigma) == repr(vehicle.load_vehicle("tactical").base.p0_sigma)
    for text, message in (
        ("dvl_variance = [1e-4, 1e-4, 1e-4]\n[filter]\ndvl_variance = [2e-4, 2e-4, 2e-4]\n",
         r"both\.toml: dvl_variance: given at the top level and in \[filter\]; give it once"),
        ("dvl_varaince = [1e-4, 1e-4, 1e-4]\n[filter]\ngrade = \"mems\"\n",
         r"both\.toml: unknown key 'dvl_varaince'"),
    ):  # fmt: skip
        with pytest.raises(ConfigError, match=message):
            vehicle.load_vehicle(_toml(tmp_path / "both.toml", text))


@pytest.mark.parametrize(
    ("given", "message"),
    [
        ("Mems", "--filter: 'Mems' is neither a file nor a grade (fog, tactical, mems;"),
        ("", "--filter: empty; give a vehicle file or a grade (fog, tactical, mems)"),
        ("vehicle.toml", "vehicle.toml: no such file"),
    ],
)
def test_a_filter_that_is_no_file_names_the_grades(tmp_path, monkeypatch, given, message):
    """A grade's name mistyped said only 'Mems: no such file'; an empty one 'Is a
    directory' (the current folder)."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError, match=re.escape(message)):
        vehicle.load_vehicle(given)
