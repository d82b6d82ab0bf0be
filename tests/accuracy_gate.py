"""The accuracy gate: pinned accuracy and consistency figures, checked in both directions.

A developer tool beside the tests, not part of the package: ``tests/test_accuracy_gate.py``
runs it, and so can you::

    python tests/accuracy_gate.py            # check; exit 1 on any departure
    python tests/accuracy_gate.py --bless    # rewrite the JSON and the tables of
                                             # docs/results/accuracy.md

Each row (scenario × strategy) records velocity SRMSE and SMAE, final and maximum
horizontal position error, mean NIS, mean velocity NEES, the fraction of velocity
errors inside ±3σ, and two counts that must match exactly: the epochs scored and the
non-finite samples dropped. Rows cover the paper's seven rows on the ``paper`` and
``varying-noise`` scenarios, the study's rows (:data:`pronet.experiments.study.STUDY_ROWS`) on the
study scenarios, at :data:`GATE_RUNS` runs (seed 0), and, where the Snapir data is
present, its sections (the real-data rows with ``detvar`` and ``adaptive``).

:func:`compare` fails a row when a metric gets worse by more than
:data:`WORSE_TOLERANCE` (relative), and also when it gets *better* by more than
:data:`BETTER_TOLERANCE`: an improvement nobody recorded is one the next change can
silently undo. "Worse" means a larger error, or NIS/NEES and the ±3σ fraction farther
from their consistent values (3 and 0.9973). With fixed seeds on one machine the runs
repeat to floating-point noise (the Rust core is deterministic across thread counts;
the nets run in float32), so the tolerances are small.

Re-blessing (``--bless``) rewrites the file and the tables in ``docs/results/accuracy.md``; it
is legitimate only when a change is *meant* to move the numbers (a fixed bug, a better
discretization, a new scenario), and the commit says why.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections.abc import Callable, Collection, Mapping
from pathlib import Path

import numpy as np

from pronet._util.files import atomic_write
from pronet.results import between_markers

ROOT = Path(__file__).resolve().parents[1]
#: The pinned figures, and the page whose tables are generated from them.
FILE = ROOT / "tests" / "accuracy_baselines.json"
PAGE = ROOT / "docs" / "results" / "accuracy.md"
#: The Snapir data: ``$PRONET_SNAPIR_DIR``, else ``../shared/data/snapir`` beside the project.
SNAPIR = Path(os.environ.get("PRONET_SNAPIR_DIR", ROOT.parent / "shared" / "data" / "snapir"))

#: Monte Carlo runs per simulated row in the gate.
GATE_RUNS = 8
#: Relative change allowed in the worse direction (floating-point noise and float32
#: inference across machines), and in the better direction before it must be recorded.
WORSE_TOLERANCE = 1e-5
BETTER_TOLERANCE = 1e-3
#: Figures smaller than this [m, m/s or 1] are judged relative to it instead: the at-rest
#: row drifts by rounding noise (~1e-12), which floating-point reassociation may move.
ABSOLUTE_FLOOR = 1e-4
#: Metrics, each with its "badness": how far from ideal a value is.
METRICS: dict[str, Callable[[float], float]] = {
    "srmse": abs,
    "smae": abs,
    "final_horizontal": abs,
    "max_horizontal": abs,
    "mean_nis": lambda v: abs(v - 3.0),
    "mean_velocity_nees": lambda v: abs(v - 3.0),
    "inside_3sigma": lambda v: abs(v - 0.9973),
}
#: Counts that must match exactly.
COUNTS = ("n_scored", "n_dropped")

Row = dict[str, float | int]
Rows = dict[str, dict[str, Row]]  # scenario → strategy → metrics


def monte_carlo_row(result) -> Row:  # result: pronet.MonteCarloResult with histories
    """The gate's figures of one Monte Carlo (means over runs and epochs)."""
    if result.error is None or result.sigma is None:
        raise ValueError("result: needs error and sigma histories (record_every > 0)")
    nis, nees_v = result.nis, result.nees[:, :, 1]
    err, sig = result.error[:, :, 3:6], result.sigma[:, :, 3:6]
    finite = np.isfinite(err) & np.isfinite(sig)
    return {
        "srmse": _mean(result.srmse),
        "smae": _mean(result.smae),
        "final_horizontal": _mean(result.final_horizontal_error),
        "max_horizontal": _mean(result.max_horizontal_error),
        "mean_nis": _mean(nis),
        "mean_velocity_nees": _mean(nees_v),
        "inside_3sigma": float(np.mean(np.abs(err[finite]) <= 3 * sig[finite])),
        "n_scored": int(np.isfinite(nis).sum()),
        "n_dropped": int((~np.isfinite(nis)).sum() + (~np.isfinite(nees_v)).sum()),
    }


def section_row(section, run) -> Row:  # recorded.alignment.Section, recorded.runs.SectionRun
    """The gate's figures of one recorded-section run, at its ground-truth rows. The
    velocity NEES uses the filter's per-axis σ (the recorded diagonal)."""
    from pronet.recorded.metrics import estimate_at_truth

    r = run.result
    rows, _, vel = estimate_at_truth(section, r)
    dv = vel - section.truth_vel[rows]
    t = section.truth_time[rows]
    sig = np.stack([np.interp(t, r.time, r.sigma[:, 3 + j]) for j in range(3)], axis=1)
    m = run.metrics
    return {
        "srmse": m.srmse,
        "smae": m.smae,
        "final_horizontal": m.final_horizontal,
        "max_horizontal": m.max_horizontal,
        "mean_nis": m.mean_nis,
        "mean_velocity_nees": _mean(np.sum((dv / sig) ** 2, axis=1)),
        "inside_3sigma": float(np.mean(np.abs(dv) <= 3 * sig)),
        "n_scored": m.n_scored,
        "n_dropped": int((~np.isfinite(r.nis[r.dvl_epoch >= 0])).sum()),
    }


def _mean(values: np.ndarray) -> float:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else math.nan


def simulated_rows(
    n_runs: int = GATE_RUNS,
    seed: int = 0,
    *,
    scenarios: Collection[str] | None = None,
    strategies: Collection[str] | None = None,
) -> Rows:
    """The paper's rows on the paper's scenarios and the study's rows on the study's
    scenarios, with the shipped models; or only the named ``scenarios`` and strategy
    labels (a quick partial gate)."""
    from pronet import run
    from pronet.experiments import study
    from pronet.learn import models
    from pronet.sim import paper
    from pronet.sim.scenarios import PAPER_SCENARIOS, SCENARIOS

    unknown = set(scenarios or ()) - set(SCENARIOS)
    if unknown:
        known = list(SCENARIOS)
        raise ValueError(f"scenarios: unknown {sorted(unknown)}; known {known}")
    labels = [*paper.PAPER_ROWS, *study.STUDY_ROWS]
    unknown = set(strategies or ()) - set(labels)
    if unknown:
        raise ValueError(
            f"strategies: unknown {sorted(unknown)}; known {list(dict.fromkeys(labels))}"
        )
    regressors = {k: models.load(k) for k in models.SHIPPED}
    out: Rows = {}
    for name, build in SCENARIOS.items():
        if scenarios is not None and name not in scenarios:
            continue
        sc = build(seed)
        if name in PAPER_SCENARIOS:
            chosen = paper.paper_strategies(sc.q_nominal, regressors, 1.0)
        else:
            chosen = study.study_strategies(sc.q_nominal, regressors, 1.0)
        if strategies is not None:  # a label a scenario's rows do not have is skipped there
            chosen = {k: v for k, v in chosen.items() if k in strategies}
            if not chosen:
                continue
        rows = run.run_strategies(
            chosen, sc, n_runs=n_runs, seed=seed, threads=None, record_every=100
        )
        out[f"{name}, {n_runs} runs"] = {row.label: monte_carlo_row(row.result) for row in rows}
    return out


#: WGS-84 defining values and the Somigliana normal gravity, stated here independently
#: of the Rust core (``rust/src/earth.rs``) on purpose: the at-rest row checks the core's
#: physics against a separate statement of it. In the simulated scenarios the truth is
#: generated with the core's own constants, so a mistyped constant cancels there.
_WGS84_A = 6378137.0  # semi-major axis [m]
_WGS84_F = 1 / 298.257223563  # flattening
_WGS84_OMEGA = 7.292115e-5  # Earth rotation rate [rad/s]
_WGS84_GAMMA = (9.7803253359, 9.8321849378)  # normal gravity at equator, pole [m/s²]
#: The at-rest row: duration [s], IMU period [s], latitude [deg].
AT_REST = (600.0, 0.01, 32.0)


def at_rest_rows() -> Rows:
    """Free-inertial navigation of a level IMU at rest on the ellipsoid, heading north,
    from an ideal IMU computed here from :data:`_WGS84_OMEGA` and normal gravity:
    ``f_b = [0, 0, −γ(φ)]`` m/s², ``ω_b = Ω [cos φ, 0, −sin φ]`` rad/s (body = NED).
    Errors are the drift from the start point [m] and from zero velocity [m/s]; the
    NIS/NEES figures do not apply (NaN)."""
    from pronet.navigation import mechanize

    duration, dt, lat_deg = AT_REST
    lat = math.radians(lat_deg)
    s2 = math.sin(lat) ** 2
    e2 = _WGS84_F * (2 - _WGS84_F)
    g_e, g_p = _WGS84_GAMMA
    gamma = g_e * (1 + ((1 - _WGS84_F) * g_p / g_e - 1) * s2) / math.sqrt(1 - e2 * s2)
    n = round(duration / dt)
    imu = np.tile(
        [0.0, 0.0, -gamma, _WGS84_OMEGA * math.cos(lat), 0.0, -_WGS84_OMEGA * math.sin(lat)],
        (n, 1),
    )
    lla0 = np.array([lat, 0.6, 0.0])
    nav = mechanize(imu, dt, lla0, np.zeros(3), np.zeros(3))
    r_n = _WGS84_A * (1 - e2) / (1 - e2 * s2) ** 1.5
    r_e = _WGS84_A / math.sqrt(1 - e2 * s2)
    horizontal = np.hypot(
        (nav.lla[1:, 0] - lat) * r_n, (nav.lla[1:, 1] - lla0[1]) * r_e * math.cos(lat)
    )
    dv = nav.vel[1:]
    row: Row = {
        "srmse": float(np.sqrt(np.mean(np.sum(dv**2, axis=1)))),
        "smae": float(np.mean(np.sum(np.abs(dv), axis=1))),
        "final_horizontal": float(horizontal[-1]),
        "max_horizontal": float(horizontal.max()),
        "mean_nis": math.nan,
        "mean_velocity_nees": math.nan,
        "inside_3sigma": math.nan,
        "n_scored": n,
        "n_dropped": int((~np.isfinite(nav.vel)).sum()),
    }
    return {f"at rest, {lat_deg:g}° N, {duration:g} s": {"free inertial": row}}


#: How the rows of recorded sections are named: ``"real: <section>"``.
REAL_PREFIX = "real: "


def real_rows(loaded: list) -> Rows:
    """Every row of ``pronet real`` (:func:`pronet.recorded.real.plan_section`: the strategies
    and the variant rows) on each aligned recorded section (``loaded``: ``(aligned, _)``
    pairs from :func:`pronet.recorded.alignment.load_section`)."""
    from pronet.learn import models
    from pronet.recorded import real

    regressors = {k: models.load(k) for k in models.SHIPPED}
    out: Rows = {}
    for aligned, _ in loaded:
        plan = real.plan_section(aligned, regressors, 1.0)
        runs, _ = real.evaluate_section(
            aligned, plan.strategies, plan.config, variants=plan.variants
        )
        out[f"{REAL_PREFIX}{aligned.name}"] = {r.label: section_row(aligned, r) for r in runs}
    return out


def fresh_rows(recorded_data: str | Path | None = None) -> Rows:
    """Every row the gate checks: the at-rest row, both simulated scenarios, and the
    Snapir sections when ``recorded_data`` is a folder holding them."""
    from pronet.recorded import alignment

    rows = at_rest_rows()
    rows.update(simulated_rows())
    if recorded_data is not None and Path(recorded_data).is_dir():
        rows.update(real_rows(alignment.load_snapir_sections(Path(recorded_data))))
    return rows


def rows_to_bless(recorded: Rows, fresh: Rows) -> Rows:
    """What ``--bless`` writes: the ``fresh`` rows, plus the recorded real-data rows when
    ``fresh`` has none (a machine without the data must not drop the rows only a machine
    with it can make)."""
    if any(k.startswith(REAL_PREFIX) for k in fresh):
        return dict(fresh)
    kept = {k: v for k, v in recorded.items() if k.startswith(REAL_PREFIX)}
    return {**fresh, **kept}


def compare(recorded: Rows, fresh: Rows) -> list[str]:
    """Every way ``fresh`` departs from ``recorded`` beyond the tolerances (empty: pass).
    Rows recorded but not computed (no data here) are not compared; rows computed but
    not recorded are failures."""
    problems = []
    for scenario, rows in fresh.items():
        for label, new in rows.items():
            old = recorded.get(scenario, {}).get(label)
            where = f"{scenario} / {label}"
            if old is None:
                problems.append(f"{where}: not recorded; re-bless to add it")
                continue
            for key in COUNTS:
                if new[key] != old[key]:
                    problems.append(f"{where}: {key} {new[key]} != recorded {old[key]}")
            for key, badness in METRICS.items():
                a, b = float(old[key]), float(new[key])
                if math.isnan(a) and math.isnan(b):
                    continue
                if math.isnan(a) != math.isnan(b):
                    problems.append(f"{where}: {key} {b} against recorded {a}")
                    continue
                scale = max(abs(a), ABSOLUTE_FLOOR)
                change = (badness(b) - badness(a)) / scale
                if change > WORSE_TOLERANCE:
                    problems.append(
                        f"{where}: {key} worse: {b:.9g} against recorded {a:.9g} "
                        f"({100 * change:+.4f} % of it)"
                    )
                elif change < -BETTER_TOLERANCE:
                    problems.append(
                        f"{where}: {key} improved beyond {100 * BETTER_TOLERANCE:g} % without "
                        f"being recorded: {b:.9g} against {a:.9g}; re-bless if intended"
                    )
    return problems


def load(path: str | Path) -> Rows:
    """The recorded baselines (JSON)."""
    data = json.loads(Path(path).read_text())
    if data.get("format") != "pronet-accuracy-baselines" or data.get("version") != 1:
        raise ValueError(f"{path}: not a pronet accuracy-baselines file (version 1)")
    return data["rows"]


def save(path: str | Path, rows: Rows) -> Path:
    """Write ``rows`` as the baselines file, atomically."""
    path = Path(path)
    doc = {
        "format": "pronet-accuracy-baselines",
        "version": 1,
        "about": "pinned accuracy figures; regenerate with `python tests/accuracy_gate.py --bless`",
        "gate_runs": GATE_RUNS,
        "worse_tolerance": WORSE_TOLERANCE,
        "better_tolerance": BETTER_TOLERANCE,
        "rows": rows,
    }
    atomic_write(path, (json.dumps(doc, indent=1, allow_nan=True) + "\n").encode())
    return path


def bless(file: Path, page: Path, rows: Rows) -> None:
    """Rewrite the baselines ``file`` and the tables of ``page`` together: the page's new
    text is made before anything is written (a page without markers changes nothing),
    and the file is put back as it was if the page cannot be written."""
    page_text = page_with_tables(page.read_text(), rows).encode()
    before = file.read_bytes() if file.exists() else None
    save(file, rows)
    try:
        atomic_write(page, page_text)
    except BaseException:
        if before is None:
            file.unlink(missing_ok=True)
        else:
            atomic_write(file, before)
        raise


COLUMNS = (
    ("srmse", "SRMSE [m/s]", "{:.4f}"),
    ("smae", "SMAE [m/s]", "{:.4f}"),
    ("final_horizontal", "final horiz. [m]", "{:.2f}"),
    ("max_horizontal", "max horiz. [m]", "{:.2f}"),
    ("mean_nis", "mean NIS", "{:.2f}"),
    ("mean_velocity_nees", "mean vel. NEES", "{:.2f}"),
    ("inside_3sigma", "inside ±3σ", "{:.3f}"),
    ("n_scored", "epochs", "{}"),
    ("n_dropped", "non-finite", "{}"),
)


def _is_nan(value: float) -> bool:
    return isinstance(value, float) and math.isnan(value)


def markdown(rows: Mapping[str, Mapping[str, Row]]) -> str:
    """The accuracy tables of ``docs/results/accuracy.md``, generated from the baselines."""
    out = []
    for scenario, table in rows.items():
        out.append(f"#### {scenario}\n")
        out.append("| strategy | " + " | ".join(h for _, h, _ in COLUMNS) + " |")
        out.append("|---" * (len(COLUMNS) + 1) + "|")
        for label, row in table.items():
            cells = ["—" if _is_nan(row[key]) else fmt.format(row[key]) for key, _, fmt in COLUMNS]
            out.append(f"| {label} | " + " | ".join(cells) + " |")
        out.append("")
    return "\n".join(out)


BEGIN, END = "<!-- accuracy-baselines:begin -->", "<!-- accuracy-baselines:end -->"


def page_with_tables(page: str, rows: Rows) -> str:
    """``page`` (Markdown text) with the text between the baseline markers replaced by the
    tables."""
    return between_markers(page, "accuracy-baselines", markdown(rows))


def partial_rows(strategies: Collection[str]) -> Rows:
    """A quick partial gate: the at-rest row and the named strategy labels of both
    simulated scenarios (no recorded data)."""
    rows = at_rest_rows()
    rows.update(simulated_rows(strategies=strategies))
    return rows


def parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python tests/accuracy_gate.py",
        description="Check fresh runs against the pinned accuracy baselines (exit 1 on any "
        "departure), or rewrite the baselines and the tables of docs/results/accuracy.md "
        "(--bless).",
    )
    p.add_argument("--bless", action="store_true", help="rewrite the file and the page's tables")
    p.add_argument("--file", metavar="JSON", type=Path, default=FILE, help="baselines JSON")
    p.add_argument(
        "--page", metavar="MD", type=Path, default=PAGE, help="page whose tables to regenerate"
    )
    p.add_argument(
        "--data",
        metavar="DIR",
        type=Path,
        default=SNAPIR,
        help="Snapir data folder, used if present (default: $PRONET_SNAPIR_DIR, else "
        "../shared/data/snapir beside the project)",
    )
    p.add_argument(
        "--strategies",
        metavar="LABELS",
        help="comma-separated strategy labels: check only these on the simulated scenarios, "
        "plus the at-rest row, without recorded data (a quick partial gate; not with --bless)",
    )
    return p


def main(argv: list[str] | None = None) -> int:
    """Run the gate; 0 when nothing departs (or after --bless), 1 otherwise."""
    import pronet._core

    args = parser().parse_args(argv)
    if args.bless and args.strategies:
        parser().error("--bless rewrites every row; it takes no --strategies")
    start = time.perf_counter()
    print(f"native core: {pronet._core.__file__}")
    recorded = load(args.file) if args.file.exists() or not args.bless else {}
    if args.strategies:
        rows = partial_rows([s.strip() for s in args.strategies.split(",") if s.strip()])
    else:
        rows = fresh_rows(args.data)
        if not args.data.is_dir():
            print(
                f"no recorded data at {args.data}: simulated rows only (the recorded real rows "
                "are not compared, and --bless keeps them as they are)"
            )
    if args.bless:
        rows = rows_to_bless(recorded, rows)
        bless(args.file, args.page, rows)
        print(f"{args.file} and the tables in {args.page} rewritten from {len(rows)} scenarios")
        return 0
    problems = compare(recorded, rows)
    for problem in problems:
        print(problem)
    print(f"{len(problems)} departures from {args.file} ({time.perf_counter() - start:.0f} s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
