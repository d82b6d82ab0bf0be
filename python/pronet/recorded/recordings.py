"""Readers for recorded INS/DVL data (real vehicles), validated before any computation.

Two readers, one result (:class:`Recording`, SI units, stamps as recorded):

- :func:`read_snapir` reads the published Snapir AUV layout: a folder holding
  ``imu.csv.gz``, ``dvl.csv.gz`` and ``gt.csv.gz`` with the publisher's headers
  (``Time [s], ACC X [m/s^2], …``). Its body frame is FRD; its altitude is negative below
  the surface, i.e. height up.
- :func:`read_recording` reads the generic format, for users' own recordings (and ROS
  bags, :mod:`pronet.recorded.bags`): either a folder holding ``imu.csv``, ``dvl.csv``
  and ``gt.csv`` (each optionally ``.gz``), or one ``.npz`` file with 2-D float arrays
  ``imu``, ``dvl``, ``gt`` and string arrays ``imu_columns``, ``dvl_columns``,
  ``gt_columns`` naming their columns. The ground truth is optional (a vehicle's own
  recording has none: :attr:`Recording.has_truth`; its arrays are then empty and the
  checks against it are not made). Every column is named ``name [unit]``:

  ===== ============================================================================
  table columns (accepted units; converted to the first)
  ===== ============================================================================
  imu   ``time [s]``, ``acc_x``, ``acc_y``, ``acc_z [m/s^2]``,
        ``gyro_x``, ``gyro_y``, ``gyro_z [rad/s | deg/s]``: body frame FRD,
        specific force and angular rate, one row per sample
  dvl   ``time [s]``, ``vel_x``, ``vel_y``, ``vel_z [m/s]``: body-frame velocity of the
        DVL
  gt    ``time [s]``, ``lat``, ``lon [rad | deg]``, ``height [m]`` (up),
        ``vel_n``, ``vel_e``, ``vel_d [m/s]``, ``roll``, ``pitch``, ``yaw [rad | deg]``
        (ZYX): the ground truth at its reference point
  ===== ============================================================================

  Extra columns are ignored (in the ``depth`` and ``fix`` tables, one named ``sigma…``
  that is none of their σ columns is refused); column order is free. The DVL table may
  hold an optional ``valid`` column (1 valid, 0 not; no unit). Three more tables are
  optional: ``depth`` (a pressure depth) and ``fix`` (position fixes: GNSS, USBL,
  LBL), each on its own stamps and rate, their columns, missing values and checks
  :mod:`pronet.recorded.aiding`'s, and ``heading`` (a compass's or an AHRS's yaw, true
  or magnetic with the ``declination`` given to the reader:
  :mod:`pronet.recorded.heading`). The DVL is optional when a depth or fixes are there
  (a GNSS/INS or a depth-and-fix recording); a recording needs at least one of the
  three.

Missing DVL readings (NaN or empty cells, no-lock markers such as RDI's −32.768 m/s,
all-zero rows while the vehicle moves, ``valid`` = 0) are not errors: they are taken out
of :attr:`Recording.dvl` and kept, with their reasons, in
:attr:`Recording.dvl_skipped_time` and :attr:`Recording.dvl_skipped_reason`; see
:mod:`pronet.recorded.missing`. A DVL without a single usable row is an error.

Checks (each failure raises :class:`RecordingError`, a ``ValueError``, naming the file
and, where there is one, the row): the file exists and is not empty (a UTF-8 byte-order
mark before the header is read as none), the columns are comma-separated and every
required one is present with a known unit, every value is a finite number (the DVL's
velocities aside: missing readings, above), time increases strictly, the sample rate is
plausible for the sensor (IMU 10 Hz–10 kHz, DVL 0.05–100 Hz, ground truth 0.05–1000 Hz,
each bound within :data:`pronet.recorded.plausible.NOMINAL_RATE_TOLERANCE`: a clock's
drift; a ground truth of one row is refused), the IMU time has no gap longer than five
median steps (a jitter beyond 15 % of a step is warned of:
:func:`pronet._util.plausibility.imu_jitter`), and the magnitudes fit their units (the
mean specific force near gravity, angular rates within 10 rad/s, the DVL's speed within
a factor 2 of the ground truth's, or without one at most
:data:`pronet.recorded.plausible.MAX_DVL_SPEED`; see
:func:`pronet.recorded.plausible.magnitudes`). A folder holding both a ``.csv`` and a
``.csv.gz`` of one stream is ambiguous and refused. Row numbers count data rows from 1
(the header is row 0).

Timestamps are kept as recorded: clock offsets and lever arms are the business of
:mod:`pronet.recorded.alignment`.
"""

from __future__ import annotations

import csv
import gzip
import io
import warnings
import zipfile
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from pronet._util.plausibility import MAX_IMU_GAP, PlausibilityWarning, imu_jitter
from pronet.recorded import aiding, heading, missing, plausible
from pronet.recorded.aiding import DepthReadings, PositionFixes
from pronet.recorded.bags import BagError, BagTopics, bag_streams, is_bag
from pronet.recorded.csvtext import parse_numbers as _parse_numbers
from pronet.recorded.csvtext import parse_rows
from pronet.recorded.heading import HeadingReadings
from pronet.recorded.plausible import Table, parse_header

F64 = NDArray[np.float64]


class RecordingError(ValueError):
    """A recording file is missing, malformed or implausible; the message names the file
    (and row)."""


#: Required columns of each table: name → accepted units and their factor to SI.
_RATE = {"rad/s": 1.0, "deg/s": np.pi / 180}
COLUMNS: dict[str, dict[str, dict[str, float]]] = {
    "imu": {
        "time": {"s": 1.0},
        **{f"acc_{a}": {"m/s^2": 1.0} for a in "xyz"},
        **{f"gyro_{a}": _RATE for a in "xyz"},
    },
    "dvl": {"time": {"s": 1.0}, **{f"vel_{a}": {"m/s": 1.0} for a in "xyz"}},
    "gt": {
        "time": {"s": 1.0},
        "lat": plausible.ANGLE_UNITS,
        "lon": plausible.ANGLE_UNITS,
        "height": {"m": 1.0},
        **{f"vel_{a}": {"m/s": 1.0} for a in "ned"},
        **{a: plausible.ANGLE_UNITS for a in ("roll", "pitch", "yaw")},
    },
}

#: Optional columns of each table, with their units (a ``valid`` flag has none).
OPTIONAL: dict[str, dict[str, dict[str, float]]] = {"dvl": {"valid": {"": 1.0, "-": 1.0}}}

#: Plausible sample rates [Hz] of each table.
RATE_RANGE = {"imu": (10.0, 10_000.0), "dvl": (0.05, 100.0), "gt": (0.05, 1000.0)}
RATE_RANGE.update(aiding.RATE_RANGE)
#: Every table's columns (the optional aiding tables' too), and their optional ones.
_SPEC = {**COLUMNS, **aiding.COLUMNS}
OPTIONAL.update(aiding.OPTIONAL)

#: The Snapir publisher's column names, by our name.
SNAPIR_NAMES = {
    "imu": {
        "time": "time",
        "acc x": "acc_x",
        "acc y": "acc_y",
        "acc z": "acc_z",
        "gyro x": "gyro_x",
        "gyro y": "gyro_y",
        "gyro z": "gyro_z",
    },
    "dvl": {"time": "time", "dvl x": "vel_x", "dvl y": "vel_y", "dvl z": "vel_z"},
    "gt": {
        "time": "time",
        "latitude": "lat",
        "longitude": "lon",
        "altitude": "height",
        "v north": "vel_n",
        "v east": "vel_e",
        "v down": "vel_d",
        "roll": "roll",
        "pitch": "pitch",
        "yaw": "yaw",
    },
}


@dataclass(frozen=True)
class Recording:
    """One recorded section, SI units, stamps as recorded (each stream its own clock).

    Attributes:
        name: section name (the folder or file stem).
        imu_time: ``(n,)`` IMU stamps [s].
        imu: ``(n, 6)`` ``[f (m/s²), ω (rad/s)]``, body frame FRD.
        dvl_time: ``(m,)`` DVL stamps [s].
        dvl: ``(m, 3)`` DVL body-frame velocity [m/s].
        gt_time: ``(k,)`` ground-truth stamps [s]; ``(0,)`` without a ground truth
            (:attr:`has_truth`), the three below then ``(0, 3)``.
        gt_lla: ``(k, 3)`` latitude, longitude [rad], height [m, up].
        gt_vel: ``(k, 3)`` NED velocity [m/s].
        gt_rpy: ``(k, 3)`` roll, pitch, yaw [rad] (ZYX).
        source: where it was read from.
        dvl_skipped_time: ``(j,)`` stamps [s] of the DVL rows skipped as missing
            readings (:mod:`pronet.recorded.missing`), not in ``dvl``.
        dvl_skipped_reason: why each was skipped (one of
            :data:`pronet.recorded.missing.REASONS`).
        dvl_variance: the DVL's noise variance R per axis [(m/s)², body FRD] that the
            recording states (a ROS bag's covariance, :mod:`pronet.recorded.bags`), or
            None (R as tuned).
        depth, fixes: the optional depth readings and position fixes
            (:mod:`pronet.recorded.aiding`), or None. ``dvl`` may then be empty.
        heading: the optional heading readings, true north
            (:mod:`pronet.recorded.heading`), or None.
    """

    name: str
    imu_time: F64
    imu: F64
    dvl_time: F64
    dvl: F64
    gt_time: F64
    gt_lla: F64
    gt_vel: F64
    gt_rpy: F64
    source: str
    dvl_skipped_time: F64 = field(default_factory=lambda: np.empty(0))
    dvl_skipped_reason: tuple[str, ...] = ()
    dvl_variance: tuple[float, float, float] | None = None
    depth: DepthReadings | None = None
    fixes: PositionFixes | None = None
    heading: HeadingReadings | None = None

    @property
    def duration(self) -> float:
        """IMU time span [s]."""
        return float(self.imu_time[-1] - self.imu_time[0])

    @property
    def has_truth(self) -> bool:
        """Whether the recording has a ground truth (``gt_time`` not empty)."""
        return len(self.gt_time) > 0


def read_snapir(folder: str | Path) -> Recording:
    """Read one Snapir section (``trajectoryNN/`` with ``imu``, ``dvl`` and ``gt``
    ``.csv.gz``) as published, validated; see the module docstring."""
    folder = Path(folder)
    tables = {kind: _read_csv(_find(folder, kind), kind, SNAPIR_NAMES[kind]) for kind in COLUMNS}
    return _recording(folder.name, tables, str(folder))


def read_recording(
    path: str | Path,
    topics: BagTopics | None = None,
    *,
    declination: float | None = None,
    read_heading: bool = True,
) -> Recording:
    """Read a recording in the generic format (a folder of ``imu``/``dvl``/``gt`` CSV
    files, or one ``.npz``; the ground truth optional), validated; see the module
    docstring for the columns. A ROS bag is read with ``topics``
    (:func:`pronet.recorded.bags.bag_streams`); ``topics`` with anything but a bag is
    refused (``RecordingError`` naming the path). ``declination``: the magnetic
    declination [deg, east positive] that turns a magnetic heading true (a magnetic one
    without it is refused; :mod:`pronet.recorded.heading`); ``read_heading`` False: the
    heading table or topic is not read (``--no-heading``)."""
    path = Path(path)
    heading.check_declination(declination, "declination")
    if is_bag(path):
        if not read_heading:
            topics = replace(topics or BagTopics(), heading=None)
        return _read_bag(path, topics, declination)
    if topics is not None:
        raise RecordingError(
            f"{path}: not a ROS bag (a .bag file, or a folder with metadata.yaml), so no "
            "bag topics to read; a folder of CSVs or an .npz is --format generic"
        )
    if path.is_dir():
        found = {
            kind: _find_optional(path, kind) if kind in _MAY_LACK else _find(path, kind)
            for kind in _SPEC
        }
        if not any(found[kind] for kind in _OPTIONAL_TABLES):
            _find(path, "dvl")  # the error: none of the three
        if not read_heading:
            found["heading"] = None
        tables = {k: _read_csv(f, k, None) for k, f in found.items() if f is not None}
        return _recording(path.name, tables, str(path), declination)
    if path.suffix == ".npz":
        tables = _read_npz(path, () if read_heading else ("heading",))
        return _recording(path.stem, tables, str(path), declination)
    raise RecordingError(
        f"{path}: expected a folder of imu/dvl/gt CSV files or an .npz file"
        + ("" if path.exists() else " (it does not exist)")
    )


def write_recording(path: str | Path, recording: Recording) -> Path:
    """Write ``recording`` in the generic format: an ``.npz`` file if ``path`` ends in
    ``.npz``, else a folder of CSV files (SI units, full precision): ``imu``, ``gt``
    when it has one, ``dvl`` unless it is empty, ``depth``, ``fix`` and ``heading``
    (true) when it has them. The rows skipped as missing values are not in it (only the
    readings the filter uses)."""
    path = Path(path)
    tables = _as_tables(recording)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix == ".npz":
        arrays: dict[str, np.ndarray] = {}
        for kind, (header, data) in tables.items():
            arrays[kind] = data
            arrays[f"{kind}_columns"] = np.array(header)
        np.savez(path, **arrays)  # type: ignore[arg-type]
        return path
    path.mkdir(parents=True, exist_ok=True)
    for kind, (header, data) in tables.items():
        buf = io.StringIO()
        buf.write(",".join(header) + "\n")
        np.savetxt(buf, data, delimiter=",", fmt="%.17g")
        (path / f"{kind}.csv").write_text(buf.getvalue())
    return path


def _read_bag(path: Path, topics: BagTopics | None, declination: float | None) -> Recording:
    """A ROS bag's streams (:func:`pronet.recorded.bags.bag_streams`), checked as the
    generic format's tables are, with the R its DVL covariance states and the water
    density its depth was computed with."""
    topics = topics or BagTopics()
    try:
        streams, variance = bag_streams(path, topics)
    except BagError as exc:
        raise RecordingError(str(exc)) from None
    tables = {}
    for kind, got in streams.items():
        picks = [(i, 1.0) for i in range(len(got.labels))]
        values = _finish(got.where, got.values, picks, got.labels, kind)
        tables[kind] = Table(values, got.where, got.labels)
    name = path.stem if path.is_file() else path.name
    reasons = streams["heading"].reasons if "heading" in streams else None
    rec = _recording(name, tables, str(path), declination, reasons)
    depth = None if rec.depth is None else replace(rec.depth, water_density=topics.water_density)
    return replace(rec, dvl_variance=variance, depth=depth)


def _as_tables(rec: Recording) -> dict[str, tuple[list[str], F64]]:
    def header(kind: str) -> list[str]:
        return [f"{name} [{next(iter(units))}]" for name, units in COLUMNS[kind].items()]

    gt = np.column_stack([rec.gt_time, rec.gt_lla, rec.gt_vel, rec.gt_rpy])
    out = {
        "imu": (header("imu"), np.column_stack([rec.imu_time, rec.imu])),
        "dvl": (header("dvl"), np.column_stack([rec.dvl_time, rec.dvl])),
        "gt": (header("gt"), gt),
    }
    if not len(rec.dvl_time):
        del out["dvl"]
    if not rec.has_truth:
        del out["gt"]
    out.update(aiding.as_tables(rec.depth, rec.fixes, rec.heading))
    return out


#: The tables of which a recording needs one; those it may lack (and the truth, heading).
_OPTIONAL_TABLES = ("dvl", "depth", "fix")
_MAY_LACK = (*_OPTIONAL_TABLES, "gt", "heading")


def _find(folder: Path, kind: str) -> Path:
    found = _find_optional(folder, kind)
    if found is None:
        also = " (nor depth.csv or fix.csv: one of the three is needed)" if kind == "dvl" else ""
        raise RecordingError(f"{folder}: no {kind}.csv or {kind}.csv.gz{also}")
    return found


def _find_optional(folder: Path, kind: str) -> Path | None:
    if not folder.is_dir():
        missing = "" if folder.exists() else " (it does not exist)"
        raise RecordingError(f"{folder}: not a folder{missing}")
    found = [folder / n for n in (f"{kind}.csv", f"{kind}.csv.gz") if (folder / n).is_file()]
    if len(found) > 1:
        raise RecordingError(
            f"{folder}: both {kind}.csv and {kind}.csv.gz; keep the one that holds the data"
        )
    return found[0] if found else None


def _select_columns(
    where: str, header: list[str], kind: str, names: dict[str, str] | None
) -> list[tuple[int, float]]:
    """Column index and SI factor of each required column, in :data:`COLUMNS` order."""
    parsed = [parse_header(h) for h in header]
    ours_all = [names.get(n, n) if names is not None else n for n, _ in parsed]
    wanted = set(_SPEC[kind]) | set(OPTIONAL.get(kind, {}))
    if (twice := plausible.duplicate_columns(where, ours_all, header, wanted)) is not None:
        raise RecordingError(twice)
    if (sigma := aiding.unknown_sigma(where, kind, ours_all, header)) is not None:
        raise RecordingError(sigma)
    found: dict[str, tuple[int, str]] = {}
    for i, (ours, (_, unit)) in enumerate(zip(ours_all, parsed, strict=True)):
        found.setdefault(ours, (i, unit))
    picks = []
    for name, units in _SPEC[kind].items():
        if name not in found:
            shown = ", ".join(header)
            raise RecordingError(
                f"{where}: missing column {name!r} [{' | '.join(units)}]; has: {shown}"
            )
        i, unit = found[name]
        if unit not in units:
            raise RecordingError(
                f"{where}: column {header[i]!r} has unit [{unit}]; expected one of "
                f"{', '.join(units)}"
            )
        picks.append((i, units[unit]))
    for name, units in OPTIONAL.get(kind, {}).items():
        if name in found:
            i, unit = found[name]
            if unit not in units:
                expected = ", ".join(u for u in units if u) or "none"
                raise RecordingError(
                    f"{where}: column {header[i]!r} has unit [{unit}]; expected {expected}"
                )
            picks.append((i, units[unit]))
    return picks


def _read_csv(path: Path, kind: str, names: dict[str, str] | None) -> Table:
    try:
        code = "utf-8-sig"  # a byte-order mark before the header (Excel's) is no cell
        gz = path.suffix == ".gz"
        raw = gzip.open(path, "rt", encoding=code) if gz else open(path, newline="", encoding=code)
        with raw as fh:
            text = fh.read()
    except (OSError, EOFError, UnicodeDecodeError) as exc:
        raise RecordingError(f"{path}: cannot be read ({exc})") from None
    reader = csv.reader(io.StringIO(text))
    header = next(reader, [])
    if not any(cell.strip() for cell in header):
        raise RecordingError(f"{path}: is empty (no header row)")
    if len(header) == 1 and (sep := next((d for d in ";\t|" if d in header[0]), None)):
        raise RecordingError(
            f"{path}: the header is one column separated by {sep!r}; "
            "the file must be comma-separated"
        )
    picks = _select_columns(str(path), header, kind, names)
    columns = [i for i, _ in picks]
    table = _parse_numbers(text, len(header))
    if table is not None:
        out = np.ascontiguousarray(table[:, columns])
    else:  # not a plain table of numbers: the careful reader names the row and cell
        # an empty DVL velocity cell is a missing reading (NaN), not a malformed file
        blank_ok = set(columns[1:4]) if kind == "dvl" else set()
        parsed = [parse_header(header[i])[0] for i in columns]
        blank_ok |= {columns[j] for j in aiding.may_be_missing(kind, parsed)}
        try:
            out = parse_rows(path, header, reader, columns, blank_ok)
        except ValueError as exc:
            raise RecordingError(str(exc)) from None
    labels = [header[i].strip() for i, _ in picks]
    return Table(_finish(str(path), out, picks, labels, kind), str(path), labels)


def _npz_array(archive: Any, path: Path, name: str, fix: str) -> NDArray[Any]:
    """Array ``name`` of an open ``.npz``; an object array (it would need pickle, which is
    refused: loading it could run code) is a :class:`RecordingError` naming it and how
    to save it instead (``fix``: the kind of array and the call that makes one)."""
    try:
        return cast("NDArray[Any]", archive[name])
    except ValueError:
        raise RecordingError(
            f"{path}[{name}]: an object array, which cannot be read without pickle (refused: "
            f"loading it could run code); save it as an array of {fix}"
        ) from None


def _read_npz(path: Path, skip: tuple[str, ...] = ()) -> dict[str, Table]:
    try:
        archive = np.load(path, allow_pickle=False)
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
        raise RecordingError(f"{path}: not a readable .npz ({exc})") from None
    tables = {}
    with archive:
        has = {k for k in _SPEC if k in archive.files or f"{k}_columns" in archive.files}
        for kind in (k for k in _SPEC if k not in skip):
            where = f"{path}[{kind}]"
            optional = kind in _MAY_LACK and kind not in _OPTIONAL_TABLES
            some = kind in _OPTIONAL_TABLES and has & set(_OPTIONAL_TABLES)
            if kind not in has and (optional or some):
                continue  # an optional table left out (a half of one is an error, below)
            if kind not in archive.files or f"{kind}_columns" not in archive.files:
                raise RecordingError(f"{path}: needs arrays {kind!r} and '{kind}_columns'")
            data = _npz_array(archive, path, kind, "numbers: np.asarray(table, dtype=float)")
            names = f"{kind}_columns"
            header = _npz_array(archive, path, names, "strings: np.array(names, dtype=str)")
            if header.dtype.kind != "U" or header.ndim != 1:
                raise RecordingError(
                    f"{path}[{kind}_columns]: must be a 1-D array of strings, got {header.dtype} "
                    f"{header.shape}; save the names as np.array(names, dtype=str)"
                )
            if data.ndim != 2 or data.shape[1] != len(header) or data.dtype.kind not in "iuf":
                raise RecordingError(
                    f"{where}: must be a 2-D numeric array with {len(header)} columns "
                    f"(one per {kind}_columns entry), got {data.dtype} {data.shape}"
                )
            if data.shape[0] == 0:
                raise RecordingError(f"{where}: has no rows")
            labels = [str(h) for h in header]
            picks = _select_columns(where, labels, kind, None)
            out = data[:, [i for i, _ in picks]].astype(np.float64)
            chosen = [labels[i] for i, _ in picks]
            tables[kind] = Table(_finish(where, out, picks, chosen, kind), where, chosen)
    return tables


def _finish(
    where: str, values: F64, picks: list[tuple[int, float]], labels: list[str], kind: str
) -> F64:
    """Check finiteness (a DVL velocity may be missing: :mod:`pronet.recorded.missing`),
    a ``valid`` column of 0 and 1, strictly increasing time and the rate; convert to SI."""
    bad = ~np.isfinite(values)
    blank = aiding.may_be_missing(kind, [parse_header(label)[0] for label in labels])
    bad[:, blank] &= ~np.isnan(values[:, blank])
    if kind == "dvl":
        bad[:, 1:4] = False
        if values.shape[1] > 4 and not np.isin(values[:, 4], (0.0, 1.0)).all():
            r = int(np.argmax(~np.isin(values[:, 4], (0.0, 1.0))))
            raise RecordingError(
                f"{where}, row {r + 1}: {labels[4]!r} is {values[r, 4]}; it must be 1 "
                "(valid) or 0 (not)"
            )
    if bad.any():
        r, j = np.argwhere(bad)[0]
        raise RecordingError(f"{where}, row {r + 1}: {labels[j]!r} is {values[r, j]}, not finite")
    t = values[:, 0]
    if kind == "gt" and len(t) < 2:
        raise RecordingError(f"{where}: one data row; a ground truth needs two or more")
    step = np.diff(t)
    if (step <= 0).any():
        r = int(np.argmax(step <= 0)) + 2
        raise RecordingError(
            f"{where}, row {r}: time {t[r - 1]} s does not increase (previous row {t[r - 2]} s)"
        )
    if len(t) > 1:
        rate = 1.0 / float(np.median(step))
        lo, hi = RATE_RANGE[kind]
        tolerance = plausible.NOMINAL_RATE_TOLERANCE  # a clock's drift at a bound
        if not lo * (1 - tolerance) <= rate <= hi * (1 + tolerance):
            raise RecordingError(  # six digits: never shown as the bound it is beyond
                f"{where}: sample rate {rate:.6g} Hz is implausible for {kind} "
                f"(expected {lo:g}–{hi:g} Hz); is the time column in seconds?"
            )
        gap = step > MAX_IMU_GAP * np.median(step)
        if kind == "imu" and gap.any():  # the strapdown would integrate across it
            r = int(np.argmax(gap)) + 2
            raise RecordingError(
                f"{where}, row {r}: a gap of {step[r - 2]:.4g} s after {t[r - 2]} s (the "
                f"median step is {np.median(step):.4g} s); cut the section there"
            )
        if kind == "imu" and (shaky := imu_jitter(where, step)) is not None:
            warnings.warn(shaky, PlausibilityWarning, stacklevel=2)
    return values * np.array([factor for _, factor in picks])


def _recording(
    name: str,
    tables: dict[str, Table],
    source: str,
    declination: float | None = None,
    heading_reasons: tuple[str, ...] | None = None,
) -> Recording:
    imu = tables["imu"].values
    truth = tables.get("gt")
    gt = np.empty((0, 10)) if truth is None else truth.values
    raw_dvl = tables["dvl"].values if "dvl" in tables else np.empty((0, 4))
    if truth is not None and (beyond := plausible.angle_beyond(truth, 1, -90, 90, "a latitude")):
        raise RecordingError(beyond)
    for kind in (k for k in tables if k != "imu"):
        if (apart := plausible.disjoint_streams(tables["imu"], tables[kind], kind)) is not None:
            raise RecordingError(apart)
    if truth is not None and (beyond := plausible.beyond_bounds(truth)) is not None:
        raise RecordingError(beyond)
    plausible.warn_upside_down(truth)
    try:
        speed = None if truth is None else (gt[:, 0], np.linalg.norm(gt[:, 4:7], axis=1))
        dvl, why = (
            missing.usable_rows(raw_dvl, speed, source)
            if len(raw_dvl)
            else (raw_dvl, np.empty(0, str))
        )
        depth, fixes = aiding.streams(tables)
        yaw = None
        if "heading" in tables:
            names = [plausible.parse_header(label)[0] for label in tables["heading"].labels]
            yaw = heading.heading_readings(tables["heading"], names, declination, heading_reasons)
    except ValueError as exc:
        raise RecordingError(str(exc)) from None
    skipped = why != ""
    for problem in (
        plausible.short_imu(tables),
        plausible.magnitudes(imu[:, 1:7], dvl[:, 1:4], gt[:, 4:7], source),
        plausible.stuck_channels(tables["imu"], range(1, 7)),
        plausible.stuck_channels(tables["dvl"], range(1, 4), ~skipped) if len(dvl) else None,
        *(
            ()
            if truth is None
            else (
                plausible.attitude_units(tables["imu"], truth),
                plausible.position_units(truth),
                aiding.against_truth(depth, fixes, truth),
                heading.against_truth(yaw, truth),
            )
        ),
    ):
        if problem is not None:
            raise RecordingError(problem)
    return Recording(
        name=name,
        imu_time=imu[:, 0].copy(),
        imu=np.ascontiguousarray(imu[:, 1:7]),
        dvl_time=dvl[:, 0].copy(),
        dvl=np.ascontiguousarray(dvl[:, 1:4]),
        gt_time=gt[:, 0].copy(),
        gt_lla=np.ascontiguousarray(gt[:, 1:4]),
        gt_vel=np.ascontiguousarray(gt[:, 4:7]),
        gt_rpy=np.ascontiguousarray(gt[:, 7:10]),
        source=source,
        dvl_skipped_time=raw_dvl[skipped, 0].copy(),
        dvl_skipped_reason=tuple(str(r) for r in why[skipped]),
        depth=depth,
        fixes=fixes,
        heading=yaw,
    )
