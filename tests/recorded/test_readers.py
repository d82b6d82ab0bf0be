"""Recorded data readers: the generic and Snapir layouts, CSV, gzip and NPZ files,
their units, and one clear error naming the file and row for anything malformed or
implausible."""

from __future__ import annotations

import gzip
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from pronet.recorded.recordings import (
    Recording,
    RecordingError,
    read_recording,
    read_snapir,
    write_recording,
)

from synthetic_recording import synthetic_recording


def assert_same_recording(a: Recording, b: Recording) -> None:
    for field in ("imu_time", "imu", "dvl_time", "dvl", "gt_time", "gt_lla", "gt_vel", "gt_rpy"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)


@pytest.mark.parametrize("where", ["folder", "recording.npz"])
def test_generic_format_round_trips(tmp_path, synthetic, where):
    path = write_recording(tmp_path / where, synthetic.recording)
    assert_same_recording(read_recording(path), synthetic.recording)


def test_gzip_csv_and_units_are_converted(tmp_path, synthetic):
    """Gzip files are read, and degrees become radians."""
    folder = write_recording(tmp_path / "rec", synthetic.recording)
    gt = (folder / "gt.csv").read_text().splitlines()
    head = gt[0].replace("lat [rad]", "lat [deg]").replace("yaw [rad]", "yaw [deg]")
    rows = [np.array(line.split(","), float) for line in gt[1:]]
    for r in rows:
        r[[1, 9]] = np.degrees(r[[1, 9]])
    body = "\n".join(",".join(repr(float(v)) for v in r) for r in rows)
    (folder / "gt.csv").unlink()
    with gzip.open(folder / "gt.csv.gz", "wt") as fh:
        fh.write(head + "\n" + body + "\n")
    back = read_recording(folder)
    np.testing.assert_allclose(back.gt_lla, synthetic.recording.gt_lla, rtol=1e-15)
    np.testing.assert_allclose(back.gt_rpy, synthetic.recording.gt_rpy, rtol=1e-14, atol=1e-15)


def write_snapir_layout(folder: Path, rec: Recording) -> Path:
    """``rec`` in the publisher's layout: gzip CSVs with its headers and column order."""
    folder.mkdir(parents=True)
    tables = {
        "imu": (
            "Time [s],ACC X [m/s^2],ACC Y [m/s^2],ACC Z [m/s^2],"
            "GYRO X [rad/s],GYRO Y [rad/s],GYRO Z [rad/s]",
            np.column_stack([rec.imu_time, rec.imu]),
        ),
        "dvl": (
            "Time [s],DVL X [m/s],DVL Y [m/s],DVL Z [m/s]",
            np.column_stack([rec.dvl_time, rec.dvl]),
        ),
        "gt": (
            "Time [s],Longitude [rad],Latitude [rad],Altitude [m],V North [m/s],"
            "V East [m/s],V Down [m/s],Roll [rad],Pitch [rad],Yaw [rad]",
            np.column_stack(
                [rec.gt_time, rec.gt_lla[:, 1], rec.gt_lla[:, 0], rec.gt_lla[:, 2]]
                + [rec.gt_vel, rec.gt_rpy]
            ),
        ),
    }
    for kind, (head, data) in tables.items():
        with gzip.open(folder / f"{kind}.csv.gz", "wt") as fh:
            fh.write(head + "\n")
            np.savetxt(fh, data, delimiter=",", fmt="%.17g")
    return folder


def test_snapir_layout_is_read(tmp_path, synthetic):
    folder = write_snapir_layout(tmp_path / "trajectory01", synthetic.recording)
    rec = read_snapir(folder)
    assert rec.name == "trajectory01"
    assert_same_recording(rec, synthetic.recording)


def csv_folder(tmp_path, synthetic) -> Path:
    return write_recording(tmp_path / "rec", synthetic.recording)


def edit_line(path: Path, index: int, edit) -> None:
    lines = path.read_text().splitlines()
    lines[index] = edit(lines[index])
    path.write_text("\n".join(lines) + "\n")


@pytest.mark.parametrize(
    ("file", "corrupt", "expected"),
    [
        (
            "imu",
            lambda p: edit_line(p, 0, lambda s: s.replace("acc_z [m/s^2]", "acc_q [m/s^2]")),
            "missing column 'acc_z'",
        ),
        (
            "gt",
            lambda p: edit_line(p, 5, lambda s: "0.0" + s[s.index(",") :]),
            "row 5: time 0.0 s does not increase",
        ),
        (  # a NaN in the DVL's velocity is a missing reading (test_missing_dvl.py)
            "gt",
            lambda p: edit_line(p, 3, lambda s: s[: s.rindex(",")] + ",nan"),
            "row 3: 'yaw [rad]' is nan, not finite",
        ),
        ("imu", lambda p: p.write_text(""), "is empty"),
        (
            "dvl",
            lambda p: p.write_text(p.read_text().replace(",", ";")),
            "the file must be comma-separated",
        ),
        (
            "imu",
            lambda p: edit_line(p, 7, lambda s: s.replace(",", ",abc", 1)),
            "row 7: 'acc_x [m/s^2]' is",
        ),
        (
            "gt",
            lambda p: edit_line(p, 0, lambda s: s.replace("height [m]", "height [ft]")),
            "unit [ft]",
        ),
        ("imu", lambda p: edit_line(p, 9, lambda s: s + ",1.0"), "row 9: has 8 fields"),
        (  # in the file's unit: 95 deg, not 1.658 rad
            "gt",
            lambda p: (
                edit_line(p, 0, lambda s: s.replace("lat [rad]", "lat [deg]")),
                edit_line(p, 4, lambda s: ",".join([s.split(",")[0], "95", *s.split(",")[2:]])),
            ),
            "row 4: 'lat [deg]' is 95, beyond -90 … 90 deg (a latitude)",
        ),
        (
            "dvl",
            lambda p: p.write_text(p.read_text().splitlines()[0] + "\n"),
            "no data rows",
        ),
    ],
    ids=[
        "missing-column",
        "unsorted-time",
        "nan",
        "empty",
        "semicolons",
        "not-a-number",
        "unknown-unit",
        "ragged-row",
        "latitude-beyond",
        "header-only",
    ],
)
def test_malformed_csv_gives_a_clear_error(tmp_path, synthetic, file, corrupt, expected):
    folder = csv_folder(tmp_path, synthetic)
    corrupt(folder / f"{file}.csv")
    with pytest.raises(RecordingError) as info:
        read_recording(folder)
    assert f"{file}.csv" in str(info.value)
    assert expected in str(info.value)


def test_implausible_rates_and_missing_files(tmp_path, synthetic):
    rec = synthetic.recording
    with pytest.raises(RecordingError, match="sample rate 0.1 Hz is implausible for imu"):
        write_recording(tmp_path / "slow", replace(rec, imu_time=rec.imu_time * 1000))
        read_recording(tmp_path / "slow")
    folder = csv_folder(tmp_path, synthetic)
    (folder / "dvl.csv").unlink()
    with pytest.raises(RecordingError, match=r"no dvl.csv or dvl.csv.gz"):
        read_recording(folder)
    with pytest.raises(RecordingError, match="does not exist"):
        read_recording(tmp_path / "nowhere")
    with pytest.raises(RecordingError, match="does not exist"):
        read_snapir(tmp_path / "nowhere")


@pytest.mark.parametrize(
    ("mistake", "message"),
    [
        ("accel in g", r"imu: the mean specific force is (0\.99|1\.0)\d* m/s², not near gravity"),
        ("gyro in deg/s", r"imu: 1 % of the angular rates exceed .* rad/s, beyond any vehicle"),
        ("dvl in cm/s", r"dvl: its median speed .* m/s against the ground truth's"),
        ("imu gap", r"imu\.csv, row 3001: a gap of 2\.01 s after"),
    ],
)
def test_implausible_data_is_caught_before_filtering(tmp_path, synthetic, mistake, message):
    rec = synthetic.recording
    imu, imu_time, dvl = rec.imu.copy(), rec.imu_time.copy(), rec.dvl.copy()
    if mistake == "accel in g":
        imu[:, :3] /= 9.80665
    elif mistake == "gyro in deg/s":
        imu[:, 3:] = np.degrees(imu[:, 3:]) * 20  # a brisk turn, read as rad/s
    elif mistake == "dvl in cm/s":
        dvl *= 100
    else:
        imu_time[3000:] += 2.0
    write_recording(tmp_path / "bad", replace(rec, imu=imu, imu_time=imu_time, dvl=dvl))
    with pytest.raises(RecordingError, match=message):
        read_recording(tmp_path / "bad")


def test_two_files_for_one_stream_are_refused(tmp_path, synthetic):
    folder = csv_folder(tmp_path, synthetic)
    (folder / "imu.csv.gz").write_bytes(gzip.compress((folder / "imu.csv").read_bytes()))
    with pytest.raises(RecordingError, match=r"both imu\.csv and imu\.csv\.gz"):
        read_recording(folder)


def test_malformed_npz_gives_a_clear_error(tmp_path, synthetic):
    good = write_recording(tmp_path / "good.npz", synthetic.recording)
    arrays = dict(np.load(good))
    cases = {
        "missing": ({k: v for k, v in arrays.items() if k != "dvl"}, "needs arrays 'dvl'"),
        "pickled": ({**arrays, "gt": np.array([object()], dtype=object)}, "[gt]: an object array"),
        # The case: column names saved as an object array; named, with the fix.
        "names": (
            {**arrays, "imu_columns": arrays["imu_columns"].astype(object)},
            "[imu_columns]: an object array, which cannot be read without pickle (refused: "
            "loading it could run code); save it as an array of strings: "
            "np.array(names, dtype=str)",
        ),
        "bytes": (
            {**arrays, "dvl_columns": arrays["dvl_columns"].astype(bytes)},
            "[dvl_columns]: must be a 1-D array of strings, got |S",
        ),
        "shape": ({**arrays, "imu": arrays["imu"][:, :3]}, "must be a 2-D numeric array"),
        "nan": (
            {**arrays, "imu": np.where(np.arange(7) == 2, np.nan, arrays["imu"])},
            "row 1: 'acc_y [m/s^2]' is nan",
        ),
    }
    for name, (content, expected) in cases.items():
        path = tmp_path / f"{name}.npz"
        np.savez(path, **content)
        with pytest.raises(RecordingError, match=re.escape(expected)) as info:
            read_recording(path)
        assert str(path) in str(info.value)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(RecordingError, match="not a readable .npz"):
        read_recording(tmp_path / "junk.npz")


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    kind=st.sampled_from(["imu", "dvl", "gt"]),
    cut=st.floats(0.0, 1.0),
    noise=st.binary(max_size=64),
)
@pytest.mark.slow
def test_hostile_files_read_or_raise_naming_the_file(tmp_path_factory, synthetic, kind, cut, noise):
    """A CSV truncated anywhere and followed by arbitrary bytes: read correctly, or a
    RecordingError (a ValueError) naming the file; never another exception."""
    folder = csv_folder(tmp_path_factory.mktemp("hostile"), synthetic)
    path = folder / f"{kind}.csv"
    data = path.read_bytes()
    path.write_bytes(data[: int(cut * len(data))] + noise)
    try:
        rec = read_recording(folder)
    except RecordingError as exc:
        assert f"{kind}.csv" in str(exc), str(exc)
        return
    for arr in (rec.imu, rec.dvl, rec.gt_lla):
        assert np.isfinite(arr).all()


def test_the_fast_csv_path_reads_what_the_careful_reader_reads(tmp_path, synthetic):
    from pronet.recorded import recordings

    folder = csv_folder(tmp_path, synthetic)
    path = folder / "imu.csv"
    text = path.read_text()
    width = len(text.partition("\n")[0].split(","))
    fast = recordings._parse_numbers(text, width)
    assert fast is not None  # a plain table: pandas' parser read it
    lines = text.splitlines()
    careful = np.array([[float(c) for c in line.split(",")] for line in lines[1:] if line])
    assert np.array_equal(fast.view(np.int64), careful.view(np.int64))  # bit for bit
    # anything else goes to the careful reader: a short row (named), an extra text
    # column the file does not need (read as before)
    assert recordings._parse_numbers("a,b\n1,2\n  \n3,4\n", 2) is None  # a line of blanks
    edit_line(path, 4, lambda s: s[: s.rindex(",")])
    with pytest.raises(RecordingError, match=r"imu.csv, row 4: has 6 fields, the header 7"):
        read_recording(folder)
    path.write_text("\n".join([lines[0] + ",note"] + [f"{s},ok" for s in lines[1:]]) + "\n")
    assert recordings._parse_numbers(path.read_text(), width + 1) is None
    np.testing.assert_array_equal(
        read_recording(folder).imu, read_recording(csv_folder(tmp_path / "b", synthetic)).imu
    )


@pytest.mark.parametrize("rate", [9.99975, 9.985, 10_010.5])
def test_a_rate_at_a_bound_is_compared_as_the_nominal_rate_and_shown_to_its_digits(tmp_path, rate):
    """An IMU at 9.99975 Hz (a 10 Hz IMU on a clock 25 ppm slow) was "10 Hz …
    implausible (expected 10–10000 Hz)": now a rate within the nominal-rate tolerance of
    a bound is that bound's (accepted), and one refused is printed with the digits that
    show it outside."""
    from pronet.recorded.tuning import NOMINAL_RATE_TOLERANCE

    base = 10.0 if rate < 100 else 10_000.0
    rec = synthetic_recording(seed=0, duration=30.0 if rate < 100 else 2.0, imu_rate=base)
    k = base / rate
    stretched = replace(
        rec.recording,
        imu_time=rec.recording.imu_time * k,
        dvl_time=rec.recording.dvl_time * k,
        gt_time=rec.recording.gt_time * k,
    )
    folder = write_recording(tmp_path / "sec", stretched)
    if abs(rate - base) <= NOMINAL_RATE_TOLERANCE * base:
        assert len(read_recording(folder).imu) == len(stretched.imu)
        return
    with pytest.raises(RecordingError) as caught:
        read_recording(folder)
    shown = str(caught.value).split("sample rate ")[1].split(" Hz")[0]
    assert float(shown) == pytest.approx(rate, rel=1e-6) and float(shown) != base
