"""Every strategy on recorded sections: filter runs, metrics against the ground truth,
plots and the result folder of ``pronet real`` (its tables: :mod:`pronet.recorded.tables`).

Each run starts from the ground truth (moved to the IMU) at its first row inside the
IMU record, with the filter tuning of :func:`pronet.recorded.tuning.real_filter_config`, and
the process noise of each strategy built around q estimated from the section's own IMU
(:func:`pronet.recorded.tuning.white_noise_q`). Metrics are taken at the ground-truth rows
after the start (:mod:`pronet.recorded.metrics`): velocity SRMSE and SMAE, final and maximum
horizontal position error, and the final error as a percentage of the distance. One
section's passes are :mod:`pronet.recorded.passes`'.
"""

from __future__ import annotations

import threading
import warnings
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from pronet import _core
from pronet._util.cores import usable_cores
from pronet._util.plausibility import PlausibilityWarning
from pronet._util.validate import seconds as seconds_arg
from pronet._util.waiting import results_in_order
from pronet.filter import FilterResult
from pronet.recorded.aiding import AidingTuning
from pronet.recorded.aidingtables import aiding_record
from pronet.recorded.alignment import (
    AIDING_CLOCKS,
    Format,
    Section,
    select_sections,
)
from pronet.recorded.dvlnoise import MatchedVariance, match_innovations, second_difference_variance
from pronet.recorded.dvltruth import TruthCalibration, truth_calibration
from pronet.recorded.figures import FigurePool
from pronet.recorded.heading import check_declination
from pronet.recorded.passes import (
    NOT_ISOLATED,
    STOP,
    evaluate_section,
    failure_reason,
    run_section,
    section_recorded,
)
from pronet.recorded.reading import read_sections
from pronet.recorded.runs import RealRuns, SectionDvlNoise, SectionRun
from pronet.recorded.tables import (
    STAMPED,
    failed_records,
    real_config,
    real_tables,
    write_metrics,
)
from pronet.recorded.tuning import (
    BOTH,
    DVL_CALIBRATION,
    R_FROM_DATA,
    REAL_VARIANT_ROWS,
    check_dvl_noise,
    imu_step,
    real_filter_config,
    real_strategies,
    white_noise_q,
)
from pronet.recorded.vehicle import VehicleTuning, lever_arms
from pronet.run import check_acts, run
from pronet.strategies import StrategyLike

if TYPE_CHECKING:  # torch loads only when a net is trained or run through torch
    from pronet.learn.models import Regressor


def estimate_dvl_noise(
    section: Section,
    strategy: StrategyLike,
    lever_arm: tuple[float, float, float],
    formulation: str | None = None,
    base: _core.FilterConfig | None = None,
    covariance_step: float | None = None,
) -> SectionDvlNoise:
    """The DVL noise of ``section``: its second-difference R, then the R that matches
    the innovations of ``strategy`` under :func:`real_filter_config`, without and with
    the calibration states (a pass per step of
    :func:`pronet.recorded.dvlnoise.match_innovations`); ``base``, ``covariance_step``:
    the vehicle's own tuning and the covariance step (:func:`real_filter_config`)."""
    imu_dt = imu_step(section.imu_time)

    def matched(calibration: bool, first: tuple[float, float, float]) -> MatchedVariance:
        def one_pass(r: tuple[float, float, float]) -> FilterResult:
            config = real_filter_config(
                lever_arm, r, calibration, formulation, imu_dt, base, covariance_step
            )
            # the matching reads the updates only: no epoch arrays, no metrics
            return run(strategy, section_recorded(section, config, epochs="last")).result

        return match_innovations(one_pass, first)

    try:
        start = second_difference_variance(section.dvl)
        without = matched(False, start)
        # With the states, R comes out close to the R without them: start from there.
        return SectionDvlNoise(start, without, matched(True, without.variance))
    except ValueError as exc:
        raise ValueError(f"section {section.name}: DVL noise: {exc}") from None


@dataclass(frozen=True)
class SectionPlan:
    """What runs on one section: the strategy rows with ``config``, and the first
    strategy with each of ``variants``' configs (:data:`REAL_VARIANT_ROWS`).

    Attributes:
        q: the section's IMU noise (:func:`white_noise_q`).
        dvl_noise: the section's DVL noise estimates, or why they could not be made
            (then the section has no variant rows).
        dvl_variance: the R of the strategy rows [(m/s)²] (the datasheet's or the data's).
        base: the vehicle's own tuning the configs were made from (None: the FOG
            defaults of :func:`real_filter_config`).
        not_run: the strategy rows left out because they could never act on the
            section (:func:`pronet.run.check_acts`), with the reason.
    """

    q: tuple[float, ...]
    strategies: dict[str, StrategyLike]
    config: _core.FilterConfig
    variants: dict[str, _core.FilterConfig]
    dvl_noise: SectionDvlNoise | str
    dvl_variance: tuple[float, float, float]
    base: _core.FilterConfig | None = None
    not_run: dict[str, str] = field(default_factory=dict)


def plan_section(
    section: Section,
    models: Mapping[str, Regressor],
    tuning_period: float,
    dvl_noise: str = "datasheet",
    formulation: str | None = None,
    base: _core.FilterConfig | None = None,
    covariance_step: float | None = None,
) -> SectionPlan:
    """The rows of ``section`` (:class:`SectionPlan`): :func:`real_strategies` around its
    estimated q, the DVL noise of ``dvl_noise`` (``"datasheet"`` or ``"data"``), and the
    variant rows, every filter in ``formulation`` (default ``FilterConfig``'s or
    ``base``'s), at the section's IMU step (:func:`imu_step`), tuned as ``base`` (None: the
    FOG defaults of :func:`real_filter_config`; R the section's own where it has one, a
    bag's), with ``covariance_step`` [s] (None: ``base``'s, else every IMU sample)."""
    check_dvl_noise(dvl_noise)
    q = white_noise_q(section.imu)
    strategies = real_strategies(q, models, tuning_period)
    arm = section.alignment.filter_lever_arm
    dt = imu_step(section.imu_time)

    def config(
        r: tuple[float, float, float] | None = None, calibration: bool = False
    ) -> _core.FilterConfig:
        r = r or section.dvl_variance  # a bag's covariance, else as tuned
        return real_filter_config(arm, r, calibration, formulation, dt, base, covariance_step)

    r = config().dvl_variance
    datasheet = (r[0], r[1], r[2])
    # a row that could never act on this section (a window longer than its DVL
    # updates, a tuning period beyond it) is left out and reported, not run as its prior
    recorded = section_recorded(section, config())
    not_run: dict[str, str] = {}
    for label, chosen in list(strategies.items())[1:]:  # the first, constant, always acts
        try:
            check_acts(chosen, recorded)
        except ValueError as exc:
            not_run[label] = str(exc)
            del strategies[label]
    try:
        if not len(section.dvl):
            raise ValueError("the section has no DVL readings")
        first = next(iter(strategies.values()))
        noise = estimate_dvl_noise(section, first, arm, formulation, base, covariance_step)
    except ValueError as exc:
        if dvl_noise == "data":  # the strategy rows need it
            raise
        # The strategy rows do not: they run, the variant rows are left out.
        return SectionPlan(q, strategies, config(), {}, str(exc), datasheet, base, not_run)
    used = noise.matched.variance if dvl_noise == "data" else datasheet
    both = noise.matched_calibrated.variance
    variants = {
        R_FROM_DATA: config(noise.matched.variance),
        DVL_CALIBRATION: config(calibration=True),
        BOTH: config(both, calibration=True),
    }
    return SectionPlan(q, strategies, config(used), variants, noise, used, base, not_run)


# ------------------------------------------------------------------------ pronet real


def run_sections(
    sections: list[tuple[Section, Section]],
    models: Mapping[str, Regressor],
    tuning_period: float,
    on_done: Callable[[str], None] | None = None,
    threads: int | None = None,
    failed: Mapping[str, str] | None = None,
    dvl_noise: str = "datasheet",
    on_section: Callable[[Section, list[SectionRun], dict[str, tuple[float, ...]]], None]
    | None = None,
    formulation: str | None = None,
    base: _core.FilterConfig | None = None,
    covariance_step: float | None = None,
    smooth: bool = False,
    thin: bool = False,
) -> RealRuns:
    """The rows of :func:`plan_section` on each aligned section (with its own estimated
    q and DVL noise from ``dvl_noise``), the first one on the section as stamped, and
    the inertial run, every filter in ``formulation`` (default ``FilterConfig``'s)
    with ``covariance_step``, each strategy row followed by its smoothed one with
    ``smooth`` (:func:`pronet.recorded.passes.smoothed_run`);
    ``on_done("<section>: <strategy>")`` after each strategy. Sections run side by side
    on ``threads`` threads (default: one per core this process may use; each filter is
    one native call without the GIL), and the results do not depend on it. ``thin``:
    each row's result kept at the epochs the tables and figures read only
    (:func:`pronet.recorded.runs.kept_for_tables`; the same metrics, bounded memory).

    ``on_section(aligned, runs, constants)`` is called (on the section's thread) as
    soon as a section's strategy rows are done, with the q of its constant rows (the
    figures start from it).

    A row whose pass raises (a numerical failure: the core gives its time; or any other
    ``Exception``, e.g. a user's model's, named with its type) is left out and its reason
    kept in :attr:`RealRuns.rows_failed`; the section's other rows still run (a smoothed
    row failing alone keeps its filter's row). A section that raises otherwise, none of
    whose strategy rows ran, or whose ``on_section`` raised (``"on_section: <type>:
    <message>"``), is left out and its reason kept in :attr:`RealRuns.failed` (after
    ``failed``: the sections that could not even be read); the others still run. Only
    :data:`~pronet.recorded.passes.NOT_ISOLATED` ends the run. Raises ValueError naming
    the section when none is left.
    """
    workers = threads if threads is not None else usable_cores()
    lock = threading.Lock()

    def done(text: str) -> None:
        if on_done is not None:
            with lock:
                on_done(text)

    def one(pair: tuple[Section, Section]) -> _SectionRuns | str:
        STOP.set(stop)  # this thread's context: its run_section calls see the event
        try:
            plan = plan_section(
                pair[0], models, tuning_period, dvl_noise, formulation, base, covariance_step
            )
            ran = _run_one_section(pair[0], pair[1], plan, done, smooth, thin)
        except NOT_ISOLATED:
            raise
        except Exception as exc:  # the reason, kept beside the section's name
            return failure_reason(exc)
        if on_section is not None:
            try:
                on_section(pair[0], ran.runs, ran.constants)
            except NOT_ISOLATED:
                raise
            except Exception as exc:  # the caller's hook: this section fails, not the run
                return f"on_section: {failure_reason(exc)}"
        return ran

    stop = threading.Event()
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        try:  # waited for in slices, so that a signal another thread took is seen at once
            outcomes = list(results_in_order([pool.submit(one, pair) for pair in sections]))
        except BaseException:  # Ctrl-C, SIGTERM, an error: the threads stop at their next pass
            stop.set()
            raise
    reasons = dict(failed or {})
    ran: list[tuple[tuple[Section, Section], _SectionRuns]] = []
    for pair, outcome in zip(sections, outcomes, strict=True):
        if isinstance(outcome, str):
            reasons[pair[0].name] = outcome
        else:
            ran.append((pair, outcome))
    if not ran:
        raise ValueError(_no_section_left(reasons))
    parts = [p for _, p in ran]
    return RealRuns(
        [pair for pair, _ in ran],
        [r for p in parts for r in p.runs],
        [p.stamped for p in parts if p.stamped is not None],
        [p.inertial for p in parts if p.inertial is not None],
        {a.name: p.q for (a, _), p in ran},
        {a.name: p.constants for (a, _), p in ran},
        reasons,
        {a.name: (p.plan.dvl_noise, p.plan.dvl_variance) for (a, _), p in ran},
        {a.name: p.truth_calibration for (a, _), p in ran},
        {a.name: p.plan.config.imu_dt for (a, _), p in ran},
        {a.name: p.plan.not_run for (a, _), p in ran if p.plan.not_run},
        {a.name: p.rows_failed for (a, _), p in ran if p.rows_failed},
    )


def _no_section_left(reasons: Mapping[str, str]) -> str:
    """The error when every section failed: the first one's reason, and how many more."""
    if not reasons:
        return "no sections to run"
    name, reason = next(iter(reasons.items()))
    more = f" (and {len(reasons) - 1} more sections failed)" if len(reasons) > 1 else ""
    # a reason raised by the section's own pass already names it: not twice
    return f"section {name}: {reason.removeprefix(f'section {name}: ')}{more}"


@dataclass(frozen=True)
class _SectionRuns:
    plan: SectionPlan
    constants: dict[str, tuple[float, ...]]
    runs: list[SectionRun]
    stamped: SectionRun | None
    inertial: SectionRun | None
    truth_calibration: TruthCalibration | str
    rows_failed: dict[str, str]

    @property
    def q(self) -> tuple[float, ...]:
        return self.plan.q


def _run_one_section(
    aligned: Section,
    stamped: Section,
    plan: SectionPlan,
    on_done: Callable[[str], None],
    smooth: bool = False,
    thin: bool = False,
) -> _SectionRuns:
    """One section's rows, each failing alone (its reason kept by label); ValueError
    when none of its strategy rows ran."""
    constants = {
        label: tuple(s.q)
        for label, s in plan.strategies.items()
        if isinstance(s, _core.Strategy) and s.kind == "constant"
    }
    failed: dict[str, str] = {}
    section_runs, inertial_run = evaluate_section(
        aligned,
        plan.strategies,
        plan.config,
        variants=plan.variants,
        on_done=lambda label: on_done(f"{aligned.name}: {label}"),
        smooth=smooth,
        failed=failed,
        thin=thin,
    )
    if not section_runs:
        label, reason = next(iter(failed.items()))
        raise ValueError(f"every strategy row failed; the first, {label}: {reason}")
    first_label, first = next(iter(plan.strategies.items()))
    label = f"{first_label}, {STAMPED}"
    config = real_filter_config(
        stamped.alignment.filter_lever_arm,
        plan.dvl_variance,
        formulation=plan.config.formulation,
        imu_dt=plan.config.imu_dt,
        base=plan.base,
        covariance_step=plan.config.covariance_step,
    )
    stamped_run: SectionRun | None = None
    try:
        stamped_run = run_section(stamped, first, config, label=label, setup=STAMPED)
    except NOT_ISOLATED:
        raise
    except Exception as exc:  # a row like the others: failed alone
        failed[label] = failure_reason(exc)
    try:
        truth: TruthCalibration | str = truth_calibration(aligned)
    except ValueError as exc:  # a section too short or too slow: the reason, in config.json
        truth = str(exc)
    return _SectionRuns(plan, constants, section_runs, stamped_run, inertial_run, truth, failed)


def run_real(
    data: str | Path,
    out: str | Path | None = None,
    *,
    fmt: Format = "snapir",
    sections: list[str] | tuple[str, ...] | None = None,
    imu_lever_arm: tuple[float, float, float] | None = None,
    dvl_lever_arm: tuple[float, float, float] | None = None,
    tuning_period: float = 1.0,
    use_models: bool = True,
    models: Sequence[str] = (),
    plots: bool = True,
    dvl_noise: str = "datasheet",
    formulation: str | None = None,
    covariance_step: float | None = None,
    vehicle: VehicleTuning | None = None,
    smooth: bool = False,
    use_depth: bool = True,
    use_fixes: bool = True,
    use_dvl: bool = True,
    aiding_clock: str = "imu",
    use_heading: bool = True,
    declination: float | None = None,
    on_start: Callable[[int, str, str | None], None] | None = None,
    on_done: Callable[[str], None] | None = None,
) -> Path:
    """Every strategy on the recorded sections under ``data`` (read where they lie, never
    copied), written as one result folder (``table.md``, ``metrics.csv``/``.json``,
    ``config.json``, plots per section); returns the folder. Every section is read and
    checked before any filter runs. A section that cannot be read or filtered is left
    out and reported (``table.md``'s "Sections not run", ``failure`` in
    ``metrics.csv``, ``failed_sections`` in ``config.json``); the others still run.
    Raises ValueError, naming the section, when no section can be run.

    Args:
        out: the result folder to create (default ``results/real-<time>``).
        fmt: one of :data:`pronet.recorded.alignment.FORMATS`.
        sections: only these section names.
        imu_lever_arm: the IMU's position from the ground-truth point [m, body FRD];
            default: ``vehicle``'s, else with ``fmt="snapir"`` the Snapir AUV's; the
            generic format has no default (ValueError: a recording of another vehicle
            with Snapir's arms would run silently wrong; give ``(0, 0, 0)`` for a
            truth at the sensors).
        dvl_lever_arm: the DVL's position, the same way. It is needed only where the
            DVL readings are used: not for a recording without them, nor with
            ``use_dvl=False`` (a section with DVL readings and no DVL arm is left out,
            with the reason).
        tuning_period: seconds between regressor calls in the learned rows (> 0).
        use_models: False: only the model-based rows.
        models: model files (paths) run as rows ``learned:PATH`` beside the others,
            e.g. a Q model trained on recorded missions (``pronet train --recorded``,
            docs/how-to/learning-q.md); each read and checked before any section is.
        plots: False: no plots (the tables and metrics only). The figures are drawn
            in worker processes (:class:`pronet.recorded.figures.FigurePool`) while the other
            sections are filtered; on the Snapir data they add about half to the run
            time (9.4 s against 6.3 s on 2 cores). A figure that cannot be drawn is
            left out, its error in ``config.json``'s ``figures_failed`` (by section
            and file); the tables and the other figures are written.
        dvl_noise: the DVL noise R of the strategy rows, one of
            :data:`pronet.recorded.dvlnoise.DVL_NOISE_SOURCES`: ``"datasheet"``
            (:data:`pronet.recorded.tuning.REAL_DVL_VARIANCE`) or ``"data"`` (each section's
            innovation-matched R, :func:`estimate_dvl_noise`). Either way the table has
            the variant rows and reports each section's R.
        formulation: the filter's error coordinates, ``"invariant"`` (the default) or
            ``"classic"`` (the attitude-error coordinates of the first filter), for
            every row (default: ``vehicle``'s, else ``FilterConfig``'s).
        covariance_step: the filters' covariance step [s] for every row (default:
            ``vehicle``'s, else ``FilterConfig``'s 0.1 s; 0: every IMU sample).
        smooth: also the RTS smoother over every strategy row: each is followed by its
            smoothed row (``"<label>, smoothed"``), its metrics taken at the same
            ground-truth rows (docs/reference/smoother.md, "The RTS smoother").
        use_depth: False ignores the sections' depth readings
            (:mod:`pronet.recorded.aiding`; ``--no-depth``), e.g. to compare the DVL
            alone with the aided filter. Used, they aid every row (the inertial sanity
            run aside), their σ the file's, else ``vehicle``'s ``depth_sigma``, else
            the default of that module.
        use_fixes: the same for the position fixes (``--no-fixes``; ``fix_sigma``).
        use_dvl: False ignores the sections' DVL (``--no-dvl``): a GNSS/INS or
            depth-and-fix run of a recording that has one.
        use_heading: False ignores the sections' heading readings (``--no-heading``;
            a heading table, or a bag's ``--heading-topic``, then not read;
            :mod:`pronet.recorded.heading`).
            Used, they aid every row as the depth and fixes do, their σ the recording's,
            else ``vehicle``'s ``heading_sigma`` (no default: refused without one).
        declination: the magnetic declination [deg, east positive] of a magnetic
            heading (``--declination``; default ``vehicle``'s ``declination``).
        aiding_clock: the clock of the depth and fixes' stamps, ``"imu"`` (as given),
            ``"dvl"`` or ``"gt"`` (that stream's estimated clock; ``--aiding-clock``).
        vehicle: the vehicle's own tuning (``--filter``,
            :func:`pronet.recorded.vehicle.load_vehicle`): P0, bias walks, DVL R,
            aiding, gate, formulation and lever arms; default the FOG tuning of
            :func:`real_filter_config`.
        on_start: the progress callback told a stage's start (see
            :mod:`pronet._util.outputs`): stages ``reading, aligning`` (a step per
            section), the runs (a step per section and strategy) and ``plots`` (a step
            per section).
        on_done: the callback told each step done.
    """
    from pronet._util.files import atomic_folder, json_bytes
    from pronet._util.outputs import new_result_folder
    from pronet.learn.frozen import SHIPPED, load_frozen
    from pronet.learn.qmodels import load_model_file

    folder = new_result_folder(out, "real")
    seconds_arg(tuning_period, "--tuning-period")
    check_dvl_noise(dvl_noise)
    if aiding_clock not in AIDING_CLOCKS:
        choices = ", ".join(AIDING_CLOCKS)
        raise ValueError(f"--aiding-clock: must be one of {choices}, got {aiding_clock!r}")
    base = None if vehicle is None else vehicle.base
    real_filter_config(  # checked now
        (0.0, 0.0, 0.0), formulation=formulation, base=base, covariance_step=covariance_step
    )
    imu_arm, dvl_arm = lever_arms(fmt, imu_lever_arm, dvl_lever_arm, vehicle)
    # Without its readings (and not its clock) the DVL's arm is never used: none needed.
    dvl_used = use_dvl or aiding_clock == "dvl"
    read_arm = (0.0, 0.0, 0.0) if dvl_arm is None and not dvl_used else dvl_arm
    aiding = AidingTuning(
        use_depth=use_depth, use_fixes=use_fixes, use_dvl=use_dvl, use_heading=use_heading
    )
    if vehicle is not None:
        aiding = vehicle.aiding(aiding)
        if (ignored := vehicle.navigate_only()) is not None:
            warnings.warn(ignored, PlausibilityWarning, stacklevel=2)
        declination = vehicle.declination if declination is None else declination
    check_declination(declination, "--declination")
    paths = select_sections(data, sections)
    # frozen in the core, loaded without torch
    regressors: dict[str, Regressor] = {k: load_frozen(k) for k in SHIPPED} if use_models else {}
    for model in models:  # a user's model files, each a row "learned:PATH"
        regressors[f"learned:{model}"] = load_model_file(model)
    if on_start is not None:
        on_start(len(paths), "section", "reading, aligning")
    loaded, unread = read_sections(
        paths, fmt, (imu_arm, read_arm), (aiding_clock, declination), aiding, on_done
    )
    if not loaded:  # nothing to run: the first reason, before any filter
        raise ValueError(_no_section_left(unread))
    if on_start is not None:
        n_rows = len(real_strategies((1.0,) * 6, regressors, 1.0)) + len(REAL_VARIANT_ROWS)
        on_start(len(loaded) * n_rows, "run", None)
    # the figures are drawn in worker processes as the sections finish
    with FigurePool() if plots else nullcontext(None) as figures:
        done = run_sections(
            loaded,
            regressors,
            tuning_period,
            on_done,
            failed=unread,
            dvl_noise=dvl_noise,
            on_section=None if figures is None else figures.submit_section,
            formulation=formulation,
            base=base,
            covariance_step=covariance_step,
            smooth=smooth,
            thin=True,  # what the folder holds is read from the tables' epochs
        )
        # the strategy rows' filter as the first section ran it (its IMU step)
        first_dt = next(iter(done.imu_dt.values()))
        tuning = real_filter_config(
            (0.0, 0.0, 0.0),
            formulation=formulation,
            imu_dt=first_dt,
            base=base,
            covariance_step=covariance_step,
        )
        config = real_config(
            data, fmt, tuning_period, (imu_arm, dvl_arm), dvl_noise, done, regressors, tuning
        )
        config["filter_file"] = None if vehicle is None else vehicle.source
        config["smooth"] = smooth
        config["aiding"] = {
            "clock": aiding_clock,
            **aiding_record(aiding, done),
            "declination_deg": declination,
        }
        with atomic_folder(folder) as tmp:
            runs = done.runs + done.stamped + done.inertial
            write_metrics(tmp, runs, real_tables(done), failed_records(done))
            not_drawn: dict[str, dict[str, Exception]] = {}
            if figures is not None:
                if on_start is not None:
                    on_start(len(done.sections), "section", "plots")
                not_drawn = figures.write(tmp, [a.name for a, _ in done.sections], on_done)
            config["figures_failed"] = {
                name: {file: str(error) for file, error in by.items()}
                for name, by in not_drawn.items()
            }  # after the figures: a figure failing leaves the rest of the folder
            (tmp / "config.json").write_bytes(json_bytes(config))
    return folder
