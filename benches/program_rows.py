"""``benches/run.py``'s rows of the programs built on the core: the learned loops,
inference, the dataset, the sweep, ``pronet real``, ``reproduce`` and ``study``.

Definitions:
- hybrid: ``run_hybrid`` with the shipped detrend net (its forward pass frozen in the
  core), and with the detrended variance (``detvar``), tuning every 1 s, split into
  time stepping the filters and time in ``predict``; and ``pronet simulate`` of
  ``learned:detrend`` over ``constant`` (the acceptance's ratio: process CPU time, every
  thread, the two alternating; ``--quick`` leaves out the torch float32 loop).
- real: ``pronet real`` on the Snapir sections (``$PRONET_SNAPIR_DIR``, else
  ``../shared/data/snapir``), every strategy; and reading plus clock estimation per
  section.
- bag-read: ``bag_streams`` on a simulated 25-minute bag (200 Hz IMU, 5 Hz DVL, 1 Hz
  truth, depth and heading, a fix every 30 s; ROS 2 mcap and sqlite3, ROS 1) against a
  plain rosbags loop over the same topics (``AnyReader``, ``reader.messages`` and
  ``reader.deserialize`` of each message), the two alternating in this process; the
  ratio's median over the rounds, its range beside it.
- study: ``pronet study`` at 100 runs (four scenarios × ten estimators).
- sweep: 2 strategies x 4 noise levels on ``paper`` in shards of a quarter of the runs,
  on the local engine (all cores per shard) and on a private Ray (one CPU per shard).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray
from rows import PAPER_STEPS, SCRIPT, Reference, Row, best_of, from_seconds_target, timed_row

from pronet.experiments.simulation import simulate
from pronet.learn import dataset, models
from pronet.learn.hybrid import HybridResult, run_hybrid
from pronet.learn.models import Regressor
from pronet.recorded.bags import BagTopics, bag_streams
from pronet.sim import paper, scenarios

ROOT = Path(__file__).resolve().parents[1]


def _best_hybrid(regressor: Regressor, runs: int, repeat: int) -> tuple[float, HybridResult]:
    """The fastest of ``repeat`` learned loops on ``paper``: wall [s] and result."""
    sc = scenarios.paper_scenario()
    best: tuple[float, HybridResult] | None = None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = run_hybrid(
            regressor,
            sc.trajectory,
            prior_q=sc.q_nominal,
            sensors=sc.sensors,
            config=paper.paper_filter_config(),
            n_runs=runs,
            seed=0,
        )
        wall = time.perf_counter() - t0
        if best is None or wall < best[0]:
            best = (wall, out)
    assert best is not None
    return best


def bench_hybrid(args: argparse.Namespace, ref: Reference) -> list[Row]:
    n = args.runs
    loaded = models.load("detrend")
    assert isinstance(loaded, models.BaselineNet)
    net: models.BaselineNet = loaded

    class TorchPass:  # the same net through torch's float32 pass: the loop before freezing
        def predict(self, windows: ArrayLike) -> NDArray[np.float64]:
            return net.predict(windows, native=False)

    choices: list[tuple[str, Regressor, float | None]] = [
        ("ProNet detrend net", net, 3.0),
        ("detrended variance (`detvar`)", models.DetrendedVariance(), 1.5),
    ]
    if not args.quick:  # the slowest by far; --quick checks the script, not torch
        choices.append(
            ("the same detrend net through torch (float32, not frozen)", TorchPass(), None)
        )
    rows = _learned_over_constant(n, args.repeat)
    for label, regressor, target in choices:
        wall, out = _best_hybrid(regressor, n, args.repeat)
        rows.append(
            timed_row(
                f"{label} loop, {n} runs × 330 s, including inference",
                wall,
                ref,
                f"{SCRIPT} --only hybrid --runs {n}",
                detail=f"filters {out.rust_seconds:.2f} s, predict {out.model_seconds:.2f} s, "
                f"{out.n_tunings} tunings",
                at_most=None if target is None else from_seconds_target(target) * n / 100,
                steps=n * PAPER_STEPS,
            )
        )
    return rows


#: ``learned:detrend`` over ``constant`` in CPU time, as ``pronet simulate`` runs them.
LEARNED_OVER_CONSTANT_TARGET = 1.5


#: A longer tuning period timed beside the default, at the learned loop's cost.
LONGER_TUNING_PERIOD = 4.0


def _simulate_cpu(spec: str, runs: int, folder: Path, tuning_period: float = 1.0) -> float:
    """Process CPU time [s] (every thread) of ``pronet simulate --strategies SPEC`` on
    ``paper`` at its defaults (``tuning_period`` aside), without plots, into ``folder``."""
    t0 = time.process_time()
    simulate("paper", [spec], folder, n_runs=runs, plots=False, tuning_period=tuning_period)
    return time.process_time() - t0


def _learned_over_constant(runs: int, repeat: int) -> list[Row]:
    """The learned loop's cost over the constant-Q Monte Carlo it replaces, at the
    default 1 s tuning period (the acceptance row) and at :data:`LONGER_TUNING_PERIOD`
    (information: the accuracy it gives up is in docs/results/performance.md): the
    commands alternate, each ``repeat`` times (at least twice), the least CPU of each."""
    cases = [("constant", 1.0), ("learned:detrend", 1.0), ("learned:detrend", LONGER_TUNING_PERIOD)]
    cpu = dict.fromkeys(cases, np.inf)
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(max(2, repeat)):
            for spec, period in cases:
                folder = Path(tmp) / f"{spec}-{period:g}-{i}".replace(":", "-")
                seconds = _simulate_cpu(spec, runs, folder, period)
                cpu[spec, period] = min(cpu[spec, period], seconds)
    constant = cpu["constant", 1.0]
    command = f"{SCRIPT} --only hybrid --runs {runs}"
    target = LEARNED_OVER_CONSTANT_TARGET
    rows = []
    for period in (1.0, LONGER_TUNING_PERIOD):
        learned = cpu["learned:detrend", period]
        ratio = learned / constant
        default = period == 1.0
        option = "" if default else f" --tuning-period {period:g}"
        rows.append(
            Row(
                f"`pronet simulate --strategies learned:detrend{option}` over `constant`, "
                f"CPU, {runs} runs",
                f"{ratio:.2f}× ({constant:.2f} → {learned:.2f} s of CPU)",
                f"≤ {target}×" if default else "—",
                ratio <= target if default else None,
                command,
                ratio,
                "x",
            )
        )
    return rows


def bench_inference(args: argparse.Namespace, ref: Reference) -> list[Row]:
    windows = (np.random.default_rng(0).standard_normal((100, 6, 200)) * 0.1).astype(np.float32)
    candidates: list[tuple[str, Callable[[], object]]] = []
    detvar = models.DetrendedVariance()
    candidates.append(("detrended variance", lambda: detvar.predict(windows)))
    for name in models.SHIPPED:
        model = models.load(name)
        if isinstance(model, models.BaselineNet):
            frozen = model.frozen()
            candidates.append((f"{name}, frozen in the core", partial(frozen.predict, windows)))
            frozen32 = model.frozen(precision="float32")  # what the loops run
            candidates.append(
                (f"{name}, frozen in the core, float32", partial(frozen32.predict, windows))
            )
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
            timed_row(
                f"inference, {label}, batch 600",
                wall,
                ref,
                f"{SCRIPT} --only inference",
                detail=f"{600 / wall:,.0f} windows/s",
            )
        )
    return rows


def bench_dataset(args: argparse.Namespace, ref: Reference) -> list[Row]:
    ds: list[dataset.Dataset] = []
    wall = best_of(args.repeat, lambda: ds.append(dataset.build_dataset()))
    n = ds[-1].q.size
    return [
        timed_row(
            f"dataset of {n:,} windows (`build_dataset`)",
            wall,
            ref,
            f"{SCRIPT} --only dataset",
            at_most=from_seconds_target(5.0),
        )
    ]


def bench_sweep(args: argparse.Namespace, ref: Reference) -> list[Row]:
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
    command = f"{SCRIPT} --only sweep"
    return [
        timed_row(f"{what}, local engine", t_local, ref, command, steps=8 * runs * PAPER_STEPS),
        Row(
            f"{what}, Ray engine (a private Ray on this machine, start-up included)",
            f"{t_ray / t_local:.2f}× local ({t_ray:.2f} s), numbers "
            + ("identical" if same else "DIFFERENT"),
            "identical numbers",
            same,
            command,
            t_ray / t_local,
            "x",
        ),
    ]


def _cli(*argv: str) -> float:
    """Wall time [s] of ``pronet ARGV`` in a fresh process."""
    pronet_cli = Path(sys.executable).with_name("pronet")
    t0 = time.perf_counter()
    subprocess.run([str(pronet_cli), *argv], check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def bench_real(args: argparse.Namespace, ref: Reference) -> list[Row]:
    from pronet.recorded import alignment

    data = Path(os.environ.get("PRONET_SNAPIR_DIR", ROOT.parent / "shared" / "data" / "snapir"))
    if not data.is_dir():
        return [Row("`pronet real`", f"skipped: no data at {data}", "—", None, "")]
    paths = alignment.find_sections(data)
    per_section = [
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
        for path in paths
    ]
    with tempfile.TemporaryDirectory() as tmp:
        wall = _cli("real", "--data", str(data), "--quiet", "--out", str(Path(tmp) / "out"))
        bare = _cli(
            "real", "--data", str(data), "--quiet", "--no-plots", "--out", str(Path(tmp) / "b")
        )
    command = f"{SCRIPT} --only real"
    return [
        timed_row(
            f"reading a Snapir section and estimating its clocks, worst of {len(paths)}",
            max(per_section),
            ref,
            command,
            detail=f"mean {np.mean(per_section):.2f} s",
            at_most=from_seconds_target(0.2),
        ),
        timed_row(
            f"`pronet real --no-plots`, {len(paths)} Snapir sections, every strategy",
            bare,
            ref,
            f"{command}  (or: time pronet real --data DIR --no-plots)",
            at_most=from_seconds_target(10.0),
        ),
        timed_row(
            f"`pronet real`, {len(paths)} Snapir sections, every strategy, plots",
            wall,
            ref,
            f"{command}  (or: time pronet real --data DIR)",
            at_most=from_seconds_target(10.0),
        ),
    ]


#: Topics of the bench's bag, as ``tests/ros_bag.py`` writes them.
BAG_TOPICS = ("/imu/data", "/dvl/twist", "/odometry", "/depth/pressure", "/gnss/fix", "/ahrs")
#: Target: pronet's bag read over the plain rosbags loop.
BAG_READ_TARGET = 1.5


def _write_bench_bag(folder: Path, storage: str, minutes: float) -> tuple[Path, BagTopics]:
    """A simulated survey of ``minutes`` as a bag of ``storage`` in ``folder``: the
    path and the :class:`~pronet.recorded.bags.BagTopics` to read it."""
    sys.path.insert(0, str(ROOT / "tests"))
    from ros_bag import write_bag
    from synthetic_recording import synthetic_recording, with_aiding

    syn = synthetic_recording(seed=3, duration=60 * minutes, imu_rate=200.0, dvl_rate=5.0)
    rec = with_aiding(syn, depth_every=1.0, fix_every=30.0)
    name = "bench.bag" if storage == "rosbag1" else f"bench-{storage}"
    cov = np.full((len(rec.dvl_time), 3), 1e-4)
    variance = np.full(len(rec.gt_time), 1e-4)
    path, topics = write_bag(
        folder / name, rec, storage, dvl_covariance=cov, heading="imu", heading_variance=variance
    )
    return path, topics


def _plain_rosbags(path: Path) -> int:
    """A plain rosbags loop over the bench's topics: open, iterate, deserialize each."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    n = 0
    with AnyReader([path], default_typestore=get_typestore(Stores.LATEST)) as reader:
        wanted = [c for c in reader.connections if c.topic in BAG_TOPICS]
        for connection, _, raw in reader.messages(connections=wanted):
            reader.deserialize(raw, connection.msgtype)
            n += 1
    return n


def bench_bag_read(args: argparse.Namespace, ref: Reference) -> list[Row]:
    command = f"{SCRIPT} --only bag-read"
    try:
        import rosbags.highlevel  # noqa: F401
        import scipy  # noqa: F401  (the tests' bag writer)
    except ImportError as exc:
        return [Row("reading a ROS bag", f"skipped: {exc}", "—", None, command)]
    minutes, rounds = (1.0, 2) if args.quick else (25.0, max(3, args.repeat))
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for storage in ("mcap", "sqlite3", "rosbag1"):
            path, topics = _write_bench_bag(Path(tmp), storage, minutes)
            ours, plain = [], []
            _plain_rosbags(path)  # warm both: imports, the file in the page cache
            bag_streams(path, topics)
            for _ in range(rounds):  # alternating, in this process
                plain.append(best_of(1, partial(_plain_rosbags, path)))
                ours.append(best_of(1, partial(bag_streams, path, topics)))
            ratios = np.array(ours) / np.array(plain)
            ratio = float(np.median(ratios))
            kind = "ROS 1 .bag" if storage == "rosbag1" else f"ROS 2 {storage}"
            rows.append(
                Row(
                    f"reading a {minutes:g}-minute 200 Hz bag ({kind}, 6 topics): pronet's "
                    "reader over a plain rosbags loop",
                    f"{ratio:.2f}× (range {ratios.min():.2f}–{ratios.max():.2f}× in {rounds} "
                    f"alternating rounds; pronet {np.median(ours):.2f} s, rosbags "
                    f"{np.median(plain):.2f} s)",
                    f"≤ {BAG_READ_TARGET}×",
                    ratio <= BAG_READ_TARGET,
                    command,
                    ratio,
                    "x",
                )
            )
    return rows


#: The peak resident memory [MiB] of ``pronet real``/``navigate`` on a long recording.
MEMORY_TARGET_MIB = 1024.0


def _peak_mib(argv: list[str], report: Path) -> float:
    """Peak resident memory [MiB] of ``pronet ARGV`` in a fresh process: its own
    ``VmHWM``, written to ``report`` as it ends (``ru_maxrss`` of a child counts the
    memory of this process, which it was forked from)."""
    code = (
        "import sys; from pronet.cli import main; code = main(sys.argv[2:]); "
        "hwm = [l for l in open('/proc/self/status') if l.startswith('VmHWM:')][0]; "
        "open(sys.argv[1], 'w').write(hwm.split()[1]); sys.exit(code)"
    )
    done = subprocess.run(
        [sys.executable, "-c", code, str(report), *argv], stdout=subprocess.DEVNULL
    )
    if done.returncode != 0:
        raise RuntimeError(f"pronet {' '.join(argv)}: exit {done.returncode}")
    return int(report.read_text()) / 1024


def bench_real_memory(args: argparse.Namespace, ref: Reference) -> list[Row]:
    """Peak memory of ``pronet real --smooth`` (every row, plots) and ``pronet
    navigate`` (smoothed) on a 25-minute recording at 200 Hz (IMU), 5 Hz (DVL), 10 Hz
    (truth), written as generic CSVs."""
    sys.path.insert(0, str(ROOT / "tests"))
    from pronet.recorded.recordings import write_recording

    from synthetic_recording import synthetic_recording

    minutes = 1.0 if args.quick else 25.0
    command = f"{SCRIPT} --only real-memory"
    rec = synthetic_recording(
        seed=1, duration=60 * minutes, name="long", imu_rate=200.0, dvl_rate=5.0, gt_rate=10.0
    ).recording
    arms = ["--imu-lever-arm=0,0,0", "--dvl-lever-arm=0,0,0", "--quiet", "--format", "generic"]
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        data = write_recording(Path(tmp) / "data" / "long", rec)
        runs = {
            "`pronet real --smooth`, every row, plots": [
                "real",
                "--smooth",
                "--data",
                str(data.parent),
            ],
            "`pronet navigate` (smoothed)": ["navigate", "--init", "truth", "--data", str(data)],
        }
        for i, (what, argv) in enumerate(runs.items()):
            out = Path(tmp) / f"out{i}"
            peak = _peak_mib([*argv, *arms, "--out", str(out)], Path(tmp) / f"hwm{i}")
            rows.append(
                Row(
                    f"{what} on a {minutes:g}-minute 200 Hz recording: peak memory",
                    f"{peak:.0f} MiB",
                    f"≤ {MEMORY_TARGET_MIB:.0f} MiB",
                    peak <= MEMORY_TARGET_MIB,
                    command,
                    peak,
                    "MiB",
                )
            )
    return rows


def bench_reproduce(args: argparse.Namespace, ref: Reference) -> list[Row]:
    with tempfile.TemporaryDirectory() as tmp:
        wall = _cli("reproduce", "--quiet", "--out", str(Path(tmp) / "out"))
    return [
        timed_row(
            "`pronet reproduce`, shipped weights, both scenarios, 100 runs",
            wall,
            ref,
            f"{SCRIPT} --only reproduce  (or: time pronet reproduce)",
            at_most=from_seconds_target(40.0),
        )
    ]


def bench_study(args: argparse.Namespace, ref: Reference) -> list[Row]:
    runs = 10 if args.quick else 100
    with tempfile.TemporaryDirectory() as tmp:
        wall = _cli("study", "--runs", str(runs), "--quiet", "--out", str(Path(tmp) / "out"))
    return [
        timed_row(
            f"`pronet study`, {runs} runs (4 scenarios × 10 estimators)",
            wall,
            ref,
            f"{SCRIPT} --only study  (or: time pronet study)",
            at_most=round(from_seconds_target(180.0) * runs / 100, 2),
        )
    ]
