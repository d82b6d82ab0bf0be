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
    add_bag_options,
    add_no_plots,
    add_output_flags,
    add_result_folder,
    add_tuning_period,
    bag_topics,
    print_warning,
    vector3,
)
from pronet.recorded.alignment import AIDING_CLOCKS, FORMATS
from pronet.recorded.bags import require_rosbags
from pronet.recorded.dvlnoise import DVL_NOISE_SOURCES
from pronet.recorded.plausible import PlausibilityWarning


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
            "snapir: the published layout; generic: see pronet.recorded.recordings; bag: "
            "ROS 1 .bag files or ROS 2 bag folders, see pronet.recorded.bags (default snapir)"
        ),
    )
    parser.add_argument(
        "--sections", metavar="LIST", default=None, help="comma-separated section names"
    )
    parser.add_argument(
        "--imu-lever-arm",
        metavar="X,Y,Z",
        type=vector3,
        default=None,
        help="IMU position from the ground-truth point, x,y,z [m, body FRD] (default: "
        "--filter's, else Snapir's with --format snapir; required with --format generic)",
    )
    parser.add_argument(
        "--dvl-lever-arm",
        metavar="X,Y,Z",
        type=vector3,
        default=None,
        help="DVL position from the ground-truth point, x,y,z [m, body FRD] (default: "
        "--filter's, else Snapir's with --format snapir; required with --format generic "
        "for recordings with DVL readings, unless --no-dvl)",
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
        choices=("invariant", "classic", "se23"),
        default=None,
        help="the filter's error coordinates: invariant (the default, consistent in "
        "heading), classic (the first filter's coordinates, to reproduce its results) or "
        "se23 (the position error too, consistent under large heading errors)",
    )
    parser.add_argument(
        "--covariance-step",
        metavar="SECONDS",
        type=float,
        default=None,
        help="interval over which every filter propagates its covariance at once (default "
        "0.1 s unless --filter sets one; 0: every IMU sample; rounded to whole IMU samples)",
    )
    parser.add_argument(
        "--filter",
        metavar="FILE",
        default=None,
        help="your vehicle's tuning: a TOML file with a scenario's [filter] keys (p0_sigma, "
        "accel_bias_psd, gyro_bias_psd, dvl_variance, ...), grade = mems|tactical|fog and "
        "imu_lever_arm/dvl_lever_arm, depth_sigma/fix_sigma/heading_sigma [deg], declination "
        "[deg] (pronet.recorded.vehicle), or "
        "a grade's name alone "
        "(default: the FOG tuning of the Snapir AUV)",
    )
    parser.add_argument(
        "--smooth",
        action="store_true",
        help="also run the RTS smoother over every strategy row: each is followed by its "
        "smoothed row ('<label>, smoothed'), scored at the same ground-truth rows",
    )
    for stream, what in (
        ("depth", "depth readings (a depth table or --depth-topic; pronet.recorded.aiding)"),
        ("fixes", "position fixes (a fix table or --fix-topic; pronet.recorded.aiding)"),
        (
            "heading",
            "heading readings (a heading table or --heading-topic; pronet.recorded.heading)",
        ),
        ("dvl", "DVL (a bag's DVL topic is then not read): a GNSS/INS or depth-and-fix run"),
    ):
        parser.add_argument(
            f"--no-{stream}",
            action="store_true",
            help=f"ignore the sections' {what}, e.g. to compare the DVL alone with the "
            "aided filter",
        )
    parser.add_argument(
        "--declination",
        metavar="DEG",
        type=float,
        default=None,
        help="the magnetic declination [deg, east positive] that turns a magnetic heading "
        "(a magnetic_heading column, --heading-magnetic) true (default: --filter's "
        "declination; a magnetic heading without one is refused)",
    )
    parser.add_argument(
        "--aiding-clock",
        choices=AIDING_CLOCKS,
        default="imu",
        help="the clock the depth, fixes and heading are stamped on: the IMU's (their stamps as "
        "given, the default), or the DVL's or the ground truth's as estimated (one logger "
        "stamping both)",
    )
    add_bag_options(parser)
    parser.add_argument("--no-models", action="store_true", help="only the model-based rows")
    parser.add_argument(
        "--model",
        metavar="PATH",
        action="append",
        default=[],
        help="also run this model file as a row 'learned:PATH' (repeatable), e.g. a Q model "
        "trained with 'pronet train --recorded' (docs/how-to/learning-q.md)",
    )
    add_no_plots(parser)
    add_result_folder(parser, "real")
    add_output_flags(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pronet.recorded.real import run_real
    from pronet.recorded.vehicle import load_vehicle

    topics = bag_topics(args)
    if topics is not None:  # before any work: the extra, then the origin
        require_rosbags()
        if topics.origin is None:
            raise ValueError("--format bag: needs --origin LAT,LON,HEIGHT (deg, deg, m)")
    vehicle = None if args.filter is None else load_vehicle(args.filter)
    show = Output(args)
    start = time.perf_counter()

    with Bars(show) as bars, warnings.catch_warnings():
        warnings.simplefilter("always", PlausibilityWarning)
        warnings.showwarning = print_warning  # a vehicle file's arm is named by the file
        out = run_real(
            args.data,
            args.out,
            fmt=args.format if topics is None else topics,
            sections=args.sections.split(",") if args.sections else None,
            imu_lever_arm=args.imu_lever_arm,
            dvl_lever_arm=args.dvl_lever_arm,
            tuning_period=args.tuning_period,
            use_models=not args.no_models,
            models=args.model,
            plots=not args.no_plots,
            dvl_noise=args.dvl_noise,
            formulation=args.formulation,
            covariance_step=args.covariance_step,
            vehicle=vehicle,
            smooth=args.smooth,
            use_depth=not args.no_depth,
            use_fixes=not args.no_fixes,
            use_dvl=not args.no_dvl,
            aiding_clock=args.aiding_clock,
            use_heading=not args.no_heading,
            declination=args.declination,
            on_start=bars.start,
            on_done=bars.done,
        )
    config = json.loads((out / "config.json").read_text())
    n, failed = len(config["sections"]), config["failed_sections"]
    for name, reason in failed.items():  # a warning, also with --quiet and --json
        print(f"pronet: section {name}: {reason} (left out; see table.md)", file=sys.stderr)
    rows = [
        (name, row, why) for name, by in config["rows_failed"].items() for row, why in by.items()
    ]
    for name, row, reason in rows:  # the section's other rows are written
        print(
            f"pronet: section {name}: row {row}: {reason} (left out; see table.md)", file=sys.stderr
        )
    not_drawn = config["figures_failed"].items()
    figures = [(name, file, why) for name, by in not_drawn for file, why in by.items()]
    for name, file, reason in figures:  # the tables and the other figures are written
        print(f"pronet: section {name}: figure {file}: {reason} (not written)", file=sys.stderr)
    for note in config["notes"]:  # what the filters know: out-of-band streams, divergence
        print(f"pronet: {note}", file=sys.stderr)
    left_out = f" ({len(failed)} left out)" if failed else ""
    left_out += f" ({len(rows)} rows failed)" if rows else ""
    left_out += f" ({len(figures)} figures not written)" if figures else ""
    show.result(
        f"{(out / 'table.md').read_text()}\n{n} section{'' if n == 1 else 's'}{left_out}; "
        f"results written to {out} "
        f"in {time.perf_counter() - start:.0f} s",
        {"folder": str(out), "metrics": json.loads((out / "metrics.json").read_text())},
    )
    return 0
