"""Your own vehicle's filter tuning for ``pronet real --filter FILE.toml``: the keys of a
scenario file's ``[filter]`` table (:data:`pronet.config.FILTER_KEYS`), an IMU grade
preset and the lever arms, over the FOG defaults of
:func:`pronet.recorded.tuning.real_filter_config`.

A file, every key optional::

    grade = "mems"                      # "mems", "tactical" or "fog" (GRADES): its P0
                                        # biases and bias random-walk PSDs, applied first
    p0_sigma = [...]                    # 15 initial 1σ, as FilterConfig (overrides grade)
    accel_bias_psd = 2.5e-7             # (m/s²)²/s
    gyro_bias_psd = 7.5e-9              # (rad/s)²/s
    dvl_variance = [1e-4, 1e-4, 1e-4]   # the DVL noise R [(m/s)²] (the "datasheet" R)
    aiding = "body"; innovation_gate = 16.27; formulation = "invariant"
    imu_lever_arm = [0.0, 0.0, 0.0]     # IMU from the ground-truth point [m, body FRD]
    dvl_lever_arm = [0.5, 0.0, 0.3]     # DVL from the ground-truth point [m, body FRD]
    depth_sigma = 0.1                   # the depth's 1σ [m] where a recording has none
    fix_sigma = [2.0, 2.0, 4.0]         # the fixes' 1σ N, E, D [m] where it has none
    heading_sigma = 1.0                 # the heading's 1σ [deg] where it has none
    declination = 4.5                   # magnetic declination [deg, east positive] of
                                        # a magnetic heading (pronet.recorded.heading)
    depth_lever_arm = [0.0, 0.2, 0.3]   # the pressure sensor from the ground-truth point
    fix_lever_arm = [0.0, 0.0, -1.0]    # the fix's antenna or transponder, likewise
    surface_depth = 0.1                 # the pressure sensor's depth [m] while the
                                        # vehicle floats (pronet.recorded.surface)
                                        # (these three: pronet navigate's; pronet real
                                        # warns that it does not apply them)
    # lever_arm = [...]                 # FilterConfig's: the DVL from the IMU, with
                                        # imu_lever_arm beside it (not dvl_lever_arm)

The same keys may sit in a ``[filter]`` table, or some at the top level and the others
in it: one rule for both levels (a key at both is refused, an unknown key at either
too; beside a ``[filter]`` table the top level may hold a scenario file's own keys and
tables, which are not read). ``imu_dt`` is refused: ``pronet real`` uses each section's own IMU step
(:func:`pronet.recorded.tuning.imu_step`). ``--filter mems`` (a grade's name, not a
file) is the preset alone.

The grades (:data:`GRADES`) take their turn-on biases from the classes of N. El-Sheimy
and A. Youssef, "Inertial sensors technologies for navigation applications: state of the
art and future trends", Satellite Navigation 1, 2 (2020), Table 1: navigation grade
(``fog``) accelerometer bias < 100 µg and gyro drift < 0.01 °/h (here the FOG
defaults, 50 µg and 0.2 °/h, a Phins-class INS as on the Snapir AUV); tactical grade
1–5 mg and 1–10 °/h (here 3 mg and 5 °/h); commercial MEMS 100–1000 µg and 0.1 °/s
(here 1 mg and 0.1 °/s). Their bias random walks take each turn-on bias as the drift
over 400 s (PSD = bias² / 400 s), the rule the FOG defaults follow to within a factor
of two to four (1e-9 (m/s²)²/s and 1e-14 (rad/s)²/s are 6e-4 m/s² and 2e-6 rad/s over
400 s, against its 50 µg = 4.9e-4 m/s² and 0.2 °/h = 9.7e-7 rad/s; ``fog`` keeps the
defaults exactly). Position, velocity and attitude
start from the ground truth in every grade (0.1 m, 0.02 m/s, 0.01°/0.06°).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from pronet import _core
from pronet._util.plausibility import long_lever_arm
from pronet._util.validate import scalar
from pronet.config import FILTER_KEYS, SCENARIO_KEYS, ConfigError, filter_config, read_toml
from pronet.recorded.aiding import MIN_FIX_SIGMA, AidingTuning
from pronet.recorded.alignment import Format, lever_arm
from pronet.recorded.heading import check_declination
from pronet.recorded.tuning import REAL_ACCEL_BIAS_PSD, REAL_GYRO_BIAS_PSD, REAL_P0_SIGMA

_G = 9.80665
_DEG_PER_H = math.pi / 180 / 3600


def _grade(accel_bias: float, gyro_bias: float) -> dict[str, Any]:
    """P0 and bias walks of a grade from its turn-on biases [m/s², rad/s]."""
    return {
        "p0_sigma": REAL_P0_SIGMA[:9] + (accel_bias,) * 3 + (gyro_bias,) * 3,
        "accel_bias_psd": accel_bias**2 / 400.0,
        "gyro_bias_psd": gyro_bias**2 / 400.0,
    }


#: The IMU grade presets (see the module docstring for their sources): the 15 initial
#: 1σ and the bias random-walk PSDs of a ``FilterConfig``.
GRADES: dict[str, dict[str, Any]] = {
    "fog": {
        "p0_sigma": REAL_P0_SIGMA,
        "accel_bias_psd": REAL_ACCEL_BIAS_PSD,
        "gyro_bias_psd": REAL_GYRO_BIAS_PSD,
    },
    "tactical": _grade(3e-3 * _G, 5.0 * _DEG_PER_H),
    "mems": _grade(1e-3 * _G, 0.1 * 3600 * _DEG_PER_H),
}

#: Keys of a ``--filter`` file beside :data:`pronet.config.FILTER_KEYS`.
VEHICLE_KEYS = (
    "grade",
    "imu_lever_arm",
    "dvl_lever_arm",
    "depth_sigma",
    "fix_sigma",
    "heading_sigma",
    "declination",
    "depth_lever_arm",
    "fix_lever_arm",
    "surface_depth",
)


@dataclass(frozen=True)
class VehicleTuning:
    """A vehicle's tuning from a ``--filter`` file or a grade's name.

    Attributes:
        base: the filter tuning (lever arm aside: each section's).
        imu_lever_arm, dvl_lever_arm: the sensors from the ground-truth point [m, body
            FRD], or None where the file does not say.
        source: the file, or the grade's name.
        depth_sigma, fix_sigma: the depth's 1σ [m] and the fixes' 1σ north, east, down
            [m] where a recording has none (:mod:`pronet.recorded.aiding`), or None.
        heading_sigma: the heading's 1σ [rad] where a recording has none (the file's
            ``heading_sigma`` is in degrees), or None.
        declination: the magnetic declination [deg, east positive] of a magnetic
            heading (:mod:`pronet.recorded.heading`), or None.
        depth_lever_arm, fix_lever_arm: the pressure sensor and the fix's antenna or
            transponder from the ground-truth point [m, body FRD], or None.
        surface_depth: the pressure sensor's depth [m] while the vehicle floats, or None.
    """

    base: _core.FilterConfig
    imu_lever_arm: tuple[float, float, float] | None
    dvl_lever_arm: tuple[float, float, float] | None
    source: str
    depth_sigma: float | None = None
    fix_sigma: tuple[float, float, float] | None = None
    heading_sigma: float | None = None
    declination: float | None = None
    depth_lever_arm: tuple[float, float, float] | None = None
    fix_lever_arm: tuple[float, float, float] | None = None
    surface_depth: float | None = None

    def navigate_only(self) -> str | None:
        """One line naming the keys this vehicle sets that ``pronet navigate`` applies
        and ``pronet real`` does not (it takes the depth and the fixes at the IMU's point,
        and the depth's surface as read), or None."""
        keys = [
            k
            for k in ("depth_lever_arm", "fix_lever_arm", "surface_depth")
            if getattr(self, k) is not None
        ]
        if not keys:
            return None
        return (
            f"{self.source}: {', '.join(keys)} {'is' if len(keys) == 1 else 'are'} applied by "
            "pronet navigate only; pronet real takes the depth and the fixes at the IMU's "
            "point and the depth's surface as read (ignored here)"
        )

    def aiding(self, given: AidingTuning) -> AidingTuning:
        """``given`` with this vehicle's σ where it has them."""
        if self.depth_sigma is not None:
            given = replace(given, depth_sigma=self.depth_sigma)
        if self.fix_sigma is not None:
            given = replace(given, fix_sigma=self.fix_sigma)
        if self.heading_sigma is not None:
            given = replace(given, heading_sigma=self.heading_sigma)
        return given


def _arm(value: Any, where: str) -> tuple[float, float, float]:
    try:
        a = lever_arm(value, where)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    return float(a[0]), float(a[1]), float(a[2])


def grade_config(name: str, where: str = "grade") -> _core.FilterConfig:
    """The FOG defaults of :func:`pronet.recorded.tuning.real_filter_config` with the
    P0 and bias walks of the grade ``name`` (:data:`GRADES`)."""
    if name not in GRADES:
        raise ConfigError(f"{where}: must be one of {', '.join(GRADES)}, got {name!r}")
    from pronet.recorded.tuning import real_filter_config

    return filter_config(GRADES[name], where, real_filter_config((0.0, 0.0, 0.0)))


def load_vehicle(path_or_grade: str | Path) -> VehicleTuning:
    """The tuning of ``--filter``: a TOML file (see the module docstring), or the name
    of a grade (:data:`GRADES`) when no such file exists. ``ConfigError`` (a
    ``ValueError``) naming the file and key for anything wrong."""
    text = str(path_or_grade)
    if text in GRADES and not Path(text).exists():
        return VehicleTuning(grade_config(text, "--filter"), None, None, text)
    path = Path(text)
    if not text.strip():
        raise ConfigError(f"--filter: empty; give a vehicle file or a grade ({', '.join(GRADES)})")
    if not path.exists() and "/" not in text and not text.endswith(".toml"):
        raise ConfigError(
            f"--filter: {text!r} is neither a file nor a grade ({', '.join(GRADES)}; "
            "a vehicle file is a .toml)"
        )
    table, where = _vehicle_keys(read_toml(path), path)
    if "imu_dt" in table:
        raise ConfigError(
            f"{where} imu_dt: pronet real uses each section's own IMU step (imu_dt_s in "
            "config.json); leave it out"
        )
    grade = table.get("grade", "fog")
    if not isinstance(grade, str):
        raise ConfigError(f"{where} grade: must be a string, got {grade!r}")
    base = grade_config(grade, f"{where} grade")
    filter_keys = {k: v for k, v in table.items() if k in FILTER_KEYS and k != "lever_arm"}
    base = filter_config(filter_keys, where, base)
    imu, dvl = (
        _arm(table[key], f"{where} {key}") if key in table else None
        for key in ("imu_lever_arm", "dvl_lever_arm")
    )
    if "lever_arm" in table:
        if imu is None or dvl is not None:
            raise ConfigError(
                f"{where} lever_arm: the DVL from the IMU needs imu_lever_arm beside it (the "
                "IMU from the ground-truth point) and no dvl_lever_arm"
            )
        arm = _arm(table["lever_arm"], f"{where} lever_arm")
        d = np.add(imu, arm)
        dvl = (float(d[0]), float(d[1]), float(d[2]))
    depth_arm, fix_arm = (
        _arm(table[key], f"{where} {key}") if key in table else None
        for key in ("depth_lever_arm", "fix_lever_arm")
    )
    return VehicleTuning(
        base, imu, dvl, str(path), *_aiding_sigma(table, where), *_heading(table, where),
        depth_arm, fix_arm, _surface_depth(table, where),
    )  # fmt: skip


def _vehicle_keys(doc: dict[str, Any], path: Path) -> tuple[dict[str, Any], str]:
    """The vehicle's keys of the file ``doc`` and the prefix of its errors: one rule for
    both levels. The keys may sit at the top level, in a ``[filter]`` table, or both
    (a key at both levels is refused); beside a ``[filter]`` table the top level may
    also hold a scenario file's own keys, which are not read. An unknown key at either
    level is refused."""
    known = (*FILTER_KEYS, *VEHICLE_KEYS)
    nested = doc.get("filter")
    top = dict(doc)
    where = f"{path}:"
    if isinstance(nested, dict):  # a scenario file, or a vehicle file with a table
        del top["filter"]
        top = {k: v for k, v in top.items() if k not in SCENARIO_KEYS or k in known}
        twice = sorted(set(top) & set(nested))
        if twice:
            raise ConfigError(
                f"{path}: {twice[0]}: given at the top level and in [filter]; give it once"
            )
        where = f"{path}: [filter]" if not top else where
    for level, keys in (("", top), ("[filter] ", nested if isinstance(nested, dict) else {})):
        unknown = sorted(set(keys) - set(known))
        if unknown:
            raise ConfigError(
                f"{path}: {level}unknown key {unknown[0]!r}; known: {', '.join(known)}"
            )
    return {**top, **(nested if isinstance(nested, dict) else {})}, where


#: The depths [m] a pressure sensor may have while its vehicle floats.
SURFACE_DEPTH_RANGE = (0.0, 10.0)


def surface_depth_problem(value: object) -> str | None:
    """Why ``value`` is no ``surface_depth`` (a number of metres within
    :data:`SURFACE_DEPTH_RANGE`), as the end of a line naming it; None where it is one."""
    lo, hi = SURFACE_DEPTH_RANGE
    if isinstance(value, bool) or not isinstance(value, int | float) or not lo <= value <= hi:
        return (
            "the pressure sensor's depth while the vehicle floats, a number of metres from "
            f"{lo:g} to {hi:g}, got {value!r}"
        )
    return None


def _surface_depth(table: dict[str, Any], where: str) -> float | None:
    """The file's ``surface_depth`` [m, 0 to 10] (None where absent), checked."""
    value = table.get("surface_depth")
    if value is None:
        return None
    if problem := surface_depth_problem(value):
        raise ConfigError(f"{where} surface_depth: {problem}")
    return float(value)


def _heading(table: dict[str, Any], where: str) -> tuple[float | None, float | None]:
    """The file's ``heading_sigma`` [deg, > 0, at most 180] as radians and
    ``declination`` [deg, east positive] (None where absent), checked."""
    sigma = table.get("heading_sigma")
    if sigma is not None and (
        isinstance(sigma, bool)
        or not isinstance(sigma, int | float)
        or not (math.isfinite(sigma) and 0 < sigma <= 180)
    ):
        raise ConfigError(
            f"{where} heading_sigma: a number of degrees > 0 and at most 180, got {sigma!r}"
        )
    try:
        declination = check_declination(table.get("declination"), f"{where} declination")
    except ValueError as exc:
        raise ConfigError(str(exc)) from None
    return (None if sigma is None else math.radians(sigma)), declination


def _aiding_sigma(
    table: dict[str, Any], where: str
) -> tuple[float | None, tuple[float, float, float] | None]:
    """The file's ``depth_sigma`` and ``fix_sigma`` [m] (None where absent), checked."""
    depth, fix = table.get("depth_sigma"), table.get("fix_sigma")
    try:  # numbers, not true or "0.3" read as one
        if fix is not None and not isinstance(fix, list):
            raise ValueError(fix)
        tuning = AidingTuning(
            depth_sigma=1.0 if depth is None else scalar(depth, "depth_sigma"),
            fix_sigma=(1.0,) * 3 if fix is None else tuple(scalar(v, "fix_sigma") for v in fix),  # type: ignore[arg-type]
        )
    except (TypeError, ValueError):
        shown = {k: table[k] for k in ("depth_sigma", "fix_sigma") if k in table}
        raise ConfigError(
            f"{where} depth_sigma, fix_sigma: a number of metres > 0 and a list of three "
            f"(north, east, down), each at least {MIN_FIX_SIGMA:g} m, got {shown}"
        ) from None
    return (
        None if depth is None else tuning.depth_sigma,
        None if fix is None else tuning.fix_sigma,
    )


def lever_arms(
    fmt: Format,
    imu: tuple[float, float, float] | None,
    dvl: tuple[float, float, float] | None,
    vehicle: VehicleTuning | None,
) -> tuple[tuple[float, float, float], tuple[float, float, float] | None]:
    """The lever arms of :func:`pronet.recorded.real.run_real` (given, else the
    vehicle's, else Snapir's for its own format), checked; ValueError when the generic
    format has no IMU arm. The DVL's may be None: a recording without DVL readings, or
    a run without them (``--no-dvl``), does not need it; one with them is refused when
    read (:func:`pronet.recorded.alignment.load_section`)."""
    from pronet.recorded.alignment import SNAPIR_DVL_LEVER_ARM, SNAPIR_IMU_LEVER_ARM

    names = {"imu": "imu_lever_arm", "dvl": "dvl_lever_arm"}
    if vehicle is not None:  # the file's arms named by the file: not an option's
        if imu is None and vehicle.imu_lever_arm is not None:
            imu, names["imu"] = vehicle.imu_lever_arm, f"{vehicle.source}: imu_lever_arm"
        if dvl is None and vehicle.dvl_lever_arm is not None:
            dvl, names["dvl"] = vehicle.dvl_lever_arm, f"{vehicle.source}: dvl_lever_arm"
    if fmt == "snapir":
        imu = SNAPIR_IMU_LEVER_ARM if imu is None else imu
        dvl = SNAPIR_DVL_LEVER_ARM if dvl is None else dvl
    for value, name in ((imu, names["imu"]), (dvl, names["dvl"])):
        if value is not None:  # a given arm's own error first, then its length
            lever_arm(value, name)
            long_lever_arm(value, name, "the ground-truth point")
    if imu is None:
        raise ValueError(
            f"--format {fmt}: needs the IMU's lever arm (--imu-lever-arm, or imu_lever_arm "
            "in --filter): its position from the ground-truth point [m, body FRD]; give "
            "0,0,0 for a truth at the IMU"
        )
    return imu, dvl
