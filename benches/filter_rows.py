"""``benches/run.py``'s rows of the core: the Rust micro-benchmarks, the mechanization
from Python, the Monte Carlos, the covariance step and the 10,000-run soak.

Definitions:
- Monte Carlo rows: the evaluation scenario (``paper``, 330 s at 100 Hz, P propagated
  every IMU step), ``--runs`` runs, the paper's filter and sensors, no histories, best
  of ``--repeat`` in a fresh process; ns per filter step counts IMU steps over all runs.
- covariance step: ``benches/covariance_step.py`` in a fresh process, the
  per-sample filter and a 0.1 s covariance step alternating, best of ``--repeat`` each:
  the constant-Q Monte Carlo of ``paper`` (2 threads) as a ratio, and ``run_filter`` in
  ns per IMU step on an hour of 100 Hz IMU with a 1 Hz DVL (6 minutes under
  ``--quick``), keeping the last epoch (the filter alone) and every epoch.
- smoother: ``benches/smoother.py`` in fresh processes. Cost: the forward
  and the smoothed pass alternating, best of ``--repeat`` each, every IMU step and a
  0.1 s covariance step: ``run_filter`` on an hour of 100 Hz IMU with a 1 Hz DVL (6
  minutes under ``--quick``) and the constant-Q Monte Carlo of ``paper`` (one thread),
  each a ratio smoothed / forward (target ≤ 2.5×). Memory: the peak resident memory of
  ``run_filter(smooth=True)`` over 10 hours of 100 Hz IMU with a 5 Hz DVL at a 0.1 s
  covariance step (half an hour under ``--quick``, extrapolated at its bytes per IMU
  sample), target ≤ 1 GiB.
- second-order heading term: :func:`bench_second_order`.
- 10,000 runs: a fresh process runs the Monte Carlo without histories at a tenth of the
  runs and at all of them; peak RSS and the time ratio (10 is linear).
- online navigator: ``benches/online.py`` in a fresh process (its definitions are
  there), its headline rows: ``run_filter``'s step and one IMU sample per call from
  Python (native and wrapper) in ns per step, each also over ``run_filter``'s in the
  same rounds (target: at most 1 µs over it); blocks of 1000 over ``run_filter``; a
  DVL reading 0.5 s late; every DVL reading 0.2–0.5 s late over in order; the peak
  memory of a 10 h feed over a 1 h one (0.5 h over 0.1 h under ``--quick``). Timed on
  the process's CPU time, which another job on the same cores moves less than the wall
  (beside one, ``run_filter``'s wall time per sample ranged 0.39–0.77 µs over 25
  rounds, its CPU time 0.39–0.41 µs).
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from rows import (
    PAPER_STEPS,
    SCRIPT,
    Reference,
    Row,
    best_of,
    from_seconds_target,
    monte_carlo_wall,
    per_step_row,
    timed_row,
    times,
)

import pronet

ROOT = Path(__file__).resolve().parents[1]

#: Criterion's summary of one benchmark: its name, then "time: [low median high unit]".
CRITERION_LINE = re.compile(r"^(\S[^\n]*?)\s+time:\s+\[\S+ \S+ (\S+) (\S+) \S+ \S+\]", re.M)
UNIT_NS = {"ps": 1e-3, "ns": 1.0, "µs": 1e3, "us": 1e3, "ms": 1e6, "s": 1e9}
#: The mechanization step's target: 100 ns (10 M steps/s per core), as a ratio.
MECHANIZATION_TARGET = round(100 / (1e9 * 1.03 / (100 * PAPER_STEPS)), 2)


def bench_rust(args: argparse.Namespace, ref: Reference) -> list[Row]:
    """Criterion's medians [ns], each over the reference's ns per filter step (criterion
    runs apart from the reference: a coarser ratio than the other rows')."""
    command = "cargo bench --features bench --bench core"
    if shutil.which("cargo") is None:
        return [Row("Rust micro-benchmarks", "skipped: no cargo", "—", None, command)]
    extra = ["--warm-up-time", "1", "--measurement-time", "2"] if args.quick else []
    out = subprocess.run(
        ["cargo", "bench", "--quiet", "--features", "bench", "--bench", "core", "--", "--noplot"]
        + extra,
        cwd=ROOT,
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    rows = []
    for name, value, unit in CRITERION_LINE.findall(out.replace("\n  ", "  ")):
        ns = float(value) * UNIT_NS[unit]
        at_most = MECHANIZATION_TARGET if name.startswith("mechanization") else None
        rows.append(per_step_row(f"{name} (Rust)", ns, ref, command, at_most=at_most))
    return rows + formulation_ratio(rows, command)


#: The most one invariant-formulation predict step may cost over a classic one.
FORMULATION_TARGET = 1.2


def formulation_ratio(rows: list[Row], command: str) -> list[Row]:
    """The invariant predict step's time over the classic one's, both measured in the
    same criterion run (no row when either is missing)."""
    ns = {}
    for row in rows:
        for name in ("classic", "invariant"):
            if row.what.startswith(f"ekf predict {name} ") and row.value is not None:
                ns[name] = row.value
    if len(ns) < 2:
        return []
    ratio = ns["invariant"] / ns["classic"]
    return [
        Row(
            "ekf predict: invariant over classic formulation",
            f"{ratio:.2f}× ({ns['classic']:.0f} → {ns['invariant']:.0f} ns)",
            f"≤ {FORMULATION_TARGET}×",
            ratio <= FORMULATION_TARGET,
            command,
            ratio,
            "x",
        )
    ]


def bench_mechanization(args: argparse.Namespace, ref: Reference) -> list[Row]:
    traj = pronet.builtin_trajectory("paper")
    imu = np.tile(traj.imu, (10 if not args.quick else 1, 1))
    lla0, vel0, rpy0 = traj.lla[0], traj.vel_ned[0], traj.rpy[0]
    wall = best_of(args.repeat, lambda: pronet.mechanize(imu, traj.dt, lla0, vel0, rpy0))
    ns = wall / len(imu) * 1e9
    return [
        per_step_row(
            "`pronet.mechanize` from Python, with roll/pitch/yaw of every step",
            ns,
            ref,
            f"{SCRIPT} --only mechanization",
            detail=f"{1e3 / ns:.1f} M steps/s",
        )
    ]


def bench_monte_carlo(args: argparse.Namespace, ref: Reference) -> list[Row]:
    n = args.runs
    steps = n * PAPER_STEPS
    command = f"{SCRIPT} --only monte-carlo --runs {n}"
    rows = []
    walls = {}
    for label, kind, target in [("constant Q", "constant", None), ("Mehra ξ = 5", "mehra", 1.5)]:
        for threads in (1, 2):
            walls[label, threads] = monte_carlo_wall(kind, n, threads, args.repeat)
        at_most = None if target is None else from_seconds_target(target) * n / 100
        rows.append(
            timed_row(
                f"{label} Monte Carlo, {n} runs × 330 s, 2 threads",
                walls[label, 2],
                ref,
                command,
                at_most=at_most,
                steps=steps,
            )
        )
    speedup = walls["constant Q", 1] / walls["constant Q", 2]
    rows.append(
        Row(
            "1 → 2 threads (constant Q)",
            f"{speedup:.2f}× ({walls['constant Q', 1]:.2f} s → {walls['constant Q', 2]:.2f} s)",
            "≥ 1.8×",
            speedup >= 1.8,
            command,
            speedup,
            "x",
        )
    )
    return rows


#: The most the second-order heading term may cost per IMU step (CPU time).
SECOND_ORDER_TARGET = 1.2


def bench_second_order(args: argparse.Namespace, ref: Reference) -> list[Row]:
    """The second-order heading term's cost: the long MEMS mission's Monte Carlo
    (``pronet.experiments.consistency``, invariant, 20 runs, 0.1 s covariance step, no
    histories; 10 minutes under ``--quick``) with the term over without it, the two
    alternating, CPU time of the process, best of ``--repeat`` each."""
    import time

    from pronet.experiments import consistency as c

    hours = 1 / 6 if args.quick else 1.0
    what: tuple[str, c.Formulation, list, str] = (
        "mems", "invariant", c.lawnmower_segments(hours), "lawnmower"
    )  # fmt: skip
    aiding = dict(dvl_period=0.2, dvl_dropout=c.LAWNMOWER_DROPOUT,
                  depth_sigma=c.LAWNMOWER_DEPTH[0], depth_period=c.LAWNMOWER_DEPTH[1])  # fmt: skip
    best = {False: np.inf, True: np.inf}
    for _ in range(args.repeat):
        for second_order in (False, True):
            t0 = time.process_time()
            c._monte_carlo(what, (20, 0, 0, True, False), second_order=second_order, **aiding)
            best[second_order] = min(best[second_order], time.process_time() - t0)
    ratio = best[True] / best[False]
    return [
        Row(
            "second-order heading term over the invariant filter: long MEMS mission, 20 runs, CPU",
            f"{ratio:.2f}× ({best[False]:.2f} → {best[True]:.2f} s of CPU)",
            f"≤ {SECOND_ORDER_TARGET}×",
            ratio <= SECOND_ORDER_TARGET,
            f"{SCRIPT} --only second-order",
            ratio,
            "x",
        )
    ]


#: The covariance step the speed rows time against the per-sample filter [s].
COVARIANCE_STEP = 0.1


def bench_covariance_step(args: argparse.Namespace, ref: Reference) -> list[Row]:
    seconds = 360 if args.quick else 3600
    argv = [str(args.runs), str(args.repeat), str(seconds), str(COVARIANCE_STEP)]
    out = subprocess.run(
        [sys.executable, str(ROOT / "benches" / "covariance_step.py"), *argv],
        check=True,
        capture_output=True,
        text=True,
    )
    m = json.loads(out.stdout)
    command = f"{SCRIPT} --only covariance-step --runs {args.runs}"
    step = f"{COVARIANCE_STEP:g} s covariance step"
    mc = m["monte_carlo_every_s"] / m["monte_carlo_step_s"]
    rows = [
        Row(
            f"{step} against every IMU step: constant Q Monte Carlo, {args.runs} runs",
            f"{mc:.2f}× ({m['monte_carlo_every_s']:.2f} s → {m['monte_carlo_step_s']:.2f} s)",
            "≥ 2×",
            mc >= 2,
            command,
            mc,
            "x",
            ns_per_step=m["monte_carlo_step_s"] / (args.runs * PAPER_STEPS) * 1e9,
        )
    ]
    for epochs, kept in (("last", "last epoch"), ("all", "every epoch")):
        every, stepped = m[f"run_filter_{epochs}_every_ns"], m[f"run_filter_{epochs}_step_ns"]
        rows.append(
            per_step_row(
                f"{step}: `run_filter`, {seconds / 3600:g} h at 100 Hz, 1 Hz DVL, {kept} kept",
                stepped,
                ref,
                command,
                detail=f"{times(every / stepped)} faster than every IMU step, {every:.0f} ns",
            )
        )
    last, everything = m["run_filter_last_step_ns"], m["run_filter_all_step_ns"]
    kept = everything / last
    rows.append(
        Row(
            f"{step}: `run_filter` keeping every epoch against the last only",
            f"{times(kept)} ({last:.0f} → {everything:.0f} ns per step)",
            f"≤ {OUTPUT_TARGET:g}×",
            kept <= OUTPUT_TARGET,
            command,
            kept,
            "x",
        )
    )
    return rows


#: Keeping every epoch's estimate and σ against the last epoch only.
OUTPUT_TARGET = 1.5


def smoother_json(*argv: str) -> dict:
    out = subprocess.run(
        [sys.executable, str(ROOT / "benches" / "smoother.py"), *argv],
        check=True,
        capture_output=True,
        text=True,
    )
    return json.loads(out.stdout)


def bench_smoother(args: argparse.Namespace, ref: Reference) -> list[Row]:
    seconds = 360 if args.quick else 3600
    runs = 10 if args.quick else args.runs
    m = smoother_json("cost", str(runs), str(args.repeat), str(seconds), "0", str(COVARIANCE_STEP))
    command = f"{SCRIPT} --only smoother --runs {args.runs}"
    rows = []
    for step in ("0", f"{COVARIANCE_STEP:g}"):
        at = "every IMU step" if step == "0" else f"{step} s covariance step"
        for key, what in (
            ("run_filter", f"`run_filter`, {seconds / 3600:g} h at 100 Hz, 1 Hz DVL"),
            ("run_filter_thinned", f"`run_filter(output_step=1)` both, {seconds / 3600:g} h"),
            ("monte_carlo", f"constant Q Monte Carlo of paper, {runs} runs, 1 thread"),
        ):
            ratio = m[step][f"{key}_ratio"]
            walls = m[step]["monte_carlo_s" if key == "monte_carlo" else "run_filter_s"]
            thinned = key == "run_filter_thinned"
            forward = walls["forward_thinned" if thinned else "forward"]
            smoothed = walls["thinned" if thinned else "smoothed"]
            cpu = m[step].get(f"{key}_cpu_ratio")
            also = "" if cpu is None else f"; CPU time {times(cpu)}"
            rows.append(
                Row(
                    f"RTS smoother, smoothed / forward ({at}): {what}",
                    f"{times(ratio)} ({forward:.2f} s → {smoothed:.2f} s{also})",
                    "≤ 2.5×",
                    ratio <= 2.5,
                    command,
                    ratio,
                    "x",
                )
            )
    hours = 0.5 if args.quick else 10.0
    mem = smoother_json("memory", str(hours), str(COVARIANCE_STEP), "1")
    # Quick: the pass's bytes per IMU sample and the inputs' (IMU, times, a 5 Hz DVL)
    # carried to 10 h.
    more = (mem["bytes_per_imu_sample"] + 7 * 8 + 4 * 8 / 20) * (3.6e6 - mem["imu_samples"])
    gib = mem["peak_gib"] if hours == 10 else mem["peak_gib"] + more / 2**30
    how = "measured" if hours == 10 else f"from {hours:g} h, extrapolated"
    rows.append(
        Row(
            "RTS smoother: peak memory of `run_filter(smooth=True, output_step=1)`, "
            "10 h at 100 Hz, 5 Hz DVL",
            f"{gib:.2f} GiB ({how}, inputs included; {mem['bytes_per_imu_sample']:.0f} B "
            "per IMU sample)",
            "≤ 1 GiB",
            gib <= 1,
            f"{SCRIPT} --only smoother",
            gib * 1024,
            "MiB",
        )
    )
    return rows


# Without pronet.sim.scenarios, which imports torch (~500 MiB that is not the Monte Carlo's).
# Peak memory from VmHWM: ru_maxrss would carry over the parent's peak across exec.
SOAK = """
import sys, time
import pronet
def peak_kib():
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1])
q = (1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6)
traj = pronet.builtin_trajectory("paper")
config = pronet.FilterConfig(accel_bias_psd=1e-3, gyro_bias_psd=1e-3, dvl_variance=(0.01,) * 3)
before = peak_kib()
t0 = time.perf_counter()
pronet.monte_carlo(traj, pronet.Strategy.constant(q), sensors=pronet.SensorConfig(imu_variance=q),
                   config=config, n_runs=int(sys.argv[1]), seed=0)
print(time.perf_counter() - t0, before, peak_kib())
"""


def bench_soak(args: argparse.Namespace, ref: Reference) -> list[Row]:
    big = 1000 if args.quick else 10_000
    measured = {}
    for n in (big // 10, big):
        out = subprocess.run(
            [sys.executable, "-c", SOAK, str(n)], check=True, capture_output=True, text=True
        )
        wall, before_kib, peak_kib = out.stdout.split()
        measured[n] = float(wall), int(before_kib) / 2**20, int(peak_kib) / 2**20
    (t_small, _, _), (t_big, before, gib) = measured[big // 10], measured[big]
    command = f"{SCRIPT} --only soak"
    return [
        Row(
            f"{big:,}-run Monte Carlo without histories: peak memory",
            f"{gib * 1024:.0f} MiB (of which {before * 1024:.0f} MiB before it started)",
            "< 1 GB",
            gib * 2**30 < 1e9,
            command,
            gib * 1024,
            "MiB",
        ),
        Row(
            f"{big:,}-run Monte Carlo: time, and its ratio to {big // 10:,} runs",
            f"{t_big / t_small:.1f}× for 10× the runs ({t_big:.0f} s)",
            "≤ 10.5× (linear in runs)",
            t_big / t_small <= 10.5,
            command,
            t_big / t_small,
            "x",
            ns_per_step=t_big / (big * PAPER_STEPS) * 1e9,
        ),
    ]


#: ``benches/online.py``'s rows that run.py's table carries (the rest: run it alone).
ONLINE_ROWS = (
    "run_filter",
    "imu_np",
    "wrapper_imu",
    "block_1000",
    "wrapper_block_1000",
    "late_reading",
    "late_feed",
    "memory_ratio",
)


def bench_online(args: argparse.Namespace, ref: Reference) -> list[Row]:
    with tempfile.TemporaryDirectory() as folder:
        out = Path(folder) / "online.json"
        argv = ["--json", str(out)] + (["--quick"] if args.quick else [])
        subprocess.run(
            [sys.executable, str(ROOT / "benches" / "online.py"), *argv],
            check=True,
            capture_output=True,
            text=True,
        )
        record = json.loads(out.read_text())
    return online_rows(record, ref, f"{SCRIPT} --only online")


def online_rows(record: dict[str, Any], ref: Reference, command: str) -> list[Row]:
    """``benches/online.py``'s ``--json`` record as run.py's rows: a time per IMU
    sample in ns per step over the reference, its ratio to ``run_filter`` (measured in
    the same rounds) in its text; a row with a target over ``run_filter`` (the blocks)
    as that ratio; the others as they are."""
    rows = []
    for r in record["rows"]:
        if r["key"] not in ONLINE_ROWS:
            continue
        what, target, met = f"online navigator: {r['what']}", r["target"], r["met"]
        if r["unit"] != "µs per sample":
            row = Row(what, r["measured"], target, met, command, r["value"], r["unit"])
        elif target.endswith("× run_filter"):
            ratio, ns = r["over_run_filter"], r["value"] * 1e3
            measured = f"{times(ratio)} run_filter ({r['measured']})"
            target = target.removesuffix(" run_filter")
            row = Row(what, measured, target, met, command, ratio, "x", ns_per_step=ns)
        else:
            ns = r["value"] * 1e3
            measured = r["measured"]
            if r["key"] != "run_filter":
                measured += f", {times(r['over_run_filter'])} run_filter"
            row = per_step_row(what, ns, ref, command)
            row.measured, row.target, row.met = measured, target, met
        rows.append(row)
    return rows
