"""What a ``pronet real`` run produced, as plain records: one strategy on one section
(:class:`SectionRun`, and :func:`kept_for_tables`, it thinned to what the tables read),
a section's DVL noise estimates (:class:`SectionDvlNoise`) and every run of
:func:`pronet.recorded.real.run_real` (:class:`RealRuns`).

They live apart from the code that makes them so that the tables
(:mod:`pronet.recorded.tables`) and figures (:mod:`pronet.recorded.figures`) read them
without importing the run itself.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from pronet.filter import FilterResult
from pronet.learn.hybrid import QSchedule
from pronet.recorded.alignment import Section
from pronet.recorded.dvlnoise import MatchedVariance
from pronet.recorded.dvltruth import TruthCalibration
from pronet.recorded.metrics import SectionMetrics


@dataclass(frozen=True)
class SectionRun:
    """One strategy on one section: the filter output, its metrics and its q.

    ``setup`` names how the section was prepared (``"aligned"``: clocks estimated and
    lever arms applied; or the comparison without them); ``schedule`` is the learned
    rows' q; ``seconds`` the wall time of the run (inference included); ``unfilled``
    the line of a Mehra or adaptive window the pass never filled
    (:attr:`pronet.run.RecordedRun.unfilled`), else None."""

    setup: str
    section: str
    label: str
    result: FilterResult
    metrics: SectionMetrics
    schedule: QSchedule | None
    seconds: float
    tuning_period: float | None = None
    unfilled: str | None = None


def kept_for_tables(run: SectionRun, section: Section) -> SectionRun:
    """``run`` with its result thinned to the epochs the tables and figures of ``pronet
    real`` read, so that a section's rows do not each hold every epoch (300,000 epochs
    of a 25-minute 200 Hz recording are ~110 MB a row): the two epochs around each of
    ``section``'s truth rows (the metrics interpolate between them: the same numbers),
    every epoch a stream's row was applied at, the first and the last. The DVL gains
    (which no table reads) and a Q no row set (not a Mehra row) become read-only NaN
    views. Its :attr:`~pronet.filter.FilterResult.epoch` names the epochs kept; the
    smoothed solution is dropped (its row is a run of its own). A result already
    thinned is returned as it is."""
    r = run.result
    n = len(r.time)
    if r.epoch.size or n < 3:
        return run
    t = section.truth_time[(section.truth_time > r.time[0]) & (section.truth_time <= r.time[-1])]
    around = np.searchsorted(r.time, t)[:, None] + np.arange(-1, 1)  # np.interp's two
    applied = [r.dvl_epoch, r.depth_epoch, r.fix_epoch, r.covariance_epoch]
    applied += [s.epoch for s in r.streams]
    keep = np.unique(np.concatenate([around.ravel(), *applied, [0, n - 1]]).astype(np.int64))
    keep = keep[(keep >= 0) & (keep < n)]
    calibrated = len(r.calibration) == n
    thin = replace(
        r,
        time=r.time[keep],
        lla=r.lla[keep],
        vel=r.vel[keep],
        rpy=r.rpy[keep],
        bias=r.bias[keep],
        sigma=r.sigma[keep],
        calibration=r.calibration[keep] if calibrated else r.calibration,
        calibration_sigma=r.calibration_sigma[keep] if calibrated else r.calibration_sigma,
        epoch=keep,
        smoothed=None,
    )
    # Read-only NaN views in place of arrays no table reads: the gains, and a Q that no
    # row set (not a Mehra row).
    gain = np.broadcast_to(np.float64(np.nan), r.gain.shape)
    q = r.adaptive_q
    if q.size and np.isnan(q).all():
        q = np.broadcast_to(np.float64(np.nan), q.shape)
    streams = tuple(
        replace(s, gain=gain, adaptive_q=q) if s.gain is r.gain else s for s in r.streams
    )
    return replace(run, result=replace(thin, gain=gain, adaptive_q=q, streams=streams))


@dataclass(frozen=True)
class SectionDvlNoise:
    """The DVL noise of one section, per body axis [(m/s)²] (:mod:`pronet.recorded.dvlnoise`).

    Attributes:
        second_difference: from the DVL's own readings, filter-free.
        matched: innovation-matched for the constant (estimated q) filter, starting
            from ``second_difference``.
        matched_calibrated: the same with the DVL calibration states on, starting from
            ``matched``.
    """

    second_difference: tuple[float, float, float]
    matched: MatchedVariance
    matched_calibrated: MatchedVariance


@dataclass(frozen=True)
class RealRuns:
    """Every run of :func:`run_real`.

    Attributes:
        sections: ``(aligned, as_stamped)`` per section (see
            :func:`pronet.recorded.alignment.load_section`).
        runs: every strategy on every aligned section.
        stamped: the first strategy on each section as stamped, without lever arms.
        inertial: the pure-inertial sanity run of each section.
        q_estimated: per section, the IMU noise q of :func:`white_noise_q`.
        constants: per section, the q of each constant strategy (for the q plots).
        failed: per section that could not be read or filtered, the reason (one line);
            the other sections' runs are complete without it.
        dvl_noise: per section, the DVL noise estimates (or why there are none) and
            the R the strategy rows used ``(estimates, used)``.
        truth_calibration: per section, the DVL scale and mounting its ground truth
            implies without a filter (:func:`pronet.recorded.dvltruth.truth_calibration`), or why
            there is none.
        imu_dt: per section, the IMU's nominal step the filter used [s]
            (:func:`pronet.recorded.tuning.imu_step`).
        rows_not_run: per section that has any, the strategy rows left out because
            they could never act on it (a window longer than its DVL updates), with
            the reason.
        rows_failed: per section that has any, the rows whose pass failed (a
            numerical failure, with the time the core gives; any other exception, e.g.
            a user's model's, with its type), by label, with the reason; the section's
            other rows are complete without them, and ``stamped`` and ``inertial`` lack
            the section's where those failed.
    """

    sections: list[tuple[Section, Section]]
    runs: list[SectionRun]
    stamped: list[SectionRun]
    inertial: list[SectionRun]
    q_estimated: dict[str, tuple[float, ...]]
    constants: dict[str, dict[str, tuple[float, ...]]]
    failed: dict[str, str] = field(default_factory=dict)
    dvl_noise: dict[str, tuple[SectionDvlNoise | str, tuple[float, float, float]]] = field(
        default_factory=dict
    )
    truth_calibration: dict[str, TruthCalibration | str] = field(default_factory=dict)
    imu_dt: dict[str, float] = field(default_factory=dict)
    rows_not_run: dict[str, dict[str, str]] = field(default_factory=dict)
    rows_failed: dict[str, dict[str, str]] = field(default_factory=dict)

    @property
    def notes(self) -> list[str]:
        """What the filters said about themselves (:attr:`pronet.FilterResult.health`),
        one line per section and stream out of band, and per section whose heading σ
        passed 5°, the first row's finding with the rows that share it, and one per row
        whose solution diverged or whose Mehra or adaptive window was never filled (a
        constant-Q row under another name). Smoothed rows are their filter's."""
        found: dict[tuple[str, str], list[tuple[str, str]]] = {}
        rows: dict[str, int] = {}
        for run in self.runs:
            if run.label.endswith(", smoothed"):
                continue
            rows[run.section] = rows.get(run.section, 0) + 1
            health = run.result.health
            if health.divergence:
                found[(run.section, run.label)] = [(run.label, health.divergence)]
            if run.unfilled:
                found[(run.section, f"{run.label}: window")] = [(run.label, run.unfilled)]
            if health.heading:
                found.setdefault((run.section, "heading σ"), []).append((run.label, health.heading))
            for s in health.streams:
                if s.flag:
                    found.setdefault((run.section, s.name), []).append((run.label, s.flag))
        lines = []
        for (section, _), flagged in found.items():
            first, flag = flagged[0]
            share = f"{len(flagged)} of {rows[section]} rows: " + "; ".join(r for r, _ in flagged)
            lines.append(f"section {section}: {flag} (row {first}; {share})")
        return lines
