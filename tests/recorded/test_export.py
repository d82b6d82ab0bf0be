"""The files a user loads from a navigated recording: ``trajectory.csv`` read back by
pandas (and by ``float``) equal to the solutions' numbers and σ, ``track.geojson``
valid RFC 7946 with the σ per point, an odometry bag in ROS 1 and ROS 2 read back by
pronet's own bag reader as a truth topic to 1e-6 m / 1e-9 rad, the figures and
``report.md``, and ``write_all`` writing them all or, on bad input, nothing."""

from __future__ import annotations

import csv
import importlib.util
import json
import math
import sys
from dataclasses import dataclass, replace
from pathlib import Path
from statistics import NormalDist

import numpy as np
import pandas as pd
import pytest
from numpy.typing import NDArray

import pronet
from pronet._util.extras import MissingExtra
from pronet.recorded import attitude, export, odometry, report
from pronet.recorded.alignment import dcm_from_euler
from pronet.recorded.bags import euler_from_dcm
from pronet.recorded.solution import InitialState, Navigation, Solution
from pronet.stats import StreamReport

#: The fake recording's first IMU stamp (Unix time, as a bag's) and origin.
EPOCH = 1_700_000_123.25
ORIGIN = np.array([np.radians(32.8), np.radians(34.95), -2.0])


@dataclass(frozen=True)
class GatedReport(StreamReport):
    """A stream report that also says which readings were applied (as
    :attr:`pronet.StreamResult.accepted`)."""

    accepted: NDArray[np.bool_] | None = None


def _solution(label: str, n: int, seed: int, wrap: bool = False) -> Solution:
    """A vehicle circling (its yaw through 0/360 twice) and diving, σ growing."""
    rng = np.random.default_rng(seed)
    time = np.arange(n) * 0.2 + 0.4
    turn = 2 * np.pi * time / 30.0
    ned = np.column_stack([20 * np.sin(turn), 20 * (1 - np.cos(turn)), 0.05 * time])
    ned += 0.01 * rng.standard_normal(ned.shape)
    origin = np.array([ORIGIN[0], np.radians(179.9998), ORIGIN[2]]) if wrap else ORIGIN
    lla = pronet.lla_from_ned(ned, origin)
    vel = np.gradient(ned, time, axis=0)
    yaw = np.angle(np.exp(1j * (turn + np.pi / 2)))  # in (−π, π]
    rpy = np.column_stack([0.05 * np.sin(time), 0.03 * np.cos(time / 3), yaw])
    sigma = (
        np.abs(rng.standard_normal((n, 15))) * np.r_[[1.0] * 3, [0.05] * 3, [0.01] * 3, [1e-3] * 6]
    )
    sigma[:, :3] += np.sqrt(time)[:, None]
    return Solution(label, time, EPOCH, lla, vel, rpy, sigma)  # type: ignore[arg-type]


def _streams(rng: np.random.Generator) -> tuple[StreamReport, ...]:
    reports = []
    for name, kind, dof, rows in (("dvl", "velocity", 3, 120), ("depth", "depth", 1, 60)):
        time = np.sort(rng.uniform(0.4, 60.0, rows))
        nis = rng.chisquare(dof, rows)
        nis[:3] = np.nan  # skipped: no bottom lock
        accepted = np.isfinite(nis) & (nis < {3: 7.81, 1: 3.84}[dof])  # a 95 % gate
        applied = int(accepted.sum())
        reports.append(
            GatedReport(
                name=name, kind=kind, rows=rows, applied=applied,
                rejected=int((np.isfinite(nis) & ~accepted).sum()), skipped={"missing": 3},
                mean_nis=float(np.nanmean(nis[accepted])), dof=float(dof),
                band=(0.8 * dof, 1.2 * dof), time=time, nis=nis,
                flag="mean NIS above its band: R too small?" if name == "dvl" else "",
                accepted=accepted,
            )
        )  # fmt: skip
    return tuple(reports)


def _navigation(n: int = 300, smooth: bool = True, wrap: bool = False, **kw) -> Navigation:
    rng = np.random.default_rng(5)
    fwd = _solution("forward", n, 1, wrap)
    fix_time = np.arange(1.0, 60.0, 1.0)
    fix_lla = fwd.lla[np.searchsorted(fwd.time, fix_time)] + 1e-7 * rng.standard_normal((59, 3))
    fix_lla[4] = np.nan  # a NavSatFix with no fix
    initial = InitialState(
        t0=0.4, lla=fwd.lla[0], vel=fwd.vel[0], rpy=fwd.rpy[0],
        p0_sigma=np.r_[1.5, 1.5, 0.1, [0.1] * 3, 0.01, 0.01, 0.05, [1e-3] * 6],
        methods={"position": "first fix (3 fixes over 2.0 s)", "depth": "first depth reading",
                 "velocity": "given", "attitude": "levelled over 12.4 s still",
                 "heading": "heading stream"},
    )  # fmt: skip
    fields = dict(
        name="mission",
        source="/data/mission.bag",
        forward=fwd,
        smoothed=_solution("smoothed", n, 2, wrap) if smooth else None,
        initial=initial,
        streams=_streams(rng),
        readings={
            "fix": (fix_time, fix_lla),
            "depth": (fwd.time[::5], -fwd.lla[::5, 2] + 0.05),
            "heading": (fwd.time[::10], fwd.rpy[::10, 2] + 2 * np.pi),
        },
        config={
            "p0_sigma": np.arange(15.0),
            "surface_pressure": {"pa": 101_900.0, "source": "the first fix at the surface"},
            "lever_arms": {"depth": [0.0, 0.0, 0.5]},
            "nan": math.nan,
        },
        score={"forward": {"final_horizontal": 0.42}, "smoothed": {"final_horizontal": 0.17}},
        notes=("the heading stream's σ is the default",),
    )
    fields.update(kw)
    return Navigation(**fields)  # type: ignore[arg-type]


@pytest.fixture(scope="module")
def nav() -> Navigation:
    return _navigation()


# ---------------------------------------------------------------------------------------
# trajectory.csv


def _expected_columns(sol: Solution) -> dict[str, np.ndarray]:
    """The columns of one solution, each from the Solution directly."""
    deg = np.degrees
    s = sol.sigma
    return {
        "time [s]": sol.time,
        "stamp [s]": sol.epoch + sol.time,
        "lat [deg]": deg(sol.lla[:, 0]),
        "lon [deg]": deg(sol.lla[:, 1]),
        "depth [m]": -sol.lla[:, 2],
        "vel_n [m/s]": sol.vel[:, 0],
        "vel_e [m/s]": sol.vel[:, 1],
        "vel_d [m/s]": sol.vel[:, 2],
        "roll [deg]": deg(sol.rpy[:, 0]),
        "pitch [deg]": deg(sol.rpy[:, 1]),
        "sigma_n [m]": s[:, 0],
        "sigma_e [m]": s[:, 1],
        "sigma_d [m]": s[:, 2],
        "sigma_vel_n [m/s]": s[:, 3],
        "sigma_vel_e [m/s]": s[:, 4],
        "sigma_vel_d [m/s]": s[:, 5],
        "sigma_psi_n [deg]": deg(s[:, 6]),
        "sigma_psi_e [deg]": deg(s[:, 7]),
        "sigma_psi_d [deg]": deg(s[:, 8]),
    }


def _euler_sigma(rpy: np.ndarray, sigma_psi: np.ndarray) -> np.ndarray:
    """σ roll, pitch, yaw through the Jacobian of the Euler angles in ψ (the inverse of
    ψ = E(roll, pitch, yaw) · δ(roll, pitch, yaw)), as a matrix product."""
    out = []
    for (_, pitch, yaw), s in zip(rpy, sigma_psi, strict=True):
        cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
        e = np.array([[cy * cp, -sy, 0.0], [sy * cp, cy, 0.0], [-sp, 0.0, 1.0]])
        j = np.linalg.inv(e)
        out.append(np.sqrt(np.diag(j @ np.diag(s**2) @ j.T)))
    return np.array(out)


def test_trajectory_csv_reads_back_in_pandas_to_the_last_bit(tmp_path, nav):
    path = export.write_trajectory(nav, tmp_path / "trajectory.csv")
    table = pd.read_csv(path)
    assert tuple(table.columns) == export.TRAJECTORY_COLUMNS
    assert list(table["solution"]) == ["forward"] * 300 + ["smoothed"] * 300
    with path.open() as fh:  # Python's own float(): exact whatever pandas' parser
        rows = list(csv.reader(fh))[1:]
    for k, sol in enumerate(nav.solutions):
        part = table.iloc[300 * k : 300 * (k + 1)]
        exact = np.array([[float(v) for v in row[1:]] for row in rows[300 * k : 300 * (k + 1)]])
        for column, expected in _expected_columns(sol).items():
            np.testing.assert_allclose(part[column], expected, rtol=1e-12, atol=0, err_msg=column)
            j = export.TRAJECTORY_COLUMNS.index(column) - 1
            np.testing.assert_array_equal(exact[:, j], expected, err_msg=column)
        yaw = part["yaw [deg]"].to_numpy()
        assert (yaw >= 0).all() and (yaw < 360).all() and yaw.min() < 10 and yaw.max() > 350
        turn = np.angle(np.exp(1j * (np.radians(yaw) - sol.rpy[:, 2])))
        np.testing.assert_allclose(turn, 0, atol=1e-12)
        euler = np.radians(part[["sigma_roll [deg]", "sigma_pitch [deg]", "sigma_yaw [deg]"]])
        np.testing.assert_allclose(euler, _euler_sigma(sol.rpy, sol.sigma[:, 6:9]), rtol=1e-12)


def test_the_euler_sigma_is_the_spread_of_the_euler_angles_of_perturbed_attitudes():
    """ψ drawn with the σ, the attitude perturbed by it, its roll, pitch, yaw taken: their
    spread is attitude_sigma's (first order: σ of 1 mrad)."""
    rng = np.random.default_rng(0)
    rpy = np.array([[0.2, 0.5, 2.0]])
    sigma_psi = np.array([[1e-3, 3e-3, 2e-3]])
    psi = rng.standard_normal((20_000, 3)) * sigma_psi
    skew = np.zeros((len(psi), 3, 3))
    skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -psi[:, 2], psi[:, 1], -psi[:, 0]
    skew -= np.swapaxes(skew, 1, 2)
    perturbed = euler_from_dcm((np.eye(3) - skew) @ dcm_from_euler(rpy[0]))
    spread = np.std(np.angle(np.exp(1j * (perturbed - rpy))), axis=0)
    np.testing.assert_allclose(spread, attitude.attitude_sigma(rpy, sigma_psi)[0], rtol=0.03)
    level = attitude.attitude_sigma(np.zeros((1, 3)), sigma_psi)  # level, heading north
    np.testing.assert_allclose(level, sigma_psi, rtol=1e-15)
    east = attitude.attitude_sigma(np.array([[0.0, 0.0, np.pi / 2]]), sigma_psi)
    np.testing.assert_allclose(east, sigma_psi[:, [1, 0, 2]], rtol=1e-12)


def test_the_sigma_columns_are_run_filters(tmp_path):
    """A real pass (a still IMU with depth and heading aiding, smoothed): the σ columns
    are FilterResult.sigma and the smoothed σ themselves."""
    rate, seconds = 100.0, 5.0
    imu_time = np.arange(1, int(rate * seconds) + 1) / rate
    imu = np.tile([0.0, 0.0, -9.79, 0.0, 0.0, 0.0], (len(imu_time), 1))
    streams = [
        pronet.Depth(imu_time[::10], np.full(len(imu_time[::10]), 2.0), sigma=0.05),
        pronet.Heading(imu_time[::20], np.full(len(imu_time[::20]), 0.3), sigma=0.02),
    ]
    lla0 = np.array([ORIGIN[0], ORIGIN[1], -2.0])
    result = pronet.run_filter(
        imu, imu_time, streams, t0=0.0, lla0=lla0, vel0=np.zeros(3), rpy0=[0.0, 0.0, 0.3],
        strategy=pronet.Strategy.constant((1e-6,) * 3 + (1e-8,) * 3), smooth=True,
    )  # fmt: skip
    assert result.smoothed is not None
    solutions = [
        Solution(label, r.time, 0.0, r.lla, r.vel, r.rpy, r.sigma)  # type: ignore[arg-type]
        for label, r in (("forward", result), ("smoothed", result.smoothed))
    ]
    navigation = _navigation(forward=solutions[0], smoothed=solutions[1])
    table = pd.read_csv(export.write_trajectory(navigation, tmp_path / "t.csv"))
    for label, r in (("forward", result), ("smoothed", result.smoothed)):
        part = table[table["solution"] == label]
        np.testing.assert_array_equal(part.filter(like="sigma_").iloc[:, :6], r.sigma[:, :6])
        np.testing.assert_array_equal(part.filter(like="sigma_psi"), np.degrees(r.sigma[:, 6:9]))


def test_a_csv_failing_half_way_leaves_the_old_file(tmp_path, nav, monkeypatch):
    """Written in pieces (not held whole), still atomically: an error while the smoothed
    rows are made leaves the file as it was, and no temporary beside it."""
    path = tmp_path / "trajectory.csv"
    path.write_text("old")
    made = export.trajectory_values

    def failing(sol):
        if sol.label == "smoothed":
            raise RuntimeError("disk gone")
        return made(sol)

    monkeypatch.setattr(export, "trajectory_values", failing)
    with pytest.raises(RuntimeError, match="disk gone"):
        export.write_trajectory(nav, path)
    assert path.read_text() == "old" and [p.name for p in tmp_path.iterdir()] == [path.name]
    monkeypatch.undo()
    pieces = list(export.trajectory_csv(nav, rows=64))
    assert len(pieces) == 1 + 2 * 5  # the header, then 300 rows in pieces of 64, twice
    assert b"".join(pieces) == export.write_trajectory(nav, path).read_bytes()


def test_an_interrupted_write_leaves_no_folder_of_its_own(tmp_path, nav, monkeypatch):
    """Ctrl-C while the files are written into a new folder: the command said "no
    result folder was written" and left the folder, empty; now it is gone, and an
    existing folder (an earlier run's) keeps its files."""

    def interrupted(files):
        raise KeyboardInterrupt

    monkeypatch.setattr(export, "replace_together", interrupted)
    with pytest.raises(KeyboardInterrupt):
        export.write_all(nav, tmp_path / "new" / "out", figures=False)
    assert not (tmp_path / "new").exists()  # nor the parent it made
    old = tmp_path / "old"
    old.mkdir()
    (old / "trajectory.csv").write_text("old")
    with pytest.raises(KeyboardInterrupt):
        export.write_all(nav, old, figures=False)
    assert [p.name for p in old.iterdir()] == ["trajectory.csv"]


def test_a_solution_of_one_epoch_or_going_back_in_time_is_refused(tmp_path, nav):
    f = nav.forward
    one = replace(
        f, time=f.time[:1], lla=f.lla[:1], vel=f.vel[:1], rpy=f.rpy[:1], sigma=f.sigma[:1]
    )
    with pytest.raises(ValueError, match="^navigation.forward: a solution needs at least 2"):
        export.write_trajectory(replace(nav, forward=one), tmp_path / "t.csv")
    back = nav.smoothed.time.copy()  # type: ignore[union-attr]
    back[7] = back[6]
    with pytest.raises(ValueError, match="^navigation.smoothed.time: not increasing at epoch 7"):
        export.write_track(replace(nav, smoothed=replace(nav.smoothed, time=back)), tmp_path / "g")
    assert not list(tmp_path.iterdir())


# ---------------------------------------------------------------------------------------
# track.geojson


def _features(path: Path, kind: str, solution: str | None = None) -> list[dict]:
    features = json.loads(path.read_text())["features"]
    return [
        f for f in features
        if f["properties"]["kind"] == kind and solution in (None, f["properties"].get("solution"))
    ]  # fmt: skip


def test_track_geojson_holds_the_track_the_sigma_per_point_and_the_fixes(tmp_path, nav):
    path = export.write_track(nav, tmp_path / "track.geojson", max_points=50)
    doc = json.loads(path.read_text())
    assert doc["type"] == "FeatureCollection" and doc["name"] == "mission"
    assert all(f["type"] == "Feature" for f in doc["features"])
    for sol in nav.solutions:
        (line,) = _features(path, "track", sol.label)
        assert line["geometry"]["type"] == "LineString"
        coords = np.array(line["geometry"]["coordinates"])
        np.testing.assert_array_equal(coords, np.degrees(sol.lla[:, [1, 0]]))  # lon, lat
        props = line["properties"]
        assert props["start_time_s"] == sol.time[0] and props["end_stamp_s"] == EPOCH + sol.time[-1]
        points = _features(path, "point", sol.label)
        assert len(points) == 50
        rows = np.searchsorted(sol.time, [p["properties"]["time_s"] for p in points])
        assert rows[0] == 0 and rows[-1] == len(sol.time) - 1
        got = np.array([[p["properties"][k] for k in ("sigma_n_m", "sigma_e_m", "sigma_d_m")]
                        for p in points])  # fmt: skip
        np.testing.assert_array_equal(got, sol.sigma[rows, :3])
        h = [p["properties"]["sigma_h_m"] for p in points]
        np.testing.assert_array_equal(h, np.hypot(sol.sigma[rows, 0], sol.sigma[rows, 1]))
        depth = [p["properties"]["depth_m"] for p in points]
        np.testing.assert_array_equal(depth, -sol.lla[rows, 2])
        xy = np.array([p["geometry"]["coordinates"] for p in points])
        np.testing.assert_array_equal(xy, np.degrees(sol.lla[rows][:, [1, 0]]))
    fixes = _features(path, "fix")
    fix_time, fix_lla = nav.readings["fix"]
    assert len(fixes) == len(fix_time) - 1  # the one without a position is left out
    assert fixes[4]["properties"]["time_s"] == fix_time[5]
    assert fixes[4]["geometry"]["coordinates"] == list(np.degrees(fix_lla[5, [1, 0]]))


def test_a_long_track_is_thinned_and_one_over_the_antimeridian_is_cut(tmp_path):
    nav = _navigation(n=3000, wrap=True, smooth=False)
    path = export.write_track(nav, tmp_path / "track.geojson", max_line=500)
    assert len(_features(path, "point")) == export.MAX_POINTS
    (line,) = _features(path, "track")
    assert line["geometry"]["type"] == "MultiLineString"
    parts = line["geometry"]["coordinates"]
    lon = np.concatenate([np.array(p)[:, 0] for p in parts])
    assert 500 <= len(lon) <= 502 and len(parts) >= 2
    for part in parts:  # within each part no step jumps the antimeridian
        assert np.all(np.abs(np.diff(np.array(part)[:, 0])) < 1e-3)
    assert lon.max() > 179.99 and lon.min() < -179.99


def test_a_non_finite_position_is_left_out_of_the_geojson_and_written_as_nan(tmp_path, nav):
    lla = nav.forward.lla.copy()
    lla[10] = np.nan
    broken = replace(nav, forward=replace(nav.forward, lla=lla))
    (line,) = _features(export.write_track(broken, tmp_path / "g.geojson"), "track", "forward")
    assert len(line["geometry"]["coordinates"]) == 299
    table = pd.read_csv(export.write_trajectory(broken, tmp_path / "t.csv"))
    assert table["lat [deg]"].isna().sum() == 1
    if importlib.util.find_spec("rosbags") is not None:  # nor is it in the bag
        options = odometry.OdometryOptions(rate=None)
        bag = odometry.write_odometry_bag(tmp_path / "o.bag", broken, "rosbag1", options)
        origin = odometry.bag_origin(broken, options)
        got, _ = _read_truth(bag, "/pronet/odometry", origin, "enu", "flu")
        np.testing.assert_allclose(got[:, 0], EPOCH + np.delete(nav.forward.time, 10), atol=3e-7)


def test_track_geojson_is_valid_for_geojson_and_shapely_when_installed(tmp_path, nav):
    geojson = pytest.importorskip("geojson", reason="geojson is not a dependency")
    shapely_geometry = pytest.importorskip("shapely.geometry", reason="nor is shapely")
    text = export.write_track(nav, tmp_path / "track.geojson").read_text()
    assert geojson.loads(text).is_valid
    for feature in json.loads(text)["features"]:
        assert shapely_geometry.shape(feature["geometry"]).is_valid


# ---------------------------------------------------------------------------------------
# The odometry bag


def _read_truth(path: Path, topic: str, origin, world: str, body: str) -> np.ndarray:
    """The topic read as pronet's bag reader reads a truth topic: rows ``[time, lla,
    vel, rpy]``, and the messages."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    from pronet.recorded import bags

    topics = bags.BagTopics(truth=topic, origin=origin, world_frame=world, body_frame=body)
    with AnyReader([path], default_typestore=get_typestore(Stores.LATEST)) as reader:
        msgs = bags._messages(reader, path, topic, "truth", bags.TRUTH_TYPES)
    return np.array(bags._truth_rows(msgs, topics, path)), msgs


@pytest.mark.parametrize(
    ("storage", "world", "body"),
    [("rosbag1", "enu", "flu"), ("mcap", "enu", "flu"), ("sqlite3", "ned", "frd")],
)
def test_the_odometry_bag_reads_back_as_a_truth_topic(tmp_path, nav, storage, world, body):
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra")
    options = odometry.OdometryOptions(rate=2.5, world_frame=world, body_frame=body)
    path = tmp_path / odometry.bag_name(storage)
    assert odometry.write_odometry_bag(path, nav, storage, options) == path
    origin = odometry.bag_origin(nav, options)
    o = np.array([np.radians(origin[0]), np.radians(origin[1]), origin[2]])
    for sol, topic in zip(nav.solutions, (options.topic, options.smoothed_topic), strict=True):
        rows = odometry.decimate(sol.time, 2.5)
        assert len(rows) == 150 and np.all(np.diff(sol.time[rows]) == pytest.approx(0.4))
        got, msgs = _read_truth(path, topic, origin, world, body)
        np.testing.assert_allclose(got[:, 0], EPOCH + sol.time[rows], rtol=0, atol=3e-7)
        back = pronet.local_ned(got[:, 1:4], o)
        np.testing.assert_allclose(back, pronet.local_ned(sol.lla[rows], o), rtol=0, atol=1e-6)
        np.testing.assert_allclose(got[:, 4:7], sol.vel[rows], rtol=0, atol=1e-9)
        turn = np.angle(np.exp(1j * (got[:, 7:10] - sol.rpy[rows])))
        np.testing.assert_allclose(turn, 0, atol=1e-9)
        pose_var = np.array([np.diag(np.reshape(m.pose.covariance, (6, 6))) for m in msgs])
        axes = [1, 0, 2] if world == "enu" else [0, 1, 2]  # ENU: x east, y north
        np.testing.assert_allclose(pose_var[:, :3], sol.sigma[rows][:, axes] ** 2, rtol=1e-15)
        np.testing.assert_allclose(pose_var[:, 3:], sol.sigma[rows][:, 6:9][:, axes] ** 2)
        twist = np.array([np.reshape(m.twist.covariance, (6, 6)) for m in msgs])
        trace = np.trace(twist[:, :3, :3], axis1=1, axis2=2)  # a rotation keeps the trace
        np.testing.assert_allclose(trace, np.sum(sol.sigma[rows, 3:6] ** 2, axis=1), rtol=1e-12)
        assert {m.header.frame_id for m in msgs} == {"map"}
        assert {m.child_frame_id for m in msgs} == {"base_link"}
    (fix,), _ = _origin_message(path)
    assert (fix.latitude, fix.longitude, fix.altitude) == origin
    assert origin[:2] == (math.degrees(nav.forward.lla[0, 0]), math.degrees(nav.forward.lla[0, 1]))


def _origin_message(path: Path):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    with AnyReader([path], default_typestore=get_typestore(Stores.LATEST)) as reader:
        conns = [c for c in reader.connections if c.topic == "/pronet/origin"]
        msgs = [reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(conns)]
        return msgs, sorted(c.topic for c in reader.connections)


def test_the_default_rate_is_10_hz_and_stamps_keep_their_nanoseconds(tmp_path):
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra")
    nav = _navigation(n=400, smooth=False)
    fast = replace(nav.forward, time=np.arange(400) * 0.005 + 0.0025)  # 200 Hz
    path = odometry.write_odometry_bag(tmp_path / "o.bag", replace(nav, forward=fast))
    _, topics = _origin_message(path)
    assert topics == ["/pronet/odometry", "/pronet/origin"]
    got, msgs = _read_truth(
        path, "/pronet/odometry", odometry.bag_origin(nav, odometry.OdometryOptions()), "enu", "flu"
    )
    assert len(msgs) == 20  # 2 s at 10 Hz
    assert [m.header.stamp.nanosec for m in msgs[:2]] == [252_500_000, 352_500_000]
    assert {m.header.stamp.sec for m in msgs} == {1_700_000_123, 1_700_000_124, 1_700_000_125}


def test_a_bad_bag_is_refused_before_anything_is_written(tmp_path, nav, monkeypatch):
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra")
    with pytest.raises(ValueError, match="^storage: expected one of rosbag1, sqlite3, mcap"):
        odometry.write_odometry_bag(tmp_path / "o", nav, "ros3")
    (tmp_path / "o.bag").write_text("mine")
    with pytest.raises(ValueError, match="o.bag exists; a bag is never overwritten"):
        odometry.write_odometry_bag(tmp_path / "o.bag", nav)
    early = replace(nav, forward=replace(nav.forward, epoch=-10.0))
    with pytest.raises(ValueError, match="^navigation.forward: stamps before 0 s"):
        odometry.write_odometry_bag(tmp_path / "early.bag", early)
    with pytest.raises(ValueError, match="^rate: expected a positive number"):
        odometry.OdometryOptions(rate=0.0)
    with pytest.raises(ValueError, match="^topics: expected distinct names"):
        odometry.OdometryOptions(smoothed_topic="/pronet/odometry")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.bag"]
    monkeypatch.setitem(sys.modules, "rosbags.rosbag1", None)
    with pytest.raises(MissingExtra, match=r"^writing an odometry bag needs rosbags"):
        odometry.write_odometry_bag(tmp_path / "x.bag", nav)


def test_quaternions_from_rotation_matrices_give_the_matrices_back():
    rng = np.random.default_rng(2)
    rpy = rng.uniform(-np.pi, np.pi, (500, 3)) * [1, 0.5, 1]
    half_turns = np.array([[np.pi, 0, 0], [0, 0, np.pi], [np.pi, 0, np.pi / 2]])
    c = dcm_from_euler(np.vstack([rpy, half_turns, np.zeros((1, 3))]))
    q = odometry.quaternion_from_dcm(c)
    assert (q[:, 3] >= 0).all()
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1, atol=1e-15)
    x, y, z, w = q.T
    back = np.stack(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    ).transpose(2, 0, 1)
    np.testing.assert_allclose(back, c, atol=2e-15)


# ---------------------------------------------------------------------------------------
# Figures, report.md, write_all


def test_chi2_quantiles_match_the_closed_forms():
    z = NormalDist().inv_cdf(0.9875)
    assert report.chi2_quantile(0.975, 1) == pytest.approx(z * z, rel=1e-10)
    assert report.chi2_quantile(0.025, 2) == pytest.approx(-2 * math.log(0.975), rel=1e-10)
    assert report.chi2_quantile(0.975, 3) == pytest.approx(9.348403604496, rel=1e-9)
    assert report.chi2_quantile(0.025, 3) == pytest.approx(0.215795282623, rel=1e-9)


def test_the_figures_show_the_ellipses_bands_and_rejected_readings(tmp_path, nav):
    track = report.track_figure(nav)
    (ax,) = track.axes
    ellipses = [c for c in ax.collections if type(c).__name__ == "EllipseCollection"]
    assert len(ellipses) == 2 and all(len(e.get_offsets()) == report.ELLIPSES for e in ellipses)
    at = np.unique(np.linspace(0, 299, report.ELLIPSES).round().astype(int))
    np.testing.assert_array_equal(ellipses[1]._widths * 2, 6 * nav.smoothed.sigma[at, 1])  # type: ignore[union-attr]
    np.testing.assert_array_equal(ellipses[1]._heights * 2, 6 * nav.smoothed.sigma[at, 0])  # type: ignore[union-attr]
    dvl = nav.streams[0]
    rejected = report._rejected(dvl)
    assert rejected.sum() == dvl.rejected > 0
    assert not report._rejected(replace(dvl, accepted=None)).any()  # type: ignore[type-var]
    innovations = report.innovations_figure(nav)
    red = [ln for ln in innovations.axes[0].lines if ln.get_color() == "tab:red"]
    assert [len(ln.get_xdata()) for ln in red] == [dvl.rejected, dvl.rejected]
    heading = report.depth_heading_figure(nav).axes[1]
    readings = [ln for ln in heading.lines if ln.get_label() == "heading readings"][0]
    near = np.degrees(np.unwrap(nav.forward.rpy[::10, 2]))
    near -= 360 * np.floor(near[0] / 360)
    np.testing.assert_allclose(readings.get_ydata(), near, atol=1e-9)  # the turn of the track
    paths = report.write_figures(nav, tmp_path)
    assert [p.name for p in paths] == list(report.FIGURES)
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in paths)


def test_report_md_states_the_initial_state_streams_pressure_notes_and_score(nav):
    text = report.report_markdown(nav, ["trajectory.csv", "odometry.bag", "report.md"],
                                  (32.8, 34.95, -2.0), odometry.OdometryOptions())  # fmt: skip
    dvl, depth = nav.streams
    assert "| attitude | roll " in text and "| levelled over 12.4 s still |" in text
    assert "| heading | " in text and "| heading stream |" in text
    row = (
        f"| dvl | velocity | 120 | {dvl.applied} | {dvl.rejected} | missing 3 | {dvl.mean_nis:.3f}"
    )
    inside = "yes" if 2.4 <= dvl.mean_nis <= 3.6 else "no"
    row += f" | 2.400 – 3.600 | {inside} | 3 |"
    assert row in text
    assert f"| depth | depth | 60 | {depth.applied} | {depth.rejected} | missing 3 |" in text
    assert "Flagged:\n- dvl: mean NIS above its band: R too small?\n" in text
    assert text.count("| yes |") + text.count("| no |") == 2
    assert "101900.0 Pa, the first fix at the surface." in text
    assert "- the heading stream's σ is the default" in text
    assert "| final_horizontal | 0.42 | 0.17 |" in text
    assert "- `odometry.bag`: `nav_msgs/Odometry` on `/pronet/odometry`, " in text
    assert "about 32.80000000°, 34.95000000°, -2.000 m (body FLU)" in text
    bare = replace(nav, score=None, notes=(), streams=(), config={})
    plain = report.report_markdown(bare, ["report.md"])
    assert "Score" not in plain and "No aiding stream was used." in plain
    assert "Not in the configuration (not stated)" in plain and "## Notes\n\nNone." in plain


def test_write_all_writes_every_file_and_the_report_lists_them(tmp_path, nav):
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra")
    paths = export.write_all(nav, tmp_path / "out", bag="mcap")
    names = ["trajectory.csv", "track.geojson", "config.json", "odometry", *report.FIGURES,
             "report.md"]  # fmt: skip
    assert [p.name for p in paths] == names
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == sorted(names)
    config = json.loads((tmp_path / "out" / "config.json").read_text())
    assert config["p0_sigma"] == list(range(15)) and config["nan"] is None
    text = (tmp_path / "out" / "report.md").read_text()
    assert all(f"- `{name}`" in text for name in names)


def test_write_all_without_smoothing_streams_or_readings(tmp_path):
    """A forward pass alone, with no aiding stream and no readings: every file but the
    bag, the innovations figure saying so."""
    nav = _navigation(smooth=False, streams=(), readings={}, score=None)
    paths = export.write_all(nav, tmp_path / "out")
    assert [p.name for p in paths] == [
        "trajectory.csv", "track.geojson", "config.json", *report.FIGURES, "report.md"
    ]  # fmt: skip
    assert set(pd.read_csv(paths[0])["solution"]) == {"forward"}
    kinds = {f["properties"]["kind"] for f in json.loads(paths[1].read_text())["features"]}
    assert kinds == {"track", "point"}
    assert "No aiding stream was used." in paths[-1].read_text()


def test_a_run_into_an_earlier_run_s_folder_leaves_none_of_its_figures(tmp_path, nav):
    """A run without figures into the folder of one with them: its files replace the
    earlier ones, and the earlier figures, which its report does not list, are gone."""
    out = tmp_path / "out"
    first = export.write_all(nav, out)
    assert {p.name for p in first} >= set(report.FIGURES)
    second = export.write_all(nav, out, figures=False)
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in second)
    assert not set(report.FIGURES) & {p.name for p in second}


def test_write_all_writes_nothing_on_bad_input(tmp_path, nav):
    with pytest.raises(ValueError, match="^storage: expected one of"):
        export.write_all(nav, tmp_path / "a", bag="ros3")
    with pytest.raises(TypeError, match=r"^navigation.config\['tuning'\]: JSON output: a object"):
        export.write_all(replace(nav, config={"tuning": object()}), tmp_path / "b")
    (tmp_path / "file").write_text("")
    with pytest.raises(ValueError, match="^out_dir: .*file is a file, not a folder"):
        export.write_all(nav, tmp_path / "file")
    assert [p.name for p in tmp_path.iterdir()] == ["file"]
