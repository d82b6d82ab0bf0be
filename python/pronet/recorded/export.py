"""The files a user loads, written from a navigated recording
(:class:`pronet.recorded.solution.Navigation`), each atomically
(:func:`pronet._util.files.atomic_write`):

- ``trajectory.csv`` (:func:`write_trajectory`): one row per epoch of each solution,
  the columns :data:`TRAJECTORY_COLUMNS`, every number at full precision (Python's
  ``repr``: ``pd.read_csv`` gives back the very floats);
- ``track.geojson`` (:func:`write_track`): the track as RFC 7946 GeoJSON for GIS tools;
- ``config.json`` (:func:`write_config`): ``navigation.config``;
- an odometry bag, when asked (:func:`pronet.recorded.odometry.write_odometry_bag`);
- the figures and ``report.md`` (:mod:`pronet.recorded.report`);

:func:`write_all` writes them all into a folder.

``trajectory.csv``. ``time [s]`` is the IMU clock counted from the recording's first
IMU stamp (:attr:`~pronet.recorded.solution.Solution.epoch`), ``stamp [s]`` is ``epoch
+ time`` (as recorded: Unix time for a bag). Latitude and longitude are WGS-84 degrees,
``depth [m]`` is down (minus the height above the ellipsoid), the velocity NED [m/s],
roll, pitch, yaw (ZYX) degrees with the yaw in [0, 360). The 1σ columns are the filter's:
``sigma_n``, ``sigma_e``, ``sigma_d`` [m] of the position error in NED (``sigma_d`` is
the depth's), ``sigma_vel_*`` [m/s] of the NED velocity error, and
``sigma_psi_n``, ``sigma_psi_e``, ``sigma_psi_d`` [deg] of the attitude error ψ, a small
rotation about the north, east and down axes. ``sigma_roll``, ``sigma_pitch``,
``sigma_yaw`` [deg] are the σ of roll, pitch and yaw themselves, angles about other
axes, to first order from these (:func:`pronet.recorded.attitude.attitude_sigma`, which
states the map): for a level vehicle ``sigma_yaw`` = ``sigma_psi_d``, and with ψ_N and
ψ_E equally uncertain (as levelling leaves them) ``sigma_roll`` ≈ ``sigma_pitch`` ≈
``sigma_psi_n``.

``track.geojson`` (RFC 7946: coordinates ``[longitude, latitude]`` in WGS-84 degrees): a
FeatureCollection of, per solution, one ``LineString`` (properties ``kind: "track"``,
``solution``, start and end time and stamp [s], ``epochs``; at most ``max_line``
vertices, every k-th epoch and the last, and a ``MultiLineString`` cut where the track
crosses the antimeridian) and at most ``max_points`` ``Point`` features spread evenly
over the epochs (``kind: "point"``, ``solution``, ``time_s``, ``stamp_s``,
``depth_m``, ``yaw_deg``, ``sigma_n_m``, ``sigma_e_m``, ``sigma_d_m``, ``sigma_h_m``);
then the position fixes (``kind: "fix"``, ``time_s``, ``stamp_s``, ``height_m``).
``sigma_h_m`` is √(σ_N² + σ_E²), the horizontal error's RMS radius (exact whatever the
north-east correlation, which a solution does not hold: the orientation of the error
ellipse is not known, only its σ along north and east). Epochs with a non-finite
position are left out of the GeoJSON (they stay in the CSV, as ``nan``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import shutil
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from pronet._util.files import atomic_write, check_writable, json_bytes, replace_together
from pronet.recorded import odometry, report
from pronet.recorded.attitude import attitude_sigma, yaw_degrees

if TYPE_CHECKING:
    from pronet.recorded.solution import Navigation, Solution

F64 = NDArray[np.float64]

#: The columns of ``trajectory.csv``, in order (module docstring).
TRAJECTORY_COLUMNS = (
    "solution",
    "time [s]",
    "stamp [s]",
    "lat [deg]",
    "lon [deg]",
    "depth [m]",
    "vel_n [m/s]",
    "vel_e [m/s]",
    "vel_d [m/s]",
    "roll [deg]",
    "pitch [deg]",
    "yaw [deg]",
    "sigma_n [m]",
    "sigma_e [m]",
    "sigma_d [m]",
    "sigma_vel_n [m/s]",
    "sigma_vel_e [m/s]",
    "sigma_vel_d [m/s]",
    "sigma_roll [deg]",
    "sigma_pitch [deg]",
    "sigma_yaw [deg]",
    "sigma_psi_n [deg]",
    "sigma_psi_e [deg]",
    "sigma_psi_d [deg]",
)
#: The file names :func:`write_all` writes (the bag's and the figures' aside).
TRAJECTORY, TRACK, CONFIG = "trajectory.csv", "track.geojson", "config.json"
#: Default caps of the GeoJSON's points per solution and of its track's vertices.
MAX_POINTS, MAX_LINE = 2000, 20000


def check_navigation(navigation: Navigation) -> None:
    """``ValueError`` naming the solution unless each has at least two epochs, finite
    increasing times and a finite epoch: checked before any file is written."""
    for sol in navigation.solutions:
        where = f"navigation.{sol.label}"
        t = np.asarray(sol.time, dtype=np.float64)
        if len(t) < 2:
            raise ValueError(f"{where}: a solution needs at least 2 epochs, got {len(t)}")
        if not (np.isfinite(t).all() and math.isfinite(sol.epoch)):
            raise ValueError(f"{where}: its times and epoch must be finite")
        if np.any(np.diff(t) <= 0):
            row = int(np.argmax(np.diff(t) <= 0)) + 1
            raise ValueError(f"{where}.time: not increasing at epoch {row}")


def trajectory_values(solution: Solution) -> F64:
    """``(n, 23)`` the numeric columns of ``trajectory.csv`` (all but ``solution``) for
    one solution, in :data:`TRAJECTORY_COLUMNS` order and units."""
    time = np.asarray(solution.time, dtype=np.float64)
    lla = np.asarray(solution.lla, dtype=np.float64)
    rpy = np.asarray(solution.rpy, dtype=np.float64)
    sigma = np.asarray(solution.sigma, dtype=np.float64)
    angles = np.degrees(rpy[:, :2])
    return np.column_stack(
        [
            time,
            solution.epoch + time,
            np.degrees(lla[:, :2]),
            -lla[:, 2],
            np.asarray(solution.vel, dtype=np.float64),
            angles,
            yaw_degrees(rpy[:, 2]),
            sigma[:, 0:6],
            np.degrees(attitude_sigma(rpy, sigma[:, 6:9])),
            np.degrees(sigma[:, 6:9]),
        ]
    )


def trajectory_csv(navigation: Navigation, rows: int = 20_000) -> Iterator[bytes]:
    """``trajectory.csv``'s text in pieces of at most ``rows`` rows (UTF-8): the header,
    then the forward solution's rows and the smoothed one's, each number as Python's
    ``repr`` (which reads back exactly)."""
    yield (",".join(TRAJECTORY_COLUMNS) + "\n").encode()
    for sol in navigation.solutions:
        values = trajectory_values(sol)
        for start in range(0, len(values), rows):
            lines = (
                f"{sol.label}," + ",".join(map(repr, row)) + "\n"
                for row in values[start : start + rows].tolist()
            )
            yield "".join(lines).encode()


def write_trajectory(navigation: Navigation, path: str | Path) -> Path:
    """Write ``trajectory.csv`` (module docstring) to ``path`` atomically; the path."""
    check_navigation(navigation)
    path = Path(path)
    atomic_write(path, trajectory_csv(navigation))
    return path


def _number(value: float) -> float | None:
    """A JSON number, or None (``null``) for NaN and infinities."""
    return value if math.isfinite(value) else None


def _spread(n: int, most: int) -> NDArray[np.intp]:
    """At most ``most`` indices of ``n`` spread evenly, the first and the last kept."""
    if n <= most:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, most).round().astype(np.intp))


def _thinned(n: int, most: int) -> NDArray[np.intp]:
    """Every k-th index of ``n`` and the last, at most about ``most`` of them."""
    k = max(1, -(-n // most))
    return np.unique(np.r_[np.arange(0, n, k), n - 1])


def _line(lon_lat: F64) -> dict[str, Any]:
    """A ``LineString`` of ``(m, 2)`` degrees, or a ``MultiLineString`` cut where a step
    crosses the antimeridian (a jump of more than 180° in longitude; RFC 7946 §3.1.9)."""
    cuts = np.flatnonzero(np.abs(np.diff(lon_lat[:, 0])) > 180.0) + 1
    parts = [p.tolist() for p in np.split(lon_lat, cuts) if len(p) >= 2]
    if len(parts) == 1 and len(cuts) == 0:
        return {"type": "LineString", "coordinates": parts[0]}
    return {"type": "MultiLineString", "coordinates": parts}


def _track_features(sol: Solution, max_points: int, max_line: int) -> list[dict[str, Any]]:
    """One solution's track line and its points (module docstring)."""
    values = trajectory_values(sol)
    finite = np.flatnonzero(np.isfinite(values[:, 2:4]).all(axis=1))
    time, stamp = values[:, 0], values[:, 1]
    features = []
    if len(finite) >= 2:
        line = finite[_thinned(len(finite), max_line)]
        props: dict[str, Any] = {"kind": "track", "solution": sol.label, "epochs": len(sol.time)}
        props |= {"start_time_s": float(time[0]), "end_time_s": float(time[-1])}
        props |= {"start_stamp_s": float(stamp[0]), "end_stamp_s": float(stamp[-1])}
        geometry = _line(values[line][:, [3, 2]])
        features.append({"type": "Feature", "geometry": geometry, "properties": props})
    sigma_h = np.hypot(values[:, 11], values[:, 12])
    for i in finite[_spread(len(finite), max_points)].tolist():
        row = values[i].tolist()
        point = {
            "kind": "point",
            "solution": sol.label,
            "time_s": row[0],
            "stamp_s": row[1],
            "depth_m": row[4],
            "yaw_deg": row[10],
            "sigma_n_m": row[11],
            "sigma_e_m": row[12],
            "sigma_d_m": row[13],
            "sigma_h_m": float(sigma_h[i]),
        }
        geometry = {"type": "Point", "coordinates": [row[3], row[2]]}
        properties = {k: v if isinstance(v, str) else _number(float(v)) for k, v in point.items()}
        features.append({"type": "Feature", "geometry": geometry, "properties": properties})
    return features


def _fix_features(navigation: Navigation) -> list[dict[str, Any]]:
    """The position fixes as ``Point`` features (those with a finite position)."""
    if "fix" not in navigation.readings:
        return []
    time, lla = (np.asarray(a, dtype=np.float64) for a in navigation.readings["fix"])
    features = []
    for t, (lat, lon, h) in zip(time.tolist(), lla.tolist(), strict=True):
        if not (math.isfinite(lat) and math.isfinite(lon)):
            continue
        properties = {"kind": "fix", "time_s": _number(t)}
        properties |= {"stamp_s": _number(navigation.forward.epoch + t), "height_m": _number(h)}
        geometry = {"type": "Point", "coordinates": [math.degrees(lon), math.degrees(lat)]}
        features.append({"type": "Feature", "geometry": geometry, "properties": properties})
    return features


def track_features(
    navigation: Navigation, max_points: int = MAX_POINTS, max_line: int = MAX_LINE
) -> list[dict[str, Any]]:
    """The GeoJSON features of ``track.geojson`` (module docstring), as plain dicts."""
    if max_points < 2 or max_line < 2:
        raise ValueError(f"max_points, max_line: at least 2 each, got {max_points}, {max_line}")
    features = []
    for sol in navigation.solutions:
        features.extend(_track_features(sol, max_points, max_line))
    return features + _fix_features(navigation)


def _feature_collection(name: str, features: Iterable[dict[str, Any]]) -> str:
    """A FeatureCollection's text, one feature a line (compact JSON, no NaN)."""
    lines = ",\n".join(json.dumps(f, separators=(",", ":"), allow_nan=False) for f in features)
    head = json.dumps({"type": "FeatureCollection", "name": name})[:-1]
    return f'{head}, "features": [\n{lines}\n]}}\n'


def write_track(
    navigation: Navigation,
    path: str | Path,
    max_points: int = MAX_POINTS,
    max_line: int = MAX_LINE,
) -> Path:
    """Write ``track.geojson`` (module docstring) to ``path`` atomically; the path.

    Args:
        navigation: the navigated recording.
        path: the file to write.
        max_points: at most this many ``Point`` features per solution.
        max_line: at most about this many vertices of each solution's track.
    """
    check_navigation(navigation)
    path = Path(path)
    atomic_write(path, track_geojson(navigation, max_points, max_line))
    return path


def track_geojson(
    navigation: Navigation, max_points: int = MAX_POINTS, max_line: int = MAX_LINE
) -> bytes:
    """The bytes of ``track.geojson`` (:func:`write_track`)."""
    return _feature_collection(
        navigation.name, track_features(navigation, max_points, max_line)
    ).encode()


def config_bytes(navigation: Navigation) -> bytes:
    """``navigation.config`` as strict JSON (:func:`pronet._util.files.json_bytes`:
    NumPy arrays as lists, NaN as ``null``); ``TypeError`` naming the key of a value
    that is not plain data."""
    config = dict(navigation.config)
    try:
        return json_bytes(config)
    except TypeError as exc:
        for key, value in config.items():
            try:
                json_bytes(value)
            except TypeError:
                raise TypeError(f"navigation.config[{key!r}]: {exc}") from None
        raise


def write_config(navigation: Navigation, path: str | Path) -> Path:
    """Write ``config.json`` (:func:`config_bytes`) to ``path`` atomically; the path."""
    path = Path(path)
    atomic_write(path, config_bytes(navigation))
    return path


def check_out_dir(out: Path, option: str = "out_dir") -> None:
    """``ValueError`` naming ``option`` unless :func:`write_all` can write into ``out``:
    a folder or none yet, below a writable one (a command checks it before its work)."""
    if out.exists() and not out.is_dir():
        raise ValueError(f"{option}: {out} is a file, not a folder")
    check_writable(out, option)


def write_all(
    navigation: Navigation,
    out_dir: str | Path,
    *,
    bag: str | None = None,
    bag_options: odometry.OdometryOptions | None = None,
    figures: bool = True,
) -> list[Path]:
    """Write every file of a navigated recording into ``out_dir`` (made if needed):
    ``trajectory.csv``, ``track.geojson``, ``config.json``, with ``bag`` (a storage:
    ``"rosbag1"``, ``"sqlite3"`` or ``"mcap"``) the odometry bag
    (:func:`pronet.recorded.odometry.write_odometry_bag`, ``odometry.bag`` or the ROS 2
    bag folder ``odometry``; ``bag_options``: its frames, topics and rate), with
    ``figures`` ``track.png``, ``depth_heading.png``, ``innovations.png`` (a figure that
    cannot be drawn is left out, named in the notes and in ``config.json``'s
    ``figures_failed``), and last ``report.md``
    (:mod:`pronet.recorded.report`), which lists them all. The files
    replace those of an earlier run as one (all old or all new, the report last:
    :func:`pronet._util.files.replace_together`), and an earlier run's figures this
    one does not draw are removed after; an existing bag is refused, and the
    new one is removed again when the other files fail.
    Everything is checked before the first file is written (``ValueError``, or
    :class:`~pronet._util.extras.MissingExtra` for a bag without ``rosbags``). Returns
    the paths written, in that order."""
    check_navigation(navigation)
    out = Path(out_dir)
    check_out_dir(out)
    options = bag_options or odometry.OdometryOptions()
    if bag is not None:
        odometry.check_bag(out / odometry.bag_name(bag), navigation, bag, options)
    config_bytes(navigation)  # a config that is not plain data: before any file
    drawn, failed = report.drawn_figures(navigation) if figures else ([], [])
    if failed:  # said in report.md's notes and config.json; the rest is written
        config = {**navigation.config, "figures_failed": failed}
        notes = (*navigation.notes, *failed)
        navigation = dataclasses.replace(navigation, notes=notes, config=config)
    bag_path = None if bag is None else out / odometry.bag_name(bag)
    made = [p for p in (out, *out.parents) if not p.exists()]  # leaf first
    out.mkdir(parents=True, exist_ok=True)
    try:  # the report, which lists them, last: the earlier files all old or all new
        files: list[tuple[Path, bytes | Iterable[bytes]]] = [
            (out / TRAJECTORY, trajectory_csv(navigation)),
            (out / TRACK, track_geojson(navigation)),
            (out / CONFIG, config_bytes(navigation)),
        ]
        files += [(out / name, png) for name, png in drawn]
        names = [p.name for p, _ in files[:3]] + ([] if bag_path is None else [bag_path.name])
        names += [p.name for p, _ in files[3:]] + [report.REPORT]
        origin = None
        if bag is not None and bag_path is not None:  # new (an existing one was refused)
            odometry.write_odometry_bag(bag_path, navigation, bag, options)
            origin = odometry.bag_origin(navigation, options)
        text = report.report_markdown(navigation, names, origin, options)
        replace_together([*files, (out / report.REPORT, text.encode())])
    except BaseException:  # an interrupt too: no partial bag, no empty folder of ours
        if bag_path is not None:
            _remove(bag_path)
        for folder in made:  # those this write made, leaf first, while empty
            try:
                folder.rmdir()
            except OSError:
                break
        raise
    for name in set(report.FIGURES) - set(names):  # an earlier run's, not this one's
        (out / name).unlink(missing_ok=True)
    return [out / name for name in names]


def _remove(path: Path) -> None:
    """Remove a bag this write made (a ROS 2 bag is a folder)."""
    if path.is_dir():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)
