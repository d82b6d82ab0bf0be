"""Clocks and lever arms: turn a :class:`~pronet.recorded.recordings.Recording` into a filter-ready
:class:`Section` on the IMU's clock, with the ground truth moved to the IMU.

Clocks. Each stream's stamps map to IMU time by ``t_imu = offset + scale · t_stamp``
(:class:`Clock`), every time counted from the section's *epoch*, its first IMU stamp:
the scale acts about the section's start, not about t = 0, so the estimates do not
depend on the stamps' origin (relative stamps or Unix time give the same clocks and
results; a float64 stamp near 1.7e9 s resolves 2.4e-7 s, the one limit Unix-time stamps
bring). A :class:`Section`'s times are on the IMU clock since its ``epoch``. Real
loggers stamp streams differently: in the Snapir data the ground-truth and DVL stamps
step by 400/399 s while the rows are 1.000 s apart on the IMU clock, and the ground
truth is shifted by about ±0.45 s. Both clocks can be given or estimated per section:

- ground truth (:func:`estimate_gt_clock`): the Euler-angle increments between consecutive
  ground-truth rows matched against the same increments integrated from the gyro (Euler rates
  from the body rates and the truth's roll and pitch); a coarse grid over scale ∈ [0.99, 1.01]
  and offset ∈ [−2, 2] s, then a fine one around the best, minimises the mean squared mismatch.
- DVL (:func:`estimate_dvl_clock`): its body velocity is matched against the aligned
  ground truth's velocity rotated into the body and moved to the DVL (``Cᵀ v + ω × r``),
  over the same kind of grid of offsets, with the ground truth's scale.

Without a ground truth (:attr:`Section.has_truth`) neither clock can be estimated: the
DVL's is then the identity unless given (:func:`estimate_alignment`'s ``dvl_clock``),
and :class:`Alignment` says which clock was given, estimated or assumed
(``gt_clock_how``, ``dvl_clock_how``). Whatever scores against a truth (``pronet
real``, :func:`pronet.recorded.passes.start_index`, the metrics) refuses such a section
in one line (:func:`no_truth`).

Lever arms (body frame FRD, metres, relative to the point the ground truth describes):
the ground truth is moved to the IMU, ``p_imu = p_gt + C r_imu``,
``v_imu = v_gt + C (ω × r_imu)`` (ω the gyro rate; the Earth's rate over a few metres
is below 2e-4 m/s and left out), and the filter's DVL lever arm is ``r_dvl − r_imu``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet import _core
from pronet._util.validate import check_type, float_array, real_array, scalar
from pronet.recorded.aiding import DepthReadings, PositionFixes
from pronet.recorded.bags import BagTopics, is_bag
from pronet.recorded.heading import HeadingReadings
from pronet.recorded.plausible import CLOCK_MIN_ROWS, too_few_clock_rows
from pronet.recorded.recordings import Recording

F64 = NDArray[np.float64]

#: Snapir lever arms from its README [m, body FRD, relative to the ground-truth point].
SNAPIR_IMU_LEVER_ARM = (-1.78, -0.04, -1.04)
SNAPIR_DVL_LEVER_ARM = (-1.85, -0.03, 0.12)


@dataclass(frozen=True)
class Clock:
    """``t_imu = offset + scale · t_stamp`` [s], both times counted from the section's
    epoch (its first IMU stamp; see the module docstring)."""

    offset: float = 0.0
    scale: float = 1.0

    def __post_init__(self) -> None:
        if not np.isfinite(scalar(self.offset, "offset")):
            raise ValueError(f"offset: must be finite, got {self.offset}")
        if not 0 < scalar(self.scale, "scale") < np.inf:
            raise ValueError(f"scale: must be finite and > 0, got {self.scale}")

    def __call__(self, stamps: ArrayLike) -> F64:
        return self.offset + self.scale * real_array(stamps, "stamps").astype(np.float64)

    def since(self, epoch: float) -> Clock:
        """The mapping for times counted from ``epoch`` [s], not 0 (``offset − epoch·(1 −
        scale)``): a clock of absolute stamps, for :func:`align` of a recording from there."""
        return Clock(offset=self.offset - float(epoch) * (1.0 - self.scale), scale=self.scale)


def lever_arm(value: ArrayLike, name: str) -> F64:
    """A lever arm ``(3,)`` [m] of finite numbers within ±:data:`pronet._core.MAX_LEVER_ARM`
    (the core's rule, 1 km), or ``ValueError`` naming it: a longer one is a slip of
    units, which would otherwise surface as an error about something else (a latitude)."""
    arm = float_array(value, name, (3,))
    if not np.isfinite(arm).all():
        raise ValueError(f"{name}: must be finite, got {arm}")
    if np.abs(arm).max() > _core.MAX_LEVER_ARM:
        raise ValueError(
            f"{name}: must be within ±{_core.MAX_LEVER_ARM:g} m (no vehicle is longer), "
            f"got {', '.join(f'{v:g}' for v in arm)} m"
        )
    return arm


#: How a clock of an :class:`Alignment` was found: given, estimated from the data,
#: assumed (the identity, nothing to estimate it from), or none (no such stream).
CLOCK_HOW = ("given", "estimated", "assumed", "none")


@dataclass(frozen=True)
class Alignment:
    """How a recording's streams are put on the IMU clock and at the IMU point.

    Attributes:
        gt_clock, dvl_clock: stamp → IMU time of the ground truth and of the DVL.
        imu_lever_arm: IMU position [m, body FRD] relative to the ground-truth point.
        dvl_lever_arm: DVL position [m, body FRD] relative to the ground-truth point.
        how: ``"estimated"``, ``"given"`` or ``"none"`` (stamps and no lever arms), or
            ``"assumed"`` (no ground truth to estimate a clock from: identities).
        aiding_clock: stamp → IMU time of the depth readings, position fixes and
            heading readings (:mod:`pronet.recorded.aiding`; never estimated: identity
            unless given).
        gt_clock_how, dvl_clock_how: how each clock was found, one of
            :data:`CLOCK_HOW` (``"none"``: the recording has no such stream).
    """

    gt_clock: Clock = field(default_factory=Clock)
    dvl_clock: Clock = field(default_factory=Clock)
    imu_lever_arm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    dvl_lever_arm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    how: str = "given"
    aiding_clock: Clock = field(default_factory=Clock)
    gt_clock_how: str = "given"
    dvl_clock_how: str = "given"

    def __post_init__(self) -> None:
        check_type(self.gt_clock, Clock, "gt_clock")
        check_type(self.dvl_clock, Clock, "dvl_clock")
        check_type(self.aiding_clock, Clock, "aiding_clock")
        lever_arm(self.imu_lever_arm, "imu_lever_arm")
        lever_arm(self.dvl_lever_arm, "dvl_lever_arm")
        for name in ("gt_clock_how", "dvl_clock_how"):
            if getattr(self, name) not in CLOCK_HOW:
                raise ValueError(
                    f"{name}: expected one of {', '.join(CLOCK_HOW)}, got {getattr(self, name)!r}"
                )

    @property
    def filter_lever_arm(self) -> tuple[float, float, float]:
        """The DVL's lever arm from the IMU [m, body FRD], as the filter takes it."""
        d = np.subtract(self.dvl_lever_arm, self.imu_lever_arm)
        return (float(d[0]), float(d[1]), float(d[2]))


@dataclass(frozen=True)
class Section:
    """A recording on the IMU clock with its truth at the IMU, ready for the filter
    (the truth optional: :attr:`has_truth`).

    Attributes:
        name: section name.
        imu_time: ``(n,)`` IMU sample times [s].
        imu: ``(n, 6)`` ``[f (m/s²), ω (rad/s)]``, body FRD.
        dvl_time: ``(m,)`` DVL times on the IMU clock [s].
        dvl: ``(m, 3)`` DVL body velocity [m/s].
        truth_time: ``(k,)`` ground-truth times on the IMU clock [s]; ``(0,)`` without
            a ground truth, the three below then ``(0, 3)``.
        truth_lla, truth_vel, truth_rpy: ``(k, 3)`` the truth moved to the IMU:
            lat, lon [rad], height [m, up]; NED velocity [m/s]; roll, pitch, yaw [rad].
        alignment: how it was aligned.
        epoch: the recording's first IMU stamp [s, as recorded], from which every time
            of the section counts (0 for stamps that start at 0).
        dvl_skipped_time: ``(j,)`` times on the IMU clock [s] of the DVL rows skipped as
            missing readings (:mod:`pronet.recorded.missing`), not in ``dvl``.
        dvl_skipped_reason: why each was skipped.
        dvl_variance: the DVL's R per axis [(m/s)²] that the recording states (a ROS
            bag's covariance), used as the strategy rows' R; None: R as tuned.
        depth, fixes: the depth readings and position fixes on the IMU clock
            (:mod:`pronet.recorded.aiding`), or None.
        heading: the heading readings (true north) on the IMU clock
            (:mod:`pronet.recorded.heading`), or None.
        truth_velocity_sigma: the truth's own velocity error 1σ per NED axis [m/s]
            (:mod:`pronet.recorded.trutherror`), or None: not stated.
    """

    name: str
    imu_time: F64
    imu: F64
    dvl_time: F64
    dvl: F64
    truth_time: F64
    truth_lla: F64
    truth_vel: F64
    truth_rpy: F64
    alignment: Alignment
    epoch: float = 0.0
    dvl_skipped_time: F64 = field(default_factory=lambda: np.empty(0))
    dvl_skipped_reason: tuple[str, ...] = ()
    dvl_variance: tuple[float, float, float] | None = None
    depth: DepthReadings | None = None
    fixes: PositionFixes | None = None
    heading: HeadingReadings | None = None
    truth_velocity_sigma: tuple[float, float, float] | None = None

    @property
    def has_truth(self) -> bool:
        """Whether the section has a ground truth (``truth_time`` not empty)."""
        return len(self.truth_time) > 0


#: Why ``pronet real`` refuses a section without a ground truth.
NO_TRUTH_FOR_REAL = "pronet real scores against one; pronet navigate runs without"


def no_truth(name: str, why: str = NO_TRUTH_FOR_REAL) -> str:
    """The one line that refuses section ``name`` without a ground truth where one is
    needed (``why``: what needs it; default ``pronet real``)."""
    return f"section {name} has no ground truth: {why}"


def dcm_from_euler(rpy: ArrayLike) -> F64:
    """Body-to-NED DCMs ``(…, 3, 3)`` from roll, pitch, yaw ``(…, 3)`` [rad] (ZYX)."""
    a = real_array(rpy, "rpy").astype(np.float64)
    if a.ndim < 1 or a.shape[-1] != 3:
        raise ValueError(f"rpy: expected shape (..., 3), got {a.shape}")
    cr, sr = np.cos(a[..., 0]), np.sin(a[..., 0])
    cp, sp = np.cos(a[..., 1]), np.sin(a[..., 1])
    cy, sy = np.cos(a[..., 2]), np.sin(a[..., 2])
    c = np.empty(a.shape[:-1] + (3, 3))
    c[..., 0, 0] = cp * cy
    c[..., 0, 1] = sr * sp * cy - cr * sy
    c[..., 0, 2] = cr * sp * cy + sr * sy
    c[..., 1, 0] = cp * sy
    c[..., 1, 1] = sr * sp * sy + cr * cy
    c[..., 1, 2] = cr * sp * sy - sr * cy
    c[..., 2, 0] = -sp
    c[..., 2, 1] = sr * cp
    c[..., 2, 2] = cr * cp
    return c


def _interp(t: F64, tp: F64, fp: F64) -> F64:
    """Linear interpolation of the columns of ``fp (k, c)`` at ``t``."""
    return np.stack([np.interp(t, tp, fp[:, j]) for j in range(fp.shape[1])], axis=1)


def _fit(cost: Callable[[F64, float], F64], what: str, scale: float | None = None) -> Clock:
    """Minimise ``cost(offsets, scale)`` (one value per offset): a coarse grid, then a
    fine one around the best; ``scale`` given: only the offset is searched. ``what``:
    the streams compared, for the error where no offset lets them overlap."""

    def search(scales: F64, offsets_for: Callable[[float], F64]) -> tuple[float, float, float]:
        best = (np.inf, 0.0, 1.0)
        for scale in scales:
            offsets = offsets_for(float(scale))
            c = cost(offsets, float(scale))
            i = int(np.argmin(c))
            if c[i] < best[0]:
                best = (float(c[i]), float(offsets[i]), float(scale))
        return best

    coarse = np.linspace(0.99, 1.01, 41) if scale is None else np.array([scale])
    _, o0, s0 = search(coarse, lambda _: np.linspace(-2.0, 2.0, 201))
    fine = s0 + np.linspace(-5e-4, 5e-4, 51) if scale is None else coarse
    c, o, s = search(fine, lambda _: o0 + np.linspace(-0.02, 0.02, 41))
    if not np.isfinite(c):
        raise ValueError(
            f"{what} do not overlap in time by {CLOCK_MIN_ROWS} rows at any clock offset "
            "within ±2 s; cannot align the clocks"
        )
    return Clock(offset=o, scale=s)


def since_epoch(rec: Recording) -> tuple[Recording, float]:
    """``rec`` with every stamp counted from its epoch (its first IMU stamp), and that
    epoch [s]. Stamps that start at 0 are returned as they are (subtracting 0 is exact)."""
    epoch = float(rec.imu_time[0])
    if epoch == 0.0:
        return rec, 0.0
    return (
        replace(
            rec,
            imu_time=rec.imu_time - epoch,
            dvl_time=rec.dvl_time - epoch,
            gt_time=rec.gt_time - epoch,
            dvl_skipped_time=rec.dvl_skipped_time - epoch,
            depth=None if rec.depth is None else rec.depth.on_clock(lambda t: t - epoch),
            fixes=None if rec.fixes is None else rec.fixes.on_clock(lambda t: t - epoch),
            heading=None if rec.heading is None else rec.heading.on_clock(lambda t: t - epoch),
        ),
        epoch,
    )


def _truth_needed(rec: Recording, what: str) -> None:
    if not rec.has_truth:
        raise ValueError(f"{rec.source}: no ground truth to estimate {what} from")


def estimate_gt_clock(rec: Recording) -> Clock:
    """The ground truth's clock (since the epoch: see the module docstring), from its
    attitude increments against the gyro's; ValueError without a ground truth."""
    _truth_needed(rec, "its clock")
    rec, _ = since_epoch(rec)
    too_few_clock_rows(rec.gt_time, CLOCK_MIN_ROWS + 1, "the ground truth", rec.source)
    euler = np.unwrap(rec.gt_rpy, axis=0)
    t_imu = rec.imu_time
    roll = np.interp(t_imu, rec.gt_time, euler[:, 0])
    pitch = np.interp(t_imu, rec.gt_time, euler[:, 1])
    w = rec.imu[:, 3:6]
    sr, cr, cp = np.sin(roll), np.cos(roll), np.cos(pitch)
    yaw_part = w[:, 1] * sr + w[:, 2] * cr
    rates = np.column_stack(
        [w[:, 0] + yaw_part * np.tan(pitch), w[:, 1] * cr - w[:, 2] * sr, yaw_part / cp]
    )
    # Cumulative integral on sample boundaries; sample k covers (t[k-1], t[k]].
    dt = np.diff(t_imu, prepend=t_imu[0] - np.median(np.diff(t_imu)))
    edges = np.concatenate([[t_imu[0] - dt[0]], t_imu])
    cum = np.vstack([np.zeros(3), np.cumsum(rates * dt[:, None], axis=0)])
    gt_step = np.diff(euler, axis=0)

    def cost(offsets: F64, scale: float) -> F64:
        # in the core: the same interpolation as numpy.interp, one walk over the edges
        return _core.attitude_increment_costs(edges, cum, rec.gt_time, gt_step, offsets, scale)

    return _fit(cost, f"{rec.source}: the ground truth and the IMU")


def estimate_dvl_clock(
    rec: Recording, gt_clock: Clock, dvl_lever_arm: ArrayLike = (0.0, 0.0, 0.0)
) -> Clock:
    """The DVL's clock, from its body velocity against the aligned ground truth's. Its
    scale is taken as the ground truth's (one logger stamps both, as in the Snapir
    data): body velocity varies slowly, so it pins an offset well but cannot also
    separate a scale from it over a short section. ``gt_clock`` and the result count
    from the epoch (see the module docstring). ValueError without a ground truth."""
    _truth_needed(rec, "the DVL's clock")
    rec, _ = since_epoch(rec)
    too_few_clock_rows(rec.dvl_time, CLOCK_MIN_ROWS, "the DVL", rec.source)
    r = lever_arm(dvl_lever_arm, "dvl_lever_arm")
    t_gt = gt_clock(rec.gt_time)
    euler = np.unwrap(rec.gt_rpy, axis=0)
    # The truth's velocity moved to the DVL at its own rows, then interpolated: the
    # lever-arm term is then as smooth as the velocity it is added to.
    w = _interp(t_gt, rec.imu_time, rec.imu[:, 3:6])
    v_dvl = rec.gt_vel + np.einsum("kij,kj->ki", dcm_from_euler(rec.gt_rpy), np.cross(w, r))
    lo, hi = max(t_gt[0], rec.imu_time[0]), min(t_gt[-1], rec.imu_time[-1])

    def cost(offsets: F64, scale: float) -> F64:
        t = offsets[:, None] + scale * rec.dvl_time  # (offsets, rows)
        inside = (t >= lo) & (t <= hi)
        c = dcm_from_euler(np.stack([np.interp(t, t_gt, euler[:, j]) for j in range(3)], -1))
        v_ned = np.stack([np.interp(t, t_gt, v_dvl[:, j]) for j in range(3)], -1)
        v_body = np.einsum("okji,okj->oki", c, v_ned)
        sq = np.where(inside, np.sum((rec.dvl - v_body) ** 2, axis=-1), 0.0)
        n = inside.sum(axis=1)
        return np.where(n >= CLOCK_MIN_ROWS, sq.sum(axis=1) / np.maximum(n, 1), np.inf)

    return _fit(cost, f"{rec.source}: the DVL and the ground truth", scale=gt_clock.scale)


def estimate_alignment(
    rec: Recording,
    imu_lever_arm: ArrayLike = (0.0, 0.0, 0.0),
    dvl_lever_arm: ArrayLike = (0.0, 0.0, 0.0),
    dvl_clock: Clock | None = None,
) -> Alignment:
    """Both clocks estimated from the data (the DVL's given as ``dvl_clock``, counted
    from the epoch, when known), with the given lever arms [m, body FRD, relative to the
    ground-truth point]. Without a ground truth nothing can be estimated: the truth's
    clock is none, the DVL's ``dvl_clock`` or else the identity, assumed (``how``
    ``"assumed"`` unless it was given)."""
    imu_arm = lever_arm(imu_lever_arm, "imu_lever_arm")
    dvl_arm = lever_arm(dvl_lever_arm, "dvl_lever_arm")
    if dvl_clock is not None:
        check_type(dvl_clock, Clock, "dvl_clock")
    arms = {
        "imu_lever_arm": tuple(float(v) for v in imu_arm),
        "dvl_lever_arm": tuple(float(v) for v in dvl_arm),
    }
    if not rec.has_truth:
        given = dvl_clock is not None
        return Alignment(
            dvl_clock=dvl_clock or Clock(),
            how="given" if given else "assumed",
            gt_clock_how="none",
            dvl_clock_how="none" if not len(rec.dvl) else ("given" if given else "assumed"),
            **arms,  # type: ignore[arg-type]
        )
    gt_clock = estimate_gt_clock(rec)
    if dvl_clock is None:
        # without a DVL (a GNSS/INS recording) a placeholder, the truth's: no DVL row is
        # put on it, and load_section refuses it as the depth and fixes' clock
        dvl_clock = estimate_dvl_clock(rec, gt_clock, dvl_arm) if len(rec.dvl) else gt_clock
        dvl_how = "estimated" if len(rec.dvl) else "none"
    else:
        dvl_how = "given"
    return Alignment(
        gt_clock=gt_clock,
        dvl_clock=dvl_clock,
        how="estimated",
        gt_clock_how="estimated",
        dvl_clock_how=dvl_how,
        **arms,  # type: ignore[arg-type]
    )


def moved_point(lla: F64, vel: F64, rpy: F64, arm: ArrayLike, gyro: F64) -> tuple[F64, F64]:
    """Position ``(k, 3)`` [rad, rad, m up] and NED velocity ``(k, 3)`` [m/s] of the point
    at ``arm`` [m, body FRD] from the point whose are ``lla``, ``vel``, at attitude
    ``rpy`` ``(k, 3)`` [rad] and body rate ``gyro`` ``(k, 3)`` [rad/s]:
    ``p + C r`` (NED metres at the point's radii) and ``v + C (ω × r)``."""
    r = np.asarray(arm, dtype=np.float64)
    lla, vel = np.array(lla, dtype=np.float64), np.array(vel, dtype=np.float64)
    if not r.any():
        return lla, vel
    c = dcm_from_euler(rpy)
    offset_ned = c @ r
    radii = np.array([_core.earth_radii(float(lat)) for lat in lla[:, 0]])
    h = lla[:, 2]
    lla[:, 0] += offset_ned[:, 0] / (radii[:, 0] + h)
    lla[:, 1] += offset_ned[:, 1] / ((radii[:, 1] + h) * np.cos(lla[:, 0]))
    lla[:, 2] -= offset_ned[:, 2]
    vel += np.einsum("kij,kj->ki", c, np.cross(gyro, r))
    return lla, vel


def align(rec: Recording, alignment: Alignment) -> Section:
    """Put ``rec`` on the IMU clock since its epoch and move its truth to the IMU (see
    the module docstring)."""
    rec, epoch = since_epoch(rec)
    truth_time = alignment.gt_clock(rec.gt_time)
    lla, vel = rec.gt_lla.copy(), rec.gt_vel.copy()
    if len(lla):
        w = _interp(truth_time, rec.imu_time, rec.imu[:, 3:6])
        lla, vel = moved_point(lla, vel, rec.gt_rpy, alignment.imu_lever_arm, w)
    return Section(
        name=rec.name,
        imu_time=rec.imu_time,
        imu=rec.imu,
        dvl_time=alignment.dvl_clock(rec.dvl_time),
        dvl=rec.dvl,
        truth_time=truth_time,
        truth_lla=lla,
        truth_vel=vel,
        truth_rpy=rec.gt_rpy,
        alignment=alignment,
        epoch=epoch,
        dvl_skipped_time=alignment.dvl_clock(rec.dvl_skipped_time),
        dvl_skipped_reason=rec.dvl_skipped_reason,
        dvl_variance=rec.dvl_variance,
        depth=None if rec.depth is None else rec.depth.on_clock(alignment.aiding_clock),
        fixes=None if rec.fixes is None else rec.fixes.on_clock(alignment.aiding_clock),
        heading=None if rec.heading is None else rec.heading.on_clock(alignment.aiding_clock),
    )


# ------------------------------------------------------------------------ sections

#: Recorded-data layouts :func:`load_section` reads (``bag``: ROS bags,
#: :mod:`pronet.recorded.bags`, with the topics of a :class:`~pronet.recorded.bags.BagTopics`).
FORMATS = ("snapir", "generic", "bag")
#: A format's name, or a bag's topics and frames (the ``bag`` format).
Format = str | BagTopics
#: The clocks the depth and fixes may be stamped on (:func:`load_section`).
AIDING_CLOCKS = ("imu", "dvl", "gt")


def find_sections(data: str | Path) -> list[Path]:
    """The sections under ``data``: sub-folders holding an ``imu.csv[.gz]``, ``.npz``
    files and ROS bags (:func:`pronet.recorded.bags.is_bag`), sorted by name; ``data``
    itself if it is one section (a folder of CSVs, one ``.npz`` file, one bag)."""
    from pronet.recorded.recordings import RecordingError

    data = Path(data)
    if (data.suffix == ".npz" and data.is_file()) or is_bag(data):
        return [data]
    if not data.is_dir():
        raise RecordingError(
            f"{data}: not a folder" + ("" if data.exists() else " (it does not exist)")
        )

    def is_section(p: Path) -> bool:
        return p.is_dir() and any((p / n).is_file() for n in ("imu.csv", "imu.csv.gz"))

    if is_section(data):
        return [data]
    found = sorted(p for p in data.iterdir() if is_section(p) or p.suffix == ".npz" or is_bag(p))
    if not found:
        raise RecordingError(
            f"{data}: no sections (folders with imu/dvl/gt CSVs, .npz files or ROS bags)"
        )
    return found


def section_name(path: Path) -> str:
    """The name of the section at ``path`` (from :func:`find_sections`): a folder's
    name, an ``.npz`` or ``.bag`` file's stem."""
    return path.stem if path.suffix in (".npz", ".bag") else path.name


def load_section(
    path: Path,
    fmt: Format,
    *,
    imu_lever_arm: tuple[float, float, float],
    dvl_lever_arm: tuple[float, float, float] | None,
    handle_alignment: bool = True,
    aiding_clock: str = "imu",
    declination: float | None = None,
    dvl_clock: Clock | None = None,
    read_heading: bool = True,
) -> tuple[Section, Section]:
    """Read one section and return it ``(aligned, as_stamped)``: clocks estimated and
    lever arms applied, and the stamps as given with no lever arms (the comparison).
    The ground truth is optional (:attr:`Section.has_truth`; without one no clock is
    estimated: :func:`estimate_alignment`, the DVL's ``dvl_clock`` when given, counted
    from the epoch).
    ``dvl_lever_arm`` None: the recording must have no DVL reading (ValueError naming
    the file otherwise).
    ``fmt``: one of :data:`FORMATS`, or a bag's :class:`~pronet.recorded.bags.BagTopics`
    (``"bag"``: the default topics). ``aiding_clock`` (:data:`AIDING_CLOCKS`): the
    clock the depth and fixes are stamped on, the IMU's (their stamps as given) or the
    estimated clock of the DVL or of the ground truth (one logger stamping both); the
    DVL's only for a recording with DVL readings, the ground truth's only for one with a
    ground truth (ValueError naming the file otherwise). ``declination``: the magnetic
    declination [deg, east positive] of a magnetic heading, ``read_heading`` False: no
    heading read (:func:`pronet.recorded.recordings.read_recording`)."""
    if aiding_clock not in AIDING_CLOCKS:
        raise ValueError(
            f"aiding_clock: expected one of {', '.join(AIDING_CLOCKS)}, got {aiding_clock!r}"
        )
    from pronet.recorded.recordings import RecordingError, read_recording, read_snapir

    if is_bag(path) and not (isinstance(fmt, BagTopics) or fmt == "bag"):
        raise RecordingError(f"{path}: a ROS bag; read it with --format bag (format {fmt})")
    if isinstance(fmt, BagTopics) or fmt == "bag":
        topics = fmt if isinstance(fmt, BagTopics) else BagTopics()
        rec = read_recording(path, topics, declination=declination, read_heading=read_heading)
    elif fmt not in FORMATS:
        raise ValueError(f"format: expected one of {', '.join(FORMATS)}, got {fmt!r}")
    else:
        rec = (
            read_snapir(path)
            if fmt == "snapir"
            else read_recording(path, declination=declination, read_heading=read_heading)
        )
    if dvl_lever_arm is None:
        if len(rec.dvl):
            raise ValueError(
                f"{path}: has DVL readings: needs the DVL's lever arm (--dvl-lever-arm, or "
                "dvl_lever_arm in --filter): its position from the ground-truth point [m, "
                "body FRD]; give 0,0,0 for a truth at the DVL, or leave the DVL out (--no-dvl)"
            )
        dvl_lever_arm = (0.0, 0.0, 0.0)  # never used: no DVL reading
    if aiding_clock == "dvl" and not len(rec.dvl):
        raise ValueError(
            f"aiding_clock 'dvl' (--aiding-clock dvl): {path} has no DVL reading, so no "
            "DVL clock to put its depth and fixes on; use 'imu' or 'gt'"
        )
    if aiding_clock == "gt" and not rec.has_truth:
        raise ValueError(
            f"aiding_clock 'gt' (--aiding-clock gt): {path} has no ground truth, so no "
            "truth clock to put its depth, fixes and heading on; use 'imu' or 'dvl'"
        )
    stamped = align(
        rec,
        Alignment(
            how="none",  # every clock the identity: the stamps as given
            gt_clock_how="given" if rec.has_truth else "none",
            dvl_clock_how="given" if len(rec.dvl) else "none",
        ),
    )
    if not handle_alignment:
        return stamped, stamped
    alignment = estimate_alignment(rec, imu_lever_arm, dvl_lever_arm, dvl_clock)
    if aiding_clock != "imu":
        clock = alignment.dvl_clock if aiding_clock == "dvl" else alignment.gt_clock
        alignment = replace(alignment, aiding_clock=clock)
    return align(rec, alignment), stamped


def load_snapir_sections(data: str | Path) -> list[tuple[Section, Section]]:
    """Every Snapir section under ``data``, ``(aligned, as_stamped)`` each, with the
    lever arms from the data's README."""
    return [
        load_section(
            p, "snapir", imu_lever_arm=SNAPIR_IMU_LEVER_ARM, dvl_lever_arm=SNAPIR_DVL_LEVER_ARM
        )
        for p in find_sections(data)
    ]


def select_sections(data: str | Path, names: list[str] | tuple[str, ...] | None) -> list[Path]:
    """The sections under ``data`` (:func:`find_sections`), only those
    whose folder or file name, or name without suffix, is in ``names`` when given."""
    paths = find_sections(data)
    if names:
        wanted = {n.strip() for n in names}
        known = {p.name for p in paths} | {p.stem for p in paths}
        unknown = sorted(wanted - known)
        if unknown:  # a misspelt name must not silently drop its section
            raise ValueError(
                f"--sections: no section named {', '.join(unknown)} in {data}; there are "
                f"{', '.join(p.name for p in paths)}"
            )
        paths = [p for p in paths if p.name in wanted or p.stem in wanted]
    return paths
