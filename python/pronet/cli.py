"""The ``pronet`` command line."""

from __future__ import annotations

import argparse
import datetime as _dt
import os
import sys
import time
from pathlib import Path

import pronet
from pronet import _core, experiment


def _info(_args: argparse.Namespace) -> int:
    import numpy

    print(f"pronet {pronet.__version__} (native core {_core.__version__})")
    print(f"python {sys.version.split()[0]}, numpy {numpy.__version__}")
    print(f"cores: {os.cpu_count()}  (Monte Carlo threads default to all of them)")
    print(f"built-in trajectories: {', '.join(_core.builtin_trajectory_names())}")
    return 0


def _reproduce(args: argparse.Namespace) -> int:
    n_runs = 10 if args.quick else args.runs
    if n_runs < 1:
        print("pronet reproduce: --runs must be at least 1", file=sys.stderr)
        return 2
    out = (
        Path(args.out)
        if args.out
        else Path("results") / ("reproduce-" + _dt.datetime.now().strftime("%Y%m%d-%H%M%S"))
    )
    if out.exists():
        print(f"pronet reproduce: {out} exists; choose another --out", file=sys.stderr)
        return 2
    trajectory = pronet.builtin_trajectory("paper")
    sensors = _core.SensorConfig()
    config = experiment.paper_filter_config()
    strategies = experiment.model_based_strategies()
    print(
        f"paper scenario: {trajectory.duration:.0f} s, {n_runs} Monte Carlo runs, "
        f"seed {args.seed}; {len(strategies)} strategies "
        "(the learned rows need trained models, not built yet)"
    )
    start = time.perf_counter()
    done = [0]

    def progress(label: str) -> None:
        done[0] += 1
        print(
            f"  [{done[0]}/{len(strategies)}] {label}  ({time.perf_counter() - start:.1f} s)",
            flush=True,
        )

    rows = experiment.run_strategies(
        strategies,
        trajectory=trajectory,
        sensors=sensors,
        config=config,
        n_runs=n_runs,
        seed=args.seed,
        threads=args.threads,
        on_done=progress,
    )
    title = f"paper scenario, {n_runs} runs"
    print()
    print(experiment.markdown_table(rows, title))
    folder = experiment.write_result_folder(
        out,
        {title: rows},
        {
            "scenario": "paper",
            "n_runs": n_runs,
            "seed": args.seed,
            "filter": repr(config),
            "sensors": repr(sensors),
            "strategies": {k: repr(v) for k, v in strategies.items()},
        },
    )
    print(f"results written to {folder}")
    return 0


def _dataset(args: argparse.Namespace) -> int:
    from pronet import dataset

    out = Path(args.out)
    if out.exists() and not args.force:
        print(f"pronet dataset: {out} exists; use --force to replace it", file=sys.stderr)
        return 2
    params = dataset.DatasetParams(seed=args.seed)
    start = time.perf_counter()
    ds = dataset.build_dataset(params)
    dataset.save_dataset(ds, out, params)
    print(
        f"{ds.q.size} examples ({ds.n_train} train / {ds.n_test} test) written to {out} "
        f"with card {dataset.card_path(out)} in {time.perf_counter() - start:.1f} s"
    )
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pronet", description="INS/DVL navigation with learned, adaptive process noise."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    info = sub.add_parser("info", help="versions, cores, built-in trajectories")
    info.set_defaults(func=_info)
    rep = sub.add_parser(
        "reproduce", help="run the paper's Monte Carlo experiment and print its table"
    )
    rep.add_argument(
        "--runs", type=int, default=100, help="Monte Carlo runs per strategy (default 100)"
    )
    rep.add_argument("--quick", action="store_true", help="10 runs per strategy")
    rep.add_argument("--seed", type=int, default=0, help="Monte Carlo seed (default 0)")
    rep.add_argument(
        "--threads", type=int, default=None, help="worker threads (default: all cores)"
    )
    rep.add_argument("--out", default=None, help="result folder (default results/reproduce-<time>)")
    rep.set_defaults(func=_reproduce)
    data = sub.add_parser(
        "dataset", help="generate the 72,000-window noise-regression training set (.npz + card)"
    )
    data.add_argument("--out", default="data/dataset.npz", help="output .npz path")
    data.add_argument("--seed", type=int, default=0, help="noise and split seed (default 0)")
    data.add_argument("--force", action="store_true", help="replace an existing file")
    data.set_defaults(func=_dataset)
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        print("interrupted; no result folder was written", file=sys.stderr)
        return 130
    except ValueError as exc:
        print(f"pronet: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    raise SystemExit(main())
