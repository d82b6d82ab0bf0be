"""``examples/online_ros2.py`` on a ROS 2 bag of a simulated 3-minute MEMS survey
(``tests/mission_recording.py``, its truth kept outside the bag): it starts from the
data, prints the state once a second close to the truth, and tallies each stream's
readings; without fixes it says why it cannot start."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest
from mission_recording import (
    STANDARD_ATMOSPHERE,
    Mission,
    simulate_mission,
    write_mission_bag,
    write_vehicle_file,
)

import pronet
from pronet.recorded.bags import STANDARD_GRAVITY

from module_file import load

ROOT = Path(__file__).resolve().parents[2]
#: Seconds of messages the example keeps to start from (its default).
INIT = 10.0


def _example() -> ModuleType:
    return load(ROOT / "examples" / "online_ros2.py")


def _run(*argv: str) -> tuple[int, list[str]]:
    """The example's exit code and the lines it printed."""
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        code = _example().main(list(argv))
    return code, out.getvalue().splitlines()


@pytest.fixture(scope="module")
def survey(tmp_path_factory) -> tuple[Mission, Path, Path]:
    """The survey, its bag (no truth topic; the reader's standard atmosphere, not the
    day's 101,900 Pa) and its vehicle file."""
    pytest.importorskip("rosbags.highlevel", reason="the rosbags extra")
    m = simulate_mission(0, minutes=3.0)
    folder = tmp_path_factory.mktemp("online")
    bag, topics = write_mission_bag(m, folder / "mission")
    assert topics.truth is None and topics.fix == "/usbl/fix"  # the example's defaults
    return m, bag, write_vehicle_file(folder, m)


@pytest.fixture(scope="module")
def run(survey) -> tuple[int, list[str]]:
    """The example on the bag with the AHRS's yaw as a heading: all four streams."""
    _, bag, vehicle = survey
    return _run(str(bag), "--vehicle", str(vehicle), "--heading-topic", "/imu/data")


def _states(lines: list[str]) -> np.ndarray:
    """The state lines: ``[time, lat (deg), lon (deg), depth, yaw (deg), σh]``."""
    rows = [line.split() for line in lines]
    return np.array([r for r in rows if len(r) == 6 and r[0][0].isdigit()], dtype=np.float64)


def _tally(lines: list[str]) -> dict[str, dict[str, float]]:
    at = next(i for i, line in enumerate(lines) if line.startswith("stream "))
    header = lines[at].split()[1:]
    return {
        row.split()[0]: dict(zip(header, map(float, row.split()[1:]), strict=True))
        for row in lines[at + 1 :]
    }


def test_it_starts_from_the_data_and_prints_the_state_once_a_second(run, survey) -> None:
    m, _, _ = survey
    code, lines = run
    assert code == 0, lines
    start = lines[0]
    assert start.startswith("start at ")
    # at rest at the surface: levelled, the fixes averaged over the kept seconds
    assert "position: mean of 10 fixes while still" in start and "attitude: levelled" in start
    t0 = float(start.split()[2])
    assert t0 == pytest.approx(m.imu_time[0] + INIT, abs=0.05)
    # the day's surface pressure measured beside the fixes while afloat: its offset [m]
    # from the reader's standard atmosphere
    assert lines[1].startswith("surface: depth offset ")
    day = (m.surface_pressure - STANDARD_ATMOSPHERE) / (m.water_density * STANDARD_GRAVITY)
    assert float(lines[1].split()[3]) == pytest.approx(day, abs=0.02)
    states = _states(lines)
    end = m.imu_time[-1]
    assert len(states) == pytest.approx(end - t0, abs=1.0)  # one a second of messages
    np.testing.assert_allclose(np.diff(states[1:, 0]), 1.0, atol=1e-6)
    assert states[0, 0] == pytest.approx(t0, abs=0.01) and states[-1, 0] == pytest.approx(end)


def test_the_printed_state_follows_the_truth(run, survey) -> None:
    m, _, _ = survey
    states = _states(run[1])
    t = m.truth
    k = np.searchsorted(t.time, states[:, 0] - 1e-4)
    assert np.abs(t.time[k] - states[:, 0]).max() < 1e-3  # printed at IMU epochs
    lla = np.column_stack([np.radians(states[:, 1:3]), -states[:, 3]])
    error = pronet.local_ned(lla, t.lla[0]) - pronet.local_ned(t.lla[k], t.lla[0])
    horizontal = np.hypot(error[:, 0], error[:, 1])
    # 1 Hz USBL fixes of 1.5 m hold it: 0.11 m at the end (σh 0.19 m), 0.75 m at worst
    assert horizontal[-1] < 1.5 and horizontal.max() < 3.0
    # the depth over the measured surface pressure (the standard atmosphere: 0.57 m off)
    assert np.abs(error[:, 2]).max() < 0.1
    yaw = np.degrees(np.angle(np.exp(1j * (np.radians(states[:, 4]) - t.rpy[k, 2]))))
    assert np.abs(yaw).max() < 3.0


def test_the_tally_counts_each_stream_s_readings(run, survey) -> None:
    m, _, _ = survey
    lines = run[1]
    t0 = float(lines[0].split()[2])
    tally = _tally(lines)
    assert list(tally) == ["dvl", "depth", "fix", "heading"]
    # every message after t0 fed (those before it started the filter); a heading a second
    valid = m.dvl_valid
    fed = {
        "dvl": int((m.dvl_time[valid] > t0).sum()),
        "depth": int((m.depth_time > t0).sum()),
        "fix": int((m.fix_time > t0).sum()),
        "heading": pytest.approx(m.imu_time[-1] - t0, abs=1.0),
    }
    for name, counts in tally.items():
        assert counts["received"] == fed[name], name
        assert counts["accepted"] > 0.95 * counts["received"], name
        assert counts["accepted"] + counts["rejected"] == counts["received"]
        assert counts["refused"] == counts["skipped"] == counts["queued"] == 0
    # each told its noise by its messages' covariance: NIS per degree of freedom near 1
    assert all(0.7 < tally[name]["NIS/dof"] < 1.3 for name in ("dvl", "depth", "fix"))


def test_without_fixes_it_says_why_it_cannot_start(survey) -> None:
    _, bag, vehicle = survey
    # tried once a second from 176 s on (the bag ends at 180 s), on the kept 176 s
    code, lines = _run(
        str(bag), "--vehicle", str(vehicle), "--fix-topic", "/none", "--init-seconds", "176"
    )
    assert code == 1
    assert lines == [
        f"{bag}: not started: initial position: no fix and no given position: "
        "give fixes or the initial position"
    ]
