"""Summary statistics over Monte Carlo runs (means with 95 % confidence intervals) and
what a filter pass says about itself (its health).

A mean's interval is Student's t interval unless that would leave the quantity's range
(an RMS below zero, a share above one, as a t-interval over two runs can): then it is
the percentile bootstrap of the mean (:data:`BOOTSTRAP` resamples, a fixed seed), which
never leaves the range of the values themselves. ``MeanCI.method`` says which.

A pass's health (:func:`pass_health`): per stream, how many readings it applied, gated
out or skipped and whether their normalised innovations (NIS) agree with the σ the
stream was given; per pass, whether the solution left physical bounds and whether its
heading σ left the range where the position's linearization holds. One line per
finding, naming the stream, the figure and its likely causes.

A consistent filter's NIS of a reading is χ² with the reading's degrees of freedom
(3 for a velocity, 1 for a depth or a heading, 2 or 3 for a fix without or with its
height). The mean over a stream's ``n`` readings of ``d`` degrees of freedom each then
lies, 95 % of the time, in the band of χ²(n·d)/n (:func:`chi2_mean_band`).
A mean above the band says the readings disagree with the filter more than their σ
allow (a σ too small, wrong units or frame, a lever arm left out, a bad clock); below
it, that their σ are too large (a placeholder covariance such as 99999 taken as R). A
gate that rejects more than a few readings is named too: a threshold given as a
probability where a χ² value belongs rejects them all."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy import special

from pronet import _core
from pronet._util.validate import count, real_array
from pronet._util.whiteness import WHITENESS_FLAG as WHITENESS_FLAG
from pronet._util.whiteness import axis_whiteness, whiteness_clause
from pronet._util.whiteness import whiteness as whiteness

#: Resamples of a percentile-bootstrap interval.
BOOTSTRAP = 2000
#: The range of a quantity that has none.
UNBOUNDED = (-math.inf, math.inf)
#: The range of a non-negative quantity (an RMS, an error, a NEES).
NON_NEGATIVE = (0.0, math.inf)
#: The range of a share.
SHARE = (0.0, 1.0)


def t_quantile_975(df: int) -> float:
    """97.5 % quantile of Student's t with ``df`` degrees of freedom (``scipy.special``'s
    inverse of its CDF, as ``scipy.stats.t.ppf``; e.g. 12.706 for df = 1, 2.262 for
    df = 9, 1.984 for df = 99)."""
    if count(df, "df") < 1:
        raise ValueError(f"df: must be >= 1, got {df}")
    # beyond 2**53 the quantile equals the normal one to float64 resolution
    return float(special.stdtrit(min(df, 2**53), 0.975))


def chi2_mean_band(dof: int, runs: int) -> tuple[float, float]:
    """The 95 % band of the mean over ``runs`` independent χ² values of ``dof`` degrees
    of freedom (a consistent filter's mean NEES or NIS at one epoch): the 2.5 % and
    97.5 % quantiles of χ²(runs·dof)/runs (``scipy.special``'s inverse of the χ²
    survival function)."""
    if count(dof, "dof") < 1 or count(runs, "runs") < 1:
        raise ValueError(f"dof and runs: must be >= 1, got {dof} and {runs}")
    nu = dof * runs
    return float(special.chdtri(nu, 0.975)) / runs, float(special.chdtri(nu, 0.025)) / runs


#: How a table prints a statistic that is undefined (a mean NIS without an update, an
#: R² of equal labels, a mean over no finite value): never as a number.
UNDEFINED = "undefined"


def format_number(value: float, spec: str = "{:.4f}") -> str:
    """``value`` formatted by ``spec``, or :data:`UNDEFINED` if it is NaN or infinite."""
    return spec.format(value) if math.isfinite(value) else UNDEFINED


@dataclass(frozen=True)
class MeanCI:
    """Mean of the finite values with its 95 % confidence interval: ``method`` ``"t"``
    (Student's t), ``"bootstrap"`` (percentile bootstrap, where a t-interval would leave
    the quantity's range) or ``"none"`` (fewer than two values: the bounds are NaN)."""

    mean: float
    low: float
    high: float
    n: int
    method: str = "t"

    def __str__(self) -> str:
        """``mean [low, high]``; an undefined mean or interval printed as such."""
        if not math.isfinite(self.mean):
            return UNDEFINED
        if not (math.isfinite(self.low) and math.isfinite(self.high)):
            return f"{self.mean:.4f} [CI {UNDEFINED}]"
        return f"{self.mean:.4f} [{self.low:.4f}, {self.high:.4f}]"


def mean_ci(values: ArrayLike, within: tuple[float, float] = UNBOUNDED) -> MeanCI:
    """Mean and 95 % CI of ``values`` over runs (NaN, e.g. failed runs, left out), for a
    quantity whose values lie ``within`` (low, high): the t-interval, or the percentile
    bootstrap where the t-interval would leave that range (see the module)."""
    x = real_array(values, "values").astype(np.float64)
    x = x[np.isfinite(x)]
    n = int(x.size)
    if n == 0:
        return MeanCI(math.nan, math.nan, math.nan, 0, "none")
    # Scaled by a power of two (exact, so ordinary values give the same bits) to keep
    # sums and squares of values near the float64 limit from overflowing.
    e = int(np.frexp(np.abs(x).max())[1])
    y = np.ldexp(x, -e)
    m = float(np.ldexp(y.mean(), e))
    if n == 1:
        return MeanCI(m, math.nan, math.nan, 1, "none")
    with np.errstate(over="ignore"):  # a half-width beyond float64 is inf
        half = float(np.ldexp(t_quantile_975(n - 1) * float(y.std(ddof=1)) / math.sqrt(n), e))
    if within[0] <= m - half and m + half <= within[1]:
        return MeanCI(m, m - half, m + half, n)
    return _bootstrap_ci(x, m)


def _bootstrap_ci(x: np.ndarray, mean: float) -> MeanCI:
    """The percentile-bootstrap 95 % CI of the mean of ``x`` (at least two values;
    ``scipy.stats.bootstrap``, :data:`BOOTSTRAP` resamples, a fixed seed): its bounds
    lie within ``[min(x), max(x)]``, so within any range the values respect."""
    # here, not with the package: scipy.stats takes 0.35 s and 46 MiB to import, and
    # only a table's interval at a quantity's edge reads it
    import scipy.stats

    # scaled as mean_ci does, so that values near the float64 limit do not overflow
    e = int(np.frexp(np.abs(x).max())[1])
    res = scipy.stats.bootstrap(
        (np.ldexp(x, -e),),
        np.mean,
        n_resamples=BOOTSTRAP,
        method="percentile",
        rng=np.random.default_rng(20261204),  # fixed: a table reads the same every time
    )
    low = float(np.ldexp(res.confidence_interval.low, e))
    high = float(np.ldexp(res.confidence_interval.high, e))
    low, high = max(low, float(x.min())), min(high, float(x.max()))
    return MeanCI(mean, min(low, mean), max(high, mean), int(x.size), "bootstrap")


# A filter pass's health.

F64 = NDArray[np.float64]

#: The degrees of freedom of one reading of each kind (a fix's: 3, or 2 without height).
DOF = {"velocity": 3, "depth": 1, "heading": 1, "fix": 3}

#: What a mean NIS above its band most often means, per kind of stream.
CAUSES_HIGH = {
    "velocity": "the DVL's σ too small, its lever arm or mounting wrong, or its frame "
    "(FRD read as FLU, a NED world read as ENU)",
    "depth": "the depth's σ too small, its units, the surface pressure or water density, "
    "or the depth sensor's lever arm",
    "fix": "the fixes' σ too small, their datum or units (degrees for radians), the "
    "antenna's lever arm, a clock offset, or the initial position (lla0)",
    "heading": "the heading's σ too small, a magnetic heading without its declination, "
    "or degrees taken for radians",
}

#: Beyond these the solution has left what any vehicle pronet navigates can do: a speed
#: [m/s], a height [m, up] and a horizontal 1σ [m]. The core's (``pass::MAX_SPEED``
#: and so on), which watches them at every epoch.
MAX_SPEED: float = _core.MAX_SPEED
MAX_ABS_HEIGHT: float = _core.MAX_ABS_HEIGHT
MAX_POSITION_SIGMA: float = _core.MAX_POSITION_SIGMA
#: What the solution does past each bound, by the bound's name in :class:`Extent`, in
#: the order they are checked at an epoch.
BOUNDS = {
    "non-finite": "is not finite",
    "speed": f"moves faster than {MAX_SPEED:g} m/s",
    "height": f"is beyond ±{MAX_ABS_HEIGHT:g} m of height",
    "position-sigma": f"has a horizontal 1σ over {MAX_POSITION_SIGMA:g} m",
}
#: Past this heading 1σ [deg] a heading error is no longer small: the filter's position
#: error, linear in it, leaves out terms that on a track with a net drift grow with the
#: distance covered (docs/results/consistency.md, "A long MEMS mission without fixes"),
#: and the position σ can understate the error many times over. The core's
#: (``pass::MAX_LINEAR_HEADING_SIGMA_DEG``), which watches for it at every epoch.
MAX_LINEAR_HEADING_SIGMA_DEG: float = _core.MAX_LINEAR_HEADING_SIGMA_DEG


class StreamRows(Protocol):
    """What a pass kept of one stream's rows (a :class:`pronet.StreamResult`)."""

    @property
    def kind(self) -> str: ...
    @property
    def epoch(self) -> NDArray[np.int64]: ...
    @property
    def nis(self) -> F64: ...
    @property
    def accepted(self) -> NDArray[np.bool_] | None: ...


@dataclass(frozen=True)
class StreamReport:
    """What one pass made of one sensor stream.

    Attributes:
        name: the stream's name in messages (``"dvl"``, ``"streams[1]"``, …).
        kind: the :class:`pronet.StreamResult` kind (``"velocity"``, ``"depth"``,
            ``"fix"``, ``"heading"``).
        rows: readings in the recording.
        applied: readings applied as updates.
        rejected: readings the innovation gate rejected.
        skipped: readings not applied (missing values, outside the pass) by reason.
        mean_nis: mean NIS of the readings the filter predicted, the rejected ones too
            (NaN without any).
        dof: the NIS's degrees of freedom per reading (mean over those readings).
        band: the 95 % band of ``mean_nis`` for a filter consistent with the stream's σ
            (χ² of ``dof × k`` degrees of freedom divided by ``k``, the ``k`` readings
            the mean is over).
        time: ``(r,)`` times [s] of the readings.
        nis: ``(r,)`` each reading's NIS, a rejected reading's too (NaN outside the
            pass).
        flag: one line when the mean NIS is out of band or the gate rejected more than
            1 % (what it suggests), else "".
        accepted: ``(r,)`` whether each reading was applied (False where the gate
            rejected it or it fell outside the pass); None: every reading inside the
            pass was (a stream without a gate).
        autocorrelation: a velocity stream's whiteness test (:func:`whiteness`): the
            lag-one autocorrelation of its whitened innovations (NaN for the other
            kinds, which keep no innovation, or with fewer than two readings).
        autocorrelation_band: the half-width of its 95 % band for white innovations.
        axis_autocorrelation: the same test per axis, each innovation over its own σ
            (:func:`pronet._util.whiteness.axis_whiteness`; empty without innovations).
        axis_autocorrelation_band: its 95 % band's half-width, √(axes) times the vector's.
    """

    name: str
    kind: str
    rows: int
    applied: int
    rejected: int
    skipped: Mapping[str, int]
    mean_nis: float
    dof: float
    band: tuple[float, float]
    time: F64
    nis: F64
    flag: str = ""
    accepted: NDArray[np.bool_] | None = None
    autocorrelation: float = math.nan
    autocorrelation_band: float = math.nan
    axis_autocorrelation: tuple[float, ...] = ()
    axis_autocorrelation_band: float = math.nan

    @property
    def gated_share(self) -> float:
        """The share of the readings inside the pass the gate rejected (NaN: none)."""
        seen = self.applied + self.rejected
        return self.rejected / seen if seen else math.nan

    @property
    def skipped_share(self) -> float:
        """The share of the stream's readings never applied (missing, outside the pass)."""
        return sum(self.skipped.values()) / self.rows if self.rows else math.nan


@dataclass(frozen=True)
class PassHealth:
    """What a pass says about itself: each stream's report and whether it diverged.

    Attributes:
        streams: one :class:`StreamReport` per stream, in the pass's order.
        divergence: one line where the solution left physical bounds, else "".
        heading: one line where the heading 1σ grew past
            :data:`MAX_LINEAR_HEADING_SIGMA_DEG`, else "" (:func:`heading_linearity`).
    """

    streams: tuple[StreamReport, ...] = ()
    divergence: str = ""
    heading: str = ""

    @property
    def flags(self) -> tuple[str, ...]:
        """Every finding, one line each: the divergence first, then the heading's, then
        the streams'."""
        lines = [self.divergence, self.heading] + [s.flag for s in self.streams]
        return tuple(line for line in lines if line)


def _dof(rows: StreamRows, lla: F64 | None) -> F64:
    """Each row's degrees of freedom (a fix's from its height: 2 where NaN)."""
    d = np.full(len(rows.nis), float(DOF[rows.kind]))
    if rows.kind == "fix" and lla is not None:
        d[np.isnan(np.asarray(lla)[:, 2])] = 2.0
    return d


def stream_report(
    name: str,
    rows: StreamRows,
    time: F64,
    *,
    lla: F64 | None = None,
    skipped: Mapping[str, int] | None = None,
) -> StreamReport:
    """The report of one stream of a pass: ``rows`` what the pass kept of the stream
    whose readings were at ``time`` [s] (``lla``: a fix stream's rows, for each row's
    degrees of freedom), ``skipped`` the readings left out before the pass, by reason."""
    nis = np.asarray(rows.nis, dtype=np.float64)
    inside = np.asarray(rows.epoch) >= 0
    applied = inside & np.isfinite(nis)
    rejected = 0
    if rows.accepted is not None:
        rejected = int(np.sum(inside & ~rows.accepted))
        applied &= rows.accepted
    skipped = dict(skipped or {})
    outside = int(np.sum(~inside))
    if outside:
        skipped["outside the pass"] = skipped.get("outside the pass", 0) + outside
    n = int(applied.sum())
    # The mean over every reading the filter predicted, the gate's rejected ones too:
    # a gate cuts off the tail a consistent stream's mean needs.
    seen = inside & np.isfinite(nis)
    total = int(round(_dof(rows, lla)[seen].sum()))
    mean, mean_dof, band = _mean_nis(rows.kind, float(nis[seen].sum()), total, int(seen.sum()))
    rho, half, axes, axes_half, said = math.nan, math.nan, np.empty(0), math.nan, ""
    innovation = getattr(rows, "innovation", None)
    cov = getattr(rows, "innovation_cov", None)
    if innovation is not None and cov is not None:
        innovation, cov = np.asarray(innovation), np.asarray(cov)
        rho, half = whiteness(innovation, cov, applied)
        axes, axes_half = axis_whiteness(innovation, cov, applied)
        said = whiteness_clause(rho, half, axes, axes_half)
    empty = len(nis) == 0 and not any(skipped.values())  # no DVL, or --no-dvl: nothing to say
    flag = "" if empty else _flag(name, rows.kind, mean, mean_dof, band, rejected, n)
    if flag and mean > band[1]:
        flag += _outlier(np.where(seen, nis, 0.0), np.asarray(time), band, rows)
    if said:  # beyond 4σ of white innovations, the vector's or an axis's
        flag = f"{flag}; {said}" if flag else f"{name}: {said}"
    return StreamReport(
        name=name,
        kind=rows.kind,
        rows=len(nis) + sum(v for k, v in skipped.items() if k != "outside the pass"),
        applied=n,
        rejected=rejected,
        skipped=skipped,
        mean_nis=mean,
        dof=mean_dof,
        band=band,
        time=np.asarray(time, dtype=np.float64),
        nis=np.where(inside, nis, np.nan),
        flag=flag,
        accepted=None if rows.accepted is None else inside & rows.accepted,
        autocorrelation=rho,
        autocorrelation_band=half,
        axis_autocorrelation=tuple(float(v) for v in axes),
        axis_autocorrelation_band=axes_half,
    )


def _outlier(nis: F64, time: F64, band: tuple[float, float], rows: StreamRows) -> str:
    """The clause naming one reading (not the first, which meets the initial error) that
    holds over half of ``nis`` (0 where not seen; five or more seen), else ""."""
    r, seen = int(np.argmax(nis)), int(np.count_nonzero(nis))
    if seen < 5 or r == int(np.argmax(nis > 0)) or not nis[r] > 0.5 * nis.sum():
        return ""
    rest = (nis.sum() - nis[r]) / (seen - 1)
    within = "within" if band[0] <= rest <= band[1] else "outside"
    when = f"at {float(time[r]):.10g} s" if r < len(time) else f"row {r}"
    if rows.accepted is not None and not rows.accepted[r]:
        left = "which the stream's gate rejected"
    elif rows.accepted is not None:
        left = "which a gate (the stream's `gate`, a χ² bound on the NIS) would reject"
    else:
        left = f"and {rows.kind} readings have no gate: leave it out of the stream"
    return (
        f"; one reading, {when}, holds {nis[r] / nis.sum():.0%} of it (NIS {nis[r]:.3g}; "
        f"without it the mean is {rest:.3g}, {within} the band): an outlier, {left}"
    )


def _mean_nis(
    kind: str, nis_sum: float, dof: int, seen: int
) -> tuple[float, float, tuple[float, float]]:
    """The mean NIS of ``seen`` readings of ``kind`` (their NIS summed, ``dof``
    components in all), its degrees of freedom per reading and its 95 % band."""
    if not seen:
        return math.nan, float(DOF[kind]), (math.nan, math.nan)
    lo, hi = chi2_mean_band(1, dof)
    per_reading = dof / seen
    return nis_sum / seen, per_reading, (lo * per_reading, hi * per_reading)


def tally_flag(name: str, kind: str, nis_sum: float, dof: int, accepted: int, rejected: int) -> str:
    """:func:`stream_report`'s line for a stream known by its counts only (an online
    navigator's tally): its readings' mean NIS against its band (``nis_sum`` over the
    ``accepted`` and ``rejected`` ones, ``dof`` components in all) and its gate's
    rejections; "" where it has nothing to say."""
    mean, mean_dof, band = _mean_nis(kind, nis_sum, dof, accepted + rejected)
    return _flag(name, kind, mean, mean_dof, band, rejected, accepted)


def _flag(
    name: str,
    kind: str,
    mean: float,
    dof: float,
    band: tuple[float, float],
    rejected: int,
    n: int,
) -> str:
    """One line when the stream's mean NIS is out of its band or the gate rejected more
    than a few readings; empty otherwise."""
    if n == 0 and rejected == 0:
        return f"{name}: no reading applied"
    lo, hi = band
    seen = n + rejected  # the readings the mean is over
    per_dof = f"{mean / dof:.3g} per degree of freedom"
    if rejected > 0.5 * seen:
        return (
            f"{name}: the innovation gate rejected {rejected} of {seen} readings: a gate "
            f"too tight (a χ² value belongs there, not a probability) or readings that "
            f"disagree with the filter (mean NIS {mean:.3g}, {per_dof}); check "
            f"{CAUSES_HIGH[kind]}"
        )
    if mean > hi:
        return (
            f"{name}: mean NIS {mean:.3g} ({per_dof}) above its 95 % band [{lo:.3g}, "
            f"{hi:.3g}] over {seen} readings: the readings disagree with the filter more "
            f"than their σ allow; check {CAUSES_HIGH[kind]}"
        )
    if mean < lo:
        return (
            f"{name}: mean NIS {mean:.3g} ({per_dof}) below its 95 % band [{lo:.3g}, "
            f"{hi:.3g}] over {seen} readings: their σ are larger than the readings' "
            "scatter (a placeholder covariance taken as R?)"
        )
    if rejected > 0.01 * seen:
        return f"{name}: the innovation gate rejected {rejected} of {seen} readings"
    return ""


def divergence(extent: Extent) -> str:
    """One line where the solution left a physical bound (:data:`BOUNDS`), naming when
    it first did; "" where it did not. ``extent``: the core's, watched at every epoch
    of the pass, kept or not; or :meth:`Extent.of` the kept epochs."""
    if not extent.out_of_bounds:
        return ""
    return (
        f"the pass diverged: its solution {BOUNDS[extent.out_of_bounds]} from t = "
        f"{extent.out_of_bounds_at:.6g} s: check the IMU's units and frame (FRD, m/s², "
        "rad/s), the initial state, the streams' σ and the process noise"
    )


def heading_linearity(extent: Extent) -> str:
    """One line where the heading 1σ passed :data:`MAX_LINEAR_HEADING_SIGMA_DEG`, naming
    when it first did; "" where it did not (NaN σ, not computed, never does).
    ``extent``: the core's, watched at every epoch of the pass, kept or not; or
    :meth:`Extent.of` the kept epochs, which a thinned output tells late, and one kept
    at its last epoch only not at all where the σ fell back since."""
    if not extent.heading2 > math.radians(MAX_LINEAR_HEADING_SIGMA_DEG) ** 2:
        return ""
    return (
        f"the heading's 1σ reached {math.degrees(math.sqrt(extent.heading2)):.3g}° (over "
        f"{MAX_LINEAR_HEADING_SIGMA_DEG:g}° from t = {extent.heading_over:.6g} s): the "
        "position σ, linear in it, understates the error along a drifting track unless the "
        "filter carries the second-order heading term (heading_second_order=True); aid "
        "the heading (a compass, fixes) to keep it small"
    )


@dataclass(frozen=True)
class Extent:
    """What a pass's :func:`divergence` and :func:`heading_linearity` are told from:
    the first epoch whose solution left a bound of :data:`BOUNDS` (the bound's name, ""
    where none did, and the epoch's time [s], NaN), the largest heading variance
    σ_ψD² [rad²] (NaN σ, not computed, skipped; NaN where every σ is) and the time [s]
    its 1σ first passed :data:`MAX_LINEAR_HEADING_SIGMA_DEG` (NaN where it did not; with
    a covariance step, the core names the close of the step it passed in).

    The core's (``pronet._core.run_filter``'s ``extent``) is watched at every epoch of
    the pass, kept or not: the solution after the epoch's updates, the covariance
    wherever P stood (after the updates where it is up to date, and at each close of a
    covariance step before them; a kept σ inside a step is interpolated between these,
    so it is never larger). :meth:`of` reads the kept epochs."""

    out_of_bounds: str
    out_of_bounds_at: float
    heading2: float
    heading_over: float

    @classmethod
    def of(cls, lla: F64, vel: F64, sigma: F64, time: F64) -> Extent:
        """The extent of the epochs ``lla`` ``(n, 3)``, ``vel`` ``(n, 3)`` and ``sigma``
        ``(n, 15)`` at ``time`` ``(n,)`` [s], by whole-array reductions."""
        with np.errstate(over="ignore", invalid="ignore"):
            masks = (
                ~np.isfinite(lla).all(axis=1) | ~np.isfinite(vel).all(axis=1),
                np.einsum("ij,ij->i", vel, vel) > MAX_SPEED**2,
                np.abs(lla[:, 2]) > MAX_ABS_HEIGHT,
                sigma[:, 0] ** 2 + sigma[:, 1] ** 2 > MAX_POSITION_SIGMA**2,
            )
            heading2 = sigma[:, 8] ** 2
            over = np.flatnonzero(heading2 > math.radians(MAX_LINEAR_HEADING_SIGMA_DEG) ** 2)
        # the first epoch, and at it the first bound in order
        broken = min(((int(np.argmax(m)), i) for i, m in enumerate(masks) if m.any()), default=None)
        return cls(
            "" if broken is None else list(BOUNDS)[broken[1]],
            math.nan if broken is None else float(time[broken[0]]),
            float(np.fmax.reduce(heading2)) if len(heading2) else math.nan,
            float(time[over[0]]) if len(over) else math.nan,
        )


@dataclass(frozen=True)
class StreamSource:
    """A stream as :func:`pass_health` reads it: its name, its readings' times [s] and,
    for a fix stream, its rows (their heights give each reading's degrees of freedom)."""

    name: str
    time: F64
    lla: F64 | None = None
    skipped: Mapping[str, int] = field(default_factory=dict)


def pass_health(
    streams: Sequence[StreamRows],
    sources: Sequence[StreamSource],
    *,
    lla: F64,
    vel: F64,
    sigma: F64,
    time: F64,
    extent: Extent | None = None,
) -> PassHealth:
    """The health of a pass: one :func:`stream_report` per stream (``streams`` the
    pass's rows, ``sources`` their names and times, in order), its :func:`divergence`
    and its :func:`heading_linearity`, told by ``extent`` (the core's, watched at every
    epoch), else by :meth:`Extent.of` the kept epochs ``lla``, ``vel``, ``sigma``,
    ``time``."""
    extent = extent or Extent.of(lla, vel, sigma, time)
    return PassHealth(
        stream_reports(streams, sources),
        divergence(extent),
        heading_linearity(extent),
    )


def stream_reports(
    streams: Sequence[StreamRows], sources: Sequence[StreamSource]
) -> tuple[StreamReport, ...]:
    """One :func:`stream_report` per stream of a pass (``streams`` its rows,
    ``sources`` their names and times, in order)."""
    if len(streams) != len(sources):
        raise ValueError(
            f"sources: one per stream of the pass ({len(streams)}), got {len(sources)}"
        )
    return tuple(
        stream_report(src.name, rows, src.time, lla=src.lla, skipped=src.skipped)
        for rows, src in zip(streams, sources, strict=True)
    )


class FilterHealthWarning(UserWarning):
    """A pass's finding (:attr:`PassHealth.flags`): a stream out of its NIS band, a gate
    that rejected most of its readings, innovations far from white, or a diverged
    solution."""


#: A stream's name in messages by the kind of its readings.
KIND_NAMES = {"velocity": "dvl", "depth": "depth", "fix": "fix", "heading": "heading"}


def sources_of(
    streams: Sequence[_core.Dvl | _core.Depth | _core.Fix | _core.Heading], kinds: Sequence[str]
) -> list[StreamSource]:
    """The :class:`StreamSource` of each of a pass's streams (``pronet.Dvl``, ``Depth``,
    ``Fix``, ``Heading`` with their rows; ``kinds`` their readings' kinds), named
    ``streams[i] (dvl)`` and so on."""
    out = []
    for i, (s, kind) in enumerate(zip(streams, kinds, strict=True)):
        name = f"streams[{i}] ({KIND_NAMES.get(kind, kind)})"
        lla = getattr(s, "lla", None) if kind == "fix" else None
        out.append(StreamSource(name, np.asarray(s.time), lla=lla))
    return out


def warn_about(health: PassHealth, where: str = "run_filter") -> None:
    """One :class:`FilterHealthWarning` per line of ``health``'s findings."""
    import warnings

    for line in health.flags:
        warnings.warn(f"{where}: {line}", FilterHealthWarning, stacklevel=3)
