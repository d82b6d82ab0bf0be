"""The simulated survey of ``mission_recording`` checked against itself and against
pronet's readers: the motion as described, the ideal IMU integrating to the truth, each
sensor's noise and bias as set, each sensor reading its own point, the files reading
back as the arrays they were written from (the truth never in them), and the filter
started at the truth navigating it to a few decimetres."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from mission_recording import (
    EPOCH,
    EXACT,
    STANDARD_ATMOSPHERE,
    STILL,
    LeverArms,
    Mission,
    filter_streams,
    fix_sigma,
    run_from_truth,
    score,
    simulate_mission,
    survey_segments,
    write_generic,
    write_mission_bag,
)
from scipy.spatial.transform import Rotation

import pronet
from pronet.recorded.recordings import read_recording

DEG = math.pi / 180.0


@pytest.fixture(scope="module")
def mission() -> Mission:
    """The 22-minute survey with USBL fixes and a compass."""
    return simulate_mission(seed=0)


@pytest.fixture(scope="module")
def short() -> Mission:
    """A 4-minute survey, for the files."""
    return simulate_mission(seed=1, minutes=4)


@pytest.fixture(scope="module")
def tiny() -> Mission:
    """A 3-minute survey (one leg), for the bags: 36,000 IMU messages."""
    return simulate_mission(seed=2, minutes=3)


def _truth_at(m: Mission, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The truth's lla, NED velocity and attitude (yaw unwrapped) at stamps ``t``."""
    tr = m.truth
    rpy = np.unwrap(tr.rpy, axis=0)

    def at(v: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(t, tr.time, v[:, j]) for j in range(3)])

    return at(tr.lla), at(tr.vel), at(rpy)


def _rotation(rpy: np.ndarray) -> Rotation:
    """Body FRD → NED of ZYX angles, by scipy (not the generator's own DCM)."""
    return Rotation.from_euler("ZYX", rpy[:, ::-1])


def _wrap(a: np.ndarray) -> np.ndarray:
    return np.angle(np.exp(1j * a))


# --- the motion ------------------------------------------------------------------------


def test_the_survey_starts_and_ends_still_at_the_surface_and_dives_to_ten_metres(mission):
    tr = mission.truth
    t = tr.time - tr.time[0]
    speed = np.linalg.norm(tr.vel, axis=1)
    depth = -tr.lla[:, 2]
    assert t[-1] == pytest.approx(22 * 60.0, abs=0.01)
    assert tr.time[0] == EPOCH and mission.imu_time[0] > EPOCH  # Unix stamps
    still = (t <= STILL) | (t >= t[-1] - STILL)
    assert speed[still].max() < 1e-9 and np.abs(depth[still] - 0.3).max() < 1e-6
    np.testing.assert_allclose(
        mission.still - EPOCH, [[0.0, STILL], [t[-1] - 30.0, t[-1]]], atol=0.1
    )
    assert 9.9 < depth.max() < 10.1 and np.mean(depth > 9.5) > 0.8  # the survey at ~10 m
    assert speed.max() == pytest.approx(1.0, abs=1e-9)
    # legs joined by 180° turns, right then left: the heading of the legs alternates
    legs = (np.abs(np.diff(np.unwrap(tr.rpy[:, 2]))) < 1e-9)[:-1] & (depth[1:-1] > 9.5)
    headings = np.round(np.degrees(np.unwrap(tr.rpy[1:-1, 2])[legs]) % 360.0, 3)
    assert set(headings) == {30.0, 210.0}
    assert survey_segments(22)[:, 2].tolist().count(6 * DEG) == 3  # five turns, 3 right


def test_the_sensors_run_at_their_rates_on_their_own_stamps(mission):
    s = mission.sensors
    for stamps, rate in (
        (mission.imu_time, s.imu_rate),
        (mission.dvl_time, s.dvl_rate),
        (mission.depth_time, s.depth_rate),
        (mission.fix_time, s.fix_rate),
        (mission.heading_time, s.heading_rate),
    ):
        # Unix stamps in float64: 2.4e-7 s apart at 1.7e9 s
        np.testing.assert_allclose(np.diff(stamps), 1.0 / rate, rtol=0, atol=3e-7)
        assert mission.truth.time[0] < stamps[0] and stamps[-1] <= mission.truth.time[-1]
    # the streams are not on the IMU's grid
    phase = (mission.dvl_time - mission.truth.time[0]) * s.imu_rate % 1.0
    assert 0.01 < phase[0] < 0.99


def test_a_short_mission_is_refused_by_name():
    with pytest.raises(ValueError, match="minutes: 2 is too short"):
        simulate_mission(minutes=2)
    with pytest.raises(ValueError, match="fixes: expected one of usbl, surface, none"):
        simulate_mission(minutes=4, fixes="lbl")  # type: ignore[arg-type]


def test_the_same_seed_draws_the_same_mission_and_each_sensor_its_own_stream():
    a, b = simulate_mission(3, minutes=4), simulate_mission(3, minutes=4)
    np.testing.assert_array_equal(a.imu, b.imu)
    np.testing.assert_array_equal(a.dvl, b.dvl)
    c = simulate_mission(4, minutes=4)
    assert not np.allclose(a.imu, c.imu)
    # no compass and no fixes: the other sensors' draws unchanged
    d = simulate_mission(3, minutes=4, heading=False, fixes="none")
    assert len(d.heading_time) == 0 and len(d.fix_time) == 0
    np.testing.assert_array_equal(a.dvl, d.dvl)
    np.testing.assert_array_equal(a.pressure, d.pressure)


# --- the IMU ---------------------------------------------------------------------------


def test_the_ideal_imu_integrates_to_the_truth_within_centimetres(mission):
    tr = mission.truth
    nav = pronet.mechanize(tr.imu, 1.0 / mission.sensors.imu_rate, tr.lla[0], tr.vel[0], tr.rpy[0])
    err = pronet.local_ned(nav.lla, tr.lla[0]) - pronet.local_ned(tr.lla, tr.lla[0])
    assert np.abs(err).max() < 0.01
    assert np.abs(nav.vel - tr.vel).max() < 1e-4
    assert np.abs(_wrap(nav.rpy - tr.rpy)).max() < 1e-6


def test_the_imu_noise_and_bias_are_as_set(mission):
    s, tr = mission.sensors, mission.truth
    noise = mission.imu - tr.imu - tr.bias
    sigma = np.sqrt(np.array([s.accel_noise_psd] * 3 + [s.gyro_noise_psd] * 3) * s.imu_rate)
    np.testing.assert_allclose(noise.std(axis=0), sigma, rtol=0.01)
    np.testing.assert_allclose(
        noise.mean(axis=0), 0.0, atol=3 * sigma.max() / math.sqrt(len(noise))
    )
    # the bias: the turn-on value plus a random walk of the set PSD
    step = np.diff(tr.bias, axis=0).std(axis=0)
    psd = np.array([s.accel_bias_psd] * 3 + [s.gyro_bias_psd] * 3)
    np.testing.assert_allclose(step, np.sqrt(psd / s.imu_rate), rtol=0.01)
    scale = np.array([s.accel_bias_sigma] * 3 + [s.gyro_bias_sigma] * 3)
    assert (np.abs(tr.bias[0]) < 4 * scale).all() and (np.abs(tr.bias[0]) > 1e-3 * scale).any()


def test_a_given_turn_on_bias_is_the_bias():
    bias = (0.01, -0.02, 0.005, 1e-3, -2e-3, 5e-4)
    m = simulate_mission(2, minutes=4, sensors=replace(EXACT, imu_bias=bias))
    np.testing.assert_allclose(m.truth.bias, np.tile(bias, (len(m.imu), 1)), rtol=0, atol=0)
    np.testing.assert_allclose(m.imu - m.truth.imu, m.truth.bias, rtol=0, atol=1e-15)


def test_the_ahrs_orientation_is_the_truth_with_a_slow_error_of_the_set_size(mission):
    s, tr = mission.sensors, mission.truth
    err = _wrap(mission.ahrs_rpy - tr.rpy[1:])
    # ~40 correlation times in the mission: the σ estimate within ~25 %
    np.testing.assert_allclose(err.std(axis=0), s.ahrs_sigma, rtol=0.3)
    lag = int(s.ahrs_tau * s.imu_rate)  # correlated over τ, not white
    corr = np.mean(err[:-lag] * err[lag:], axis=0) / err.var(axis=0)
    assert (0.1 < corr).all() and (corr < 0.7).all()


# --- the aiding sensors: their noise, each at its own point ----------------------------


def test_the_dvl_reads_its_own_point_with_the_set_noise_and_loses_the_bottom(mission):
    s, arm = mission.sensors, np.array(mission.lever_arms.dvl)
    _, vel, rpy = _truth_at(mission, mission.dvl_time)
    row = np.searchsorted(mission.truth.time, mission.dvl_time) - 1
    omega = mission.truth.imu[row, 3:6]
    expected = _rotation(rpy).inv().apply(vel) + np.cross(omega, arm)
    valid = mission.dvl_valid
    residual = (mission.dvl - expected)[valid]
    np.testing.assert_allclose(residual.std(axis=0), s.dvl_sigma, rtol=0.03)
    assert np.abs(residual.mean(axis=0)).max() < 3 * s.dvl_sigma / math.sqrt(valid.sum())
    # runs of missing readings, exactly in the outages
    inside = (
        (mission.dvl_time[:, None] >= mission.dvl_outages[:, 0])
        & (mission.dvl_time[:, None] < mission.dvl_outages[:, 1])
    ).any(axis=1)
    np.testing.assert_array_equal(~valid, inside)
    assert len(mission.dvl_outages) >= 3 and 0.03 < np.mean(~valid) < 0.3
    assert np.isnan(mission.dvl[~valid]).all()


def test_the_depth_and_its_pressure_are_the_sensors_point_over_the_true_surface_pressure(mission):
    s, arm = mission.sensors, np.array(mission.lever_arms.depth)
    lla, _, rpy = _truth_at(mission, mission.depth_time)
    expected = -lla[:, 2] + _rotation(rpy).apply(arm)[:, 2]
    residual = mission.depth() - expected
    np.testing.assert_allclose(residual.std(), s.depth_sigma, rtol=0.03)
    assert abs(residual.mean()) < 3 * s.depth_sigma / math.sqrt(len(residual))
    # the standard atmosphere, not the day's 101,900 Pa: every depth 5.7 cm too deep
    offset = mission.depth(STANDARD_ATMOSPHERE) - mission.depth()
    np.testing.assert_allclose(offset, (101_900.0 - 101_325.0) / (1025.0 * 9.80665), rtol=1e-9)
    assert offset[0] == pytest.approx(0.0572, abs=1e-4)
    assert mission.depth().min() > 0  # the sensor always under water


def test_the_fixes_are_the_antennas_horizontal_position_with_the_set_noise(mission):
    s, arm = mission.sensors, np.array(mission.lever_arms.fix)
    lla, _, rpy = _truth_at(mission, mission.fix_time)
    offset = _rotation(rpy).apply(arm)
    assert np.isnan(mission.fix_lla[:, 2]).all()  # horizontal fixes
    residual = np.empty((len(lla), 2))
    for k in range(len(lla)):
        fix = np.array([*mission.fix_lla[k, :2], lla[k, 2]])
        residual[k] = pronet.local_ned(fix, lla[k])[:2] - offset[k, :2]
    np.testing.assert_allclose(residual.std(axis=0), s.fix_sigma, rtol=0.06)
    assert np.abs(residual.mean(axis=0)).max() < 3 * s.fix_sigma / math.sqrt(len(residual))
    assert len(mission.fix_time) == pytest.approx(22 * 60, abs=1)  # 1 Hz all along


def test_surface_fixes_come_only_while_the_antenna_is_above_water():
    m = simulate_mission(5, minutes=5, fixes="surface")
    tr, arm = m.truth, np.array(m.lever_arms.fix)
    lla, _, rpy = _truth_at(m, m.fix_time)
    antenna_depth = -lla[:, 2] + _rotation(rpy).apply(arm)[:, 2]
    assert (antenna_depth < 0).all()
    t = m.fix_time - tr.time[0]
    assert t.min() < 2 and t.max() > tr.time[-1] - tr.time[0] - 2  # start and end
    assert 60 < len(t) < 120  # not during the survey


@pytest.mark.parametrize("magnetic", [False, True])
def test_the_compass_reads_the_heading_with_the_set_noise_magnetic_if_asked(magnetic):
    m = simulate_mission(6, minutes=8, magnetic=magnetic, declination=5.0 * DEG)
    _, _, rpy = _truth_at(m, m.heading_time)
    assert ((0 <= m.heading) & (m.heading < 2 * math.pi)).all()
    residual = _wrap(m.heading - rpy[:, 2])
    expected_mean = -5.0 * DEG if magnetic else 0.0
    assert residual.mean() == pytest.approx(expected_mean, abs=3 * DEG / math.sqrt(len(residual)))
    np.testing.assert_allclose(residual.std(), m.sensors.heading_sigma, rtol=0.03)
    np.testing.assert_allclose(_wrap(m.true_heading() - rpy[:, 2]).mean(), 0.0, atol=1e-3)
    ahrs_yaw = _wrap(m.ahrs_rpy[:, 2] - m.truth.rpy[1:, 2]).mean()
    assert ahrs_yaw == pytest.approx(expected_mean, abs=1.5 * DEG)


@pytest.mark.parametrize("arms", [LeverArms(), LeverArms((1.0, 0, 0), (0, 0, 1.0), (0, -1.0, 0))])
def test_without_noise_each_sensor_reads_exactly_its_own_point(arms):
    """Depth reading minus the IMU's depth is (C r)_D; the fix minus the IMU is (C r)
    north and east; the DVL minus the IMU's body velocity is ω × r (to the truth
    interpolated at Unix stamps, each within 1.2e-7 s of its instant)."""
    m = simulate_mission(7, minutes=4, sensors=EXACT, lever_arms=arms)
    lla, vel, rpy = _truth_at(m, m.depth_time)
    np.testing.assert_allclose(
        m.depth() + lla[:, 2], _rotation(rpy).apply(arms.depth)[:, 2], rtol=0, atol=1e-6
    )
    lla, vel, rpy = _truth_at(m, m.fix_time)
    offset = _rotation(rpy).apply(arms.fix)
    for k in range(0, len(lla), 7):
        fix = np.array([*m.fix_lla[k, :2], lla[k, 2]])
        np.testing.assert_allclose(pronet.local_ned(fix, lla[k])[:2], offset[k, :2], atol=1e-6)
    lla, vel, rpy = _truth_at(m, m.dvl_time)
    omega = m.truth.imu[np.searchsorted(m.truth.time, m.dvl_time) - 1, 3:6]
    body = _rotation(rpy).inv().apply(vel)
    np.testing.assert_allclose(m.dvl - body, np.cross(omega, arms.dvl), rtol=0, atol=1e-6)
    assert m.dvl_valid.all()


# --- the files -------------------------------------------------------------------------


def test_the_generic_folder_holds_the_recording_and_no_truth(tmp_path, short):
    folder = write_generic(short, tmp_path / "mission")
    names = sorted(p.name for p in folder.iterdir())
    assert names == ["depth.csv", "dvl.csv", "fix.csv", "heading.csv", "imu.csv"]
    heading = pd.read_csv(folder / "heading.csv")
    assert list(heading.columns) == ["time [s]", "heading [deg]", "sigma [deg]"]
    np.testing.assert_array_equal(heading["time [s]"], short.heading_time)
    np.testing.assert_allclose(np.radians(heading["heading [deg]"]), short.heading, rtol=1e-15)
    assert (heading["sigma [deg]"] == 1.0).all()
    dvl = pd.read_csv(folder / "dvl.csv")
    assert dvl.isna().any(axis=1).sum() == (~short.dvl_valid).sum()  # empty cells
    depth = pd.read_csv(folder / "depth.csv")
    np.testing.assert_array_equal(depth["pressure [Pa]"], short.pressure)
    none = write_generic(
        simulate_mission(1, minutes=4, heading=False, fixes="none"), tmp_path / "n"
    )
    assert sorted(p.name for p in none.iterdir()) == ["depth.csv", "dvl.csv", "imu.csv"]


@pytest.mark.parametrize(
    ("marker", "reason"), [("empty", "nan"), ("sentinel", "sentinel"), ("valid", "invalid")]
)
def test_the_generic_folder_reads_back_as_the_missions_arrays(tmp_path, short, marker, reason):
    """Through a test-only gt.csv (the reader still needs one): IMU, DVL with its missing
    rows, depth and fixes as simulated, at full precision."""
    folder = write_generic(short, tmp_path / "mission", truth=True, dvl_missing=marker, gz=True)
    assert (folder / "gt.csv.gz").is_file()
    rec = read_recording(folder)
    np.testing.assert_array_equal(rec.imu_time, short.imu_time)
    np.testing.assert_array_equal(rec.imu, short.imu)
    valid = short.dvl_valid
    np.testing.assert_array_equal(rec.dvl_time, short.dvl_time[valid])
    np.testing.assert_array_equal(rec.dvl, short.dvl[valid])
    np.testing.assert_array_equal(rec.dvl_skipped_time, short.dvl_time[~valid])
    assert set(rec.dvl_skipped_reason) == {reason}
    assert rec.depth is not None and rec.fixes is not None
    np.testing.assert_array_equal(rec.depth.time, short.depth_time)
    np.testing.assert_array_equal(rec.depth.depth, short.depth(STANDARD_ATMOSPHERE))
    np.testing.assert_array_equal(rec.depth.sigma, short.sensors.depth_sigma)
    np.testing.assert_array_equal(rec.fixes.time, short.fix_time)
    np.testing.assert_allclose(rec.fixes.lla[:, :2], short.fix_lla[:, :2], rtol=0, atol=1e-15)
    assert np.isnan(rec.fixes.lla[:, 2]).all()
    np.testing.assert_array_equal(
        rec.fixes.sigma, np.tile(fix_sigma(short), (len(short.fix_time), 1))
    )


def test_the_generic_folder_reads_without_its_truth(tmp_path, short):
    folder = write_generic(short, tmp_path / "mission")
    rec = read_recording(folder)
    assert not rec.has_truth
    np.testing.assert_array_equal(rec.imu, short.imu)
    np.testing.assert_array_equal(rec.dvl, short.dvl[short.dvl_valid])
    assert rec.depth is not None and rec.fixes is not None
    np.testing.assert_array_equal(rec.depth.depth, short.depth(STANDARD_ATMOSPHERE))
    assert len(rec.gt_time) == 0


def test_the_heading_table_reads_back(tmp_path, short):
    folder = write_generic(short, tmp_path / "mission")
    heading = read_recording(folder).heading
    assert heading is not None
    np.testing.assert_array_equal(heading.time, short.heading_time)
    np.testing.assert_allclose(heading.heading, short.heading, rtol=0, atol=1e-15)


def _storage_path(tmp_path: Path, storage: str) -> Path:
    return tmp_path / ("mission.bag" if storage == "rosbag1" else f"mission-{storage}")


@pytest.mark.parametrize("storage", ["rosbag1", pytest.param("mcap", marks=pytest.mark.slow)])
def test_the_bag_reads_back_as_the_missions_arrays(tmp_path, tiny, storage):
    """Through a test-only truth topic (the reader still needs one)."""
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra")
    path, topics = write_mission_bag(tiny, _storage_path(tmp_path, storage), storage, truth=True)
    rec = read_recording(path, topics)
    valid = tiny.dvl_valid
    assert not valid.all()  # a loss of bottom lock to leave out
    np.testing.assert_allclose(rec.imu_time, tiny.imu_time, rtol=0, atol=3e-7)
    np.testing.assert_array_equal(rec.imu, tiny.imu)  # FLU ↔ FRD: sign flips
    np.testing.assert_allclose(rec.dvl_time, tiny.dvl_time[valid], rtol=0, atol=3e-7)
    np.testing.assert_array_equal(rec.dvl, tiny.dvl[valid])  # no bottom lock: absent
    assert rec.dvl_variance == pytest.approx((tiny.sensors.dvl_sigma**2,) * 3)
    assert rec.depth is not None and rec.fixes is not None
    np.testing.assert_allclose(rec.depth.depth, tiny.depth(), rtol=0, atol=1e-9)
    np.testing.assert_allclose(rec.depth.sigma, tiny.sensors.depth_sigma, rtol=1e-9)
    np.testing.assert_allclose(rec.fixes.lla[:, :2], tiny.fix_lla[:, :2], rtol=0, atol=1e-15)
    assert np.isnan(rec.fixes.lla[:, 2]).all()
    np.testing.assert_allclose(rec.fixes.sigma[0], fix_sigma(tiny), rtol=1e-12)
    if storage != "mcap":
        return
    # a user who does not know the day's surface pressure reads 5.7 cm too deep
    default = read_recording(path, replace(topics, surface_pressure=STANDARD_ATMOSPHERE))
    assert default.depth is not None
    np.testing.assert_allclose(default.depth.depth - rec.depth.depth, 0.0572, atol=1e-4)


@pytest.mark.parametrize("storage", ["sqlite3"])
def test_the_bag_has_no_truth_topic_and_the_ahrs_orientation_in_each_imu_message(
    tmp_path, tiny, storage
):
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra")
    from rosbags.highlevel import AnyReader

    path, topics = write_mission_bag(tiny, _storage_path(tmp_path, storage), storage)
    with AnyReader([path]) as reader:
        assert sorted(c.topic for c in reader.connections) == sorted(
            [topics.imu, topics.dvl, topics.depth, topics.fix]
        )
        imu = [c for c in reader.connections if c.topic == topics.imu]
        msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(imu)]
    q = np.array(
        [[m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w] for m in msgs]
    )
    flu, enu = np.diag([1.0, -1.0, -1.0]), np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1.0]])
    c_nb = enu @ Rotation.from_quat(q).as_matrix() @ flu  # back to FRD → NED
    rpy = Rotation.from_matrix(c_nb).as_euler("ZYX")[:, ::-1]
    np.testing.assert_allclose(_wrap(rpy - tiny.ahrs_rpy), 0.0, atol=1e-9)
    cov = np.array(msgs[0].orientation_covariance).reshape(3, 3)
    np.testing.assert_allclose(np.diag(cov), np.square(tiny.sensors.ahrs_sigma))


@pytest.mark.parametrize("storage", ["rosbag1", pytest.param("mcap", marks=pytest.mark.slow)])
def test_the_bag_reads_without_its_truth(tmp_path, tiny, storage):
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra")
    path, topics = write_mission_bag(tiny, _storage_path(tmp_path, storage), storage)
    assert topics.truth is None and topics.origin is None
    rec = read_recording(path, topics)
    assert not rec.has_truth
    np.testing.assert_array_equal(rec.imu, tiny.imu)
    np.testing.assert_array_equal(rec.dvl, tiny.dvl[tiny.dvl_valid])
    assert rec.depth is not None
    np.testing.assert_allclose(rec.depth.depth, tiny.depth(), rtol=0, atol=1e-9)
    assert len(rec.gt_time) == 0


# --- the filter on it ------------------------------------------------------------------


def test_the_filter_started_at_the_truth_navigates_the_survey_to_a_few_decimetres(mission):
    """The data are sane: every stream at its lever arm, the depth over the true surface
    pressure, the compass, the ``mems`` grade's tuning: a few decimetres horizontally,
    the heading and the position within 3σ (the baseline of navigating without truth;
    the numbers are measured, nothing tuned to them)."""
    result = run_from_truth(mission, filter_streams(mission), smooth=True)
    forward = score(mission, result.lla, result.rpy, result.sigma)
    sm = result.smoothed
    smoothed = score(mission, sm.lla, sm.rpy, sm.sigma)
    assert forward.horizontal_rms < 0.6 and smoothed.horizontal_rms < forward.horizontal_rms
    assert forward.heading_within_3sigma > 0.95 and smoothed.heading_within_3sigma > 0.95
    assert forward.horizontal_within_3sigma > 0.95
    assert forward.heading_rms < 0.5 * DEG
