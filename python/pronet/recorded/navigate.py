"""Navigate a recording: one filter with the vehicle's tuning over every stream the
recording has, forward and smoothed, from an initial state found in the data (or
given); a ground truth, when there is one, only scores the result (``pronet navigate``).

The pass, in order:

1. the filter tuning: the vehicle's (:func:`pronet.recorded.vehicle.load_vehicle`) at
   the recording's IMU step, with the DVL's R the recording states (a bag's
   covariance), else the vehicle's;
2. the depth's surface reference measured at the surface
   (:mod:`pronet.recorded.surface`), the σ the vehicle gives streams without their own;
3. the initial state and the P0 its methods earn (:mod:`pronet.recorded.initial`), or
   the ground truth's first row with the vehicle's P0 (``init="truth"``: what ``pronet
   real`` does, for scoring the same pass);
4. the streams, each sensor at its lever arm: the DVL (:class:`pronet.Dvl`), the depth
   (:class:`pronet.Depth`), the fixes (:class:`pronet.Fix`) and the heading
   (:class:`pronet.Heading`), in that order at an epoch;
5. the pass (:func:`pronet.run.run`: native or learned strategies alike) and the
   smoother, their solutions moved to the vehicle's reference point
   (:func:`pronet.recorded.solution.solution_of`), each stream's report
   (:mod:`pronet.stats`, with the pass's divergence) and, with a truth, the score
   (:func:`pronet.recorded.metrics.section_metrics`).
"""

from __future__ import annotations

import dataclasses
from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import NDArray

from pronet import _core
from pronet._util.plausibility import depth_beyond, long_lever_arm
from pronet.config import filter_config
from pronet.filter import FilterResult, Stream
from pronet.recorded.aiding import AidingTuning, DepthReadings, PositionFixes, tuned, tuned_heading
from pronet.recorded.alignment import Format, Section, load_section
from pronet.recorded.heading import HeadingReadings
from pronet.recorded.initial import initial_state
from pronet.recorded.initialinputs import GivenState
from pronet.recorded.metrics import section_metrics
from pronet.recorded.passes import NOT_ISOLATED, failure_reason, start_index
from pronet.recorded.solution import F64, InitialState, Navigation, solution_of
from pronet.recorded.surface import G0, SurfaceOffset, surface_offset
from pronet.recorded.tables import clocks_record
from pronet.recorded.tuning import imu_step, real_filter_config, white_noise_q
from pronet.recorded.vehicle import VehicleTuning, surface_depth_problem
from pronet.run import Recorded, run
from pronet.stats import PassHealth, StreamSource, stream_reports
from pronet.strategies import StrategyLike, StrategySpec, strategy

Arm = tuple[float, float, float]
ZERO: Arm = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class LeverArms:
    """Where each sensor sits [m, body FRD] from the vehicle's reference point (the
    point a ground truth describes, the point the trajectory is written for).

    Attributes:
        imu, dvl, depth, fix: the IMU, the DVL, the pressure sensor and the fix's antenna
            or transponder; ``dvl`` None where no DVL reading is used.
        assumed: the sensors whose arm was not given, taken at the IMU.
    """

    imu: Arm = ZERO
    dvl: Arm | None = None
    depth: Arm = ZERO
    fix: Arm = ZERO
    assumed: tuple[str, ...] = ()

    def from_imu(self, arm: Arm | None) -> Arm:
        """``arm`` from the IMU instead of the reference point (the filter's lever arms)."""
        a = np.subtract(arm or self.imu, self.imu)
        return float(a[0]), float(a[1]), float(a[2])


@dataclass(frozen=True)
class NavigateOptions:
    """What :func:`navigate` uses and how.

    Attributes:
        use_dvl, use_depth, use_fixes, use_heading: False switches a stream off
            (``--no-dvl``, …).
        smooth: also the RTS smoother.
        init: ``"data"`` (the initial state from the recording, :mod:`pronet.recorded.
            initial`, with ``given`` parts winning) or ``"truth"`` (the ground truth's
            first row inside the IMU record, with the vehicle's P0, as ``pronet real``).
        surface_offset: the depth's surface offset [m] to take off (None: measured at
            the surface where the recording allows, :mod:`pronet.recorded.surface`).
        surface_depth: the depth sensor's depth [m] while the vehicle floats (its
            draft at the sensor), what the surface readings are taken to read.
        still: the interval ``(start, end)`` [s] the vehicle rests in for levelling,
            ``"auto"`` (detected) or ``"none"`` (:func:`pronet.recorded.initial.
            initial_state`).
        strategy: the process-noise strategy, a :class:`~pronet.strategies.StrategySpec`
            text around the recording's IMU noise (default ``"constant"``).
        heading_interval: a heading stream is thinned to one reading per this many
            seconds [s] (0: every reading): a compass's or an AHRS's error is slow, and
            readings closer than its correlation time taken as independent make the
            filter overconfident.
    """

    use_dvl: bool = True
    use_depth: bool = True
    use_fixes: bool = True
    use_heading: bool = True
    smooth: bool = True
    init: Literal["data", "truth"] = "data"
    given: GivenState | None = None
    surface_offset: float | None = None
    surface_depth: float = 0.0
    still: tuple[float, float] | Literal["auto", "none"] = "auto"
    strategy: str = "constant"
    heading_interval: float = 1.0

    def __post_init__(self) -> None:
        if problem := surface_depth_problem(self.surface_depth):
            raise ValueError(f"surface_depth: {problem}")
        if self.init == "truth" and self.given is not None:
            raise ValueError(
                "init: 'truth' takes the ground truth's first row, whole; the given parts "
                "of the initial state (--init-position, --init-heading) are for init='data'"
            )


def _surface(
    depth: DepthReadings | None,
    fixes: PositionFixes | None,
    given: float | None,
    surface_depth: float,
) -> tuple[DepthReadings | None, SurfaceOffset | None, float | None]:
    """``depth`` with its surface offset taken off, the offset (None: no depth) and the
    surface pressure [Pa] it implies where the readings kept their pressure (a bag's);
    ValueError naming ``surface_offset`` and the depth's file or topic where a given
    offset takes a depth beyond the ocean (in pascals?), as the readers name a row."""
    if depth is None:
        return None, None, None
    fix_time = np.empty(0) if fixes is None else fixes.time
    s = surface_offset(depth.time, depth.depth, fix_time, surface_depth=surface_depth, given=given)
    pa = None
    if depth.pressure is not None and depth.water_density is not None and len(depth.time):
        rho_g = depth.water_density * G0
        reference = float(depth.pressure[0] - depth.depth[0] * rho_g)  # the reader's
        pa = s.pressure(reference, depth.water_density)
    if s.offset != 0.0:
        depth = dataclasses.replace(depth, depth=depth.depth - s.offset)
        where = f"surface_offset: {s.offset:g} m taken off {depth.source or 'the depth'}"
        if (beyond := depth_beyond(depth.depth, where, _file_rows(depth))) is not None:
            raise ValueError(beyond)
    return depth, s, pa


def _file_rows(depth: DepthReadings) -> NDArray[np.int64]:
    """Each kept reading's row in its file (1: the first data row), counting the rows
    skipped as missing values before it (a file's stamps increase: the readers check)."""
    before = np.searchsorted(np.sort(depth.skipped_time), depth.time)
    return np.arange(1, len(depth.time) + 1) + before


def _truth_initial(section: Section, p0: Sequence[float]) -> InitialState:
    """The ground truth's first row inside the IMU record, with the vehicle's P0."""
    i0 = start_index(section)
    method = "ground truth (moved to the IMU)"
    return InitialState(
        t0=float(section.truth_time[i0]),
        lla=section.truth_lla[i0].copy(),
        vel=section.truth_vel[i0].copy(),
        rpy=section.truth_rpy[i0].copy(),
        p0_sigma=np.asarray(p0, dtype=np.float64),
        methods=dict.fromkeys(("position", "depth", "velocity", "attitude", "heading"), method),
    )


def _skipped(reasons: Sequence[str]) -> dict[str, int]:
    return dict(Counter(reasons))


def _data_initial(
    section: Section,
    config: _core.FilterConfig,
    streams: Streams,
    arms: LeverArms,
    given: GivenState | None,
    still: tuple[float, float] | Literal["auto", "none"],
) -> InitialState:
    """The initial state from ``section``'s data (:func:`pronet.recorded.initial.
    initial_state`), every sensor at its arm from the IMU, ``given`` parts winning."""
    dvl = None
    if len(streams.dvl_time):
        r = np.sqrt(np.asarray(config.dvl_variance, dtype=np.float64))
        dvl = (streams.dvl_time, streams.dvl, r)
    try:
        return initial_state(
            section.imu_time,
            section.imu,
            config.p0_sigma,
            fixes=None if streams.fixes is None else _as_input(streams.fixes, "lla"),
            depth=None if streams.depth is None else _as_input(streams.depth, "depth"),
            heading=None if streams.heading is None else _as_input(streams.heading, "heading"),
            dvl=dvl,
            fix_lever_arm=arms.from_imu(arms.fix),
            depth_lever_arm=arms.from_imu(arms.depth),
            dvl_lever_arm=config.lever_arm,
            given=given,
            still=still,
        )
    except ValueError as exc:  # the API's words, and the command's
        said = str(exc)
        tail = "give a still interval, an AHRS orientation or the initial roll, pitch and yaw"
        if said.startswith("initial roll and pitch") and said.endswith(tail):
            raise ValueError(
                said[: -len(tail)] + "give a still interval (still=, --still START,END), an "
                "AHRS orientation, or start from the ground truth where the recording has "
                "one (init='truth', --init truth)"
            ) from None
        raise


def _as_input(readings: Any, values: str) -> tuple[F64, F64, F64]:
    """A stream as :func:`~pronet.recorded.initial.initial_state` takes it."""
    return readings.time, getattr(readings, values), readings.sigma


@dataclass(frozen=True)
class Streams:
    """The streams of a pass as used: the DVL's rows, and the depth, fixes and heading
    with their σ (None: not used)."""

    dvl_time: F64
    dvl: F64
    depth: DepthReadings | None
    fixes: PositionFixes | None
    heading: HeadingReadings | None
    surface: SurfaceOffset | None
    surface_pa: float | None = None


def _streams(section: Section, vehicle: VehicleTuning, options: NavigateOptions) -> Streams:
    """``section``'s streams as ``options`` and ``vehicle`` have them: switched off, σ
    where the recording has none, the depth's surface offset taken off."""
    tuning = vehicle.aiding(
        AidingTuning(
            use_depth=options.use_depth,
            use_fixes=options.use_fixes,
            use_heading=options.use_heading,
        )
    )
    depth, fixes = tuned(section.depth, section.fixes, tuning)
    heading = _thinned(tuned_heading(section.heading, tuning), options.heading_interval)
    depth, surface, pa = _surface(depth, fixes, options.surface_offset, options.surface_depth)
    keep = options.use_dvl
    dvl_time = section.dvl_time if keep else np.empty(0)
    dvl = section.dvl if keep else np.empty((0, 3))
    if not len(dvl) and depth is None and fixes is None and heading is None:
        raise ValueError(
            f"section {section.name}: no DVL reading, depth, position fix or heading is "
            "used: nothing aids the IMU"
        )
    return Streams(dvl_time, dvl, depth, fixes, heading, surface, pa)


def _thinned(heading: HeadingReadings | None, interval: float) -> HeadingReadings | None:
    """``heading`` with one reading kept per ``interval`` [s] (the first of each)."""
    if heading is None or interval <= 0.0 or len(heading.time) < 2:
        return heading
    keep = np.zeros(len(heading.time), dtype=bool)
    last = -np.inf
    for i, t in enumerate(heading.time):
        if t >= last + interval:
            keep[i], last = True, t
    sigma = None if heading.sigma is None else heading.sigma[keep]
    return dataclasses.replace(
        heading, time=heading.time[keep], heading=heading.heading[keep], sigma=sigma
    )


def _aiding(streams: Streams, arms: LeverArms) -> tuple[Stream, ...]:
    """The depth, fixes and heading as the filter takes them, each at its arm."""
    out: list[Stream] = []
    if streams.depth is not None:
        d = streams.depth
        out.append(_core.Depth(d.time, d.depth, sigma=d.sigma, lever_arm=arms.from_imu(arms.depth)))
    if streams.fixes is not None:
        f = streams.fixes
        out.append(_core.Fix(f.time, f.lla, sigma=f.sigma, lever_arm=arms.from_imu(arms.fix)))
    if streams.heading is not None:
        h = streams.heading
        out.append(_core.Heading(h.time, h.heading, sigma=h.sigma))
    return tuple(out)


def _config(section: Section, vehicle: VehicleTuning, arms: LeverArms) -> _core.FilterConfig:
    """The vehicle's tuning at the section's IMU step, R the recording's where it
    states one, the DVL's lever arm from the IMU."""
    return real_filter_config(
        arms.from_imu(arms.dvl),
        section.dvl_variance,
        imu_dt=imu_step(section.imu_time),
        base=vehicle.base,
    )


def _initial(
    section: Section,
    config: _core.FilterConfig,
    streams: Streams,
    arms: LeverArms,
    options: NavigateOptions,
) -> tuple[InitialState, _core.FilterConfig]:
    """The initial state ``options.init`` asks for and the tuning with the P0 it
    earns (the truth's: the vehicle's P0, as ``pronet real``)."""
    if options.init == "truth":
        if not len(section.truth_time):
            raise ValueError(
                f"section {section.name}: init='truth' needs a ground truth, and the "
                "recording has none: start from the data (init='data')"
            )
        return _truth_initial(section, config.p0_sigma), config
    if options.init != "data":
        raise ValueError(f"init: must be 'data' or 'truth', got {options.init!r}")
    initial = _data_initial(section, config, streams, arms, options.given, options.still)
    p0 = [float(v) for v in initial.p0_sigma]
    return initial, filter_config({"p0_sigma": p0}, "the initial state", config)


def _strategy(spec: str, section: Section) -> StrategyLike:
    """The strategy ``spec`` around the section's own IMU noise
    (:func:`pronet.recorded.tuning.white_noise_q`); the oracle is refused (it needs
    the true noise)."""
    parsed = StrategySpec.parse(spec)
    if parsed.kind == "oracle":
        raise ValueError("strategy: the oracle needs the simulation's true IMU noise")
    return strategy(parsed, white_noise_q(section.imu))


def _health(section: Section, streams: Streams, result: FilterResult) -> PassHealth:
    """The pass's health (its divergence and heading, as the core watched them), with
    each stream's report named as the section names it, in the order the pass applied
    them, and the rows left out before it."""
    sources, rows = [], list(result.streams)
    if len(streams.dvl):
        skipped = _skipped(section.dvl_skipped_reason)
        sources.append(StreamSource("dvl", streams.dvl_time, skipped=skipped))
    else:  # the pass's DVL stream without rows (Recorded.streams: always first)
        rows = rows[1:]
    aiding = (("depth", streams.depth), ("fix", streams.fixes), ("heading", streams.heading))
    for name, readings in aiding:
        if readings is not None:
            lla = getattr(readings, "lla", None)
            skipped = _skipped(readings.skipped_reason)
            sources.append(StreamSource(name, readings.time, lla=lla, skipped=skipped))
    return dataclasses.replace(result.health, streams=stream_reports(rows, sources))


def _smoothed(result: FilterResult) -> FilterResult:
    """``result`` with the smoothed solution in place of the filter's (its updates the
    filter's), as ``pronet real``'s smoothed rows are scored."""
    s = result.smoothed
    if s is None:
        raise ValueError("the pass was run without smooth=True")
    return dataclasses.replace(
        result, lla=s.lla, vel=s.vel, rpy=s.rpy, bias=s.bias, sigma=s.sigma,
        calibration=s.calibration, calibration_sigma=s.calibration_sigma, smoothed=None,
    )  # fmt: skip


def _score(section: Section, result: FilterResult, use_dvl: bool) -> dict[str, dict[str, float]]:
    """The errors against ``section``'s truth, per solution (empty without a truth)."""
    if not len(section.truth_time):
        return {}
    out = {"forward": dataclasses.asdict(section_metrics(section, result, use_dvl))}
    if result.smoothed is not None:
        smoothed = section_metrics(section, _smoothed(result), use_dvl)
        out["smoothed"] = dataclasses.asdict(smoothed)
    return out


def _filter_keys(config: _core.FilterConfig) -> dict[str, Any]:
    """The tuning a ``config.json`` states."""
    keys = ("p0_sigma", "accel_bias_psd", "gyro_bias_psd", "dvl_variance", "lever_arm",
            "aiding", "innovation_gate", "formulation", "covariance_step", "imu_dt",
            "heading_second_order")  # fmt: skip
    return {k: getattr(config, k) for k in keys}


@dataclass(frozen=True)
class Setup:
    """What :func:`navigate` runs the filter with, set up from a section (the pass's
    steps 1 to 4): the tuning (with the P0 the initial state earns), the streams as
    used, the initial state, the strategy and the depth, fix and heading streams at
    their arms (:func:`setup`)."""

    config: _core.FilterConfig
    streams: Streams
    initial: InitialState
    strategy: StrategyLike
    aiding: tuple[Stream, ...]


def setup(
    section: Section,
    vehicle: VehicleTuning,
    arms: LeverArms = LeverArms(),
    options: NavigateOptions = NavigateOptions(),
) -> Setup:
    """The filter :func:`navigate` runs over ``section``, set up (steps 1 to 4 of the
    module docstring): also where an online navigator starts from the first minutes of a
    mission (:func:`pronet.recorded.online.navigator_for`)."""
    config = _config(section, vehicle, arms)
    streams = _streams(section, vehicle, options)
    initial, config = _initial(section, config, streams, arms, options)
    chosen = _strategy(options.strategy, section)
    return Setup(config, streams, initial, chosen, _aiding(streams, arms))


def navigate(
    section: Section,
    vehicle: VehicleTuning,
    arms: LeverArms = LeverArms(),
    options: NavigateOptions = NavigateOptions(),
    source: str = "",
) -> Navigation:
    """Navigate ``section`` with ``vehicle``'s tuning, its sensors at ``arms``, as
    ``options`` say (the steps are in the module docstring). ValueError, one line naming
    what is missing or wrong, before the filter runs; from the pass, the core's
    numerical failure, or any other exception of the strategy's (a user's model) as a
    ValueError naming the strategy, the type and the message, caused by it."""
    made = setup(section, vehicle, arms, options)
    config, streams, initial = made.config, made.streams, made.initial
    take = section.imu_time > initial.t0
    recorded = Recorded(
        imu=section.imu[take], imu_time=section.imu_time[take], dvl=streams.dvl,
        dvl_time=streams.dvl_time, t0=initial.t0, lla0=initial.lla, vel0=initial.vel,
        rpy0=initial.rpy, config=config, smooth=options.smooth, aiding=made.aiding,
    )  # fmt: skip
    try:
        done = run(made.strategy, recorded)
    except ValueError:  # a numerical failure names itself and its time
        raise
    except NOT_ISOLATED:
        raise
    except Exception as exc:  # e.g. a user's model raising: one line, the cause kept
        raise ValueError(f"strategy {options.strategy!r}: {failure_reason(exc)}") from exc
    result = done.result
    reference = np.negative(arms.imu)
    forward = solution_of("forward", result, section.epoch, recorded.imu, reference)
    smoothed = None
    if result.smoothed is not None:
        smoothed = solution_of("smoothed", result.smoothed, section.epoch, recorded.imu, reference)
    health = _health(section, streams, result)
    reports = health.streams
    notes = list(health.flags)
    if done.unfilled:  # a constant-Q pass under the strategy's name
        notes.append(f"strategy {options.strategy}: {done.unfilled}")
    kinds = {"dvl": "dvl", "depth": "depth", "fix": "fix"}
    for name in arms.assumed:
        if any(r.name == kinds[name] for r in reports):
            notes.append(f"{name}: no lever arm given: taken at the IMU")
    if (
        streams.surface is not None
        and streams.surface.readings == 0
        and streams.surface.offset == 0.0
    ):
        notes.append(f"depth: {streams.surface.note}")
    return Navigation(
        name=section.name,
        source=source,
        forward=forward,
        smoothed=smoothed,
        initial=initial,
        streams=reports,
        readings=_readings(streams),
        config=_config_json(section, vehicle, arms, options, config, streams, initial),
        score=_score(section, result, len(streams.dvl) > 0) or None,
        notes=tuple(notes),
    )


def _readings(streams: Streams) -> dict[str, tuple[F64, F64]]:
    """The readings as applied, for the figures."""
    out: dict[str, tuple[F64, F64]] = {}
    if streams.fixes is not None:
        out["fix"] = (streams.fixes.time, streams.fixes.lla)
    if streams.depth is not None:
        out["depth"] = (streams.depth.time, streams.depth.depth)
    if streams.heading is not None:
        out["heading"] = (streams.heading.time, streams.heading.heading)
    return out


def _config_json(
    section: Section,
    vehicle: VehicleTuning,
    arms: LeverArms,
    options: NavigateOptions,
    config: _core.FilterConfig,
    streams: Streams,
    initial: InitialState,
) -> dict[str, Any]:
    """What a ``config.json`` says: the recording, the clocks applied to its streams
    (estimated against a ground truth, else as given or assumed), the tuning, the arms,
    the streams used, the surface reference, the initial state's methods, the strategy,
    versions."""
    surface = streams.surface
    used = {
        "dvl": bool(len(streams.dvl)),
        "depth": streams.depth is not None,
        "fix": streams.fixes is not None,
        "heading": streams.heading is not None,
    }
    return {
        "recording": {"name": section.name, "epoch": section.epoch},
        "clocks": clocks_record(section),
        "vehicle": vehicle.source,
        "filter": _filter_keys(config),
        "lever_arms": dataclasses.asdict(arms),
        "streams_used": used,
        "switched_off": [
            k for k, on in dataclasses.asdict(options).items() if k.startswith("use_") and not on
        ],
        "surface_pressure": {
            "pa": streams.surface_pa,
            "offset_m": None if surface is None else surface.offset,
            "source": "no depth" if surface is None else surface.note,
        },
        "initial_state": {
            "t0": initial.t0,
            "methods": dict(initial.methods),
            "p0_sigma": [float(v) for v in initial.p0_sigma],
            "init": options.init,
        },
        "strategy": options.strategy,
        "smooth": options.smooth,
        "version": _core.__version__,
    }


def lever_arms(
    vehicle: VehicleTuning,
    *,
    imu: Arm | None = None,
    dvl: Arm | None = None,
    depth: Arm | None = None,
    fix: Arm | None = None,
    given_as: str = "{}_lever_arm",
) -> LeverArms:
    """The sensors' lever arms from the reference point: each given, else the vehicle
    file's; the IMU's else 0 (the trajectory is the IMU's), the others' else at the IMU
    (named in :attr:`LeverArms.assumed`, which the report states). An arm beyond
    10 m is warned of (in cm?), a given one named by ``given_as`` with the sensor
    (the command's ``--{}-lever-arm``), the vehicle file's by its key."""
    imu_arm = imu or vehicle.imu_lever_arm or ZERO
    given = {"imu": imu, "dvl": dvl, "depth": depth, "fix": fix}
    chosen = {k: given[k] or getattr(vehicle, f"{k}_lever_arm") for k in ("dvl", "depth", "fix")}
    for name, arm in (("imu", imu_arm), *chosen.items()):
        if arm is not None:
            named = (given_as if given[name] else "{}_lever_arm").format(name)
            long_lever_arm(arm, named, "the reference point")
    assumed = tuple(name for name, arm in chosen.items() if arm is None)
    return LeverArms(
        imu=imu_arm,
        dvl=chosen["dvl"] or imu_arm,
        depth=chosen["depth"] or imu_arm,
        fix=chosen["fix"] or imu_arm,
        assumed=assumed,
    )


def navigate_recording(
    path: str | Path,
    fmt: Format,
    vehicle: VehicleTuning,
    arms: LeverArms,
    options: NavigateOptions = NavigateOptions(),
) -> Navigation:
    """Read the recording at ``path`` (``fmt``: :data:`pronet.recorded.alignment.
    FORMATS`, or a bag's :class:`~pronet.recorded.bags.BagTopics`; a ground truth is
    optional) and :func:`navigate` it. Every check of the reader and of the options
    runs before the filter."""
    section, _ = load_section(
        Path(path),
        fmt,
        imu_lever_arm=arms.imu,
        dvl_lever_arm=arms.dvl,  # its rows are read, then left out without use_dvl
        declination=vehicle.declination,
        read_heading=options.use_heading,
    )
    if not options.use_dvl:
        section = dataclasses.replace(
            section, dvl=np.empty((0, 3)), dvl_time=np.empty(0), dvl_skipped_time=np.empty(0),
            dvl_skipped_reason=(), dvl_variance=None,
        )  # fmt: skip
    return navigate(section, vehicle, arms, options, source=str(path))
