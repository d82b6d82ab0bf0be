"""What a pass says about each of its sensor streams: how many readings it applied,
rejected or skipped, and whether their normalised innovations (NIS) agree with the σ
the stream was given (:func:`stream_reports`); one line per stream that does not,
naming the figure and the likely causes.

A consistent filter's NIS of a reading is χ² with the reading's degrees of freedom
(3 for a velocity, 1 for a depth or a heading, 2 or 3 for a fix without or with its
height). The mean over a stream's ``n`` applied readings of ``d`` degrees of freedom
each then lies, 95 % of the time, in the band of χ²(n·d)/n
(:func:`pronet.stats.chi2_mean_band`). A mean above the band says the readings
disagree with the filter more than their σ allow (a σ too small, wrong units or frame,
a lever arm left out, a bad clock); below it, that their σ are too large.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

from pronet.filter import FilterResult, StreamResult
from pronet.recorded.solution import F64, StreamReport
from pronet.stats import chi2_mean_band

#: The degrees of freedom of one reading of each kind (a fix's: 3, or 2 without height).
DOF = {"velocity": 3, "depth": 1, "heading": 1, "fix": 3}

#: What a mean NIS above its band most often means, per kind of stream.
CAUSES_HIGH = {
    "velocity": "the DVL's σ too small, its lever arm or mounting wrong, or its frame",
    "depth": "the depth's σ too small, the surface pressure or water density, or the "
    "depth sensor's lever arm",
    "fix": "the fixes' σ too small, their datum or units, the antenna's lever arm, or a "
    "clock offset",
    "heading": "the heading's σ too small, a magnetic heading without its declination, "
    "or degrees taken for radians",
}


def _dof(result: StreamResult, lla: F64 | None) -> F64:
    """Each row's degrees of freedom (a fix's from its height: 2 where NaN)."""
    d = np.full(len(result.nis), float(DOF[result.kind]))
    if result.kind == "fix" and lla is not None:
        d[np.isnan(np.asarray(lla)[:, 2])] = 2.0
    return d


def stream_report(
    name: str,
    result: StreamResult,
    time: F64,
    *,
    lla: F64 | None = None,
    skipped: Mapping[str, int] | None = None,
) -> StreamReport:
    """The report of one stream of a pass: ``result`` is the pass's
    :class:`pronet.StreamResult` of the stream whose readings were at ``time`` [s]
    (``lla``: a fix stream's rows, for each row's degrees of freedom), ``skipped`` the
    readings left out before the pass, by reason."""
    nis = np.asarray(result.nis, dtype=np.float64)
    inside = result.epoch >= 0
    applied = inside & np.isfinite(nis)
    rejected = 0
    if result.accepted is not None:
        rejected = int(np.sum(inside & ~result.accepted))
        applied &= result.accepted
    skipped = dict(skipped or {})
    outside = int(np.sum(~inside))
    if outside:
        skipped["outside the pass"] = skipped.get("outside the pass", 0) + outside
    n = int(applied.sum())
    # The mean over every reading the filter predicted, the gate's rejected ones too:
    # a gate cuts off the tail a consistent stream's mean needs.
    seen = inside & np.isfinite(nis)
    dof = _dof(result, lla)[seen]
    if not seen.any():
        mean, mean_dof, band = math.nan, float(DOF[result.kind]), (math.nan, math.nan)
    else:
        mean, total = float(nis[seen].mean()), int(round(dof.sum()))
        mean_dof = total / int(seen.sum())
        lo, hi = chi2_mean_band(1, total)
        band = (lo * mean_dof, hi * mean_dof)
    return StreamReport(
        name=name,
        kind=result.kind,
        rows=len(nis) + sum(v for k, v in skipped.items() if k != "outside the pass"),
        applied=n,
        rejected=rejected,
        skipped=skipped,
        mean_nis=mean,
        dof=mean_dof,
        band=band,
        time=np.asarray(time, dtype=np.float64),
        nis=np.where(inside, nis, np.nan),
        flag=_flag(name, result.kind, mean, mean_dof, band, rejected, n),
        accepted=None if result.accepted is None else inside & result.accepted,
    )


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
    n += rejected  # the readings the mean is over
    per_dof = f"{mean / dof:.3g} per degree of freedom"
    if mean > hi:
        return (
            f"{name}: mean NIS {mean:.3g} ({per_dof}) above its 95 % band [{lo:.3g}, "
            f"{hi:.3g}] over {n} readings: the readings disagree with the filter more than "
            f"their σ allow; check {CAUSES_HIGH[kind]}"
        )
    if mean < lo:
        return (
            f"{name}: mean NIS {mean:.3g} ({per_dof}) below its 95 % band [{lo:.3g}, "
            f"{hi:.3g}] over {n} readings: their σ are larger than the readings' scatter"
        )
    if rejected > 0.01 * n:
        return f"{name}: the innovation gate rejected {rejected} of {n} readings"
    return ""


def stream_reports(
    result: FilterResult,
    names: Sequence[str],
    times: Sequence[F64],
    *,
    lla: Mapping[int, F64] | None = None,
    skipped: Mapping[int, Mapping[str, int]] | None = None,
) -> tuple[StreamReport, ...]:
    """One :func:`stream_report` per stream of ``result`` (in order), named ``names``,
    its readings at ``times``; ``lla`` and ``skipped`` by stream index."""
    if not (len(names) == len(times) == len(result.streams)):
        raise ValueError(
            f"names, times: one per stream of the pass ({len(result.streams)}), got "
            f"{len(names)} and {len(times)}"
        )
    lla, skipped = lla or {}, skipped or {}
    return tuple(
        stream_report(name, s, t, lla=lla.get(i), skipped=skipped.get(i))
        for i, (name, s, t) in enumerate(zip(names, result.streams, times, strict=True))
    )
