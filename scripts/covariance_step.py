"""The accuracy cost of the covariance step: every built-in scenario's
constant-Q Monte Carlo (and the ``paper`` scenario's with Mehra's ξ = 5 and the
adaptive strategy), and every strategy of ``pronet real`` on the Snapir sections,
at covariance steps of one IMU step (0: the filter as it always was), 0.05, 0.1, 0.2
and 0.5 s, with the same seeds and data at every step (so each difference is the
step's alone). About five minutes on two cores.

    python scripts/covariance_step.py              # rewrite the tables in the page
                                                   # docs/results/covariance-step.md
    python scripts/covariance_step.py --print      # print them instead
    python scripts/covariance_step.py --runs 20 --print   # a quicker look

The Snapir data is read from ``$PRONET_SNAPIR_DIR``, else ``../shared/data/snapir``
beside the checkout (never copied); without it the recorded table says so.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import pronet
from pronet import config
from pronet._util.files import atomic_write
from pronet.montecarlo import MonteCarloResult
from pronet.recorded.real import run_real
from pronet.results import between_markers, markdown
from pronet.sim.scenarios import SCENARIOS
from pronet.stats import mean_ci
from pronet.strategies import StrategySpec, strategy

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "results" / "covariance-step.md"
#: Covariance steps [s]; 0 is every IMU sample (0.01 s in every built-in scenario).
STEPS = (0.0, 0.05, 0.1, 0.2, 0.5)
RUNS = 100
#: The strategies of ``pronet real`` reported per step (means over the sections).
REAL_ROWS = (
    "constant (estimated q)",
    "adaptive",
    "mehra xi=5",
    "constant (estimated q), DVL calibration",
)
#: Scenario and strategy of each simulated row group.
SIMULATED = (
    *((name, "constant") for name in SCENARIOS),
    ("paper", "mehra:5"),
    ("paper", "adaptive"),
)
SIM_HEADER = (
    "scenario, strategy",
    "step",
    "SRMSE [m/s] (95 % CI)",
    "inside step-0 CI",
    "ΔSRMSE paired (95 % CI)",
    "final horiz. [m]",
    "vel. NEES (in band)",
    "att. NEES (in band)",
    "pos. NEES (in band)",
)
REAL_HEADER = ("row", "step", "SRMSE [m/s]", "final horiz. [m]", "NIS", "largest |ΔSRMSE|")


def _step_label(step: float) -> str:
    return "IMU (0.01 s)" if step == 0 else f"{step:g} s"


def _strategy(kind: str, q: Sequence[float]) -> pronet.Strategy:
    made = strategy(StrategySpec.parse(kind), tuple(q))
    assert isinstance(made, pronet.Strategy)  # a model-free spec
    return made


def simulate(name: str, kind: str, step: float, runs: int, threads: int | None) -> MonteCarloResult:
    """The Monte Carlo of scenario ``name`` with strategy ``kind`` (told the scenario's
    nominal q) at covariance ``step``."""
    sc = SCENARIOS[name](0)
    cfg = config.filter_config({"covariance_step": step}, "covariance_step:", base=sc.config)
    return pronet.monte_carlo(
        sc.trajectory,
        _strategy(kind, sc.q_nominal),
        sensors=sc.sensors,
        config=cfg,
        n_runs=runs,
        seed=0,
        threads=threads,
    )


def _nees(result: MonteCarloResult, block: str) -> str:
    mean = float(np.nanmean(result.mean_nees(block)))
    return f"{mean:.2f} ({100 * result.nees_in_band(block):.0f} %)"


def simulated_table(runs: int, threads: int | None) -> tuple[str, list[dict[str, object]]]:
    """The scenarios' table and its rows as records."""
    rows: list[list[str]] = []
    records: list[dict[str, object]] = []
    for name, kind in SIMULATED:
        base: MonteCarloResult | None = None
        for step in STEPS:
            r = simulate(name, kind, step, runs, threads)
            base = base or r
            ci, ref = mean_ci(r.srmse), mean_ci(base.srmse)
            diff = mean_ci(r.srmse - base.srmse)
            inside = ref.low <= ci.mean <= ref.high
            final = float(np.nanmean(r.final_horizontal_error))
            rows.append(
                [
                    f"{name}, {kind}",
                    _step_label(step),
                    f"{ci.mean:.4f} ({ci.low:.4f}–{ci.high:.4f})",
                    "yes" if inside else "**no**",
                    "—" if step == 0 else f"{diff.mean:+.5f} ({diff.low:+.5f}, {diff.high:+.5f})",
                    f"{final:.2f}",
                    _nees(r, "velocity"),
                    _nees(r, "attitude"),
                    _nees(r, "position"),
                ]
            )
            records.append(
                {
                    "scenario": name,
                    "strategy": kind,
                    "step": step,
                    **r.summary_row(),
                    "inside_step0_ci": inside,
                }
            )
            print(f"{name} {kind} {_step_label(step)}: SRMSE {ci.mean:.4f}", file=sys.stderr)
    return markdown(SIM_HEADER, rows), records


def snapir_dir() -> Path:
    return Path(os.environ.get("PRONET_SNAPIR_DIR", ROOT.parent / "shared" / "data" / "snapir"))


def real_table(data: Path) -> tuple[str, list[dict[str, object]]]:
    """``pronet real`` (every model-free row) at each step: per row of
    :data:`REAL_ROWS`, the means over the sections, and the largest change of a
    section's SRMSE from the per-sample filter's."""
    by_step: dict[float, list[dict[str, object]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for step in STEPS:
            out = run_real(
                data,
                Path(tmp) / f"step-{step:g}",
                use_models=False,
                plots=False,
                covariance_step=step,
            )
            by_step[step] = json.loads((out / "metrics.json").read_text())
            print(f"snapir {_step_label(step)}: done", file=sys.stderr)
    rows, records = [], []
    for label in REAL_ROWS:
        base = {r["scenario"]: r for r in by_step[0.0] if r["strategy"] == label}
        for step in STEPS:
            mine = [r for r in by_step[step] if r["strategy"] == label]
            srmse = np.array([float(r["srmse"]) for r in mine])  # type: ignore[arg-type]
            final = np.array([float(r["final_horizontal_error"]) for r in mine])  # type: ignore[arg-type]
            nis = np.array([float(r["mean_nis"]) for r in mine])  # type: ignore[arg-type]
            change = max(
                abs(float(r["srmse"]) / float(base[str(r["scenario"])]["srmse"]) - 1)  # type: ignore[arg-type]
                for r in mine
            )
            rows.append(
                [
                    label,
                    _step_label(step),
                    f"{srmse.mean():.4f}",
                    f"{final.mean():.2f}",
                    f"{nis.mean():.2f}",
                    "—" if step == 0 else f"{100 * change:.1f} %",
                ]
            )
            records += [{"step": step, **r} for r in mine]
    return markdown(REAL_HEADER, rows) + f"\n{len(base)} sections.\n", records


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=RUNS, help=f"Monte Carlo runs (default {RUNS})")
    parser.add_argument("--threads", type=int, default=None)
    parser.add_argument("--print", action="store_true", help="print the tables, do not write")
    parser.add_argument("--json", metavar="FILE", help="also write every row to FILE")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    sim, sim_records = simulated_table(args.runs, args.threads)
    data = snapir_dir()
    if data.is_dir():
        real, real_records = real_table(data)
    else:
        real, real_records = f"No Snapir data at {data}: not measured.\n", []
    note = f"\n{args.runs} runs per row, seed 0; {time.perf_counter() - start:.0f} s.\n"
    if args.json:
        record = {"runs": args.runs, "simulated": sim_records, "snapir": real_records}
        atomic_write(Path(args.json), json.dumps(record, indent=1, default=str).encode())
    if args.print:
        print(sim + note + "\n" + real)
        return 0
    page = PAGE.read_text(encoding="utf-8")
    page = between_markers(page, "covariance-step-simulated", sim + note, str(PAGE))
    page = between_markers(page, "covariance-step-snapir", real, str(PAGE))
    atomic_write(PAGE, page.encode("utf-8"))
    print(f"wrote {PAGE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
