"""Two or more builds of pronet's core, timed side by side in one process.

Run:  ~/.cache/pronet-venv/bin/python benches/compare_builds.py NAME=PATH.so NAME=PATH.so
      [--threads N] [--rounds R] [--calls C] [--no-net] [--monte-carlo]
      [--filter [--rtol X] [--hours H] [--epochs last|all|both]]

Each PATH is a ``_core.abi3.so`` (e.g. ``python/pronet/_core.abi3.so`` copied aside
before and after a change). All of them are loaded into this one process, each under
the name ``pronet._core``, and their calls are interleaved: R rounds, each timing C
calls of every build, in alternating order. Prints each build's median time per call,
its min and max, and its ratio to the first build's median. Every build must give the
same answers, bit for bit (checked first, for each thing timed), so that only the speed
is compared; ``--rtol X`` relaxes that for ``--filter`` to X relative to the largest
magnitude of each array (a change that reorders a sum, such as the sparse update).

Why not time each build in its own process: on the machines of this project the same
build ran up to ~8 % faster or slower from one process to the next, more than the
changes being measured: the machine drifts between runs, and where the allocator puts
a build's buffers moved the CNN by that much (its buffers are 64-byte aligned since).
Interleaving in one process cancels the drift. Where each build's buffers lie stays
fixed for the process: to rule it out for code whose data is not aligned, compare again
in a second process.

Timed: the shipped detrend net's forward pass on 600 windows (what the learned loop
calls at each tuning instant), and with ``--monte-carlo`` the constant-Q Monte Carlo
of 100 runs on the paper's scenario (one call per round), and with ``--filter``
``run_filter`` at the default covariance step over an hour at 100 Hz with a 5 Hz DVL
(the last epoch kept: the filter alone; ``--epochs all`` every epoch, ``both`` each
build both ways, as NAME/last and NAME/all; one call per round, printed per IMU step).
"""

from __future__ import annotations

import argparse
import importlib.machinery
import importlib.util
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

from pronet.learn import frozen
from pronet.sim import paper


def load_core(path: str) -> ModuleType:
    """The extension module at ``path``, loaded as ``pronet._core`` (not registered in
    ``sys.modules``, so several builds coexist)."""
    loader = importlib.machinery.ExtensionFileLoader("pronet._core", path)
    spec = importlib.util.spec_from_file_location("pronet._core", path, loader=loader)
    try:
        module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
        loader.exec_module(module)
    except (ImportError, OSError) as exc:
        raise SystemExit(f"{path}: not a loadable build of pronet's core ({exc})") from None
    return module


def first_difference(answers: Mapping[str, Any], rtol: float = 0.0) -> str | None:
    """Where a build's answer differs from the first build's (``None`` when each is the
    same, bit for bit, or with ``rtol`` > 0 within ``rtol`` of the largest magnitude of
    the first build's array). An answer is an array or a mapping of names to arrays. Two
    empty arrays of the same rows, dimensions and type are the same whatever their
    columns (an older build's empty calibration array has fewer: no value differs)."""

    def arrays(answer: Any) -> dict[str, np.ndarray]:
        if isinstance(answer, Mapping):
            return {k: np.asarray(v) for k, v in answer.items() if isinstance(v, np.ndarray)}
        return {"": np.asarray(answer)}

    def bits(a: np.ndarray) -> np.ndarray:
        return np.ascontiguousarray(a).view(np.uint8).reshape(*a.shape, a.dtype.itemsize)

    (first, reference), *others = ((n, arrays(a)) for n, a in answers.items())
    for name, got in others:
        for key in sorted(set(reference) | set(got)):
            where = f"{name}: {key + ' ' if key else ''}"
            want, have = reference.get(key), got.get(key)
            if (
                want is not None
                and have is not None
                and want.size == have.size == 0
                and (want.ndim, want.dtype) == (have.ndim, have.dtype)
                and want.shape[:1] == have.shape[:1]
            ):
                continue
            if want is None or have is None or (want.shape, want.dtype) != (have.shape, have.dtype):
                return f"{where}not shaped or typed as {first}'s"
            same = (bits(want) == bits(have)).all(axis=-1)
            if rtol > 0 and want.dtype.kind == "f":
                scale = np.nanmax(np.abs(want), initial=0.0)
                same |= np.abs(have - want) <= rtol * scale
            if not np.all(same):
                i = tuple(int(j) for j in np.argwhere(~same)[0])
                return (
                    f"{where}{np.count_nonzero(~same)} of {same.size} values differ from "
                    f"{first}'s, the first at {i}: {have[i].item()!r} against {want[i].item()!r}"
                )
    return None


@contextmanager
def building_with(module: ModuleType, core: ModuleType) -> Iterator[None]:
    """Within the block, ``module``'s functions build their core objects from ``core``."""
    saved = getattr(module, "_core")  # noqa: B009 (mypy: _core is not re-exported)
    setattr(module, "_core", core)  # noqa: B010
    try:
        yield
    finally:
        setattr(module, "_core", saved)  # noqa: B010


def net_call(core: ModuleType, threads: int) -> Callable[[], Any]:
    """The detrend net of ``core`` predicting 600 windows (100 runs × 6 channels)."""
    tensors, card, weights, card_file = frozen.read_model("detrend")
    arch = frozen.checked_architecture(card, tensors, weights, card_file)
    with building_with(frozen, core):
        net = frozen.conv_net("detrend", arch, tensors, threads)
    rng = np.random.default_rng(0)
    windows = (rng.standard_normal((600, 200)) * 0.01 + 9.8).astype(np.float32)
    return lambda: net.predict(windows)


def monte_carlo_call(core: ModuleType, threads: int) -> Callable[[], Any]:
    """The constant-Q Monte Carlo of ``core``: 100 runs of the paper's scenario (its
    sensors and filter, built from ``core``'s own types)."""
    q = tuple(paper.PAPER_Q)
    trajectory = core.builtin_trajectory("paper")
    sensors = core.SensorConfig(imu_variance=q)  # as scenarios.paper_scenario's
    with building_with(paper, core):
        config = paper.paper_filter_config()
    strategy = core.Strategy.constant(q)
    return lambda: core.monte_carlo(
        trajectory, sensors, config, strategy, n_runs=100, seed=0, threads=threads
    )


def filter_data(seconds: float) -> tuple[dict[str, Any], Any]:
    """``benches/covariance_step.py``'s recording of ``seconds`` at 100 Hz with a 5 Hz
    DVL and the filter told its model (that script is loaded from beside this one)."""
    path = Path(__file__).with_name("covariance_step.py")
    spec = importlib.util.spec_from_file_location("covariance_step", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    data: dict[str, Any] = module.recording(seconds, dvl_rate=5)
    return data, module.RECORDING_CONFIG


def filter_call(core: ModuleType, seconds: float, epochs: str = "last") -> Callable[[], Any]:
    """``run_filter`` of ``core`` at its default covariance step over ``seconds`` at
    100 Hz with a 5 Hz body-frame DVL (:func:`filter_data`), keeping ``epochs`` (the
    last: the filter alone; or all)."""
    data, told = filter_data(seconds)
    (dvl,) = data.pop("streams")
    streams = [core.Dvl(dvl.time, dvl.velocity)]
    strategy = core.Strategy.constant(tuple(paper.PAPER_Q))
    # Bias walks small, as the recording has none: with the default (the paper's) walks
    # the heading is lost within minutes (σ of radians), where rounding grows chaotically
    # and no two builds could be compared. Each build's own FilterConfig, with the values
    # of the script's.
    config = core.FilterConfig(
        accel_bias_psd=told.accel_bias_psd,
        gyro_bias_psd=told.gyro_bias_psd,
        dvl_variance=tuple(told.dvl_variance),
    )
    return lambda: core.run_filter(
        **{**data, "streams": streams, "strategy": strategy}, config=config, epochs=epochs
    )


def interleave(
    calls: dict[str, Callable[[], Any]], rounds: int, per_round: int
) -> dict[str, list[float]]:
    """Seconds per call of each entry, ``rounds`` rounds of ``per_round`` calls each,
    the order reversed every other round."""
    times: dict[str, list[float]] = {name: [] for name in calls}
    names = list(calls)
    for r in range(rounds):
        for name in names if r % 2 == 0 else names[::-1]:
            f = calls[name]
            t0 = time.perf_counter()
            for _ in range(per_round):
                f()
            times[name].append((time.perf_counter() - t0) / per_round)
    return times


def report(title: str, times: dict[str, list[float]], unit: float, unit_name: str) -> None:
    first = float(np.median(next(iter(times.values()))))
    print(f"{title}")
    for name, ts in times.items():
        a = np.asarray(ts)
        print(
            f"  {name:12s} median {np.median(a) / unit:8.3f} {unit_name}"
            f"  min {a.min() / unit:8.3f}  max {a.max() / unit:8.3f}"
            f"  ×{np.median(a) / first:.3f}"
        )


def positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def timed(
    title: str,
    calls: dict[str, Callable[[], Any]],
    rounds: int,
    per_round: int,
    rtol: float = 0.0,
    unit: tuple[float, str] | None = None,
    alike: list[list[str]] | None = None,
) -> None:
    """Check that every build answers alike (within each list of names of ``alike``:
    by default all of them), then time them interleaved and report (in ``unit``:
    seconds per unit and its name; ms for repeated calls, else s)."""
    answers = {name: f() for name, f in calls.items()}
    for names in alike or [list(calls)]:
        difference = first_difference({name: answers[name] for name in names}, rtol)
        if difference is not None:
            raise SystemExit(f"{title}: {difference}; the builds do not compute the same")
    del answers
    if unit is None:
        unit = (1e-3, "ms") if per_round > 1 else (1.0, "s")
    report(title, interleave(calls, rounds, per_round), *unit)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("builds", nargs="+", metavar="NAME=PATH.so")
    parser.add_argument("--threads", type=positive, default=2, help="worker threads (2)")
    parser.add_argument("--rounds", type=positive, default=20, help="rounds (default 20)")
    parser.add_argument("--calls", type=positive, default=20, help="net calls per round (20)")
    parser.add_argument(
        "--no-net",
        action="store_true",
        help="leave out the detrend net (a build older than its precision argument has none)",
    )
    parser.add_argument("--monte-carlo", action="store_true", help="also time the Monte Carlo")
    parser.add_argument("--filter", action="store_true", help="also time run_filter (5 Hz DVL)")
    parser.add_argument(
        "--rtol", type=float, default=0.0, help="--filter's answers agree to this (0: bit for bit)"
    )
    parser.add_argument("--hours", type=float, default=1.0, help="--filter's recording (1 h)")
    parser.add_argument(
        "--epochs",
        choices=("last", "all", "both"),
        default="last",
        help="--filter keeps the last epoch (the filter alone, the default), all, or times both",
    )
    args = parser.parse_args()
    if args.no_net and not (args.filter or args.monte_carlo):
        parser.error("--no-net leaves nothing to time without --filter or --monte-carlo")
    paths: dict[str, str] = {}
    for item in args.builds:
        name, sep, path = item.partition("=")
        if not sep or not name or not path:
            parser.error(f"builds: expected NAME=PATH.so, got {item!r}")
        if name in paths:
            parser.error(f"builds: the name {name!r} is given twice")
        paths[name] = path
    cores = {name: load_core(path) for name, path in paths.items()}
    if not args.no_net:
        nets = {name: net_call(core, args.threads) for name, core in cores.items()}
        timed(f"detrend net, 600 windows, {args.threads} threads", nets, args.rounds, args.calls)
    if args.monte_carlo:
        runs = {name: monte_carlo_call(core, args.threads) for name, core in cores.items()}
        title = f"constant-Q Monte Carlo, 100 runs, {args.threads} threads"
        timed(title, runs, max(args.rounds // 2, 3), 1)
    if args.filter:
        seconds = args.hours * 3600.0
        kept = ("last", "all") if args.epochs == "both" else (args.epochs,)
        named = {
            e: {f"{name}/{e}" if len(kept) > 1 else name: core for name, core in cores.items()}
            for e in kept
        }
        filters = {
            name: filter_call(core, seconds, e) for e in kept for name, core in named[e].items()
        }
        steps = len(filter_data(seconds)[0]["imu"])
        title = (
            f"run_filter, {args.hours:g} h at 100 Hz, 5 Hz DVL, default covariance step, "
            f"epochs kept: {args.epochs}"
        )
        per_step = (1e-9 * steps, "ns/step")
        alike = [list(names) for names in named.values()]
        timed(title, filters, max(args.rounds // 2, 3), 1, args.rtol, per_step, alike)


if __name__ == "__main__":
    main()
