"""Physical bounds that catch a unit or frame slip before it runs to a silently wrong
answer, one rule each, shared by the API
(:func:`pronet.run_filter`, :func:`pronet.local_ned`, :func:`pronet.lla_from_ned`) and
the readers (:mod:`pronet.recorded.plausible`, :mod:`pronet.recorded.recordings`).

Each check returns the problem as one line naming the argument, or None; the caller
raises it, or warns of it as a :class:`PlausibilityWarning`. Values that are not finite
are left to the checks that name them (the core's). The bounds come from physics, with
a wide margin for legitimate data:

- the mean specific force within :data:`GRAVITY_RANGE` of :data:`STANDARD_GRAVITY`
  (:func:`specific_force`): over a record a vehicle's mean acceleration is nearly 0, so
  the mean magnitude is gravity's within a few % (vibration and manoeuvres add little);
  accelerations in g, ft/s², mg or cm/s² are off by 0.1, 3.3, 100 or 100;
- its direction over the first :data:`GRAVITY_WINDOW` against the initial attitude
  (:func:`gravity_sign`): refused when it points more than 90° from where ``rpy0``
  puts it (the sign of gravity: an IMU in FLU, or upside down, points 180° away when
  level); legitimate data are off by the initial attitude's error and the tilt of the
  vehicle's acceleration (atan(a/g): 6° at 0.1 g), well below;
- the first IMU step, from ``t0``, at most :data:`MAX_IMU_GAP` median steps
  (:func:`first_step`: the readers' gap rule; the strapdown integrates the first sample
  over it, and it is one step when ``t0`` starts the first sample's interval);
- a depth within :data:`HEIGHT_RANGE`, negated (:func:`depth_beyond`: the deepest ocean
  is 11 km; a depth in pascals is 10,000 times its metres);
- the same two checks on the samples a mechanization (:func:`pronet.mechanize`) or an
  online navigator (:class:`pronet.recorded.online.Navigator`, its first feed) starts
  with (:func:`check_imu_start`: the magnitude over a second or more only);
- a latitude within ±90° and a longitude within ``_core.LONGITUDE_RANGE_DEG`` (the core's
  rule for fixes: both conventions, −180° … 360°), in radians (:func:`angles_beyond`:
  degrees are 57 times as large).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pronet import _core

F64 = NDArray[np.float64]

#: Standard gravity [m/s²].
STANDARD_GRAVITY = 9.80665
#: The mean specific force over a record, as a share of :data:`STANDARD_GRAVITY`.
GRAVITY_RANGE = (0.8, 1.2)
#: The heights a position may have [m, up]: the deepest trench to high above sea.
HEIGHT_RANGE = (-12_000.0, 10_000.0)
#: No IMU step (the first, from ``t0``, included) longer than this many median steps
#: (the core's rule, which the online navigator applies against its steps so far).
MAX_IMU_GAP: float = _core.MAX_IMU_GAP
#: The first seconds of IMU samples [s] whose mean specific force gives gravity's sign.
GRAVITY_WINDOW = 1.0


class PlausibilityWarning(UserWarning):
    """Usable data that is probably a mistake (a lever arm beyond 10 m, an IMU whose
    stamps jitter, a stream none of whose rows falls within the run)."""


def specific_force(imu: F64) -> str | None:
    """``imu`` ``(n, 6)``'s mean specific force outside :data:`GRAVITY_RANGE` of
    gravity (the problem, without the argument's name)."""
    f = imu[:, :3]
    mean = float(np.sqrt(np.einsum("ij,ij->i", f, f)).mean())
    lo, hi = GRAVITY_RANGE
    if not math.isfinite(mean) or lo <= mean / STANDARD_GRAVITY <= hi:
        return None
    return (
        f"the mean specific force is {mean:.4g} m/s², not near gravity ({STANDARD_GRAVITY} "
        "m/s²); are the accelerations in g, or mis-scaled?"
    )


def gravity_sign(imu: F64, imu_time: F64, rpy0: F64) -> str | None:
    """The mean specific force of ``imu``'s first :data:`GRAVITY_WINDOW` pointing more
    than 90° from the reaction to gravity (up) in the body frame ``rpy0`` gives."""
    first = imu[imu_time <= imu_time[0] + GRAVITY_WINDOW, :3].mean(axis=0)
    roll, pitch = float(rpy0[0]), float(rpy0[1])
    up = np.array([math.sin(pitch), -math.sin(roll), -math.cos(roll)])
    up[1:] *= math.cos(pitch)
    norm = float(np.linalg.norm(first))
    if not (math.isfinite(norm) and norm > 0):
        return None
    cos = float(first @ up) / norm
    if cos >= 0:
        return None
    angle = math.degrees(math.acos(max(cos, -1.0)))
    return (
        f"imu, rpy0: the specific force of the first {GRAVITY_WINDOW:g} s points {angle:.0f}° from "
        "where rpy0 puts it (up, against gravity: the body frame is FRD, x forward, y right, "
        "z down, so a level IMU at rest reads f_z = −9.8 m/s²); is the IMU in FLU (y and z "
        "flipped), or upside down without the roll in rpy0 that says so?"
    )


def first_step(imu_time: F64, t0: float) -> str | None:
    """The first IMU step, from ``t0`` to ``imu_time[0]``, longer than
    :data:`MAX_IMU_GAP` median steps."""
    if len(imu_time) < 2:
        return None
    step = float(np.median(np.diff(imu_time)))
    gap = float(imu_time[0]) - t0
    if not step > 0 or gap <= MAX_IMU_GAP * step:
        return None
    return (
        f"t0: {t0:.10g} s is {gap:.4g} s before the first IMU sample (imu_time[0] = "
        f"{imu_time[0]:.10g} s, {gap / step:.3g} median steps), over which the first sample "
        "would be integrated (t0 starts its step); are t0 and imu_time on one clock, in seconds?"
    )


def depth_beyond(depth: F64, name: str, rows: NDArray[np.int64] | None = None) -> str | None:
    """A depth [m, down] beyond :data:`HEIGHT_RANGE` (negated), naming ``name`` and the
    row: its number in ``rows`` (each depth's row as its file numbers it, 1 for the first
    data row), else its index in ``depth``."""
    lo, hi = -HEIGHT_RANGE[1], -HEIGHT_RANGE[0]
    bad = (depth < lo) | (depth > hi)
    if not bad.any():
        return None
    r = int(np.argmax(bad))
    row = r if rows is None else int(rows[r])
    return (
        f"{name}: depth row {row} is {depth[r]:.6g} m, beyond {lo:g} … {hi:g} m (metres, "
        "positive down: the deepest ocean is 11 km); in pascals or another unit?"
    )


def height_beyond(height: float, name: str) -> str | None:
    """A height [m, up] beyond :data:`HEIGHT_RANGE`, naming ``name``."""
    lo, hi = HEIGHT_RANGE
    if lo <= height <= hi:
        return None
    return (
        f"{name}: height {height:.6g} m is beyond {lo:g} … {hi:g} m (metres, positive up: "
        "the deepest ocean is 11 km); in another unit, or a depth?"
    )


def angles_beyond(lla: F64, name: str) -> str | None:
    """A latitude of ``lla`` (``(3,)`` or ``(n, 3)`` [rad, rad, m]) beyond ±90° or a
    longitude beyond ``_core.LONGITUDE_RANGE_DEG``, naming ``name`` and the row."""
    rows = np.atleast_2d(lla)
    lon_lo, lon_hi = _core.LONGITUDE_RANGE_DEG
    for j, what, lo, hi in ((0, "latitude", -90.0, 90.0), (1, "longitude", lon_lo, lon_hi)):
        bad = (rows[:, j] < math.radians(lo)) | (rows[:, j] > math.radians(hi))
        if bad.any():
            r = int(np.argmax(bad))
            row = f"row {r}: " if lla.ndim == 2 else ""
            return (
                f"{name}: {row}{what} {rows[r, j]:.6g} is beyond {math.radians(lo):.6g} … "
                f"{math.radians(hi):.6g} rad ({lo:g}° … {hi:g}°); in degrees? (radians expected)"
            )
    return None


def attitude_beyond(rpy: F64, name: str) -> str | None:
    """A roll or pitch of ``rpy`` ``(3,)`` [rad] beyond ±π, or a yaw beyond ±2π (the
    0–360° convention taken), naming ``name``: degrees given for radians."""
    for j, what, bound in ((0, "roll", math.pi), (1, "pitch", math.pi), (2, "yaw", 2 * math.pi)):
        if abs(rpy[j]) > bound:
            return (
                f"{name}: {what} {rpy[j]:.6g} is beyond ±{bound:.6g} rad; in degrees? "
                "(radians expected)"
            )
    return None


#: A lever arm with a component beyond this [m] is warned of: typed in cm or mm, an
#: arm runs to metres, usable and wrong.
LONG_LEVER_ARM = 10.0


def long_lever_arm(arm: Sequence[float], name: str, reference: str = "the IMU") -> None:
    """Warn (:class:`PlausibilityWarning`) of a lever arm ``arm`` [m] (from
    ``reference``) with a component beyond :data:`LONG_LEVER_ARM`, naming the first
    such component and the arm's length."""
    far = [(axis, v) for axis, v in zip("xyz", arm, strict=False) if abs(v) > LONG_LEVER_ARM]
    if far:
        shown = ",".join(f"{v:g}" for v in arm)
        length = math.sqrt(sum(v * v for v in arm))
        warnings.warn(
            f"{name}: {shown} m ({length:.3g} m long): its {far[0][0]} of {far[0][1]:g} m "
            f"from {reference} is beyond ±{LONG_LEVER_ARM:g} m; typed in cm or mm? (used as "
            "given)",
            PlausibilityWarning,
            stacklevel=3,
        )


#: An IMU's stamped steps, by the 99th percentile of ``|step / median − 1|``, beyond this
#: share of a step are warned of (:func:`imu_jitter`).
MAX_IMU_JITTER = 0.15


def imu_jitter(where: str, step: F64, median: float | None = None) -> str | None:
    """The IMU's ``step`` s between stamps spread beyond :data:`MAX_IMU_JITTER` of their
    median (``median``: theirs, where the caller has it; the 99th percentile of
    ``|step / median − 1|``). Each sample is integrated
    over its stamped step, exact when the IMU sampled so (a 10 % spread of such steps
    runs as well as a uniform IMU: ``tests/recorded/test_rates.py``; the 15 % bound
    leaves half that again); an IMU samples on its own crystal, steady to 1e-4, so a
    larger spread is a logger's stamping, which moves the solution (50.5 Hz stamped
    within ±2 ms: 18 %, the Snapir IMU: 4e-12)."""
    if median is None:
        median = float(np.median(step)) if len(step) > 1 else 0.0
    if not median > 0:
        return None
    spread = float(np.percentile(np.abs(step / median - 1.0), 99))
    if spread <= MAX_IMU_JITTER:
        return None
    return (
        f"{where}: the IMU steps jitter by {100 * spread:.0f} % of the median step "
        f"{median:.4g} s (1 % of them more; at most {100 * MAX_IMU_JITTER:g} % expected); "
        "each sample is integrated over its stamped step, so stamps from a logger's clock, "
        "not the IMU's, move the solution: re-stamp the samples on the IMU's clock if it "
        "has one (used as given)"
    )


def imu_gap(where: str, step: F64, median: float | None = None) -> str | None:
    """The first of the IMU's ``step`` s between stamps longer than :data:`MAX_IMU_GAP`
    median steps (``median``: theirs, where the caller has it): the sample after it is
    integrated over the whole gap."""
    if len(step) < 2:
        return None
    median = float(np.median(step)) if median is None else median
    gap = step > MAX_IMU_GAP * median
    if not gap.any():
        return None
    r = int(np.argmax(gap))
    return (
        f"{where}: a gap of {step[r]:.4g} s after row {r} (the median step is "
        f"{median:.4g} s): the sample after it is integrated over the whole gap, "
        "as if the vehicle had turned and accelerated evenly across it; cut the run there "
        "(used as given)"
    )


def gaps_fed(gaps: int, end: float, length: float, longest: float, usual: float) -> str:
    """An online navigator's IMU gaps so far (``_core.Navigator.imu_gaps``: their number,
    the first's end and length [s], the longest's length [s], the usual step [s]) as one
    line, or "" with none."""
    if gaps == 0:
        return ""
    more = "" if gaps == 1 else f"; {gaps} gaps in all, the longest {longest:.4g} s"
    return (
        f"imu: a gap of {length:.4g} s before the sample at {end:.10g} s (the usual step "
        f"is {usual:.4g} s{more}): the sample after a gap is integrated over the whole "
        "of it, as if the vehicle had turned and accelerated evenly across it"
    )


def imu_period(imu_dt: float, step: float) -> str | None:
    """The filter's nominal IMU period ``imu_dt`` [s] against the IMU's typical stamped
    ``step`` [s], beyond :data:`MAX_IMU_JITTER` of it: the filter adds ``q · imu_dt · dt``
    per step (``q`` each sample's variance at ``imu_dt``), so with samples ``step`` apart
    its process noise is ``imu_dt / step`` times what ``q`` per sample gives (a 200 Hz
    IMU under the default 0.01 s: twice)."""
    if not (step > 0 and abs(imu_dt / step - 1.0) > MAX_IMU_JITTER):
        return None
    return (
        f"config.imu_dt: {imu_dt:.4g} s, but the IMU stamps step {step:.4g} s: the filter "
        "takes q as each sample's variance over imu_dt, so its process noise is "
        f"{imu_dt / step:.3g}× what samples {step:.4g} s apart with that variance give; "
        f"set FilterConfig(imu_dt={step:.4g}) (used as given)"
    )


def warn_of_imu_dt(imu_dt: float, dt: float, where: str) -> None:
    """Warn (:class:`PlausibilityWarning`) of a simulation's filter whose ``imu_dt`` [s]
    differs from its trajectory's IMU period ``dt`` [s] beyond :data:`MAX_IMU_JITTER`
    (:func:`imu_period`: its process noise is ``imu_dt / dt`` times the simulated IMU's;
    ``imu_dt = 100``, a rate in Hz, ran 10⁴ times mistuned without a word); ``where``
    (a file and table) names the key. Used as given."""
    if imu_period(imu_dt, dt) is not None:
        warnings.warn(
            f"{where} imu_dt: {imu_dt:.4g} s, but the trajectory's IMU period (dt_s) is "
            f"{dt:.4g} s: the filter takes q as each sample's variance over imu_dt, so its "
            f"process noise is {imu_dt / dt:.3g}× the simulated IMU's (used as given; "
            "without imu_dt the filter takes dt_s)",
            PlausibilityWarning,
            stacklevel=3,
        )


#: A simulated heading sensor's largest plausible 1σ [rad] (28.6°, a compass beside
#: iron); beyond it the value is likely degrees (:func:`warn_of_heading_sigma`).
MAX_HEADING_SIGMA_RAD = 0.5


def warn_of_heading_sigma(sigma: float | None, where: str) -> None:
    """Warn (:class:`PlausibilityWarning`) of a scenario's heading sensor whose 1σ
    ``sigma`` [rad] exceeds :data:`MAX_HEADING_SIGMA_RAD`: degrees, as a vehicle file's
    ``heading_sigma`` is (``2`` simulated a 115° compass, without a word); ``where``
    (the file and table) names the key. Used as given."""
    if sigma is not None and sigma > MAX_HEADING_SIGMA_RAD:
        warnings.warn(
            f"{where} heading_sigma: {sigma:g} rad ({math.degrees(sigma):.3g}°) is no "
            f"heading sensor's 1σ; in degrees? A scenario's heading_sigma is in radians "
            "(a vehicle file's in degrees); used as given",
            PlausibilityWarning,
            stacklevel=3,
        )


def warn_of_sensors(sensors: _core.SensorConfig, traj: _core.Trajectory, where: str) -> None:
    """Warn (:class:`PlausibilityWarning`) of a scenario's sensors that make no sensor
    the user meant: a heading 1σ in degrees (:func:`warn_of_heading_sigma`), and DVL
    outages that hold every DVL epoch of ``traj`` (every ``round(dvl_period / dt)``
    IMU steps from the first such, as the core reads them), so that the DVL never
    reports: every row inertial-only, its NIS and NEES undefined, where
    ``dvl_period = 0`` says "no DVL". ``where`` (the file and table) names the keys.
    Used as given."""
    warn_of_heading_sigma(sensors.heading_sigma, where)
    outages = np.asarray(sensors.dvl_outages, dtype=np.float64).reshape(-1, 2)
    if sensors.dvl_period <= 0 or not len(outages):
        return
    every = max(1, round(sensors.dvl_period / traj.dt))
    t = traj.time[every::every]
    out = ((t[:, None] >= outages[:, 0]) & (t[:, None] < outages[:, 1])).any(axis=1)
    if len(t) and out.all():  # no epoch at all (a period past the run) is not this
        warnings.warn(
            f"{where} dvl_outages: hold every DVL epoch of the {traj.duration:g} s run, so "
            "the DVL never reports (no update: the rows are inertial-only, their NIS and "
            "NEES undefined); dvl_period = 0 says no DVL; used as given",
            PlausibilityWarning,
            stacklevel=3,
        )


def unfilled_window(kind: str, window: int | None, accepted: int) -> str | None:
    """A Mehra or adaptive strategy (``kind``) whose ``window`` of accepted velocity
    updates the pass never filled (``accepted`` of them): it ran on its prior q
    throughout, a constant-Q run under another name. The problem as one line, without
    the strategy's name (the API's warning says ``strategy``, a command its option or
    row), or None."""
    if kind not in ("mehra", "adaptive") or window is None or accepted >= window:
        return None
    return (
        f"{kind}'s window of {window} velocity updates was never filled "
        f"({accepted} accepted in the pass): it ran on its prior q throughout, as a constant "
        "strategy would; a window shorter than the pass's updates adapts"
    )


def warn_unfilled_window(kind: str, window: int | None, accepted: int) -> None:
    """Warn (:class:`PlausibilityWarning`) of a Mehra or adaptive strategy whose window
    the pass never filled (:func:`unfilled_window`), naming the argument ``strategy``."""
    if (problem := unfilled_window(kind, window, accepted)) is not None:
        warnings.warn(f"strategy: {problem}", PlausibilityWarning, stacklevel=3)


def warn_of_stamps(imu_time: F64, imu_dt: float) -> None:
    """Warn (:class:`PlausibilityWarning`) of a pass's IMU stamps that jitter
    (:func:`imu_jitter`), leave a gap (:func:`imu_gap`) or step otherwise than the
    filter's ``imu_dt`` [s] (:func:`imu_period`)."""
    step = np.diff(imu_time)
    if len(step) and 0 < step.min() and step.max() <= step.min() * (1 + MAX_IMU_JITTER):
        # every step within the bounds of any median: the usual case, one pass
        problems = [imu_period(imu_dt, float(imu_time[-1] - imu_time[0]) / len(step))]
    else:
        median = float(np.median(step)) if len(step) > 1 else 0.0  # once, for all three
        problems = [
            imu_jitter("imu_time", step, median),
            imu_gap("imu_time", step, median),
            imu_period(imu_dt, median),
        ]
    for problem in problems:
        if problem is not None:
            warnings.warn(problem, PlausibilityWarning, stacklevel=3)


def check_pass(
    imu: F64,
    imu_time: F64,
    t0: float,
    rpy0: F64,
    streams: Sequence[Any],
    names: Sequence[str] | None = None,
) -> None:
    """The plausibility of a filter pass's inputs (:func:`pronet.run_filter`'s, checked
    for shape): ``ValueError`` with the first problem, naming its argument (a stream by
    its ``names`` entry, else ``streams[i]``)."""
    finite = all(np.isfinite(a).all() for a in (imu, imu_time, rpy0, t0))
    if not (len(imu) and len(imu) == len(imu_time) and finite):
        return  # the core names the argument
    with np.errstate(all="ignore"):
        problem = (
            attitude_beyond(rpy0, "rpy0")
            or first_step(imu_time, t0)
            or (f"imu: {bad}" if (bad := specific_force(imu)) else None)
            or gravity_sign(imu, imu_time, rpy0)
        )
        for i, s in enumerate(streams):
            if problem is None and isinstance(s, _core.Depth):
                problem = depth_beyond(s.depth, names[i] if names else f"streams[{i}]")
    if problem is not None:
        raise ValueError(problem)


def long_lever_arms(
    dvl: Sequence[float], streams: Sequence[Any], names: Sequence[str] | None = None
) -> None:
    """Warn of each lever arm of a pass beyond :data:`LONG_LEVER_ARM`: the config's DVL
    arm ``dvl`` and each stream's own (named by ``names``, else ``streams[i]``)."""
    long_lever_arm(dvl, "config.lever_arm")
    for i, s in enumerate(streams):
        # a DVL's None: the config's; a heading has none
        if (arm := getattr(s, "lever_arm", None)) is not None:
            long_lever_arm(arm, f"{names[i] if names else f'streams[{i}]'}.lever_arm")


def check_imu_start(imu: F64, imu_time: F64, rpy0: F64) -> None:
    """The IMU samples a mechanization or a navigator starts with (``imu`` ``(n, 6)``
    stamped ``imu_time``, at the attitude ``rpy0``): ``ValueError`` when their mean
    specific force is not gravity's (:func:`specific_force`, over a second or more) or
    points away from where ``rpy0`` puts it (:func:`gravity_sign`)."""
    if not (len(imu) and np.isfinite(imu).all() and np.isfinite(rpy0).all()):
        return  # the core names the argument
    with np.errstate(all="ignore"):
        long_enough = imu_time[-1] - imu_time[0] >= GRAVITY_WINDOW
        problem = (f"imu: {bad}" if long_enough and (bad := specific_force(imu)) else None) or (
            gravity_sign(imu, imu_time, rpy0)
        )
    if problem is not None:
        raise ValueError(problem)


def warn_unapplied(
    streams: Sequence[Any],
    epochs: Sequence[NDArray[np.int64]],
    span: tuple[float, float],
    names: Sequence[str] | None = None,
) -> None:
    """Warn (:class:`PlausibilityWarning`) of each stream with rows none of which fell
    within the run (``epochs``: each stream's epoch per row, -1 outside; ``span``: the
    run's first and last epoch times [s]; ``names``: each stream's, else
    ``streams[i] (Kind)``)."""
    for i, (s, epoch) in enumerate(zip(streams, epochs, strict=True)):
        if len(epoch) and (np.asarray(epoch) < 0).all():
            t = s.time
            name = names[i] if names else f"streams[{i}] ({type(s).__name__})"
            warnings.warn(
                f"{name}: none of its {len(t)} row{'s' * (len(t) > 1)} "
                f"({t[0]:.10g} … {t[-1]:.10g} s) falls within the run ({span[0]:.10g} … "
                f"{span[1]:.10g} s), which ran without it; are its times on the IMU's clock, "
                "in seconds?",
                PlausibilityWarning,
                stacklevel=3,
            )
