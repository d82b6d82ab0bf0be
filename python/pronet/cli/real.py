"""``pronet real``: every strategy on recorded INS/DVL sections
(:func:`pronet.recorded.real.run_real`)."""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings

from pronet.cli._common import (
    Bars,
    Output,
    Subparsers,
    add_no_plots,
    add_output_flags,
    add_result_folder,
    add_tuning_period,
)
from pronet.recorded.alignment import FORMATS
from pronet.recorded.dvlnoise import DVL_NOISE_SOURCES
from pronet.recorded.plausible import PlausibilityWarning


def _vector3(text: str) -> tuple[float, float, float]:
    """``x,y,z`` as three floats [m], or the error argparse reports."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected x,y,z in metres, got {text!r}") from None
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"expected three comma-separated numbers, got {text!r}")
    return values[0], values[1], values[2]


def add_parser(sub: Subparsers) -> None:
    parser = sub.add_parser(
        "real",
        help="run every strategy on recorded INS/DVL sections (e.g. the Snapir AUV data)",
    )
    parser.add_argument(
        "--data",
        metavar="PATH",
        required=True,
        help="folder of sections, or one section: a folder of CSVs or one .npz (never copied)",
    )
    parser.add_argument(
        "--format",
        choices=FORMATS,
        default="snapir",
        help=(
            "snapir: the published layout; generic: see pronet.recorded.recordings "
            "(default snapir)"
        ),
    )
    parser.add_argument(
        "--sections", metavar="LIST", default=None, help="comma-separated section names"
    )
    parser.add_argument(
        "--imu-lever-arm",
        metavar="X,Y,Z",
        type=_vector3,
        default=None,
        help="IMU position from the ground-truth point, x,y,z [m, body FRD] (default: "
        "--filter's, else Snapir's with --format snapir; required with --format generic)",
    )
    parser.add_argument(
        "--dvl-lever-arm",
        metavar="X,Y,Z",
        type=_vector3,
        default=None,
        help="DVL position from the ground-truth point, x,y,z [m, body FRD] (default: "
        "--filter's, else Snapir's with --format snapir; required with --format generic)",
    )
    add_tuning_period(parser)
    parser.add_argument(
        "--dvl-noise",
        choices=DVL_NOISE_SOURCES,
        default="datasheet",
        help="the DVL noise R of the strategy rows: the datasheet's (0.02 m/s) or each "
        "section's, matched to the filter's innovations (default datasheet; the table "
        "has a row with R from the data and each section's R either way)",
    )
    parser.add_argument(
        "--formulation",
        choices=("invariant", "classic"),
        default=None,
        help="the filter's error coordinates: invariant (the default, consistent in "
        "heading) or classic (pronet's filter before 2026-12, to reproduce its results)",
    )
    parser.add_argument(
        "--covariance-step",
        metavar="SECONDS",
        type=float,
        default=None,
        help="interval over which every filter propagates its covariance at once (0: every "
        "IMU sample, the default unless --filter sets one; rounded to whole IMU samples)",
    )
    parser.add_argument(
        "--filter",
        metavar="FILE",
        default=None,
        help="your vehicle's tuning: a TOML file with a scenario's [filter] keys (p0_sigma, "
        "accel_bias_psd, gyro_bias_psd, dvl_variance, ...), grade = mems|tactical|fog and "
        "imu_lever_arm/dvl_lever_arm (pronet.recorded.vehicle), or a grade's name alone "
        "(default: the FOG tuning of the Snapir AUV)",
    )
    parser.add_argument(
        "--smooth",
        action="store_true",
        help="also run the RTS smoother over every strategy row: each is followed by its "
        "smoothed row ('<label>, smoothed'), scored at the same ground-truth rows",
    )
    parser.add_argument("--no-models", action="store_true", help="only the model-based rows")
    add_no_plots(parser)
    add_result_folder(parser, "real")
    add_output_flags(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pronet.recorded.real import run_real
    from pronet.recorded.vehicle import load_vehicle

    vehicle = None if args.filter is None else load_vehicle(args.filter)
    show = Output(args)
    start = time.perf_counter()

    def warn(message: Warning | str, *_: object, **__: object) -> None:
        print(f"pronet: warning: {message}", file=sys.stderr)  # also with --quiet

    with Bars(show) as bars, warnings.catch_warnings():
        warnings.simplefilter("always", PlausibilityWarning)
        warnings.showwarning = warn
        out = run_real(
            args.data,
            args.out,
            fmt=args.format,
            sections=args.sections.split(",") if args.sections else None,
            imu_lever_arm=args.imu_lever_arm,
            dvl_lever_arm=args.dvl_lever_arm,
            tuning_period=args.tuning_period,
            use_models=not args.no_models,
            plots=not args.no_plots,
            dvl_noise=args.dvl_noise,
            formulation=args.formulation,
            covariance_step=args.covariance_step,
            vehicle=vehicle,
            smooth=args.smooth,
            on_start=bars.start,
            on_done=bars.done,
        )
    config = json.loads((out / "config.json").read_text())
    n, failed = len(config["sections"]), config["failed_sections"]
    for name, reason in failed.items():  # a warning, also with --quiet and --json
        print(f"pronet: section {name}: {reason} (left out; see table.md)", file=sys.stderr)
    left_out = f" ({len(failed)} left out)" if failed else ""
    show.result(
        f"{(out / 'table.md').read_text()}\n{n} sections{left_out}; results written to {out} "
        f"in {time.perf_counter() - start:.0f} s",
        {"folder": str(out), "metrics": json.loads((out / "metrics.json").read_text())},
    )
    return 0
