"""``pronet navigate``: navigate a recording of your own vehicle, with or without a
ground truth (:func:`pronet.recorded.navigate.navigate_recording`), and write the
trajectory, the track, the report and the figures (:func:`pronet.recorded.export.
write_all`)."""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from pronet.cli._common import (
    Output,
    Subparsers,
    add_bag_options,
    add_no_plots,
    add_output_flags,
    add_result_folder,
    bag_topics,
    vector3,
)
from pronet.recorded.alignment import FORMATS
from pronet.recorded.bags import BagTopics, require_rosbags
from pronet.recorded.plausible import PlausibilityWarning

if TYPE_CHECKING:
    from pronet.recorded.solution import Navigation

#: The storages of ``--bag`` (``none``: no odometry bag).
BAG_STORAGES = ("rosbag1", "sqlite3", "mcap", "none")


def _still(text: str) -> tuple[float, float] | str:  # "auto" or "none" as given
    """``auto``, ``none`` or ``START,END`` [s]."""
    if text in ("auto", "none"):
        return text
    try:
        a, b = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected auto, none or START,END in seconds, got {text!r}"
        ) from None
    return a, b


def _position(text: str) -> tuple[float, float, float]:
    """``LAT,LON,DEPTH`` [deg, deg, m down] as the initial state takes them (finite, the
    latitude within ±89°, the longitude within the core's range, a depth in the ocean),
    or the error argparse reports."""
    from pronet._core import LONGITUDE_RANGE_DEG
    from pronet.recorded.initialinputs import DEPTH_RANGE, MAX_GIVEN_LATITUDE

    try:
        lat, lon, depth = vector3(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"expected LAT,LON,DEPTH in deg, deg, m, got {text!r}"
        ) from None
    west, east = LONGITUDE_RANGE_DEG
    if not all(math.isfinite(v) for v in (lat, lon, depth)):
        raise argparse.ArgumentTypeError(f"expected finite LAT,LON,DEPTH, got {text!r}")
    if abs(lat) > MAX_GIVEN_LATITUDE:
        raise argparse.ArgumentTypeError(
            f"latitude {lat:g}° is beyond ±{MAX_GIVEN_LATITUDE:g}°, got {text!r}"
        )
    if not west <= lon <= east:
        raise argparse.ArgumentTypeError(
            f"longitude {lon:g}° is beyond {west:g} … {east:g}°, got {text!r}"
        )
    if not DEPTH_RANGE[0] <= depth <= DEPTH_RANGE[1]:
        raise argparse.ArgumentTypeError(
            f"depth {depth:g} m is beyond {DEPTH_RANGE[0]:g} … {DEPTH_RANGE[1]:g} m (metres, "
            f"positive down: the deepest ocean is 11 km), got {text!r}; in pascals?"
        )
    return lat, lon, depth


def _heading(text: str) -> float:
    """A heading [deg] within ±360° (a heading file's bound), or the error argparse
    reports."""
    from pronet.recorded.initialinputs import MAX_GIVEN_HEADING

    value = _degrees(text)
    if abs(value) > MAX_GIVEN_HEADING:
        raise argparse.ArgumentTypeError(
            f"{value:g}° is beyond -{MAX_GIVEN_HEADING:g} … {MAX_GIVEN_HEADING:g}° (a heading "
            "from true north); in another unit?"
        )
    return value


def _sigma(text: str) -> float:
    """A heading's 1σ [deg]: finite and > 0, or the error argparse reports."""
    value = _degrees(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected a 1σ in degrees > 0, got {text}")
    return value


def _degrees(text: str) -> float:
    """A finite number of degrees, or the error argparse reports."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected degrees, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number of degrees, got {text}")
    return value


def _add_init(parser: argparse.ArgumentParser) -> None:
    """The initial-state options (:mod:`pronet.recorded.initial`)."""
    init = parser.add_argument_group("initial state (pronet.recorded.initial)")
    init.add_argument(
        "--init",
        choices=("data", "truth"),
        default="data",
        help="data: from the recording (fixes and depth, levelling while still, a heading "
        "stream or gyrocompassing), the given parts winning; truth: the ground truth's "
        "first row with the vehicle's P0, as pronet real (default data)",
    )
    init.add_argument(
        "--init-position",
        metavar="LAT,LON,DEPTH",
        type=_position,
        default=None,
        help="the IMU's starting latitude, longitude [deg] and depth [m, down]",
    )
    init.add_argument(
        "--init-heading",
        metavar="DEG",
        type=_heading,
        default=None,
        help="the starting heading [deg, from true north]",
    )
    init.add_argument(
        "--init-heading-sigma",
        metavar="DEG",
        type=_sigma,
        default=None,
        help="its 1σ [deg] (default the given state's, 5°)",
    )
    init.add_argument(
        "--still",
        metavar="START,END",
        type=_still,
        default="auto",
        help="the interval the vehicle rests in for levelling [s from the recording's "
        "start], or auto (detected, the default) or none",
    )


def add_parser(sub: Subparsers) -> None:
    parser = sub.add_parser(
        "navigate",
        help="navigate a recording of your own vehicle (no ground truth needed): "
        "trajectory.csv, track.geojson, report.md",
    )
    parser.add_argument(
        "--data",
        metavar="PATH",
        required=True,
        help="one recording: a folder of CSVs, one .npz, or a ROS bag (never copied)",
    )
    parser.add_argument(
        "--format",
        choices=FORMATS,
        default="generic",
        help="generic (the default), snapir or bag (ROS 1 or ROS 2; pronet.recorded.bags)",
    )
    parser.add_argument(
        "--filter",
        metavar="FILE",
        default="mems",
        help="your vehicle's tuning: a TOML file (pronet.recorded.vehicle: grade, P0, R, "
        "lever arms, σ, declination, surface_depth) or a grade's name (default mems)",
    )
    for sensor, what in (
        ("imu", "IMU"),
        ("dvl", "DVL"),
        ("depth", "pressure sensor"),
        ("fix", "fix's antenna or transponder"),
    ):
        parser.add_argument(
            f"--{sensor}-lever-arm",
            metavar="X,Y,Z",
            type=vector3,
            default=None,
            help=f"the {what}'s position from the vehicle's reference point, x,y,z [m, "
            "body FRD] (default --filter's, else "
            + ("0: the trajectory is the IMU's)" if sensor == "imu" else "at the IMU)"),
        )
    for stream in ("dvl", "depth", "fixes", "heading"):
        parser.add_argument(
            f"--no-{stream}", action="store_true", help=f"do not use the recording's {stream}"
        )
    parser.add_argument(
        "--declination",
        metavar="DEG",
        type=float,
        default=None,
        help="the magnetic declination [deg, east positive] of a magnetic heading "
        "(default --filter's)",
    )
    parser.add_argument(
        "--surface-depth",
        metavar="M",
        type=float,
        default=None,
        help="the pressure sensor's depth while the vehicle floats [m] (default --filter's, "
        "else 0): the surface pressure is measured there, beside fixes",
    )
    parser.add_argument(
        "--surface-offset",
        metavar="M",
        type=float,
        default=None,
        help="the depth's surface offset to take off [m] (default: measured at the surface "
        "beside fixes; 0: the reader's surface pressure as it is)",
    )
    parser.add_argument(
        "--strategy",
        default="constant",
        help="the process-noise strategy (constant, mehra:N, adaptive:N, detvar, "
        "learned:NAME), around the recording's own IMU noise (default constant)",
    )
    parser.add_argument("--no-smooth", action="store_true", help="the filter alone")
    parser.add_argument(
        "--bag",
        choices=BAG_STORAGES,
        default=None,
        help="also write the solution as nav_msgs/Odometry in a bag of this storage "
        "(default: with --format bag, the input's, rosbag1 for a .bag file and mcap for a "
        "ROS 2 bag; else none)",
    )
    _add_init(parser)
    add_bag_options(parser)
    add_no_plots(parser)
    add_result_folder(parser, "navigate")
    add_output_flags(parser)
    parser.set_defaults(func=run)


def _one_recording(data: str) -> None:
    """ValueError where ``--data`` is a folder of recordings (``pronet real``'s data:
    sections in sub-folders, ``.npz`` files, bags), not one: naming a few and the one
    to give (the reader said ``no imu.csv``)."""
    from pronet.recorded.alignment import find_sections, section_name

    path = Path(data)
    try:
        found = find_sections(path) if path.is_dir() else [path]
    except ValueError:  # no recording in it: the reader names what is missing
        return
    if found != [path]:
        names = ", ".join(section_name(p) for p in found[:3]) + (", …" if len(found) > 3 else "")
        raise ValueError(
            f"--data: {path} is a folder of {len(found)} recording"
            f"{'' if len(found) == 1 else 's'} ({names}); pronet navigate takes one "
            f"(--data {found[0]}), pronet real all of them"
        )


def _given(args: argparse.Namespace):  # noqa: ANN202
    """The given parts of the initial state (None for none); ValueError for a heading's
    σ without the heading (it was dropped without a word)."""
    from pronet.recorded.initialinputs import GivenState

    if args.init_heading_sigma is not None and args.init_heading is None:
        raise ValueError(
            "--init-heading-sigma: the 1σ of --init-heading, which is not given (the heading "
            "found in the data has the σ its method earns)"
        )
    if args.init_position is None and args.init_heading is None:
        return None
    lla = depth = None
    if args.init_position is not None:
        lat, lon, d = args.init_position
        lla, depth = (math.radians(lat), math.radians(lon), math.nan), d
    heading = None if args.init_heading is None else math.radians(args.init_heading)
    sigma = None if args.init_heading_sigma is None else math.radians(args.init_heading_sigma)
    return GivenState(lla=lla, depth=depth, heading=heading, heading_sigma=sigma)


def _navigate(
    args: argparse.Namespace, topics: BagTopics | None, bag: str | None
) -> tuple[Navigation, Path, list[Path]]:
    """Navigate the recording as the options say and write the files: the navigation,
    the folder and the paths written."""
    from pronet.recorded.export import check_out_dir, write_all
    from pronet.recorded.navigate import NavigateOptions, lever_arms, navigate_recording
    from pronet.recorded.vehicle import load_vehicle

    vehicle = load_vehicle(args.filter)
    if args.declination is not None:
        vehicle = replace(vehicle, declination=args.declination)
    arms = lever_arms(
        vehicle, imu=args.imu_lever_arm, dvl=args.dvl_lever_arm,
        depth=args.depth_lever_arm, fix=args.fix_lever_arm, given_as="--{}-lever-arm",
    )  # fmt: skip
    options = NavigateOptions(
        use_dvl=not args.no_dvl, use_depth=not args.no_depth, use_fixes=not args.no_fixes,
        use_heading=not args.no_heading, smooth=not args.no_smooth, init=args.init,
        given=_given(args), strategy=args.strategy, still=args.still,
        surface_offset=args.surface_offset,
        surface_depth=args.surface_depth if args.surface_depth is not None
        else (vehicle.surface_depth or 0.0),
    )  # fmt: skip
    out = Path(args.out or f"results/navigate-{time.strftime('%Y%m%d-%H%M%S')}")
    check_out_dir(out, "--out")  # before the work, not after it
    _one_recording(args.data)
    navigation = navigate_recording(
        args.data, args.format if topics is None else topics, vehicle, arms, options
    )
    paths = write_all(navigation, out, bag=bag, figures=not args.no_plots)
    return navigation, out, paths


def run(args: argparse.Namespace) -> int:
    from pronet.recorded.report import FIGURES

    topics = bag_topics(args)
    if topics is not None:
        require_rosbags()
        if args.truth_topic is None:  # a truth is read only where named
            topics = replace(topics, truth=None, origin=None)
    bag = args.bag
    if bag is None and topics is not None:  # a bag in: the solution as a bag out
        bag = "rosbag1" if Path(args.data).suffix == ".bag" else "mcap"
    bag = None if bag == "none" else bag
    if bag is not None:
        require_rosbags()
    show = Output(args)
    start = time.perf_counter()
    with warnings.catch_warnings():  # every warning one line, from the options on
        warnings.simplefilter("always", PlausibilityWarning)
        warnings.showwarning = lambda m, *_, **__: print(f"pronet: warning: {m}", file=sys.stderr)
        navigation, out, paths = _navigate(args, topics, bag)
    for note in navigation.notes:  # what the filter knows, also with --quiet and --json
        print(f"pronet: {note}", file=sys.stderr)
    for name in [] if args.no_plots else sorted(set(FIGURES) - {p.name for p in paths}):
        print(
            f"pronet: figure {name} could not be drawn (not written; see report.md)",
            file=sys.stderr,
        )
    lines = [f"{navigation.name}: {len(navigation.forward.time)} epochs"]
    lines += [
        f"  {s.name}: {s.applied} applied, mean NIS {s.mean_nis:.3g}" for s in navigation.streams
    ]
    lines.append(f"written to {out} in {time.perf_counter() - start:.0f} s")
    show.result(
        "\n".join(lines),
        {
            "folder": str(out),
            "files": [str(p) for p in paths],
            "notes": list(navigation.notes),
            "initial_state": dict(navigation.initial.methods),
            "score": navigation.score,
        },
    )
    return 0
