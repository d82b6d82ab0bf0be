"""One recorded section's filter passes: where a run starts (:func:`start_index`), its
sensors ready to filter (:func:`section_recorded`), one strategy's pass with its
metrics against the ground truth (:func:`run_section`) and the strategy rows with the
pure-inertial sanity run (:func:`evaluate_section`). :mod:`pronet.recorded.real`
runs them on every section of ``pronet real``.
"""

from __future__ import annotations

import contextvars
import dataclasses
import threading
from collections.abc import Callable, Mapping
from typing import Any, Literal

import numpy as np

from pronet import _core
from pronet._util.validate import flag, scalar
from pronet.recorded.aiding import AidingTuning, filter_aiding, tuned, tuned_heading
from pronet.recorded.alignment import Section, no_truth
from pronet.recorded.metrics import section_metrics
from pronet.recorded.runs import SectionRun, kept_for_tables
from pronet.run import Recorded, run
from pronet.strategies import StrategyLike


def start_index(section: Section) -> int:
    """The ground-truth row a run starts from: the first at or after the first IMU
    sample's time; a section without a ground truth is refused in one line."""
    if not section.has_truth:
        raise ValueError(no_truth(section.name))
    inside = np.flatnonzero(section.truth_time >= section.imu_time[0])
    if inside.size < 2:
        raise ValueError(f"section {section.name}: the ground truth does not overlap the IMU")
    return int(inside[0])


def aided_section(section: Section, tuning: AidingTuning) -> Section:
    """``section`` with its DVL, depth, fixes and heading as ``tuning`` has them (σ
    where the file has none, a stream ignored: ``use_dvl=False`` leaves no DVL row, used
    or skipped); ValueError when nothing is left to aid the IMU's position, or for a
    heading without σ (:func:`pronet.recorded.aiding.tuned_heading`)."""
    depth, fixes = tuned(section.depth, section.fixes, tuning)
    heading = tuned_heading(section.heading, tuning)
    if not tuning.use_dvl:
        empty = np.empty(0)
        section = dataclasses.replace(
            section,
            dvl=np.empty((0, 3)),
            dvl_time=empty,
            dvl_skipped_time=empty,
            dvl_skipped_reason=(),
            dvl_variance=None,
        )
    if not len(section.dvl) and depth is None and fixes is None:
        ignored = [
            flag
            for flag, stream, used in (
                ("--no-depth", section.depth, tuning.use_depth),
                ("--no-fixes", section.fixes, tuning.use_fixes),
                ("--no-dvl", True, tuning.use_dvl),
            )
            if stream is not None and not used
        ]
        why = f" (ignored: {', '.join(ignored)})" if ignored else ""
        raise ValueError(
            f"section {section.name}: no DVL reading, depth or position fix{why}: nothing "
            "aids the IMU"
        )
    return dataclasses.replace(section, depth=depth, fixes=fixes, heading=heading)


#: Set (to an event) on the threads of :func:`run_sections`: once the event is set,
#: each thread's next filter pass raises :class:`Stopped` instead of running, so that
#: Ctrl-C ends the sections within one pass (~0.05 s) instead of a whole section.
STOP: contextvars.ContextVar[threading.Event | None] = contextvars.ContextVar(
    "pronet_real_stop", default=None
)


class Stopped(Exception):
    """A section thread told to stop (the caller is already raising its own error)."""


#: What a row or section raising ends the whole run with instead of failing alone: the
#: stop of a Ctrl-C (:class:`Stopped`) and a refused allocation (``MemoryError``, the
#: CLI's one line "out of memory"). ``KeyboardInterrupt`` and ``SystemExit`` are no
#: ``Exception`` and are never caught.
NOT_ISOLATED: tuple[type[Exception], ...] = (Stopped, MemoryError)


def failure_reason(exc: Exception) -> str:
    """The one line a row or section that raised ``exc`` is reported with: a
    ``ValueError``'s message (the core's numerical failures give their time), any other
    exception's type and message (a user's model or estimator raising, or a bug: named,
    never silent)."""
    text = " ".join(str(exc).splitlines()).strip()
    if isinstance(exc, ValueError):
        return text
    name = type(exc).__name__
    return f"{name}: {text}" if text else name


def run_section(
    section: Section,
    strategy: StrategyLike,
    config: _core.FilterConfig,
    *,
    label: str = "",
    setup: str = "aligned",
    duration: float | None = None,
    use_dvl: bool = True,
    smooth: bool = False,
    aided: bool = True,
) -> SectionRun:
    """Run one strategy over ``section`` from the ground truth at :func:`start_index`,
    for ``duration`` seconds (default: to the end), with or without the DVL, with or
    without (``aided``) its depth, fixes and heading; with ``smooth``, the pass's result carries
    the smoothed solution (:func:`smoothed_run`)."""
    recorded = section_recorded(
        section, config, duration=duration, use_dvl=use_dvl, smooth=smooth, aided=aided
    )
    done = run(strategy, recorded)
    metrics = section_metrics(section, done.result, use_dvl)
    return SectionRun(
        setup,
        section.name,
        label,
        done.result,
        metrics,
        done.schedule,
        done.seconds,
        done.tuning_period,
        done.unfilled,
    )


def section_recorded(
    section: Section,
    config: _core.FilterConfig,
    *,
    duration: float | None = None,
    use_dvl: bool = True,
    epochs: Literal["all", "last"] = "all",
    smooth: bool = False,
    aided: bool = True,
) -> Recorded:
    """``section``'s sensors from the ground truth at :func:`start_index` on, for
    ``duration`` seconds (default: to the end), with or without the DVL, with or
    without (``aided``) its depth readings, position fixes and heading readings
    (:func:`pronet.recorded.aiding.filter_aiding`), ready to filter with ``config``
    (``epochs``: see :class:`pronet.run.Recorded`). Inside
    :func:`run_sections`, it stops the section's thread once the run is told to stop."""
    stop = STOP.get()
    if stop is not None and stop.is_set():
        raise Stopped
    if duration is not None and not scalar(duration, "duration") > 0:
        raise ValueError(f"duration: must be > 0 s, got {duration}")
    i0 = start_index(section)
    t0 = float(section.truth_time[i0])
    take = section.imu_time > t0
    if duration is not None:
        take &= section.imu_time <= t0 + float(duration)
        end = section.imu_time[take].max(initial=-np.inf)
        if not np.any((section.truth_time > t0) & (section.truth_time <= end)):
            raise ValueError(f"duration: {duration} s from the start reach no ground-truth row")
    keep = np.full(len(section.dvl), flag(use_dvl, "use_dvl"))
    return Recorded(
        imu=section.imu[take],
        imu_time=section.imu_time[take],
        dvl=section.dvl[keep],
        dvl_time=section.dvl_time[keep],
        t0=t0,
        lla0=section.truth_lla[i0],
        vel0=section.truth_vel[i0],
        rpy0=section.truth_rpy[i0],
        config=config,
        epochs=epochs,
        smooth=smooth,
        aiding=(
            filter_aiding(section.depth, section.fixes, section.heading)
            if flag(aided, "aided")
            else ()
        ),
    )


#: Seconds of the pure-inertial sanity run.
INERTIAL_SECONDS = 60.0


def evaluate_section(
    section: Section,
    strategies: Mapping[str, StrategyLike],
    config: _core.FilterConfig,
    *,
    variants: Mapping[str, _core.FilterConfig] | None = None,
    setup: str = "aligned",
    on_done: Callable[[str], None] | None = None,
    smooth: bool = False,
    failed: dict[str, str] | None = None,
    thin: bool = False,
) -> tuple[list[SectionRun], SectionRun | None]:
    """Every strategy on ``section`` with ``config``, the first strategy with each of
    ``variants``' configs (by row label), and the pure-inertial run over the first
    :data:`INERTIAL_SECONDS` with the first strategy's noise. With ``smooth``, each
    strategy and variant row is followed by its smoothed one (:func:`smoothed_run`; with
    the DVL calibration states all 19 are smoothed).

    ``failed``: None raises the first row's error (a ``ValueError`` for a numerical
    failure of the core, which gives its time). A dict isolates the rows instead: a row
    whose pass raises (any ``Exception`` but :data:`NOT_ISOLATED`) is left out and its
    :func:`failure_reason` kept there by label, the others still run (the inertial run
    then None if it failed); a smoothed pass that fails is run again without the
    smoother, so that only its smoothed row fails.

    ``thin``: each row's result is kept at the epochs the tables and figures read only
    (:func:`pronet.recorded.runs.kept_for_tables`: the same metrics, a fraction of the
    memory), once its smoothed row, if any, has been made."""
    first = next(iter(strategies.values()))
    rows = [(label, chosen, config) for label, chosen in strategies.items()]
    rows += [(label, first, cfg) for label, cfg in (variants or {}).items()]
    runs = []
    for label, chosen, cfg in rows:
        done = _row(section, (label, chosen, cfg), setup, smooth, failed)
        runs += [kept_for_tables(r, section) for r in done] if thin else done
        if on_done is not None:
            on_done(label)
    inertial = isolated_run(
        failed,
        section,
        first,
        config,
        label=f"inertial only, first {INERTIAL_SECONDS:g} s",
        setup=setup,
        duration=INERTIAL_SECONDS,
        use_dvl=False,
        aided=False,
    )
    return runs, inertial


def isolated_run(
    failed: dict[str, str] | None,
    section: Section,
    strategy: StrategyLike,
    config: _core.FilterConfig,
    **kwargs: Any,
) -> SectionRun | None:
    """:func:`run_section` (``kwargs`` its keywords); with ``failed`` a dict, None when it
    raises (any ``Exception`` but :data:`NOT_ISOLATED`), its :func:`failure_reason`
    kept in ``failed`` under the row's ``label``."""
    if failed is None:
        return run_section(section, strategy, config, **kwargs)
    try:
        return run_section(section, strategy, config, **kwargs)
    except NOT_ISOLATED:
        raise
    except Exception as exc:  # a user's model or estimator too: its type and message
        failed[kwargs.get("label", "")] = failure_reason(exc)
        return None


def _row(
    section: Section,
    row: tuple[str, StrategyLike, _core.FilterConfig],
    setup: str,
    smooth: bool,
    failed: dict[str, str] | None,
) -> list[SectionRun]:
    """One row of :func:`evaluate_section` (and its smoothed one): the runs it kept."""
    label, chosen, cfg = row
    reason = None
    if smooth:
        try:
            done = run_section(section, chosen, cfg, label=label, setup=setup, smooth=True)
            return [done, smoothed_run(section, done)]
        except NOT_ISOLATED:
            raise
        except Exception as exc:
            if failed is None:
                raise
            reason = failure_reason(exc)
    alone = isolated_run(failed, section, chosen, cfg, label=label, setup=setup)
    if failed is not None and reason is not None:  # after the row's own, if it failed too
        failed[f"{label}, {SMOOTHED}"] = reason
    return [] if alone is None else [alone]


#: The suffix of a smoothed row's label.
SMOOTHED = "smoothed"


def smoothed_run(section: Section, done: SectionRun) -> SectionRun:
    """The row of ``done``'s RTS-smoothed solution (``"<label>, smoothed"``): its
    result is the filter's with the smoothed position, velocity, attitude, biases, DVL
    calibration (with its states) and σ (updates, NIS and q the filter's), its metrics
    taken against the ground truth as the filter's are. ``ValueError`` if the pass was
    not smoothed."""
    s = done.result.smoothed
    if s is None:
        raise ValueError(f"{done.label}: the pass was run without smooth=True")
    result = dataclasses.replace(
        done.result,
        lla=s.lla,
        vel=s.vel,
        rpy=s.rpy,
        bias=s.bias,
        sigma=s.sigma,
        calibration=s.calibration,
        calibration_sigma=s.calibration_sigma,
        smoothed=None,
    )
    metrics = section_metrics(section, result, True)
    return dataclasses.replace(
        done, label=f"{done.label}, {SMOOTHED}", result=result, metrics=metrics
    )
