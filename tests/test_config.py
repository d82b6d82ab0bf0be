"""TOML configs (scenario, filter, sweep grid) and strategy specs: what they build, and
errors that name the file, the table and the key before anything runs."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import pronet
from pronet import config
from pronet._util.plausibility import PlausibilityWarning
from pronet.config import ConfigError
from pronet.sim import paper, scenarios
from pronet.strategies import StrategySpec


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_a_scenario_file_builds_its_trajectory_sensors_and_filter(tmp_path) -> None:
    path = write(
        tmp_path,
        "turns.toml",
        """
        [trajectory]
        segments = [[20, 0.1, 0, 0], [30, 0, 3, -0.5]]
        lat_deg = 10.0
        heading_deg = 90.0
        speed_mps = 2.0
        [sensors]
        imu_variance = [4e-4, 4e-4, 4e-4, 4e-6, 4e-6, 4e-6]
        dvl_period = 0.5
        [filter]
        dvl_variance = [0.02, 0.02, 0.03]
        innovation_gate = 16.27
        """,
    )
    sc = config.load_scenario(path)
    assert sc.name == "turns"  # the file name
    assert sc.trajectory.duration == pytest.approx(50.0)
    assert sc.trajectory.lla[0, 0] == pytest.approx(math.radians(10.0))
    assert sc.trajectory.rpy[0, 2] == pytest.approx(math.radians(90.0))
    assert sc.trajectory.vel_ned[0] == pytest.approx([0.0, 2.0, 0.0], abs=1e-12)  # east
    expect = pronet.trajectory_from_segments(
        [
            pronet.Segment(20, 0.1),
            pronet.Segment.degrees(30, 0, 3, -0.5),
        ],
        lla0=(math.radians(10), math.radians(34), -5.0),
        speed0=2.0,
        rpy0=(0, 0, math.radians(90)),
    )
    np.testing.assert_array_equal(sc.trajectory.imu, expect.imu)
    assert sc.sensors.dvl_period == 0.5
    assert sc.sensors.dvl_variance == [0.01] * 3  # the base's, not overridden
    assert sc.config.dvl_variance == [0.02, 0.02, 0.03]
    assert sc.config.innovation_gate == 16.27
    assert sc.config.accel_bias_psd == paper.paper_filter_config().accel_bias_psd
    # a constant variance set in [sensors] is what the constant rows are told
    assert sc.q_nominal == (4e-4,) * 3 + (4e-6,) * 3


def test_a_schedule_is_told_as_its_time_average_unless_q_nominal_is_given(tmp_path) -> None:
    text = """
        [trajectory]
        builtin = "paper"
        [sensors]
        imu_variance_times = [0, 110]
        imu_variance = [[1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6], [4e-4, 4e-4, 4e-4, 4e-6, 4e-6, 4e-6]]
        """
    sc = config.load_scenario(write(tmp_path, "s.toml", text))
    # 110 s at q, 220 s at 4q over the 330 s trajectory: a mean of 3q
    assert sc.q_nominal == pytest.approx((3e-4,) * 3 + (3e-6,) * 3)
    assert sc.schedule_time.tolist() == [0, 110]
    told = write(tmp_path, "t.toml", "q_nominal = [1, 1, 1, 2, 2, 2]\n" + text)
    told = config.load_scenario(told)
    assert told.q_nominal == (1, 1, 1, 2, 2, 2)


def test_a_scenario_starts_from_its_base() -> None:
    doc = {"base": "varying-noise", "filter": {"gyro_bias_psd": 1e-5}}
    sc = config.scenario(doc, "inline", "mine")
    base = scenarios.varying_noise_scenario()
    assert sc.name == "mine"
    assert sc.q_nominal == base.q_nominal
    np.testing.assert_array_equal(sc.schedule_q, base.schedule_q)
    assert sc.config.gyro_bias_psd == 1e-5 and sc.config.accel_bias_psd == 1e-3
    assert config.load_scenario("paper").name == "paper"


def test_a_filter_file_holds_the_filter_keys_at_the_top(tmp_path) -> None:
    cfg = config.load_filter_config(
        write(tmp_path, "f.toml", 'aiding = "nav"\nimu_dt = 0.02\nlever_arm = [0.5, 0, 0]\n')
    )
    assert cfg.aiding == "nav" and cfg.imu_dt == 0.02 and cfg.lever_arm == [0.5, 0.0, 0.0]
    assert cfg.dvl_variance == pronet.FilterConfig().dvl_variance
    assert cfg.covariance_step == pronet.FilterConfig().covariance_step  # the default unless named
    stepped = config.load_filter_config(write(tmp_path, "s.toml", "covariance_step = 0.1\n"))
    assert stepped.covariance_step == 0.1


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[filter]\ndvl_variance = [0.02, 0.02]\n", "[filter] dvl_variance: expected 3"),
        ("[filter]\ndvl_varience = 1\n", "[filter] dvl_varience: unknown key"),
        ("[filter]\naccel_bias_psd = 'small'\n", "[filter] accel_bias_psd: expected a real"),
        ("[filter]\naccel_bias_psd = -1.0\n", "[filter] accel_bias_psd"),
        ("[filter]\naiding = 'ned'\n", "[filter] aiding"),
        ("[filter]\ncovariance_step = -0.1\n", "[filter] covariance_step: must be a finite"),
        ("[filter]\ncovariance_step = nan\n", "[filter] covariance_step: must be a finite"),
        ("[sensors]\ndvl_period = true\n", "[sensors] dvl_period"),
        ("[sensors]\nimu_variance_times = [0, 10]\n", "[sensors] imu_variance_times: needs"),
        ("[sensors]\nimu_variance = [1, 2, 3]\n", "[sensors] imu_variance"),
        ("[trajectory]\nbuiltin = 'circle'\n", "[trajectory] builtin: 'circle' is not one"),
        ("[trajectory]\nbuiltin = 'paper'\nlat_deg = 3\n", "[trajectory] lat_deg: not used"),
        ("[trajectory]\nspeed_mps = 3\n", "[trajectory]: give either builtin or segments"),
        ("[trajectory]\nsegments = [[1, 2]]\n", "[trajectory] segments: expected rows"),
        ("[trajectory]\nsegments = [[10, 0, 0, 0]]\nlat_deg = 'n'\n", "[trajectory] lat_deg"),
        ("[trajectory]\nsegments = [[-10, 0, 0, 0]]\n", "[trajectory] segments"),
        ("[trajectory]\nsegments = [[10, 0, 0, 0]]\ndt_s = '0.01'\n", "[trajectory] dt_s:"),
        ("[trajectory]\nsegments = [[10, 0, 0, 0]]\ndt_s = 0\n", "[trajectory] dt_s: must"),
        ("[trajectory]\nsegments = [[10, 0, 0, 0]]\nheight_m = 'a'\n", "height_m: expected"),
        ("[trajectory]\nsegments = [[10, 0, 0, 0]]\nspeed_mps = true\n", "speed_mps: expected"),
        ("[trajectory]\nbuiltin = 'paper'\ndt_s = 'x'\n", "[trajectory] dt_s: expected"),
        # one type rule: text and booleans are not numbers, in a list as anywhere
        (
            "[trajectory]\nsegments = [['60', 0, 0, 0]]\n",
            "segments: expected real numbers, got '60'",
        ),
        (
            "[trajectory]\nsegments = [[60, true, false, 0]]\n",
            "segments: expected real numbers, got True",
        ),
        (
            "[trajectory]\nsegments = [[true, 0, 0, 0]]\n",
            "segments: expected real numbers, got True",
        ),
        # answered in the unit the file gives
        (
            "[trajectory]\nsegments = [[10, 0, 0, 0]]\nlat_deg = 89.5\n",
            "lat_deg: must be within ±89° (NED is singular at the poles), got 89.5°",
        ),
        (
            "[sensors]\ndvl_period = 1e-9\n",
            "[sensors] dvl_period: must be a whole multiple of the IMU period",
        ),
        ("[sensors]\nlever_arm = [1e9, 0, 0]\n", "[sensors] lever_arm: must be within ±1000 m"),
        # a boolean in a fix's list must not be read as 1; a sensor scheduled past the
        # run's end is refused as a fix source is
        (
            "[[sensors.fixes]]\nsigma = [true, 2]\nperiod = 60.0\n",
            "[sensors] fixes[0].sigma: expected real numbers, got True",
        ),
        ("[[sensors.fixes]]\nsigma = [2, 2]\ntimes = [false, 9]\n", "fixes[0].times: expected"),
        (
            "[sensors]\ndepth_sigma = 0.1\ndepth_period = 1000.0\n",
            "[sensors] depth_period: schedules no depth reading inside the trajectory's 330 s "
            "(period 1000 s): the sensor would take no reading",
        ),
        (
            "[sensors]\nheading_sigma = 0.01\nheading_period = 331.0\n",
            "[sensors] heading_period: schedules no heading reading inside the trajectory's",
        ),
        (
            "[sensors]\ndvl_period = 400.0\n",
            "[sensors] dvl_period: schedules no DVL reading inside the trajectory's 330 s "
            "(period 400 s): the sensor would take no reading (dvl_period = 0: no DVL)",
        ),
        (
            "[sensors]\ndepth_sigma = 0.1\ndepth_period = 10.0\n"
            "[trajectory]\nsegments = [[5, 0, 0, 0]]\n",
            "[sensors] depth_period: schedules no depth reading inside the trajectory's 5 s",
        ),
        ("[filter]\nlever_arm = [0, 0, -1e9]\n", "[filter] lever_arm: must be within ±1000 m"),
        # in the file's units (these ran: a roll of 200° as -160°, a 1e9 m height to a
        # velocity error of 88 km/s)
        ("[trajectory]\nsegments = [[60, 0, 0, 0]]\nlon_deg = 500\n", "lon_deg: must be within"),
        ("[trajectory]\nsegments = [[60, 0, 0, 0]]\nheight_m = 1e9\n", "height_m: must be "),
        ("[trajectory]\nsegments = [[60, 0, 0, 0]]\nroll_deg = 200\n", "roll_deg: must be "),
        ("base = 'lake'\n", "base: 'lake' is not one of paper, varying-noise"),
        ("colour = 'red'\n", "colour: unknown key"),
        ("q_nominal = [1, 2]\n", "q_nominal: expected 6"),
        ("q_nominal = [1, 1, 1, 1, 1, -1]\n", "q_nominal: expected 6"),
        ("name = ''\n", "name: expected non-empty"),
        ("filter = 3\n", "[filter]: expected a table"),
        ("[filter\n", "not valid TOML"),
    ],
)
def test_scenario_errors_name_the_file_and_key(tmp_path, text, message) -> None:
    path = write(tmp_path, "bad.toml", text)
    with pytest.raises(ConfigError) as err:
        config.load_scenario(path)
    assert message in str(err.value)
    assert str(err.value).startswith(str(path))


def test_a_missing_or_unknown_scenario_says_so(tmp_path) -> None:
    with pytest.raises(ConfigError, match="no such file"):
        config.load_scenario(tmp_path / "none.toml")
    with pytest.raises(ConfigError, match="neither a built-in scenario"):
        config.load_scenario("lake")


@pytest.mark.parametrize(
    ("text", "kind", "factor", "model"),
    [
        ("constant", "constant", 1.0, ""),
        ("constant:20", "constant", 20.0, ""),
        ("constant:0.5", "constant", 0.5, ""),
        ("mehra:5", "mehra", 5.0, ""),
        ("learned:detrend", "learned", 0.0, "detrend"),
        ("learned:models/my net", "learned", 0.0, "models/my net"),
        ("oracle", "oracle", 0.0, ""),
        ("adaptive", "adaptive", 60.0, ""),
        ("adaptive:30", "adaptive", 30.0, ""),
        ("detvar", "detvar", 0.0, ""),
        ("learned:detvar", "detvar", 0.0, ""),
    ],
)
def test_strategy_specs_parse(text, kind, factor, model) -> None:
    spec = StrategySpec.parse(text)
    assert (spec.text, spec.kind, spec.factor, spec.model) == (text, kind, factor, model)
    assert spec.uses_tuning_period == (kind in ("learned", "detvar"))


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("mehra", "mehra needs a window"),
        ("mehra:0", "mehra needs a window"),
        ("mehra:2.5", "mehra needs a window"),
        ("constant:0", "must be finite and > 0"),
        ("constant:inf", "must be finite and > 0"),
        ("constant:x", "'x' is not a number"),
        ("learned:", "learned needs a model"),
        ("adaptive:0", "adaptive needs a window"),
        ("adaptive:x", "adaptive needs a window"),
        ("oracle:2", "oracle takes no argument"),
        ("detvar:200", "detvar takes no argument"),
        ("kalman", "expected constant[:S], oracle, adaptive[:W], mehra:W, detvar or learned"),
        (5, "expected text"),
    ],
)
def test_bad_strategy_specs_say_what_is_wrong(text, message) -> None:
    with pytest.raises(ValueError, match=message.replace("[", r"\[")):
        StrategySpec.parse(text)


def test_the_paper_rows_are_built_from_specs() -> None:
    rows = paper.model_based_strategies((1e-4,) * 3 + (1e-6,) * 3)
    assert list(rows) == list(paper.PAPER_ROWS)[:4]
    assert list(rows)[:2] == ["constant (true q)", "constant (20 x q)"]
    assert rows["constant (20 x q)"].q == [20 * 1e-4] * 3 + [20 * 1e-6] * 3
    assert rows["mehra xi=5"].window == 5
    assert paper.LEARNED_LABELS == {
        "paper-hcf": "HCF-ensemble",
        "paper-baseline": "baseline net",
        "paper-detrend": "detrend net",
    }


GRID = """
scenarios = ["paper", "short.toml"]
strategies = ["constant", "mehra:5", "learned:detrend"]
tuning_periods_s = [1.0, 2.0]
noise_levels = [1, 4]
runs = 10
shard_runs = 4
seed = 3
"""


def test_a_sweep_file_is_checked_whole(tmp_path) -> None:
    write(tmp_path, "short.toml", "[trajectory]\nsegments = [[30, 0, 0, 0]]\n")
    grid = config.load_sweep(write(tmp_path, "grid.toml", GRID))
    assert [s.name for s in grid.scenarios] == ["paper", "short"]
    assert [s.text for s in grid.strategies] == ["constant", "mehra:5", "learned:detrend"]
    assert (grid.tuning_periods, grid.noise_levels) == ((1.0, 2.0), (4.0 / 4, 4.0))
    assert (grid.runs, grid.shard_runs, grid.seed) == (10, 4, 3)
    assert grid.scenarios[1].build().trajectory.duration == pytest.approx(30.0)
    plain = grid.as_dict()
    assert plain["scenarios"]["paper"] == "paper" and "segments" in plain["scenarios"]["short"]


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (("runs = 10", "runs = 0"), "runs: expected a whole number >= 1"),
        (("runs = 10", "runs = 2.5"), "runs: expected a whole number"),
        (("seed = 3", "seed = -1"), "seed: expected a whole number >= 0"),
        (("noise_levels = [1, 4]", "noise_levels = [1, -4]"), "noise_levels: expected finite"),
        (("noise_levels = [1, 4]", "noise_levels = []"), "noise_levels: expected a non-empty"),
        (("noise_levels = [1, 4]", "noise_levels = [1, 1]"), "noise_levels: lists a value twice"),
        (("noise_levels = [1, 4]", "noise_levels = [1, 1.0]"), "noise_levels: lists a value"),
        (("[1.0, 2.0]", "[2, 2.0]"), "tuning_periods_s: lists a value twice"),
        (('"mehra:5"', '"mehra:99999999999999999999999"'), "strategies: window"),
        (('"mehra:5"', '"mehra:five"'), "strategies: strategy 'mehra:five'"),
        (('"learned:detrend"', '"learned:nowhere"'), "strategies: 'learned:nowhere': "),
        (('"short.toml"', '"lake"'), "scenarios: 'lake' is neither"),
        (('"short.toml"', '"gone.toml"'), "gone.toml: no such file"),
        (('"short.toml"', '"bad.toml"'), "bad.toml: [filter] imu_dt"),
        (('"short.toml"', '"paper.toml"'), "two scenarios are named alike"),
        (("seed = 3", "seeds = 3"), "seeds: unknown key"),
        (('strategies = ["constant", "mehra:5", "learned:detrend"]', ""), "strategies: missing"),
    ],
)
def test_sweep_errors_point_at_the_key(tmp_path, change, message) -> None:
    write(tmp_path, "short.toml", "[trajectory]\nsegments = [[30, 0, 0, 0]]\n")
    write(tmp_path, "bad.toml", "[filter]\nimu_dt = 0\n")
    write(tmp_path, "paper.toml", "")  # a scenario file named like the built-in
    old, new = change
    assert old in GRID
    path = write(tmp_path, "grid.toml", GRID.replace(old, new))
    with pytest.raises(ConfigError) as err:
        config.load_sweep(path)
    assert message in str(err.value)


def test_a_sweep_finds_model_files_beside_it(tmp_path) -> None:
    import shutil

    from pronet.learn import modelfile

    (tmp_path / "nets").mkdir()
    for suffix in (".safetensors", ".json"):
        shutil.copy(modelfile.SHIPPED_DIR / f"baseline{suffix}", tmp_path / "nets")
    grid = 'scenarios = ["paper"]\nstrategies = ["learned:nets/baseline"]\n'
    path = write(tmp_path, "grid.toml", grid)
    (spec,) = config.load_sweep(path).strategies
    assert spec.text == "learned:nets/baseline"
    assert Path(spec.model) == (tmp_path / "nets" / "baseline").resolve()


def test_the_readme_toml_examples_load(tmp_path) -> None:
    """The scenario and sweep files shown in the README are valid as written."""
    import re

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    blocks = dict(
        (m.group(1), m.group(2))
        for m in re.finditer(r"```toml\n# (\S+)\n(.*?)```", readme, flags=re.S)
    )
    assert set(blocks) == {"my-scenario.toml", "grid.toml"}
    for name, text in blocks.items():
        write(tmp_path, name, text)
    sc = config.load_scenario(tmp_path / "my-scenario.toml")
    assert sc.name == "fast-turns" and sc.trajectory.duration == pytest.approx(165.0)
    grid = config.load_sweep(tmp_path / "grid.toml")
    assert [s.name for s in grid.scenarios] == ["paper", "fast-turns"]


def test_the_docstring_examples_load() -> None:
    """The scenario and sweep shown in pronet.config's docstring are valid as written."""
    import re
    import textwrap
    import tomllib

    scenario_text, sweep_text = (
        textwrap.dedent(b) for b in re.findall(r"::\n\n(.*?)\n\n(?=\S)", config.__doc__, re.S)
    )
    sc = config.scenario(tomllib.loads(scenario_text), "docstring", "x")
    assert sc.name == "fast-turns" and sc.config.dvl_variance == [0.01] * 3
    doc = tomllib.loads(sweep_text)
    doc["scenarios"] = ["paper"]  # the example's my-scenario.toml is not on disk
    assert config.sweep_grid(doc, "docstring").shard_runs == 25


def test_a_new_trajectory_carries_its_period_and_noise_average_into_the_filter(tmp_path) -> None:
    """The filter's Q_d = q·imu_dt·Δt equals the sample variance only with imu_dt the IMU
    period, and the constant rows must be told the average over this trajectory."""
    path = write(
        tmp_path,
        "s.toml",
        'base = "varying-noise"\n[trajectory]\nsegments = [[40, 0, 0, 0]]\ndt_s = 0.02\n',
    )
    sc = config.load_scenario(path)
    assert sc.trajectory.dt == 0.02 and sc.config.imu_dt == 0.02
    times, q = scenarios.noise_schedule(330.0, 0)
    assert sc.q_nominal == pytest.approx(scenarios.time_average_q(times, q, 40.0))
    assert sc.q_nominal != scenarios.varying_noise_scenario().q_nominal
    told = write(tmp_path, "t.toml", path.read_text() + "[filter]\nimu_dt = 0.01\n")
    with pytest.warns(PlausibilityWarning, match=r"t.toml: \[filter\] imu_dt: 0.01 s, but"):
        assert config.load_scenario(told).config.imu_dt == 0.01  # said outright: kept


def test_keys_over_a_base_keep_its_dvl_calibration_states() -> None:
    """A file's keys over a base with the DVL calibration states (``--formulation`` on a
    scenario, ``--filter`` over a tuned base) keep the states and their priors; a base
    without them gains none."""
    base = pronet.FilterConfig(
        dvl_calibration=True, dvl_scale_sigma=0.02, dvl_misalignment_sigma=[0.01] * 3,
        dvl_scale_psd=1e-8, dvl_misalignment_psd=1e-9,
    )  # fmt: skip
    tuned = config.filter_config({"formulation": "classic"}, "test:", base=base)
    assert tuned.formulation == "classic" and tuned.dvl_calibration
    assert tuned.dvl_scale_sigma == 0.02 and tuned.dvl_misalignment_sigma == [0.01] * 3
    assert (tuned.dvl_scale_psd, tuned.dvl_misalignment_psd) == (1e-8, 1e-9)
    plain = config.filter_config({"formulation": "classic"}, "test:")
    assert not plain.dvl_calibration


def test_sensor_kwargs_rebuild_every_argument_of_the_sensors() -> None:
    """``sensor_kwargs`` (what ``sensor_config``, the sweep's noise levels and the aided
    calibration experiment rebuild a ``SensorConfig`` from) keeps every argument, the
    simulated DVL's scale error and misalignment too: dropping them silently turned the
    miscalibrated DVL of ``pronet.experiments.aided_calibration`` into an ideal one."""
    sensors = pronet.SensorConfig(
        imu_variance=[2e-4] * 3 + [3e-7] * 3, imu_bias=[1e-3] * 3 + [1e-6] * 3,
        imu_bias_psd=[1e-9] * 3 + [1e-14] * 3, dvl_variance=[4e-4] * 3, dvl_period=0.5,
        lever_arm=[0.5, -0.2, 1.0], dvl_outages=[[60.0, 120.0]], dvl_scale=0.005,
        dvl_misalignment=[0.001, -0.002, 0.0087], dvl_dropout=(120.0, 20.0),
        depth_sigma=0.1, depth_period=2.0, fixes=[{"sigma": [2.0, 2.0], "period": 60.0}],
    )  # fmt: skip
    properties = {name for name in dir(pronet.SensorConfig) if not name.startswith("_")}
    kwargs = config.sensor_kwargs(sensors)
    assert set(kwargs) == properties
    rebuilt = pronet.SensorConfig(**kwargs)
    for name in sorted(properties):
        np.testing.assert_array_equal(
            np.asarray(getattr(rebuilt, name), dtype=object),
            np.asarray(getattr(sensors, name), dtype=object),
            err_msg=name,
        )
    over = config.sensor_config({"dvl_period": 2.0}, "test:", sensors)  # a file's keys
    assert over.dvl_scale == 0.005 and over.dvl_misalignment == sensors.dvl_misalignment


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"rpy0": (10.0, 0.0, 0.0)}, "rpy0: roll 10 is beyond ±3.14159 rad; in degrees?"),
        ({"rpy0": (0.0, 0.0, 270.0)}, "rpy0: yaw 270 is beyond ±6.28319 rad; in degrees?"),
        ({"lla0": (0.5, 500.0, 0.0)}, "lla0: longitude 500 is beyond -3.14159 … 6.28319 rad"),
        ({"lla0": (0.5, 0.2, 1e9)}, "lla0: height 1e+09 m is beyond -12000 … 10000 m"),
        ({"lla0": (0.5, 0.2, -1e6)}, "lla0: height -1e+06 m is beyond -12000 … 10000 m"),
    ],
)
def test_trajectory_from_segments_refuses_degrees_and_heights_beyond_the_earth(
    kwargs, message
) -> None:
    """Each built a trajectory: a roll of 10 rad flies at 213° (upside down), a start
    1e9 m up ran a Monte Carlo to a velocity error of 88 km/s."""
    start = {"lla0": (0.5, 0.2, 0.0), "speed0": 1.0, **kwargs}
    with pytest.raises(ValueError) as err:
        pronet.trajectory_from_segments([[60.0, 0.0, 0.0, 0.0]], **start)
    assert str(err.value).startswith(message)


def test_a_trajectory_too_long_names_its_duration_in_a_few_digits() -> None:
    """The core printed an f64 duration in full: 1e300 s as a 301-digit number."""
    with pytest.raises(ValueError) as err:
        pronet.trajectory_from_segments([[1e300, 0.0, 0.0, 0.0]], lla0=(0.5, 0.2, 0.0), speed0=1.0)
    assert "total duration 1.0000e300 s" in str(err.value) and len(str(err.value)) < 200
