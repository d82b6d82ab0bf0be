"""The aiding sensors in simulation (``SensorConfig(depth_sigma=..., heading_sigma=...,
fixes=[...])``, ``dvl_period=0``): the schedule and noise of the simulated depth readings,
headings and fixes, what they do to the filter (bounded where DVL-only drifts; GNSS/INS
and depth-only runs without a DVL), the scenario files' keys, and the mistakes refused
by name."""

from __future__ import annotations

import math

import numpy as np
import pytest

import pronet
from pronet import _core
from pronet.config import ConfigError, load_scenario
from pronet.sim.paper import PAPER_Q

TRAJ = pronet.builtin_trajectory("paper")  # 330 s at 5 m depth (12.8 m at its deepest)
CFG = pronet.FilterConfig(accel_bias_psd=1e-10, gyro_bias_psd=1e-14)
CONSTANT = pronet.Strategy.constant(PAPER_Q)


def _mc(sensors: _core.SensorConfig, n_runs: int = 8, **kw) -> pronet.MonteCarloResult:
    return pronet.monte_carlo(
        TRAJ, CONSTANT, sensors=sensors, config=CFG, n_runs=n_runs, seed=4, **kw
    )


def _sensors(**kw) -> _core.SensorConfig:
    return _core.SensorConfig(imu_variance=PAPER_Q, **kw)


def test_updates_follow_the_schedule() -> None:
    """Depth every 2 s; fixes every 60 s and at listed times (merged, none twice, none past
    the end); fixes limited to the surface only while the true depth is above the limit
    (the trajectory is at 5 m or deeper throughout)."""
    sensors = _sensors(
        depth_sigma=0.1,
        depth_period=2.0,
        fixes=[
            {"sigma": [2.0, 2.0], "period": 60.0, "times": [0.0, 60.0, 100.0, 500.0]},
            {"sigma": [2.0, 2.0, 2.0], "period": 1.0, "max_depth": 4.9},
        ],
    )
    res = _mc(sensors, n_runs=2)
    assert res.depth_updates.tolist() == [165, 165]  # 330 s / 2 s
    assert res.fix_updates.tolist() == [5 + 2, 5 + 2]  # 60..300 s, and 0 and 100 s
    # the Monte Carlo runs the source that never fires; a scenario file is refused with it
    with pytest.raises(ValueError, match=r"^fixes\[1\]\.max_depth: no scheduled fix"):
        _core.check_fixes_fire(TRAJ, sensors)
    deeper = _mc(_sensors(fixes=[{"sigma": [2.0, 2.0], "period": 1.0, "max_depth": 13.0}]), 2)
    assert deeper.fix_updates.tolist() == [330, 330]
    # the DVL's epochs are as before, and a run without aiding sensors has none
    assert len(res.dvl_time) == 330
    plain = _mc(_sensors(), n_runs=2)
    assert plain.depth_updates.tolist() == plain.fix_updates.tolist() == [0, 0]
    assert np.isnan(plain.mean_aiding_nis).all()


@pytest.mark.parametrize("simulated", [1.0, 4.0])
def test_the_fix_noise_is_as_configured(simulated: float) -> None:
    """The filter is told the σ the fixes and depth readings are simulated with, so their
    NIS per degree of freedom is 1 when the drawn noise has that σ (drawn with another,
    it would be off by the square of the ratio: at σ 4 m, 16 if drawn with 1 m)."""
    sigma = [simulated, simulated, simulated]
    res = _mc(_sensors(depth_sigma=0.2, fixes=[{"sigma": sigma, "period": 5.0}]), n_runs=12)
    nis = float(res.mean_aiding_nis.mean())
    # 12 runs x (66 fixes x 3 + 330 depths) ≈ 6300 dof: the mean's standard error ≈ 0.02
    assert abs(nis - 1.0) < 0.1, nis
    assert res.fix_updates.tolist() == [66] * 12


def test_a_compass_is_consistent_and_holds_the_heading() -> None:
    """A heading sensor (σ 2 mrad at 1 Hz; the paper's DVL-only runs let the heading
    drift): the filter is told its σ, so the NIS per degree of freedom is 1, and the
    heading error at the end is below the compass's σ where DVL-only it is ten times it."""
    compass = _mc(_sensors(heading_sigma=2e-3), n_runs=12, record_every=330 * 100)
    plain = _mc(_sensors(), n_runs=12, record_every=330 * 100)
    # 12 runs x 330 headings ≈ 4000 dof: the mean's standard error ≈ 0.02
    nis = float(compass.mean_aiding_nis.mean())
    assert abs(nis - 1.0) < 0.1, nis
    assert compass.depth_updates.tolist() == compass.fix_updates.tolist() == [0] * 12
    assert compass.error is not None and plain.error is not None
    yaw = lambda r: np.sqrt(np.mean(r.error[:, -1, 8] ** 2))  # noqa: E731
    # (Measured: 0.4 mrad with it, σ 0.5; 27 mrad without, σ 24.)
    assert yaw(compass) < 1e-3 and yaw(plain) > 1e-2, (yaw(compass), yaw(plain))


def test_fixes_bound_the_error_where_dvl_only_drifts() -> None:
    """DVL-only, the horizontal error grows with the heading error over the run; fixes
    every 30 s (σ 2 m) keep it near their σ."""
    dvl_only = _mc(_sensors())
    fixed = _mc(_sensors(fixes=[{"sigma": [2.0, 2.0], "period": 30.0}]))
    assert np.all(fixed.fix_updates == 11)
    assert fixed.max_horizontal_error.mean() < dvl_only.max_horizontal_error.mean()
    assert fixed.final_horizontal_error.mean() < 0.5 * dvl_only.final_horizontal_error.mean()


def test_gnss_ins_and_depth_only_runs_without_a_dvl() -> None:
    """``dvl_period=0``: no DVL epoch. GNSS/INS (fixes every second, σ 2.5 m, with a
    height) stays within metres where the free INS drifts hundreds; depth alone holds
    the vertical error but not the horizontal."""
    free = _mc(_sensors(dvl_period=0), n_runs=4, record_every=100)
    gnss = _mc(
        _sensors(dvl_period=0, fixes=[{"sigma": [2.5, 2.5, 4.0], "period": 1.0}]),
        n_runs=4,
        record_every=100,
    )
    depth = _mc(_sensors(dvl_period=0, depth_sigma=0.1), n_runs=4, record_every=100)
    for res in (free, gnss, depth):
        assert len(res.dvl_time) == 0 and res.nis.shape == (4, 0)
        assert not any(res.failure)
    assert free.final_horizontal_error.min() > 100.0
    assert gnss.max_horizontal_error.max() < 15.0
    assert depth.final_horizontal_error.min() > 100.0
    assert free.error is not None and depth.error is not None
    down = lambda r: np.abs(r.error[:, -1, 2]).max()  # noqa: E731
    assert down(depth) < 1.0 < down(free)


def test_aiding_does_not_move_the_other_draws() -> None:
    """The aiding sensors draw from their own streams: the DVL-aided runs and the runs
    with fixes whose σ is so large they move nothing start from the same IMU and DVL
    noise, so their errors agree to far below the noise."""
    plain = _mc(_sensors(), n_runs=3)
    wide = _mc(_sensors(depth_sigma=1e8, fixes=[{"sigma": [1e8, 1e8], "period": 1.0}]), 3)
    np.testing.assert_allclose(wide.srmse, plain.srmse, rtol=1e-5)
    np.testing.assert_allclose(wide.final_horizontal_error, plain.final_horizontal_error, 1e-5)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"dvl_period": -1.0}, "dvl_period: must be finite and >= 0 s (0: no DVL)"),
        ({"depth_sigma": 0.0}, "depth_sigma: must be finite and > 0"),
        ({"depth_sigma": 0.1, "depth_period": math.nan}, "depth_period: must be finite"),
        ({"depth_period": 0.5}, "depth_period: needs depth_sigma beside it"),
        ({"heading_sigma": 5.0}, "heading_sigma: must be at most π [rad], got 5 (degrees?)"),
        ({"heading_sigma": -0.1}, "heading_sigma: must be finite and > 0"),
        ({"heading_sigma": 0.01, "heading_period": 0.0}, "heading_period: must be finite"),
        ({"heading_period": 0.5}, "heading_period: needs heading_sigma beside it"),
        ({"fixes": {"sigma": [1, 1]}}, "fixes: expected a list of dicts"),
        ({"fixes": [[1, 1]]}, "fixes[0]: expected a dict"),
        ({"fixes": [{"period": 1.0}]}, "fixes[0].sigma: missing"),
        ({"fixes": [{"sigma": [1.0], "period": 1.0}]}, "fixes[0].sigma: expected 2"),
        ({"fixes": [{"sigma": [1, -1], "period": 1.0}]}, "fixes[0].sigma: needs 1σ"),
        ({"fixes": [{"sigma": [1, 1], "period": 1.0, "every": 2}]}, "fixes[0].every: unknown"),
        ({"fixes": [{"sigma": [1, 1]}]}, "fixes[0].period: no fix is scheduled"),
        ({"fixes": [{"sigma": [1, 1], "times": [5, 5]}]}, "fixes[0].times: must increase"),
        ({"fixes": [{"sigma": [1, 1], "times": [-1.0]}]}, "fixes[0].times: must be >= 0"),
        ({"fixes": [{"sigma": [1, 1], "period": "1"}]}, "fixes[0].period: "),
    ],
)
def test_bad_sensor_arguments_are_named(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError) as exc:
        _core.SensorConfig(**kwargs)
    assert str(exc.value).startswith(message), exc.value


def test_a_period_that_is_no_whole_number_of_steps_is_named() -> None:
    sensors = _sensors(fixes=[{"sigma": [1, 1], "period": 1.0}, {"sigma": [1, 1], "period": 0.015}])
    with pytest.raises(ValueError, match=r"^fixes\[1\]\.period: must be a whole multiple"):
        _mc(sensors, n_runs=1)


def test_scenario_files_take_the_aiding_keys(tmp_path) -> None:
    path = tmp_path / "gnss.toml"
    path.write_text(
        'base = "matched"\n[sensors]\ndvl_period = 0\ndepth_sigma = 0.1\ndepth_period = 0.5\n'
        "depth_lever_arm = [0.2, 0, 0.5]\nheading_sigma = 0.005\nheading_period = 0.2\n"
        "[[sensors.fixes]]\nsigma = [2.5, 2.5]\nperiod = 1.0\nmax_depth = 20.0\n"
        "[[sensors.fixes]]\nsigma = [3, 3, 3]\ntimes = [10.0, 20.0]\nlever_arm = [0, 0, -1.5]\n"
    )
    sc = load_scenario(path)
    assert sc.sensors.dvl_period == 0.0
    assert (sc.sensors.depth_sigma, sc.sensors.depth_period) == (0.1, 0.5)
    assert sc.sensors.depth_lever_arm == [0.2, 0.0, 0.5]
    assert (sc.sensors.heading_sigma, sc.sensors.heading_period) == (0.005, 0.2)
    no_arm = [0.0, 0.0, 0.0]
    assert sc.sensors.fixes == [
        {"sigma": [2.5, 2.5], "period": 1.0, "times": [], "max_depth": 20.0, "lever_arm": no_arm},
        {
            "sigma": [3.0, 3.0, 3.0],
            "period": 0.0,
            "times": [10.0, 20.0],
            "max_depth": None,
            "lever_arm": [0.0, 0.0, -1.5],
        },
    ]
    # a file over a base with fixes: an empty list removes them, other keys keep them
    over = tmp_path / "over.toml"
    over.write_text('base = "matched"\n[sensors]\nfixes = []\n')
    assert load_scenario(over).sensors.fixes == []


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("[sensors]\ndepth_sigma = -1\n", "[sensors] depth_sigma: must be finite and > 0"),
        ("[sensors]\ndepth_sigma = 0.1\ndepth_period = 0.015\n",
         "[sensors] depth_period: must be a whole multiple of the IMU period 0.01 s"),
        ("[[sensors.fixes]]\nsigma = [2, 2]\nperod = 1\n", "[sensors] fixes[0].perod: unknown key"),
        ("[[sensors.fixes]]\nsigma = [2, 2]\nperiod = 1\n[[sensors.fixes]]\nsigma = [2]\n",
         "[sensors] fixes[1].sigma: expected 2"),
        ("[sensors]\nfixes = 3\n", "[sensors] fixes: expected a list of dicts"),
        ("[sensors]\ndepth_period = 0.5\n", "[sensors] depth_period: needs depth_sigma"),
        ("[sensors]\nheading_sigma = 0.01\nheading_period = 0.015\n",
         "[sensors] heading_period: must be a whole multiple of the IMU period 0.01 s"),
        # a source that takes no fix on the trajectory (paper's: 330 s, 5 m deep or more)
        ("[[sensors.fixes]]\nsigma = [2, 2]\nperiod = 1\nmax_depth = 0.5\n",
         "[sensors] fixes[0].max_depth: no scheduled fix comes at a true depth of at most "
         "0.5 m (at the scheduled epochs the trajectory is never shallower than 5.000 m)"),
        ("[[sensors.fixes]]\nsigma = [2, 2]\nperiod = 60\n[[sensors.fixes]]\nsigma = [2, 2]\n"
         "times = [400.0]\n", "[sensors] fixes[1]: schedules no fix inside the trajectory's 330 s"),
        ('base = "mission"\n[trajectory]\nsegments = [[30, 0, 0, 0]]\n',
         "[trajectory], with mission's fixes[0]"),
    ],
)  # fmt: skip
def test_bad_scenario_keys_name_file_table_and_key(tmp_path, text: str, message: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ConfigError) as exc:
        load_scenario(path)
    assert str(exc.value).startswith(f"{path}: {message}"), exc.value
    assert "\n" not in str(exc.value)


def test_the_mission_scenario_dives_surveys_and_surfaces(tmp_path) -> None:
    """``mission``: from the surface to about 30 m and back; GNSS fixes at 1 Hz exactly
    while the true depth is at most 0.5 m, USBL every 60 s, depth every second; the
    fixes at the end bring the vehicle home within metres. ``pronet simulate`` runs it."""
    from pronet.cli import main
    from pronet.sim.scenarios import SCENARIOS, STUDY_SCENARIOS

    sc = SCENARIOS["mission"](0)
    depth = -sc.trajectory.lla[:, 2]
    assert sc.trajectory.duration == 1036.0
    assert abs(depth[0]) < 1e-9 and abs(depth[-1]) < 1e-6 and 25.0 < depth.max() < 35.0
    seconds = np.arange(100, len(depth), 100)  # the epochs of whole seconds
    gnss = int(np.sum(depth[seconds] <= 0.5))
    assert 120 <= gnss <= 140  # 60 s at each end and the first metres of dive and ascent
    res = pronet.monte_carlo(
        sc.trajectory, CONSTANT, sensors=sc.sensors, config=sc.config, n_runs=2, seed=1
    )
    assert res.fix_updates.tolist() == [gnss + 1036 // 60] * 2
    assert res.depth_updates.tolist() == [1036, 1036]
    assert not any(res.failure) and res.final_horizontal_error.max() < 5.0
    assert "mission" in STUDY_SCENARIOS
    out = tmp_path / "mission"
    argv = ["simulate", "--scenario", "mission", "--strategies", "constant", "--runs", "2"]
    assert main([*argv, "--no-plots", "--quiet", "--out", str(out)]) == 0
    assert "mission scenario, 2 runs" in (out / "table.md").read_text()
