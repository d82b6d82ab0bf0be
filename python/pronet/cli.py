"""The ``pronet`` command line."""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import json
import math
import os
import shutil
import sys
import time
from pathlib import Path
from typing import Any

import pronet
from pronet import _core, experiment
from pronet._files import atomic_folder
from pronet._validate import threads as threads_arg
from pronet.alignment import SNAPIR_DVL_LEVER_ARM, SNAPIR_IMU_LEVER_ARM
from pronet.shards import ShardStore


class _Output:
    """Where a command's words go. ``--quiet``: no progress bars, no messages (results
    still print). ``--json``: stdout holds only the final JSON document; messages go to
    stderr."""

    def __init__(self, args: argparse.Namespace) -> None:
        self.quiet = bool(getattr(args, "quiet", False))
        self.json = bool(getattr(args, "json", False))

    def say(self, text: str = "") -> None:
        if not self.quiet:
            print(text, file=sys.stderr if self.json else sys.stdout, flush=True)

    def result(self, text: str, data: object) -> None:
        """The command's result: ``text`` for people, or ``data`` as JSON."""
        if self.json:
            print(json.dumps(_strict_json(data), indent=2))
        else:
            print(text)

    def bar(self, **kwargs: Any):  # -> tqdm
        from tqdm.auto import tqdm

        return tqdm(disable=self.quiet, **kwargs)


def _strict_json(value: object) -> object:
    """``value`` with NaN and infinities as null: strict JSON, which every reader takes."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _strict_json(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_strict_json(v) for v in value]
    return value


def _version_of(package: str) -> str | None:
    """The installed version of ``package``, or None; without importing it."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(package)
    except PackageNotFoundError:
        return None


def _info(args: argparse.Namespace) -> int:
    import numpy
    import torch

    from pronet import modelfile, models

    info = {
        "pronet": pronet.__version__,
        "native_core": _core.__version__,
        "python": sys.version.split()[0],
        "numpy": numpy.__version__,
        "torch": torch.__version__,
        "cores": os.cpu_count(),
        "torch_threads": torch.get_num_threads(),
        "ray": _version_of("ray"),
        "weights": str(modelfile.SHIPPED_DIR),
        "shipped_models": list(models.SHIPPED),
        "trajectories": list(_core.builtin_trajectory_names()),
    }
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"pronet {info['pronet']} (native core {info['native_core']})")
    print(f"python {info['python']}, numpy {info['numpy']}, torch {info['torch']}")
    print(
        f"cores: {info['cores']}  (Monte Carlo threads default to all of them; "
        f"torch uses {info['torch_threads']})"
    )
    print(f"ray: {info['ray'] or 'not installed (pronet sweep --engine ray needs it)'}")
    print(f"shipped models: {', '.join(info['shipped_models'])} in {info['weights']}")
    print(f"built-in trajectories: {', '.join(info['trajectories'])}")
    return 0


#: History every this many IMU steps in ``reproduce`` (1 s at 100 Hz), for the plots.
RECORD_EVERY = 100


def _new_result_folder(out: str | None, command: str) -> Path | None:
    """``--out``, or ``results/<command>-<time>``; None (after saying why) if it exists."""
    stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
    folder = Path(out) if out else Path("results") / f"{command}-{stamp}"
    if folder.exists():
        print(f"pronet {command}: {folder} exists; choose another --out", file=sys.stderr)
        return None
    return folder


def _partial_folder(out: Path, resume: bool) -> Path:
    """Where the finished pieces of a run into ``out`` are kept (``<out>.partial``);
    ``ValueError`` if an interrupted run left some there and ``resume`` is not set."""
    partial = out.with_name(out.name + ".partial")
    if partial.exists() and not resume:
        raise ValueError(
            f"{partial} holds an interrupted run of this folder; add --resume to continue "
            "it, or remove it"
        )
    return partial


def _reproduce(args: argparse.Namespace) -> int:
    import tempfile

    from pronet import models, plots, training
    from pronet.dataset import DatasetParams, build_dataset

    show = _Output(args)
    n_runs = 10 if args.quick else args.runs
    if n_runs < 1:
        print("pronet reproduce: --runs must be at least 1", file=sys.stderr)
        return 2
    if not args.tuning_period > 0:
        print("pronet reproduce: --tuning-period must be > 0 s", file=sys.stderr)
        return 2
    if args.resume and (not args.out or args.retrain):
        print(
            "pronet reproduce: --resume needs the --out of the interrupted run, and "
            "cannot be used with --retrain",
            file=sys.stderr,
        )
        return 2
    out = _new_result_folder(args.out, "reproduce")
    if out is None:
        return 2
    partial = _partial_folder(out, args.resume)
    start = time.perf_counter()
    ds = None
    trained_dir = None
    if args.retrain:
        trained_dir = Path(tempfile.mkdtemp(prefix="pronet-models-"))
        params = DatasetParams()
        ds = build_dataset(params)
        for kind in training.MODEL_KINDS:
            training.train_and_save(kind, ds, params, trained_dir, progress=not args.quiet)
        regressors = {k: models.load(trained_dir / k) for k in training.MODEL_KINDS}
    else:
        regressors = {k: models.load(k) for k in models.SHIPPED}
    scenarios = [experiment.SCENARIOS[name]() for name in experiment.SCENARIOS]
    jobs = {
        sc.name: experiment.paper_strategies(sc.q_nominal, regressors, args.tuning_period)
        for sc in scenarios
    }
    show.say(
        f"{len(scenarios)} scenarios x {len(jobs['paper'])} strategies, {n_runs} Monte Carlo "
        f"runs each, seed {args.seed}; weights: {'retrained' if args.retrain else 'shipped'}"
    )
    shards = None
    if not args.retrain:  # shards of retrained models would not belong together
        # Everything that shapes a shard's numbers: shards of another version, other
        # weights or other settings must not be mixed in.
        settings = {
            "n_runs": n_runs,
            "seed": args.seed,
            "tuning_period": args.tuning_period,
            "record_every": RECORD_EVERY,
            "pronet": pronet.__version__,
            "native_core": _core.__version__,
            "weights": models.shipped_sha256(),
        }
        shards = ShardStore(partial, settings)
        if len(shards):
            show.say(f"resuming: {len(shards)} finished Monte Carlos loaded from {partial}")
    bar = show.bar(total=sum(len(j) for j in jobs.values()), unit="strategy")
    tables: dict[str, list[experiment.Row]] = {}
    try:
        for sc in scenarios:

            def done(label: str, sc: experiment.Scenario = sc) -> None:
                bar.set_postfix_str(f"{sc.name}: {label}")
                bar.update()

            title = f"{sc.name} scenario, {n_runs} runs"
            tables[title] = experiment.run_strategies(
                jobs[sc.name],
                sc,
                n_runs=n_runs,
                seed=args.seed,
                threads=args.threads,
                record_every=RECORD_EVERY,
                on_done=done,
                shards=shards,
            )
    except KeyboardInterrupt:
        bar.close()
        if shards is not None:
            print(
                f"\ninterrupted: {len(shards)} finished Monte Carlos kept in {partial}; "
                f"the same command with --resume continues from there",
                file=sys.stderr,
            )
        raise
    bar.close()
    if ds is None:
        ds = build_dataset(DatasetParams())
    test = ~ds.train

    def figures(folder: Path) -> None:
        plots.predicted_vs_true(
            {
                experiment.LEARNED_LABELS[k]: (ds.q[test], m.predict(ds.windows[test]))
                for k, m in regressors.items()
            },
            folder / "predicted_vs_true_q.png",
        )
        plots.metrics_with_ci(tables, folder / "srmse_smae.png")
        plots.trajectory(scenarios[0].trajectory, folder / "trajectory.png", "paper trajectory")
        for sc, (title, rows) in zip(scenarios, tables.items(), strict=True):
            plots.velocity_error(rows, folder / f"velocity_error_{sc.name}.png", title)
            plots.q_tracking(
                rows, sc.schedule_time, sc.schedule_q, folder / f"q_{sc.name}.png", title
            )
        if trained_dir is not None:
            shutil.copytree(trained_dir, folder / "models")

    config = {
        "n_runs": n_runs,
        "seed": args.seed,
        "tuning_period_s": args.tuning_period,
        "weights": "retrained" if args.retrain else "shipped",
        "scenarios": {
            sc.name: {
                "trajectory": "paper",
                "filter": repr(sc.config),
                "sensors": repr(sc.sensors),
                "q_nominal": list(sc.q_nominal),
                "schedule_time_s": sc.schedule_time,
                "schedule_q": sc.schedule_q,
                "strategies": {k: repr(v) for k, v in jobs[sc.name].items()},
            }
            for sc in scenarios
        },
        "models": {k: getattr(m, "card", {}).get("test") for k, m in regressors.items()},
    }
    folder = experiment.write_result_folder(out, tables, config, extra=figures)
    if shards is not None:
        shards.remove()
    if trained_dir is not None:
        shutil.rmtree(trained_dir, ignore_errors=True)
    _experiment_result(show, folder, start)
    return 0


def _experiment_result(show: _Output, folder: Path, start: float) -> None:
    """Print a written experiment folder's tables (or, with --json, its metrics)."""
    show.result(
        (folder / "table.md").read_text()
        + f"\nresults written to {folder} in {time.perf_counter() - start:.0f} s",
        {"folder": str(folder), "metrics": json.loads((folder / "metrics.json").read_text())},
    )


def _dataset(args: argparse.Namespace) -> int:
    from pronet import dataset

    out = Path(args.out)
    if out.exists() and not args.force:
        print(f"pronet dataset: {out} exists; use --force to replace it", file=sys.stderr)
        return 2
    params = dataset.DatasetParams(seed=args.seed, n_levels=args.levels)
    params.validate()
    start = time.perf_counter()
    ds = dataset.build_dataset(params)
    dataset.save_dataset(ds, out, params)
    _Output(args).result(
        f"{ds.q.size} examples ({ds.n_train} train / {ds.n_test} test) written to {out} "
        f"with card {dataset.card_path(out)} in {time.perf_counter() - start:.1f} s",
        {
            "file": str(out),
            "card": str(dataset.card_path(out)),
            "examples": int(ds.q.size),
            "train": int(ds.n_train),
            "test": int(ds.n_test),
        },
    )
    return 0


def _dataset_for(args: argparse.Namespace):
    """The dataset named by ``--dataset``, or the default one regenerated from
    ``--data-seed``."""
    from pronet import dataset

    if args.dataset:
        ds = dataset.load_dataset(args.dataset)
        return ds, dataset.load_params(args.dataset)
    params = dataset.DatasetParams(seed=args.data_seed)
    _Output(args).say(f"generating the dataset (seed {params.seed}) ...")
    return dataset.build_dataset(params), params


def _train(args: argparse.Namespace) -> int:
    from pronet import training

    kinds = training.MODEL_KINDS if args.model == "all" else (args.model,)
    hp = training.NetTraining(seed=args.seed, max_epochs=args.max_epochs)
    ds, params = _dataset_for(args)
    out = _Output(args)
    reports = {}
    for kind in kinds:
        start = time.perf_counter()
        reports[kind] = training.train_and_save(
            kind, ds, params, args.out, hp=hp, progress=not out.quiet
        )
        out.say(f"{kind}: trained in {time.perf_counter() - start:.0f} s -> {args.out}/{kind}.*")
    out.result(training.scores_table(reports), {"folder": str(args.out), "models": reports})
    return 0


def _evaluate(args: argparse.Namespace) -> int:
    from pronet import models, plots, training

    names = [n.strip() for n in args.models.split(",") if n.strip()]
    loaded = {n: models.load(n) for n in names}  # fail on a bad file before any work
    ds, _ = _dataset_for(args)
    test = ~ds.train
    reports, panels = {}, {}
    for name, model in loaded.items():
        reports[name] = training.test_report(model, ds)
        panels[name] = (ds.q[test], model.predict(ds.windows[test]))
    out = _Output(args)
    if args.figure:
        out.say(f"figure written to {plots.predicted_vs_true(panels, args.figure)}")
    out.result(training.scores_table(reports), {"models": reports, "figure": args.figure})
    return 0


def _vector3(text: str) -> tuple[float, float, float]:
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected x,y,z in metres, got {text!r}") from None
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"expected three comma-separated numbers, got {text!r}")
    return values  # type: ignore[return-value]


def _real(args: argparse.Namespace) -> int:
    from pronet import models, plots, realdata

    show = _Output(args)
    out = _new_result_folder(args.out, "real")
    if out is None:
        return 2
    if not args.tuning_period > 0:
        print("pronet real: --tuning-period must be > 0 s", file=sys.stderr)
        return 2
    start = time.perf_counter()
    paths = realdata.find_sections(args.data)
    if args.sections:
        wanted = {s.strip() for s in args.sections.split(",")}
        paths = [p for p in paths if p.name in wanted or p.stem in wanted]
        if not paths:
            print(f"pronet real: no section named {args.sections}", file=sys.stderr)
            return 2
    regressors = {} if args.no_models else {k: models.load(k) for k in models.SHIPPED}
    # Read and validate every section before any filtering.
    loaded = []
    for path in show.bar(iterable=paths, unit="section", desc="reading, aligning"):
        loaded.append(
            realdata.load_section(
                path,
                args.format,
                imu_lever_arm=args.imu_lever_arm,
                dvl_lever_arm=args.dvl_lever_arm,
            )
        )
    runs, stamped_runs, inertial, constants, q_estimated = [], [], [], {}, {}
    n_rows = len(realdata.real_strategies((1.0,) * 6, regressors, 1.0))
    bar = show.bar(total=len(loaded) * n_rows, unit="run")
    for aligned, stamped in loaded:
        q = q_estimated[aligned.name] = realdata.white_noise_q(aligned.imu)
        strategies = realdata.real_strategies(q, regressors, args.tuning_period)
        constants[aligned.name] = {
            label: s.q
            for label, s in strategies.items()
            if isinstance(s, _core.Strategy) and s.kind == "constant"
        }
        config = realdata.real_filter_config(aligned.alignment.filter_lever_arm)

        def done(label: str, name: str = aligned.name) -> None:
            bar.set_postfix_str(f"{name}: {label}")
            bar.update()

        section_runs, inertial_run = realdata.evaluate_section(
            aligned, strategies, config, on_done=done
        )
        runs += section_runs
        inertial.append(inertial_run)
        first_label, first = next(iter(strategies.items()))
        stamped_runs.append(
            realdata.run_section(
                stamped,
                first,
                realdata.real_filter_config(stamped.alignment.filter_lever_arm),
                label=f"{first_label}, stamps as given, no lever arms",
                setup="stamps as given, no lever arms",
            )
        )
    bar.close()
    n = len(loaded)
    first_label = runs[0].label
    tables = [
        realdata.summary_table(runs, "Clocks estimated, lever arms applied"),
        realdata.per_section_table(runs, "srmse", "Per section"),
        realdata.per_section_table(runs, "final_horizontal", "Per section"),
        realdata.summary_table(
            [r for r in runs if r.label == first_label] + stamped_runs,
            f"{first_label}: alignment handled against stamps as given",
        ),
        realdata.summary_table(inertial, "Sanity: pure inertial, no DVL"),
    ]
    text = "\n".join(tables)

    def write(folder: Path) -> None:
        (folder / "table.md").write_text(text)
        realdata.write_metrics(folder, runs + stamped_runs + inertial)
        config = {
            "data": str(Path(args.data).resolve()),
            "format": args.format,
            "sections": [a.name for a, _ in loaded],
            "tuning_period_s": args.tuning_period,
            "filter": repr(realdata.real_filter_config((0.0, 0.0, 0.0))),
            "imu_lever_arm_m": args.imu_lever_arm,
            "dvl_lever_arm_m": args.dvl_lever_arm,
            "clocks": {
                a.name: {
                    "gt": [a.alignment.gt_clock.offset, a.alignment.gt_clock.scale],
                    "dvl": [a.alignment.dvl_clock.offset, a.alignment.dvl_clock.scale],
                }
                for a, _ in loaded
            },
            "q_estimated": q_estimated,
            "models": {k: getattr(m, "card", {}).get("test") for k, m in regressors.items()},
        }
        (folder / "config.json").write_text(json.dumps(config, indent=2))
        for aligned, _ in show.bar(iterable=loaded, unit="section", desc="plots"):
            mine = [r for r in runs if r.section == aligned.name]
            plots.section_track(aligned, mine, folder / f"track_{aligned.name}.png")
            plots.section_velocity_error(
                aligned, mine, folder / f"velocity_error_{aligned.name}.png"
            )
            plots.section_q(
                aligned,
                mine,
                constants[aligned.name],
                realdata.real_filter_config((0.0, 0.0, 0.0)).imu_dt,
                folder / f"q_{aligned.name}.png",
            )

    with atomic_folder(out) as tmp:
        write(tmp)
    show.result(
        f"{text}\n{n} sections; results written to {out} in {time.perf_counter() - start:.0f} s",
        {"folder": str(out), "metrics": json.loads((out / "metrics.json").read_text())},
    )
    return 0


def _simulate(args: argparse.Namespace) -> int:
    from pronet import config, plots

    show = _Output(args)
    # everything the run needs is read and checked before anything runs
    if args.runs < 1:
        raise ValueError(f"--runs: must be at least 1, got {args.runs}")
    for name, value in (("tuning-period", args.tuning_period), ("record-every", args.record_every)):
        if not 0 < value < math.inf:
            raise ValueError(f"--{name}: must be a finite number of seconds > 0, got {value}")
    threads_arg(args.threads, "--threads")
    scenario = config.load_scenario(args.scenario)
    if args.filter:
        scenario = dataclasses.replace(scenario, config=config.load_filter_config(args.filter))
    texts = [t.strip() for t in args.strategies.split(",") if t.strip()]
    if not texts or len(set(texts)) != len(texts):
        raise ValueError(f"strategies: expected distinct comma-separated specs, got {texts}")
    specs = [experiment.StrategySpec.parse(t) for t in texts]
    strategies = {
        spec.text: experiment.strategy(spec, scenario.q_nominal, args.tuning_period)
        for spec in specs
    }
    out = _new_result_folder(args.out, "simulate")
    if out is None:
        return 2
    start = time.perf_counter()
    show.say(
        f"scenario {scenario.name} ({scenario.trajectory.duration:g} s): "
        f"{len(strategies)} strategies, {args.runs} Monte Carlo runs each, seed {args.seed}"
    )
    bar = show.bar(total=len(strategies), unit="strategy")

    def done(label: str) -> None:
        bar.set_postfix_str(label)
        bar.update()

    title = f"{scenario.name} scenario, {args.runs} runs"
    rows = experiment.run_strategies(
        strategies,
        scenario,
        n_runs=args.runs,
        seed=args.seed,
        threads=args.threads,
        record_every=max(1, round(args.record_every / scenario.trajectory.dt)),
        on_done=done,
    )
    bar.close()

    def figures(folder: Path) -> None:
        plots.metrics_with_ci({title: rows}, folder / "srmse_smae.png")
        plots.trajectory(scenario.trajectory, folder / "trajectory.png", scenario.name)
        plots.velocity_error(rows, folder / "velocity_error.png", title)
        plots.q_tracking(rows, scenario.schedule_time, scenario.schedule_q, folder / "q.png", title)

    settings = {
        "scenario": str(args.scenario),
        "filter": repr(scenario.config),
        "sensors": repr(scenario.sensors),
        "trajectory": scenario.trajectory.name,
        "q_nominal": list(scenario.q_nominal),
        "strategies": texts,
        "n_runs": args.runs,
        "seed": args.seed,
        "tuning_period_s": args.tuning_period,
    }
    folder = experiment.write_result_folder(
        out, {title: rows}, settings, extra=figures, paper_columns=False
    )
    _experiment_result(show, folder, start)
    return 0


def _sweep(args: argparse.Namespace) -> int:
    from pronet import config, sweep

    show = _Output(args)
    grid = config.load_sweep(args.grid)  # every file, spec and model checked first
    if args.address is not None and args.engine != "ray":
        raise ValueError("--address: only with --engine ray")
    sweep.check_engine(args.engine, args.address, args.threads)  # before any .partial
    if args.resume and not args.out:
        raise ValueError("--resume: needs the --out of the interrupted sweep")
    out = _new_result_folder(args.out, "sweep")
    if out is None:
        return 2
    partial = _partial_folder(out, args.resume)
    settings = sweep.settings(grid)
    store = ShardStore(partial, settings)
    shards = sweep.plan(grid)
    points = len({s.point for s in shards})
    show.say(
        f"{points} grid points x {grid.runs} runs = {len(shards)} shards of up to "
        f"{grid.shard_runs} runs, engine {args.engine}"
        + (f", {len(store)} already finished in {partial}" if len(store) else "")
    )
    start = time.perf_counter()
    bar = show.bar(total=len(shards), unit="shard")

    def done(shard: sweep.Shard) -> None:
        bar.set_postfix_str(shard.point.key, refresh=False)
        bar.update()

    try:
        result = sweep.run_sweep(
            grid,
            engine=args.engine,
            address=args.address,
            threads=args.threads,
            store=store,
            on_shard=done,
        )
    except KeyboardInterrupt:
        bar.close()
        print(
            f"\ninterrupted: {len(store)} finished shards kept in {partial}; the same "
            "command with --resume continues from there",
            file=sys.stderr,
        )
        raise
    bar.close()
    seconds = time.perf_counter() - start
    config_json = {**settings, "engine": args.engine, "seconds": seconds}
    sweep.write_result_folder(out, result, config_json)
    store.remove()
    summary = result.to_dataframe()
    show.result(
        result.markdown() + f"results written to {out} in {seconds:.0f} s",
        {"folder": str(out), "summary": summary.to_dict(orient="records")},
    )
    return 0


def _add_output_flags(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quiet", action="store_true", help="no progress bars or messages")
    parser.add_argument(
        "--json",
        action="store_true",
        help="print the result as one JSON document on stdout (messages go to stderr)",
    )


def _add_monte_carlo_args(parser: argparse.ArgumentParser) -> None:
    """--runs, --seed and --threads, as reproduce and simulate take them."""
    parser.add_argument(
        "--runs",
        metavar="N",
        type=int,
        default=100,
        help="Monte Carlo runs per strategy (default 100)",
    )
    parser.add_argument(
        "--seed", metavar="N", type=int, default=0, help="Monte Carlo seed (default 0)"
    )
    parser.add_argument(
        "--threads", metavar="N", type=int, default=None, help="worker threads (default: all cores)"
    )


def _add_tuning_period(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--tuning-period",
        metavar="SECONDS",
        type=float,
        default=1.0,
        help="seconds between regressor calls in the learned rows (default 1 s)",
    )


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="pronet", description="INS/DVL navigation with learned, adaptive process noise."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    info = sub.add_parser(
        "info", help="versions, cores and threads, where the weights live, trajectories"
    )
    info.add_argument("--json", action="store_true", help="print it as JSON, for scripts")
    info.set_defaults(func=_info)
    rep = sub.add_parser(
        "reproduce", help="run the paper's Monte Carlo experiment and print its table"
    )
    _add_monte_carlo_args(rep)
    rep.add_argument("--quick", action="store_true", help="10 runs per strategy")
    rep.add_argument(
        "--out",
        metavar="PATH",
        default=None,
        help="result folder (default results/reproduce-<time>)",
    )
    rep.add_argument(
        "--retrain", action="store_true", help="train all three regressors first (~10 min)"
    )
    _add_tuning_period(rep)
    _add_output_flags(rep)
    rep.add_argument(
        "--resume",
        action="store_true",
        help="continue an interrupted run of the same --out from its <out>.partial "
        "folder, without redoing the Monte Carlos it finished",
    )
    rep.set_defaults(func=_reproduce)
    from pronet.dataset import DatasetParams

    dataset_defaults = DatasetParams()
    data = sub.add_parser(
        "dataset", help="generate the 72,000-window noise-regression training set (.npz + card)"
    )
    data.add_argument("--out", metavar="PATH", default="data/dataset.npz", help="output .npz path")
    data.add_argument(
        "--seed", metavar="N", type=int, default=0, help="noise and split seed (default 0)"
    )
    data.add_argument(
        "--levels",
        metavar="N",
        type=int,
        default=dataset_defaults.n_levels,
        help="noise variances, evenly spaced from 0.001 to 0.05 (m/s²)² or (rad/s)² per "
        f"sample; 4,800 windows each (default {dataset_defaults.n_levels}, the paper's)",
    )
    data.add_argument("--force", action="store_true", help="replace an existing file")
    _add_output_flags(data)
    data.set_defaults(func=_dataset)
    for name, func, text in (
        ("train", _train, "train a noise regressor and write safetensors weights + JSON card"),
        ("evaluate", _evaluate, "score noise regressors on the test split; draw Fig. 8"),
    ):
        p = sub.add_parser(name, help=text)
        p.add_argument(
            "--dataset",
            metavar="FILE",
            default=None,
            help="dataset .npz (default: regenerate from --data-seed)",
        )
        p.add_argument(
            "--data-seed",
            metavar="N",
            type=int,
            default=0,
            help="seed of the regenerated dataset (default 0)",
        )
        p.set_defaults(func=func)
        _add_output_flags(p)
        if name == "train":
            p.add_argument(
                "--model",
                choices=("baseline", "detrend", "hcf", "all"),
                default="all",
                help="which regressor to train (default all three)",
            )
            p.add_argument(
                "--out", metavar="PATH", default="models", help="output folder (default models/)"
            )
            p.add_argument(
                "--seed", metavar="N", type=int, default=0, help="training seed (default 0)"
            )
            p.add_argument(
                "--max-epochs",
                metavar="N",
                type=int,
                default=20,
                help="epoch limit for the nets (default 20)",
            )
        else:
            p.add_argument(
                "--models",
                metavar="LIST",
                default="baseline,detrend,hcf",
                help="comma-separated shipped names or model file paths",
            )
            p.add_argument(
                "--figure", metavar="PNG", default=None, help="write predicted-vs-true q PNG here"
            )
    real = sub.add_parser(
        "real",
        help="run every strategy on recorded INS/DVL sections (e.g. the Snapir AUV data)",
    )
    real.add_argument(
        "--data",
        metavar="DIR",
        required=True,
        help="folder of sections, or one section (never copied)",
    )
    real.add_argument(
        "--format",
        choices=("snapir", "generic"),
        default="snapir",
        help="snapir: the published layout; generic: see pronet.recordings (default snapir)",
    )
    real.add_argument(
        "--sections", metavar="LIST", default=None, help="comma-separated section names"
    )
    real.add_argument(
        "--imu-lever-arm",
        metavar="X,Y,Z",
        type=_vector3,
        default=SNAPIR_IMU_LEVER_ARM,
        help="IMU position from the ground-truth point, x,y,z [m, body FRD] (default Snapir's)",
    )
    real.add_argument(
        "--dvl-lever-arm",
        metavar="X,Y,Z",
        type=_vector3,
        default=SNAPIR_DVL_LEVER_ARM,
        help="DVL position from the ground-truth point, x,y,z [m, body FRD] (default Snapir's)",
    )
    _add_tuning_period(real)
    real.add_argument("--no-models", action="store_true", help="only the model-based rows")
    real.add_argument(
        "--out", metavar="PATH", default=None, help="result folder (default results/real-<time>)"
    )
    _add_output_flags(real)
    real.set_defaults(func=_real)
    sim = sub.add_parser(
        "simulate",
        help="Monte Carlo of chosen strategies on one scenario (built-in or TOML file)",
        description="Run strategies on the same simulated noise realizations and write "
        "a result folder (table, metrics, plots). Scenario and filter files: see "
        "pronet.config (docs/api.md).",
    )
    sim.add_argument(
        "--scenario",
        metavar="NAME|FILE",
        default="paper",
        help="built-in scenario (paper, varying-noise) or a scenario .toml file (default paper)",
    )
    sim.add_argument(
        "--filter",
        metavar="FILE",
        default=None,
        help="filter configuration .toml replacing the scenario's",
    )
    sim.add_argument(
        "--strategies",
        metavar="SPECS",
        default=",".join(experiment.PAPER_ROWS.values()),
        help="comma-separated specs: constant[:FACTOR on q], mehra:WINDOW [DVL updates], "
        "learned:MODEL (shipped name or model file) (default: the paper's seven rows)",
    )
    _add_monte_carlo_args(sim)
    sim.add_argument(
        "--record-every",
        metavar="SECONDS",
        type=float,
        default=1.0,
        help="seconds between the saved history samples the plots use (default 1 s)",
    )
    _add_tuning_period(sim)
    sim.add_argument(
        "--out",
        metavar="PATH",
        default=None,
        help="result folder (default results/simulate-<time>)",
    )
    _add_output_flags(sim)
    sim.set_defaults(func=_simulate)
    swp = sub.add_parser(
        "sweep",
        help="a grid of Monte Carlos (scenario x strategy x noise level x tuning period), "
        "as shards, on this machine or a Ray cluster",
        description="Run the grid of a sweep .toml file (see pronet.config) as shards "
        "of runs, each one native Monte Carlo call, and merge them into one result "
        "folder (table.md, summary.csv, metrics.csv, plots). The Ray engine gives "
        "exactly the local engine's numbers.",
    )
    swp.add_argument("grid", help="sweep grid .toml file")
    swp.add_argument(
        "--engine",
        choices=("local", "ray"),
        default="local",
        help="local: shard after shard in this process; ray: shards as Ray tasks",
    )
    swp.add_argument(
        "--address",
        metavar="ADDR",
        default=None,
        help="Ray cluster to join (auto, HOST:6379 or ray://HOST:10001); default: start "
        "a private Ray on this machine",
    )
    swp.add_argument(
        "--threads",
        metavar="N",
        type=int,
        default=None,
        help="local: threads per shard (default all cores); ray: CPUs per shard (default 1)",
    )
    swp.add_argument(
        "--out", metavar="PATH", default=None, help="result folder (default results/sweep-<time>)"
    )
    swp.add_argument(
        "--resume",
        action="store_true",
        help="continue an interrupted sweep of the same --out, without redoing its finished shards",
    )
    _add_output_flags(swp)
    swp.set_defaults(func=_sweep)
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
