"""``pronet sweep``: a grid of Monte Carlos as shards, here or on a Ray cluster
(:mod:`pronet.experiments.sweep`)."""

from __future__ import annotations

import argparse
import time

from pronet.cli._common import Bars, Output, Subparsers, add_output_flags, add_result_folder


def add_parser(sub: Subparsers) -> None:
    parser = sub.add_parser(
        "sweep",
        help="a grid of Monte Carlos (scenario x strategy x noise level x tuning period), "
        "as shards, on this machine or a Ray cluster",
        description="Run the grid of a sweep .toml file (see pronet.config) as shards "
        "of runs, each one native Monte Carlo call, and merge them into one result "
        "folder (table.md, summary.csv, metrics.csv, plots). The Ray engine gives "
        "exactly the local engine's numbers.",
    )
    parser.add_argument("grid", help="sweep grid .toml file")
    parser.add_argument(
        "--engine",
        choices=("local", "ray"),
        default="local",
        help="local: shard after shard in this process; ray: shards as Ray tasks",
    )
    parser.add_argument(
        "--address",
        metavar="ADDR",
        default=None,
        help="Ray cluster to join (auto, HOST:6379 or ray://HOST:10001); default: start "
        "a private Ray on this machine",
    )
    parser.add_argument(
        "--threads",
        metavar="N",
        type=int,
        default=None,
        help="local: threads per shard (default all cores); ray: CPUs per shard (default 1)",
    )
    add_result_folder(parser, "sweep")
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue an interrupted sweep of the same --out, without redoing its finished shards",
    )
    add_output_flags(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pronet import config
    from pronet._util.outputs import new_result_folder, partial_folder
    from pronet.experiments import sweep
    from pronet.results import check_a_run_finished
    from pronet.shards import ShardStore

    show = Output(args)
    grid = config.load_sweep(args.grid)  # every file, spec and model checked first
    if args.address is not None and args.engine != "ray":
        raise ValueError("--address: only with --engine ray")
    sweep.check_engine(args.engine, args.address, args.threads)  # before any .partial
    if args.resume and not args.out:
        raise ValueError("--resume: needs the --out of the interrupted sweep")
    out = new_result_folder(args.out, "sweep")
    partial = partial_folder(out, args.resume)
    shards = sweep.plan(grid)  # its size and every strategy checked: no .partial yet
    settings = sweep.settings(grid)
    store = ShardStore(partial, settings)
    points = len({s.point for s in shards})
    show.say(
        f"{points} grid points x {grid.runs} runs = {len(shards)} shards of up to "
        f"{grid.shard_runs} runs, engine {args.engine}"
        + (f", {len(store)} already finished in {partial}" if len(store) else "")
    )
    start = time.perf_counter()
    with Bars(show) as bars:
        bars.start(len(shards), "shard", None)
        try:
            result = sweep.run_sweep(
                grid,
                engine=args.engine,
                address=args.address,
                threads=args.threads,
                store=store,
                on_shard=lambda shard: bars.done(shard.point.key),
            )
        except KeyboardInterrupt as exc:
            exc.add_note(
                f"interrupted: {len(store)} finished shards kept in {partial}; the same "
                "command with --resume continues from there"
            )
            raise
    seconds = time.perf_counter() - start
    try:  # not one run finished: an error, not a folder of NaN (and no shards to resume)
        check_a_run_finished((pr.point.key, pr.result) for pr in result.points)
    except ValueError:
        store.remove()
        raise
    # no wall time in config.json: identical sweeps write identical files
    sweep.write_result_folder(out, result, {**settings, "engine": args.engine})
    store.remove()
    show.result(
        result.markdown() + f"results written to {out} in {seconds:.0f} s",
        {"folder": str(out), "summary": result.to_dataframe().to_dict(orient="records")},
    )
    return 0
