"""Every performance figure of pronet beside its target, in one table.

Run:  ~/.cache/pronet-venv/bin/python benches/run.py [--quick] [--only NAME ...] [--json FILE]

Each row is printed with the command that reproduces it alone (``--only NAME``).
``--json FILE`` also writes every row (with its number in seconds where it has one) and
the machine to FILE; ``--compare OLD.json NEW.json`` prints two such files side by side
(two commits, two machines). The Rust micro-benchmarks of the inner steps are
separate: ``cargo bench --features bench --bench core``.
Benchmarks are not tests: nothing here fails on a slow machine; a missed target is
printed as missed. ``--quick`` scales the long rows down (fewer runs, no reproduce) to
check that the script works, not to measure.

Definitions:
- Monte Carlo rows: the evaluation scenario (``paper``, 330 s at 100 Hz, P propagated
  every IMU step), 100 runs, the paper's filter and sensors, no histories, best of
  ``--repeat``; "filter steps/s" counts IMU steps over all runs.
- hybrid: ``run_hybrid`` with the shipped detrend net (its forward pass frozen in the
  core), and with the detrended variance (``detvar``), tuning every 1 s, split into
  time stepping the filters and time in ``predict``.
- real: ``pronet real`` on the Snapir sections (``$PRONET_SNAPIR_DIR``, else
  ``../shared/data/snapir``), every strategy; and reading plus clock estimation per
  section.
- study: ``pronet study`` at 100 runs (four scenarios × ten estimators).
- NumPy reference: ``tests/numpy_reference_ekf.py`` (the same filter equations with
  dense 15×15 matrices, here with NED-velocity aiding and sensor arrays made up front)
  on the first ``--reference-seconds`` of one run, scaled to a whole run, against the
  1-thread Monte Carlo time per run (which also simulates the sensors and aids with body
  velocity, so the ratio is conservative).
- sweep: 2 strategies x 4 noise levels on ``paper`` in shards of a quarter of the runs,
  on the local engine (all cores per shard) and on a private Ray (one CPU per shard).
- 10,000 runs: a fresh process runs the Monte Carlo without histories at a tenth of the
  runs and at all of them; peak RSS and the time ratio (10 is linear).
- covariance step (issue 43): ``benches/covariance_step.py`` in a fresh process, the
  per-sample filter and a 0.1 s covariance step alternating, best of ``--repeat`` each:
  the 100-run constant-Q Monte Carlo of ``paper`` (2 threads) as a ratio, and
  ``run_filter`` in ns per IMU step on an hour of 100 Hz IMU with a 1 Hz DVL (6 minutes
  under ``--quick``), keeping the last epoch (the filter alone) and every epoch.
- yardsticks: after the table, each timed row with a target in seconds divided by the
  same run's constant-Q Monte Carlo time, beside its target divided by that Monte
  Carlo's time on the machine the targets were set on (:data:`TARGET_MACHINE_YARDSTICK`):
  a reading from which much of a machine's speed cancels, its drift within the hour
  only in part.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

import pronet
from pronet._util.cores import usable_cores
from pronet._util.files import atomic_write
from pronet.learn import dataset, models
from pronet.learn.hybrid import HybridResult, run_hybrid
from pronet.learn.models import Regressor
from pronet.sim import paper, scenarios

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = "python benches/run.py"
#: The constant-Q Monte Carlo row [s] (100 runs, 2 threads) on the machine the
#: targets were set on (issue 19's measurements).
TARGET_MACHINE_YARDSTICK = 1.03
YARDSTICK_ROW = "constant Q Monte Carlo"


@dataclass
class Row:
    what: str
    measured: str
    target: str
    met: bool | None  # None: no target
    command: str
    #: the row's headline number in ``unit`` (for --json and --compare)
    value: float | None = None
    unit: str = "s"


def best_of(repeat: int, f: Callable[[], object]) -> float:
    """Smallest wall time [s] of ``repeat`` calls of ``f``."""
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t0)
    return float(best)


def paper_monte_carlo(strategy: pronet.Strategy, n_runs: int, threads: int | None) -> None:
    sc = scenarios.paper_scenario()
    pronet.monte_carlo(
        sc.trajectory,
        strategy,
        sensors=sc.sensors,
        config=paper.paper_filter_config(),
        n_runs=n_runs,
        seed=0,
        threads=threads,
    )


#: Criterion's summary of one benchmark: its name, then "time: [low median high unit]".
CRITERION_LINE = re.compile(r"^(\S[^\n]*?)\s+time:\s+\[\S+ \S+ (\S+) (\S+) \S+ \S+\]", re.M)
UNIT_NS = {"ps": 1e-3, "ns": 1.0, "µs": 1e3, "us": 1e3, "ms": 1e6, "s": 1e9}


def bench_rust(args: argparse.Namespace) -> list[Row]:
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
        target, met = "—", None
        if name.startswith("mechanization"):
            target, met = "≥ 10 M steps/s per core", ns <= 100
        measured = f"{ns:.0f} ns ({1e3 / ns:.1f} M/s)"
        rows.append(Row(f"{name} (Rust)", measured, target, met, command, ns, "ns"))
    return rows + formulation_ratio(rows, command)


#: The most one invariant-formulation predict step may cost over a classic one (issue 41).
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


def bench_mechanization(args: argparse.Namespace) -> list[Row]:
    traj = pronet.builtin_trajectory("paper")
    imu = np.tile(traj.imu, (10 if not args.quick else 1, 1))
    lla0, vel0, rpy0 = traj.lla[0], traj.vel_ned[0], traj.rpy[0]
    wall = best_of(args.repeat, lambda: pronet.mechanize(imu, traj.dt, lla0, vel0, rpy0))
    return [
        Row(
            "`pronet.mechanize` from Python, with roll/pitch/yaw of every step",
            f"{len(imu) / wall / 1e6:.1f} M steps/s",
            "—",
            None,
            f"{SCRIPT} --only mechanization",
            wall / len(imu) * 1e9,
            "ns per step",
        )
    ]


#: One Monte Carlo of the paper scenario, best of N, in a fresh process: the core alone,
#: without torch's threads beside it (an earlier torch call in the same process can leave
#: them competing with rayon's) and with the trajectory built before the clock starts.
MONTE_CARLO = """
import sys, time
import pronet
from pronet.sim import paper, scenarios
kind, n_runs, threads, repeat = sys.argv[1], *map(int, sys.argv[2:5])
sc = scenarios.SCENARIOS["paper"]()
q = paper.PAPER_Q
strategy = pronet.Strategy.constant(q) if kind == "constant" else pronet.Strategy.mehra(5, q)
assert "torch" not in sys.modules
best = float("inf")
for _ in range(repeat):
    t0 = time.perf_counter()
    pronet.monte_carlo(sc.trajectory, strategy, sensors=sc.sensors,
                       config=paper.paper_filter_config(), n_runs=n_runs, seed=0, threads=threads)
    best = min(best, time.perf_counter() - t0)
print(best)
"""


def bench_monte_carlo(args: argparse.Namespace) -> list[Row]:
    n = args.runs
    steps = n * pronet.builtin_trajectory("paper").n_samples
    rows = []
    walls = {}
    for label, kind, target in [("constant Q", "constant", 0.8), ("Mehra ξ = 5", "mehra", 1.5)]:
        for threads in (1, 2):
            argv = [kind, str(n), str(threads), str(args.repeat)]
            out = subprocess.run(
                [sys.executable, "-c", MONTE_CARLO, *argv],
                check=True,
                capture_output=True,
                text=True,
            )
            walls[label, threads] = float(out.stdout)
        wall = walls[label, 2]
        rows.append(
            Row(
                f"{label} Monte Carlo, {n} runs × 330 s, 2 threads",
                f"{wall:.2f} s ({steps / wall / 1e6:.1f} M filter steps/s)",
                f"≤ {target * n / 100:g} s",
                wall <= target * n / 100,
                f"{SCRIPT} --only monte-carlo --runs {n}",
                wall,
            )
        )
    speedup = walls["constant Q", 1] / walls["constant Q", 2]
    rows.append(
        Row(
            "1 → 2 threads (constant Q)",
            f"{speedup:.2f}× ({walls['constant Q', 1]:.2f} s → {walls['constant Q', 2]:.2f} s)",
            "≥ 1.8×",
            speedup >= 1.8,
            f"{SCRIPT} --only monte-carlo --runs {n}",
            speedup,
            "x",
        )
    )
    return rows


#: The covariance step the speed rows time against the per-sample filter [s].
COVARIANCE_STEP = 0.1


def bench_covariance_step(args: argparse.Namespace) -> list[Row]:
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
        )
    ]
    for epochs, kept, target in (("last", "last epoch", 300.0), ("all", "every epoch", None)):
        every, stepped = m[f"run_filter_{epochs}_every_ns"], m[f"run_filter_{epochs}_step_ns"]
        rows.append(
            Row(
                f"{step} against every IMU step: `run_filter`, {seconds / 3600:g} h at "
                f"100 Hz, 1 Hz DVL, {kept} kept, per IMU step",
                f"{stepped:.0f} ns ({every / stepped:.2f}× faster than every IMU step, "
                f"{every:.0f} ns)",
                "—" if target is None else f"≤ {target:g} ns",
                None if target is None else stepped <= target,
                command,
                stepped,
                "ns per step",
            )
        )
    return rows


def bench_hybrid(args: argparse.Namespace) -> list[Row]:
    sc = scenarios.paper_scenario()
    n = args.runs
    rows = []
    loaded = models.load("detrend")
    assert isinstance(loaded, models.BaselineNet)
    net: models.BaselineNet = loaded

    class TorchPass:  # the same net through torch's float32 pass: the loop before freezing
        def predict(self, windows: ArrayLike) -> NDArray[np.float64]:
            return net.predict(windows, native=False)

    choices: list[tuple[str, Regressor, float | None]] = [
        ("ProNet detrend net", net, 3.0),
        ("detrended variance (`detvar`)", models.DetrendedVariance(), 1.5),
        ("the same detrend net through torch (float32, not frozen)", TorchPass(), None),
    ]
    for label, regressor, target in choices:
        best: tuple[float, HybridResult] | None = None
        for _ in range(args.repeat):
            t0 = time.perf_counter()
            out = run_hybrid(
                regressor,
                sc.trajectory,
                prior_q=sc.q_nominal,
                sensors=sc.sensors,
                config=paper.paper_filter_config(),
                n_runs=n,
                seed=0,
            )
            wall = time.perf_counter() - t0
            if best is None or wall < best[0]:
                best = (wall, out)
        assert best is not None
        wall, out = best
        rows.append(
            Row(
                f"{label} loop, {n} runs × 330 s, including inference",
                f"{wall:.2f} s (filters {out.rust_seconds:.2f} s, predict "
                f"{out.model_seconds:.2f} s, {out.n_tunings} tunings)",
                "—" if target is None else f"≤ {target * n / 100:g} s",
                None if target is None else wall <= target * n / 100,
                f"{SCRIPT} --only hybrid --runs {n}",
                wall,
            )
        )
    return rows


def bench_inference(args: argparse.Namespace) -> list[Row]:
    windows = (np.random.default_rng(0).standard_normal((100, 6, 200)) * 0.1).astype(np.float32)
    candidates: list[tuple[str, Callable[[], object]]] = []
    detvar = models.DetrendedVariance()
    candidates.append(("detrended variance", lambda: detvar.predict(windows)))
    for name in models.SHIPPED:
        model = models.load(name)
        if isinstance(model, models.BaselineNet):
            frozen = model.frozen()
            candidates.append((f"{name}, frozen in the core", partial(frozen.predict, windows)))
            candidates.append(
                (f"{name}, torch float32", partial(model.predict, windows, native=False))
            )
        else:
            candidates.append((name, partial(model.predict, windows)))
    rows = []
    for label, call in candidates:
        call()  # warm-up
        wall = best_of(args.repeat * 5, call)
        rows.append(
            Row(
                f"inference, {label}, batch 600",
                f"{600 / wall:,.0f} windows/s ({wall * 1e3:.1f} ms per call)",
                "—",
                None,
                f"{SCRIPT} --only inference",
                wall,
            )
        )
    return rows


def bench_dataset(args: argparse.Namespace) -> list[Row]:
    ds: list[dataset.Dataset] = []
    wall = best_of(args.repeat, lambda: ds.append(dataset.build_dataset()))
    n = ds[-1].q.size
    return [
        Row(
            f"dataset of {n:,} windows (`build_dataset`)",
            f"{wall:.2f} s",
            "≤ 5 s",
            wall <= 5,
            f"{SCRIPT} --only dataset",
            wall,
        )
    ]


def bench_reference(args: argparse.Namespace) -> list[Row]:
    sys.path.insert(0, str(ROOT / "tests"))
    from numpy_reference_ekf import run_reference_filter

    sc = scenarios.paper_scenario()
    cfg = paper.paper_filter_config()
    traj = sc.trajectory
    n = int(round(args.reference_seconds / traj.dt))
    rng = np.random.default_rng(0)
    imu = traj.imu[:n] + rng.normal(size=(n, 6)) * np.sqrt(paper.PAPER_Q)
    k = np.arange(100, n + 1, 100)
    dvl = traj.vel_ned[k] + rng.normal(size=(k.size, 3)) * 0.1  # nav aiding: no rotation
    t0 = time.perf_counter()
    run_reference_filter(
        imu,
        traj.time[1 : n + 1],
        dvl,
        traj.time[k],
        traj.time[0],
        traj.lla[0],
        traj.vel_ned[0],
        traj.rpy[0],
        q=paper.PAPER_Q,
        accel_bias_psd=cfg.accel_bias_psd,
        gyro_bias_psd=cfg.gyro_bias_psd,
        dvl_variance=cfg.dvl_variance,
        p0_sigma=cfg.p0_sigma,
        imu_dt=traj.dt,
        aiding="nav",
    )
    reference_per_run = (time.perf_counter() - t0) * traj.n_samples / n
    runs = 10
    wall = best_of(
        args.repeat, lambda: paper_monte_carlo(pronet.Strategy.constant(sc.q_nominal), runs, 1)
    )
    ratio = reference_per_run / (wall / runs)
    return [
        Row(
            "against the NumPy reference filter, per run, one core",
            f"{ratio:,.0f}× ({reference_per_run:.1f} s vs {wall / runs * 1e3:.1f} ms; "
            f"100 runs: {reference_per_run * 100 / 60:.0f} min vs {wall * 10:.1f} s)",
            "≥ 200×",
            ratio >= 200,
            f"{SCRIPT} --only reference --reference-seconds {args.reference_seconds:g}",
            ratio,
            "x",
        )
    ]


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


def bench_soak(args: argparse.Namespace) -> list[Row]:
    big = 1000 if args.quick else 10_000
    measured = {}
    for n in (big // 10, big):
        out = subprocess.run(
            [sys.executable, "-c", SOAK, str(n)], check=True, capture_output=True, text=True
        )
        wall, before_kib, peak_kib = out.stdout.split()
        measured[n] = float(wall), int(before_kib) / 2**20, int(peak_kib) / 2**20
    (t_small, _, _), (t_big, before, gib) = measured[big // 10], measured[big]
    return [
        Row(
            f"{big:,}-run Monte Carlo without histories: peak memory",
            f"{gib * 1024:.0f} MiB (of which {before * 1024:.0f} MiB before it started)",
            "< 1 GB",
            gib * 2**30 < 1e9,
            f"{SCRIPT} --only soak",
        ),
        Row(
            f"{big:,}-run Monte Carlo: time, and its ratio to {big // 10:,} runs",
            f"{t_big:.0f} s, {t_big / t_small:.1f}× for 10× the runs",
            "linear in runs (10×)",
            t_big / t_small <= 10.5,
            f"{SCRIPT} --only soak",
        ),
    ]


def bench_reproduce(args: argparse.Namespace) -> list[Row]:
    pronet_cli = Path(sys.executable).with_name("pronet")
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        subprocess.run(
            [str(pronet_cli), "reproduce", "--quiet", "--out", str(Path(tmp) / "out")],
            check=True,
            stdout=subprocess.DEVNULL,
        )
        wall = time.perf_counter() - t0
    return [
        Row(
            "`pronet reproduce`, shipped weights, both scenarios, 100 runs",
            f"{wall:.0f} s",
            "≤ 40 s",
            wall <= 40,
            f"{SCRIPT} --only reproduce  (or: time pronet reproduce)",
            wall,
        )
    ]


def bench_sweep(args: argparse.Namespace) -> list[Row]:
    from pronet import config
    from pronet.experiments import sweep

    runs = 20 if args.quick else args.runs
    grid = config.sweep_grid(
        {
            "scenarios": ["paper"],
            "strategies": ["constant", "mehra:5"],
            "noise_levels": [1, 2, 4, 8],
            "runs": runs,
            "shard_runs": max(1, runs // 4),
        },
        "bench",
    )
    n_shards = len(sweep.plan(grid))
    t0 = time.perf_counter()
    local = sweep.run_sweep(grid, engine="local")
    t_local = time.perf_counter() - t0
    t0 = time.perf_counter()
    on_ray = sweep.run_sweep(grid, engine="ray")  # starts a private Ray: counted
    t_ray = time.perf_counter() - t0
    same = all(
        np.array_equal(a.result.srmse, b.result.srmse)
        for a, b in zip(local.points, on_ray.points, strict=True)
    )
    what = f"sweep, 8 grid points x {runs} runs in {n_shards} shards"
    return [
        Row(
            f"{what}, local engine", f"{t_local:.2f} s", "", None, f"{SCRIPT} --only sweep", t_local
        ),
        Row(
            f"{what}, Ray engine (a private Ray on this machine, start-up included)",
            f"{t_ray:.2f} s ({t_ray / t_local:.2f}x local), numbers "
            + ("identical" if same else "DIFFERENT"),
            "identical numbers",
            same,
            f"{SCRIPT} --only sweep",
        ),
    ]


def _cli(*argv: str) -> float:
    """Wall time [s] of ``pronet ARGV`` in a fresh process."""
    pronet_cli = Path(sys.executable).with_name("pronet")
    t0 = time.perf_counter()
    subprocess.run([str(pronet_cli), *argv], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def bench_real(args: argparse.Namespace) -> list[Row]:
    from pronet.recorded import alignment

    data = Path(os.environ.get("PRONET_SNAPIR_DIR", ROOT.parent / "shared" / "data" / "snapir"))
    if not data.is_dir():
        return [Row("`pronet real`", f"skipped: no data at {data}", "—", None, "")]
    paths = alignment.find_sections(data)
    per_section = []
    for path in paths:
        per_section.append(
            best_of(
                args.repeat,
                partial(
                    alignment.load_section,
                    path,
                    "snapir",
                    imu_lever_arm=alignment.SNAPIR_IMU_LEVER_ARM,
                    dvl_lever_arm=alignment.SNAPIR_DVL_LEVER_ARM,
                ),
            )
        )
    worst = max(per_section)
    with tempfile.TemporaryDirectory() as tmp:
        wall = _cli("real", "--data", str(data), "--quiet", "--out", str(Path(tmp) / "out"))
        bare = _cli(
            "real", "--data", str(data), "--quiet", "--no-plots", "--out", str(Path(tmp) / "b")
        )
    return [
        Row(
            f"reading a Snapir section and estimating its clocks ({len(paths)} sections)",
            f"{np.mean(per_section):.2f} s mean, {worst:.2f} s worst",
            "≤ 0.2 s per section",
            worst <= 0.2,
            f"{SCRIPT} --only real",
            worst,
        ),
        Row(
            f"`pronet real --no-plots`, {len(paths)} Snapir sections, every strategy",
            f"{bare:.1f} s",
            "≤ 10 s",
            bare <= 10,
            f"{SCRIPT} --only real  (or: time pronet real --data DIR --no-plots)",
            bare,
        ),
        Row(
            f"`pronet real`, {len(paths)} Snapir sections, every strategy, plots",
            f"{wall:.1f} s",
            "≤ 10 s",
            wall <= 10,
            f"{SCRIPT} --only real  (or: time pronet real --data DIR)",
            wall,
        ),
    ]


def bench_study(args: argparse.Namespace) -> list[Row]:
    runs = 10 if args.quick else 100
    with tempfile.TemporaryDirectory() as tmp:
        wall = _cli("study", "--runs", str(runs), "--quiet", "--out", str(Path(tmp) / "out"))
    return [
        Row(
            f"`pronet study`, {runs} runs (4 scenarios × 10 estimators)",
            f"{wall:.0f} s",
            f"≤ {180 * runs / 100:g} s",
            wall <= 180 * runs / 100,
            f"{SCRIPT} --only study  (or: time pronet study)",
            wall,
        )
    ]


BENCHES: dict[str, Callable[[argparse.Namespace], list[Row]]] = {
    "rust": bench_rust,
    "mechanization": bench_mechanization,
    "monte-carlo": bench_monte_carlo,
    "covariance-step": bench_covariance_step,
    "hybrid": bench_hybrid,
    "dataset": bench_dataset,
    "inference": bench_inference,
    "reference": bench_reference,
    "soak": bench_soak,
    "sweep": bench_sweep,
    "real": bench_real,
    "reproduce": bench_reproduce,
    "study": bench_study,
}


def in_yardsticks(rows: list[dict[str, object]], runs: int) -> list[str]:
    """Comment lines: each row with a target in seconds ("≤ X s") as a multiple of the
    constant-Q Monte Carlo row of the same run, beside its target as a multiple of
    :data:`TARGET_MACHINE_YARDSTICK`; nothing when that row was not run or the run was
    not at the targets' 100 Monte Carlo runs."""
    stick = next((r for r in rows if str(r["what"]).startswith(YARDSTICK_ROW)), None)
    if runs != 100 or stick is None or not isinstance(stick["value"], float):
        return []
    if stick["value"] <= 0:
        return []
    yardstick = stick["value"]
    lines = [
        f"# in yardsticks (this run's {YARDSTICK_ROW}, {yardstick:.2f} s; the targets "
        f"over its {TARGET_MACHINE_YARDSTICK} s on the machine they were set on):"
    ]
    for row in rows:
        target = re.fullmatch(r"≤ ([0-9.]+) s", str(row["target"]))
        if row is stick or target is None or not isinstance(row["value"], float):
            continue
        measured, limit = row["value"] / yardstick, float(target[1]) / TARGET_MACHINE_YARDSTICK
        met = "met" if measured <= limit else "**not met**"
        lines.append(f"#   {row['what']}: {measured:.2f} (target {limit:.2f}, {met})")
    return lines


def compare(old_path: str, new_path: str) -> int:
    """Print two ``--json`` files side by side, row by row (matched on ``what``)."""
    old, new = (json.loads(Path(p).read_text()) for p in (old_path, new_path))
    before = {r["what"]: r for r in old["rows"]}
    print(f"| what | {old_path} | {new_path} | new / old |")
    print("|---|---|---|---|")
    for row in new["rows"]:
        was = before.get(row["what"], {})
        ratio = ""
        if row.get("value") and was.get("value"):
            ratio = f"{row['value'] / was['value']:.2f}×"
        print(f"| {row['what']} | {was.get('measured', '—')} | {row['measured']} | {ratio} |")
    for path, record in ((old_path, old), (new_path, new)):
        # files written before they recorded "runs": from their command (--quick: 10)
        command = record.get("command", "")
        given = re.search(r"--runs (\d+)", command)
        fallback = 10 if "--quick" in command else int(given[1]) if given else 100
        for line in in_yardsticks(record["rows"], record.get("runs", fallback)):
            print(line.replace("this run's", f"{path}'s", 1))
    return 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", choices=list(BENCHES), help="run these rows only")
    parser.add_argument("--quick", action="store_true", help="a fast smoke run, not a measurement")
    parser.add_argument("--runs", type=int, default=100, help="Monte Carlo runs (default 100)")
    parser.add_argument("--repeat", type=int, default=3, help="best of this many (default 3)")
    parser.add_argument(
        "--reference-seconds",
        type=float,
        default=20.0,
        help="seconds of a run the NumPy reference filters (default 20)",
    )
    parser.add_argument("--json", metavar="FILE", help="also write every row to FILE")
    parser.add_argument(
        "--compare", nargs=2, metavar=("OLD", "NEW"), help="print two --json files side by side"
    )
    args = parser.parse_args()
    if args.compare:
        return compare(*args.compare)
    if args.quick:
        args.runs, args.repeat, args.reference_seconds = 10, 1, 2.0
    slow = ("reproduce", "real", "study")
    chosen = args.only or [k for k in BENCHES if not (args.quick and k in slow)]
    import torch

    machine = (
        f"{usable_cores()} cores, python {sys.version.split()[0]}, "
        f"numpy {np.__version__}, torch {torch.__version__} ({torch.get_num_threads()} threads)"
    )
    print(f"# {SCRIPT} {' '.join(sys.argv[1:])}".rstrip())
    print(f"# machine: {machine}")
    print("| what | measured | target | met | command |")
    print("|---|---|---|---|---|")
    rows: list[Row] = []
    for name in chosen:
        for row in BENCHES[name](args):
            rows.append(row)
            met = {True: "yes", False: "**no**", None: ""}[row.met]
            print(f"| {row.what} | {row.measured} | {row.target} | {met} | `{row.command}` |")
            sys.stdout.flush()
    for line in in_yardsticks([dataclasses.asdict(r) for r in rows], args.runs):
        print(line)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"# this process's peak memory: {peak:.0f} MiB")
    if args.json:
        record = {
            "command": f"{SCRIPT} {' '.join(sys.argv[1:])}".rstrip(),
            "machine": machine,
            "date": time.strftime("%Y-%m-%d %H:%M:%S"),
            "runs": args.runs,
            "rows": [dataclasses.asdict(r) for r in rows],
        }
        atomic_write(Path(args.json), (json.dumps(record, indent=1) + "\n").encode())
        print(f"# wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
