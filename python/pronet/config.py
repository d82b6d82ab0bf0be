"""TOML configuration files: a scenario, a filter configuration, a sweep grid.

Each file is read and checked completely before any computation. A mistake raises
:class:`ConfigError` (a ``ValueError``) that names the file, the table and the key, e.g.
``my.toml: [filter] dvl_variance: expected 3 numbers, got 2``; unknown keys are
mistakes too, so a misspelt key never silently falls back to a default.

**Scenario** (``pronet simulate --scenario FILE``, or listed in a sweep)::

    name = "fast-turns"        # default: the file name without .toml
    base = "paper"             # built-in scenario it starts from (pronet.sim.scenarios.SCENARIOS):
                               # paper, varying-noise, matched, varying-matched, regimes, outage,
                               # mission
    q_nominal = [1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6]   # optional, see below
    schedule_seed = 3          # optional: the seed of a drawn noise schedule (varying-noise,
                               # varying-matched, regimes, outage); default: the run's seed

    [trajectory]               # optional; replaces the base's trajectory
    builtin = "paper"          # a built-in trajectory ... or segments:
    # segments = [[60, 0, 0, 0], [30, 0, 3, 0]]  # rows: duration [s], forward
    #                            # acceleration [m/s²], yaw rate [deg/s, + turns right],
    #                            # pitch rate [deg/s, + noses up]
    # lat_deg = 32.0, lon_deg = 34.0, height_m = -5.0 (height positive up),
    # speed_mps = 1.0, roll_deg = pitch_deg = heading_deg = 0.0
    dt_s = 0.01                # IMU period [s]

    [sensors]                  # optional; keys of pronet.SensorConfig, overriding the base's
    imu_variance = [4e-4, 4e-4, 4e-4, 4e-6, 4e-6, 4e-6]   # per sample, (m/s²)², (rad/s)²
    # imu_variance_times = [0, 100]  with imu_variance a list of 6-lists: a schedule [s]
    # imu_bias, imu_bias_psd (6 each), dvl_variance (3) [(m/s)²], dvl_period [s],
    # lever_arm (3) [m, body FRD], dvl_outages = [[60, 120], [150, 210]]  ([start, end) [s])
    # dvl_dropout = [120, 20]   random bottom-lock loss: [mean time between losses, mean
    #                           # length of a loss] [s]; unset: none (see SensorConfig)
    # dvl_period = 0            no DVL (a GNSS/INS or depth-only run)
    depth_sigma = 0.1          # optional: a depth sensor, 1σ [m] ...
    depth_period = 1.0         # ... every this many s
    # depth_lever_arm = [0.0, 0.0, 0.5]   # ... at this point [m, body FRD from the IMU]
    # heading_sigma = 0.01     # optional: a heading sensor (compass, AHRS), 1σ [rad] ...
    # heading_period = 1.0     # ... every this many s
    # fixes = []               no position fixes (over a base that has them)

    [[sensors.fixes]]          # optional, repeatable: a source of position fixes
    sigma = [2.5, 2.5]         # 1σ [m] north, east (and down: then the fix has a height)
    period = 60.0              # [s]; 0 or absent: only the listed times
    # times = [0.0, 600.0]     # [s] single fixes, each at the IMU epoch nearest it
    # max_depth = 0.5          # fixes only while the true depth <= this [m] (GNSS)
    # lever_arm = [0.0, 0.0, -1.0]   # the antenna's point [m, body FRD from the IMU]
    # A source that would take no fix on the trajectory is refused, as is a DVL, depth
    # or heading period longer than the trajectory.

    [filter]                   # optional; keys of pronet.FilterConfig, overriding the base's
    dvl_variance = [0.01, 0.01, 0.01]
    # p0_sigma (15), accel_bias_psd [(m/s²)²/s], gyro_bias_psd [(rad/s)²/s],
    # lever_arm (3) [m], aiding ("body" or "nav"), imu_dt [s], innovation_gate (NIS),
    # formulation ("invariant", "classic" or "se23": the error coordinates),
    # covariance_step [s] (default 0.1; 0: the covariance propagated at every IMU sample)

``q_nominal`` is what the constant rows are told and every adaptive row starts from.
Without it: the base's, unless ``[sensors]`` sets ``imu_variance``, in which case it is
that variance (or its time average over the trajectory, for a schedule).

**Filter configuration** (``pronet simulate --filter FILE``): the keys of a scenario's
``[filter]`` table, at the top level of their own file. It overrides the keys it names
and keeps the scenario's filter for the rest.

**Sweep grid** (``pronet sweep FILE``)::

    scenarios = ["paper", "my-scenario.toml"]   # built-in names or scenario files
                                                 # (relative to the sweep file)
    strategies = ["constant", "mehra:5", "learned:detrend"]  # see StrategySpec
    tuning_periods_s = [1.0, 2.0]  # seconds between regressor calls (learned rows only)
    noise_levels = [1.0, 4.0]      # factor on the scenario's true IMU noise variance
    runs = 100                     # Monte Carlo runs per grid point
    shard_runs = 25                # runs per shard (one native Monte Carlo call)
    seed = 0

A noise level multiplies the variance the simulated IMU draws from, not the q the
strategies are told: at level 4 the constant rows are mistuned by 4x, which is what an
adaptive strategy should notice.
"""

from __future__ import annotations

import functools
import math
import tomllib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pronet import _core
from pronet._util.plausibility import HEIGHT_RANGE, warn_of_imu_dt, warn_of_sensors
from pronet._util.validate import real_array
from pronet.sim.paper import PAPER_Q
from pronet.sim.scenarios import SCENARIOS, Scenario, time_average_q
from pronet.strategies import StrategySpec, strategy
from pronet.trajectory import builtin_trajectory, trajectory_from_segments


class ConfigError(ValueError):
    """A configuration file that cannot be used; the message says where and why."""


#: Keys of a ``[filter]`` table (the keyword arguments of ``pronet.FilterConfig``).
FILTER_KEYS = (
    "p0_sigma",
    "accel_bias_psd",
    "gyro_bias_psd",
    "dvl_variance",
    "lever_arm",
    "aiding",
    "imu_dt",
    "innovation_gate",
    "formulation",
    "covariance_step",
    "dvl_bias_sigma",
    "dvl_bias_time_constant",
    "heading_second_order",
)
#: The DVL calibration states' arguments of a ``FilterConfig``: not keys of a file, but
#: kept from the base configuration a file's keys are laid over.
CALIBRATION_KEYS = (
    "dvl_calibration",
    "dvl_scale_sigma",
    "dvl_misalignment_sigma",
    "dvl_scale_psd",
    "dvl_misalignment_psd",
)
#: Keys of a ``[sensors]`` table (the keyword arguments of ``pronet.SensorConfig``).
SENSOR_KEYS = (
    "imu_variance",
    "imu_variance_times",
    "imu_bias",
    "imu_bias_psd",
    "dvl_variance",
    "dvl_period",
    "lever_arm",
    "dvl_outages",
    "dvl_dropout",
    "depth_sigma",
    "depth_period",
    "depth_lever_arm",
    "heading_sigma",
    "heading_period",
    "fixes",
)
#: The simulated DVL's scale-factor error and mounting misalignment: arguments of a
#: ``SensorConfig`` that are not keys of a file (as :data:`CALIBRATION_KEYS` for the
#: filter), but kept by :func:`sensor_kwargs` and from the base a ``[sensors]`` table
#: is laid over.
DVL_ERROR_KEYS = ("dvl_scale", "dvl_misalignment")
#: Keys of a ``[trajectory]`` table with their defaults (``builtin`` excludes the rest
#: but ``dt_s``); the defaults are the paper trajectory's start.
TRAJECTORY_DEFAULTS: dict[str, Any] = {
    "builtin": None,
    "segments": None,
    "lat_deg": 32.0,
    "lon_deg": 34.0,
    "height_m": -5.0,
    "speed_mps": 1.0,
    "roll_deg": 0.0,
    "pitch_deg": 0.0,
    "heading_deg": 0.0,
    "dt_s": 0.01,
    "name": None,
}
SCENARIO_KEYS = (
    "name",
    "base",
    "q_nominal",
    "schedule_seed",
    "trajectory",
    "sensors",
    "filter",
)
SWEEP_KEYS = (
    "scenarios",
    "strategies",
    "tuning_periods_s",
    "noise_levels",
    "runs",
    "shard_runs",
    "seed",
)


def read_toml(path: str | Path) -> dict[str, Any]:
    """The TOML document at ``path``; ``ConfigError`` for a missing or malformed file."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot be read: {exc}") from None


def _check_keys(table: object, allowed: tuple[str, ...], where: str) -> dict[str, Any]:
    if not isinstance(table, dict):
        raise ConfigError(f"{where}: expected a table, got {type(table).__name__}")
    unknown = sorted(set(table) - set(allowed))
    if unknown:
        raise ConfigError(
            f"{where} {unknown[0]}: unknown key; expected one of {', '.join(allowed)}"
        )
    return table


def _native(where: str, make: Callable[[], Any]) -> Any:
    """``make()``, its ``ValueError`` (which starts with the key) prefixed by ``where``."""
    try:
        return make()
    except ValueError as exc:
        raise ConfigError(f"{where} {exc}") from None


def filter_config(
    table: Mapping[str, Any], where: str, base: _core.FilterConfig | None = None
) -> _core.FilterConfig:
    """A ``FilterConfig`` from the keys of ``table`` over ``base``'s values (default:
    ``FilterConfig()``'s). ``where`` prefixes errors, e.g. ``"my.toml: [filter]"``."""
    _check_keys(table, FILTER_KEYS, where)
    base = base if base is not None else _core.FilterConfig()
    kwargs = {key: getattr(base, key) for key in FILTER_KEYS}
    if base.dvl_calibration:  # not file keys, but the base's states stay
        kwargs.update({key: getattr(base, key) for key in CALIBRATION_KEYS})
    kwargs.update(table)
    return _native(where, lambda: _core.FilterConfig(**kwargs))


def load_filter_config(
    path: str | Path, base: _core.FilterConfig | None = None
) -> _core.FilterConfig:
    """The filter configuration file at ``path`` (the keys of ``FilterConfig``) over
    ``base`` (default ``FilterConfig()``): the keys the file does not name keep
    ``base``'s values."""
    return filter_config(read_toml(path), f"{path}:", base)


def sensor_kwargs(sensors: _core.SensorConfig) -> dict[str, Any]:
    """The keyword arguments that rebuild ``sensors`` (``SensorConfig(**kwargs)``): a
    constant IMU variance as 6 values without times, a schedule as ``(k, 6)`` with its
    ``(k,)`` times [s]. Every argument is kept, the DVL's scale error and misalignment
    (:data:`DVL_ERROR_KEYS`) too."""
    kwargs = {key: getattr(sensors, key) for key in (*SENSOR_KEYS, *DVL_ERROR_KEYS)}
    times = np.asarray(kwargs["imu_variance_times"], dtype=np.float64)
    variance = np.asarray(kwargs["imu_variance"], dtype=np.float64)
    constant = len(times) == 1
    kwargs["imu_variance"] = variance[0] if constant else variance
    kwargs["imu_variance_times"] = None if constant else times
    return kwargs


def sensor_config(
    table: Mapping[str, Any], where: str, base: _core.SensorConfig
) -> _core.SensorConfig:
    """A ``SensorConfig`` from the keys of ``table`` over ``base``'s. Setting
    ``imu_variance`` replaces the base's noise schedule: ``imu_variance_times`` then
    comes from ``table`` only."""
    _check_keys(table, SENSOR_KEYS, where)
    kwargs = sensor_kwargs(base)
    if "imu_variance" in table:
        kwargs["imu_variance_times"] = None
    elif "imu_variance_times" in table:
        raise ConfigError(f"{where} imu_variance_times: needs imu_variance beside it")
    kwargs.update(table)

    def make() -> _core.SensorConfig:
        for key in ("imu_variance", "imu_variance_times", "dvl_outages"):  # arrays, natively
            if kwargs[key] is not None:
                kwargs[key] = real_array(kwargs[key], key).astype(np.float64)
        fixes = table.get("fixes")
        for j, fix in enumerate(fixes if isinstance(fixes, list) else ()):  # true is no 1 m
            for key in ("sigma", "times"):
                if isinstance(fix, dict) and isinstance(fix.get(key), list):
                    real_array(fix[key], f"fixes[{j}].{key}")
        if kwargs["dvl_outages"] is not None and kwargs["dvl_outages"].size == 0:
            kwargs["dvl_outages"] = kwargs["dvl_outages"].reshape(0, 2)
        return _core.SensorConfig(**kwargs)

    return _native(where, make)


def trajectory(table: Mapping[str, Any], where: str) -> _core.Trajectory:
    """A trajectory from a ``[trajectory]`` table (see the module docstring)."""
    _check_keys(table, tuple(TRAJECTORY_DEFAULTS), where)
    t = {**TRAJECTORY_DEFAULTS, **table}
    if (t["builtin"] is None) == (t["segments"] is None):
        raise ConfigError(f"{where}: give either builtin or segments")
    dt = _number(t["dt_s"], f"{where} dt_s")  # named as the file does, builtin or not
    if not 0 < dt < math.inf:
        raise ConfigError(f"{where} dt_s: must be a finite period > 0 s, got {dt}")
    if t["builtin"] is not None:
        extra = sorted(set(table) - {"builtin", "dt_s"})
        if extra:
            raise ConfigError(f"{where} {extra[0]}: not used with builtin; remove it")
        if t["builtin"] not in _core.builtin_trajectory_names():
            raise ConfigError(
                f"{where} builtin: {t['builtin']!r} is not one of "
                f"{', '.join(_core.builtin_trajectory_names())}"
            )
        return _native(where, lambda: builtin_trajectory(t["builtin"], dt))
    rows = _native(where, lambda: real_array(t["segments"], "segments").astype(np.float64))
    if rows.ndim != 2 or rows.shape[1] != 4 or len(rows) == 0:
        raise ConfigError(
            f"{where} segments: expected rows of [duration s, accel m/s², yaw rate deg/s, "
            f"pitch rate deg/s], got shape {rows.shape}"
        )
    rows[:, 2:] = np.radians(rows[:, 2:])
    # numbers checked under their own (unit-carrying) names, not the native arguments'
    v = {k: _number(t[k], f"{where} {k}") for k in TRAJECTORY_DEFAULTS if k.endswith(_UNITS)}
    if not abs(v["lat_deg"]) <= _core.MAX_LATITUDE_DEG:  # in degrees, as the file gives it
        raise ConfigError(
            f"{where} lat_deg: must be within ±{_core.MAX_LATITUDE_DEG:g}° (NED is singular "
            f"at the poles), got {v['lat_deg']:g}°"
        )
    lon_lo, lon_hi = _core.LONGITUDE_RANGE_DEG
    for key, lo, hi in (  # in the file's units, before trajectory_from_segments' radians
        ("lon_deg", lon_lo, lon_hi),
        ("height_m", *HEIGHT_RANGE),
        ("roll_deg", -180.0, 180.0),
        ("pitch_deg", -180.0, 180.0),
        ("heading_deg", -360.0, 360.0),
    ):
        if not lo <= v[key] <= hi:
            raise ConfigError(f"{where} {key}: must be within {lo:g} … {hi:g}, got {v[key]:g}")
    return _native(
        where,
        lambda: trajectory_from_segments(
            rows,
            lla0=(math.radians(v["lat_deg"]), math.radians(v["lon_deg"]), v["height_m"]),
            speed0=v["speed_mps"],
            rpy0=tuple(math.radians(v[k]) for k in ("roll_deg", "pitch_deg", "heading_deg")),
            dt=v["dt_s"],
            name=t["name"] if t["name"] is not None else "custom",
        ),
    )


_UNITS = ("_deg", "_m", "_mps", "_s")


def _number(value: object, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"{where}: expected a number, got {value!r}")
    return float(value)


def scenario(data: Mapping[str, Any], where: str, default_name: str, seed: int = 0) -> Scenario:
    """A :class:`~pronet.sim.scenarios.Scenario` from a scenario document (the module
    docstring); ``where`` (the file) prefixes errors. A drawn noise schedule comes from
    the document's ``schedule_seed``, else from ``seed`` (the run's)."""
    _check_keys(data, SCENARIO_KEYS, f"{where}:")
    base_name = data.get("base", "paper")
    if base_name not in SCENARIOS:
        raise ConfigError(f"{where}: base: {base_name!r} is not one of {', '.join(SCENARIOS)}")
    if "schedule_seed" in data:
        seed = _whole(data, "schedule_seed", f"{where}:", 0, 0)
    base = SCENARIOS[base_name](seed)
    name = data.get("name", default_name)
    if not isinstance(name, str) or not name.strip():
        raise ConfigError(f"{where}: name: expected non-empty text, got {name!r}")
    traj = base.trajectory
    if "trajectory" in data:
        traj = trajectory(data["trajectory"], f"{where}: [trajectory]")
    sensors = base.sensors
    if "sensors" in data:
        sensors = sensor_config(data["sensors"], f"{where}: [sensors]", base.sensors)
        warn_of_sensors(sensors, traj, f"{where}: [sensors]")
    config = base.config
    filter_table = data.get("filter", {})
    if "filter" in data:
        config = filter_config(filter_table, f"{where}: [filter]", base.config)
    if "imu_dt" not in filter_table and config.imu_dt != traj.dt:
        # the filter's Q_d = q·imu_dt·Δt is the sample variance only when imu_dt is the
        # IMU period: a new trajectory's period carries over unless [filter] says otherwise
        config = filter_config({"imu_dt": traj.dt}, f"{where}: [trajectory] dt_s", config)
    warn_of_imu_dt(config.imu_dt, traj.dt, f"{where}: [filter]")  # said outright: kept
    # the DVL period must be a whole number of IMU periods: named with the file now,
    # not by the first Monte Carlo
    periods = ("dvl_period", "depth_period", "heading_period", "fixes")
    period_key = (
        "[sensors]" if any(k in data.get("sensors", {}) for k in periods) else "[trajectory] dt_s:"
    )
    _native(f"{where}: {period_key}", lambda: _core.check_result_size(traj, sensors, n_runs=1))
    # a fix source that never fires on this trajectory is a mistake in the file
    fixes_key = (
        "[sensors]" if "fixes" in data.get("sensors", {}) else f"[trajectory], with {base_name}'s"
    )
    _native(f"{where}: {fixes_key}", lambda: _core.check_fixes_fire(traj, sensors))
    for sensor, called, period in (
        ("dvl", "DVL", sensors.dvl_period if sensors.dvl_period else None),
        ("depth", "depth", sensors.depth_period if sensors.depth_sigma is not None else None),
        ("heading", "heading", sensors.heading_period if sensors.heading_sigma else None),
    ):  # as a fix source: a sensor that would take no reading is a mistake in the file
        key = f"{sensor}_period"
        if period is not None and round(period / traj.dt) > traj.n_samples:
            raise ConfigError(
                f"{where}: {'[sensors]' if key in data.get('sensors', {}) else fixes_key} "
                f"{key}: schedules no {called} reading inside the trajectory's "
                f"{traj.duration:g} s (period {period:g} s): the sensor would take no reading"
                + (" (dvl_period = 0: no DVL)" if sensor == "dvl" else "")
            )
    times = np.asarray(sensors.imu_variance_times, dtype=np.float64)
    schedule = np.asarray(sensors.imu_variance, dtype=np.float64)
    if "q_nominal" in data:
        q = data["q_nominal"]
        if (
            not isinstance(q, list)
            or len(q) != 6
            or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in q)
            or not all(0 <= v < math.inf for v in q)
        ):
            raise ConfigError(f"{where}: q_nominal: expected 6 finite variances >= 0, got {q!r}")
        q_nominal = tuple(float(v) for v in q)
    elif "imu_variance" in data.get("sensors", {}) or "trajectory" in data:
        # what the IMU draws over this trajectory (the base's average was over its own)
        q_nominal = (
            tuple(float(v) for v in schedule[0])
            if len(times) == 1
            else time_average_q(times, schedule, traj.duration)
        )
    else:
        q_nominal = base.q_nominal
    drawn = "imu_variance" not in data.get("sensors", {})
    return Scenario(
        name=name,
        trajectory=traj,
        sensors=sensors,
        config=config,
        q_nominal=q_nominal,
        schedule_time=times,
        schedule_q=schedule,
        schedule_seed=base.schedule_seed if drawn else None,
    )


def load_scenario(name_or_path: str | Path, seed: int = 0) -> Scenario:
    """A built-in scenario by name (:data:`pronet.sim.scenarios.SCENARIOS`) or a scenario
    file; a drawn noise schedule comes from ``seed`` unless the file sets
    ``schedule_seed``."""
    if str(name_or_path) in SCENARIOS:
        return SCENARIOS[str(name_or_path)](seed)
    path = Path(name_or_path)
    if path.suffix != ".toml" and not path.exists():
        raise ConfigError(
            f"scenario: {str(name_or_path)!r} is neither a built-in scenario "
            f"({', '.join(SCENARIOS)}) nor a .toml file"
        )
    return scenario(read_toml(path), str(path), path.stem, seed)


@dataclass(frozen=True)
class ScenarioSource:
    """Where a sweep's scenario comes from, as plain data that can travel to another
    process or machine: a built-in name, or a scenario file's parsed contents."""

    name: str
    builtin: str | None = None
    document: str = ""  # the scenario file's TOML text (when not built in)
    origin: str = ""  # the file it was read from, for error messages

    def build(self, seed: int = 0) -> Scenario:
        """The scenario, its drawn noise schedule (if any) from ``seed`` unless the
        file sets ``schedule_seed``."""
        if self.builtin is not None:
            return SCENARIOS[self.builtin](seed)
        return scenario(tomllib.loads(self.document), self.origin, self.name, seed)


@dataclass(frozen=True)
class SweepGrid:
    """A validated sweep grid (see the module docstring).

    Attributes:
        scenarios: the scenarios, by name.
        strategies: the strategy specs.
        tuning_periods: seconds between regressor calls (learned strategies only).
        noise_levels: factors on each scenario's true IMU noise variance.
        runs: Monte Carlo runs per grid point.
        shard_runs: runs per shard.
        seed: Monte Carlo seed.
    """

    scenarios: tuple[ScenarioSource, ...]
    strategies: tuple[StrategySpec, ...]
    tuning_periods: tuple[float, ...] = (1.0,)
    noise_levels: tuple[float, ...] = (1.0,)
    runs: int = 100
    shard_runs: int = 25
    seed: int = 0

    def as_dict(self) -> dict[str, Any]:
        """The grid as plain data (the sweep's ``config.json``; also what a resumed
        sweep must match)."""
        return {
            "scenarios": {
                s.name: s.builtin if s.builtin is not None else s.document for s in self.scenarios
            },
            "strategies": [s.text for s in self.strategies],
            "tuning_periods_s": list(self.tuning_periods),
            "noise_levels": list(self.noise_levels),
            "runs": self.runs,
            "shard_runs": self.shard_runs,
            "seed": self.seed,
        }


def _list(doc: Mapping[str, Any], key: str, where: str, default: list[Any] | None = None):
    value = doc.get(key, default)
    if value is None:
        raise ConfigError(f"{where} {key}: missing; it is required")
    if not isinstance(value, list) or not value:
        raise ConfigError(f"{where} {key}: expected a non-empty list, got {value!r}")
    if len(set(map(repr, value))) != len(value):
        raise ConfigError(f"{where} {key}: lists a value twice")
    return value


def _whole(doc: Mapping[str, Any], key: str, where: str, default: int, low: int) -> int:
    value = doc.get(key, default)
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value < 2**62:
        raise ConfigError(f"{where} {key}: expected a whole number >= {low}, got {value!r}")
    return value


def _positive(values: list[Any], key: str, where: str) -> tuple[float, ...]:
    for v in values:
        if isinstance(v, bool) or not isinstance(v, int | float) or not 0 < v < math.inf:
            raise ConfigError(f"{where} {key}: expected finite numbers > 0, got {v!r}")
    numbers = tuple(float(v) for v in values)
    if len(set(numbers)) != len(numbers):  # 1 and 1.0 are one grid point
        raise ConfigError(f"{where} {key}: lists a value twice")
    return numbers


def sweep_grid(doc: Mapping[str, Any], path: str | Path) -> SweepGrid:
    """A :class:`SweepGrid` from a sweep document read from ``path`` (scenario files
    are found relative to it). Every scenario file, strategy spec and learned model is
    checked here, before anything runs."""
    where = f"{path}:"
    _check_keys(doc, SWEEP_KEYS, where)
    sources = []
    for entry in _list(doc, "scenarios", where):
        if not isinstance(entry, str):
            raise ConfigError(f"{where} scenarios: expected names or paths, got {entry!r}")
        if entry in SCENARIOS:
            sources.append(ScenarioSource(entry, builtin=entry))
            continue
        file = Path(path).parent / entry
        if file.suffix != ".toml":
            raise ConfigError(
                f"{where} scenarios: {entry!r} is neither a built-in scenario "
                f"({', '.join(SCENARIOS)}) nor a .toml file"
            )
        read_toml(file)  # exists and parses
        source = ScenarioSource(file.stem, document=file.read_text(), origin=str(file))
        built = source.build()  # every key checked now, not on a worker later
        sources.append(ScenarioSource(built.name, None, source.document, str(file)))
    names = [s.name for s in sources]
    if len(set(names)) != len(names):
        raise ConfigError(f"{where} scenarios: two scenarios are named alike: {names}")
    specs = []
    for text in _list(doc, "strategies", where):
        spec = _native(f"{where} strategies:", functools.partial(StrategySpec.parse, text))
        if spec.kind == "learned":
            from pronet.learn import frozen

            if spec.model not in frozen.SHIPPED:  # a model file, relative to the sweep file
                model = Path(path).parent / spec.model
                spec = StrategySpec(spec.text, spec.kind, spec.factor, str(model.resolve()))
            load = functools.partial(frozen.load_frozen, spec.model)
            _native(f"{where} strategies: {text!r}:", load)
        else:  # e.g. a window the native core cannot take fails here, not in a shard
            _native(f"{where} strategies:", functools.partial(strategy, spec, PAPER_Q))
        specs.append(spec)
    runs = _whole(doc, "runs", where, 100, 1)
    return SweepGrid(
        scenarios=tuple(sources),
        strategies=tuple(specs),
        tuning_periods=_positive(
            _list(doc, "tuning_periods_s", where, [1.0]), "tuning_periods_s", where
        ),
        noise_levels=_positive(_list(doc, "noise_levels", where, [1.0]), "noise_levels", where),
        runs=runs,
        shard_runs=min(_whole(doc, "shard_runs", where, 25, 1), runs),
        seed=_whole(doc, "seed", where, 0, 0),
    )


def load_sweep(path: str | Path) -> SweepGrid:
    """The sweep grid file at ``path``, checked (see :func:`sweep_grid`)."""
    return sweep_grid(read_toml(path), path)
