"""What the commands share: where their words go (``--quiet``, ``--json``), progress
bars over the library's callbacks, and the options several commands take."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, NoReturn, TypeAlias

from pronet._util.files import json_bytes
from pronet.recorded.bags import BagTopics

if TYPE_CHECKING:
    from tqdm import tqdm

    from pronet.learn.dataset import Dataset, DatasetParams

#: What ``add_subparsers`` returns: each command module adds its parser to it.
Subparsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"


class Output:
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
            sys.stdout.write(json_bytes(data).decode())  # NaN and infinities as null
        else:
            print(text)

    def bar(self, total: int, unit: str, desc: str | None = None) -> tqdm[NoReturn]:
        """A progress bar of ``total`` steps (hidden with ``--quiet``)."""
        from tqdm.auto import tqdm

        return tqdm(total=total, unit=unit, desc=desc, disable=self.quiet)


class Bars:
    """The library's progress callbacks (``say``, ``on_start``, ``on_done``) as one tqdm
    bar per stage; used as a context manager, the last bar is closed on the way out
    (before any interrupt or error is reported)."""

    def __init__(self, show: Output) -> None:
        self.show = show
        self._bar: tqdm[NoReturn] | None = None

    def say(self, text: str) -> None:
        self.show.say(text)

    def start(self, total: int, unit: str, desc: str | None) -> None:
        self.close()
        self._bar = self.show.bar(total, unit, desc)

    def done(self, label: str) -> None:
        if self._bar is not None:
            self._bar.set_postfix_str(label)
            self._bar.update()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Bars:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


#: Library arguments whose errors and warnings reach the command line, and the options
#: that set them.
OPTIONS = {
    "n_runs": "--runs",
    "n_levels": "--levels",
    "seed": "--seed",
    "threads": "--threads",
    "imu_lever_arm": "--imu-lever-arm",
    "dvl_lever_arm": "--dvl-lever-arm",
    "surface_offset": "--surface-offset",
    "still": "--still",
    "tuning_period": "--tuning-period",
}


def as_option(line: str) -> str:
    """``line`` (``"<argument>: <reason>"``) with a library argument of :data:`OPTIONS`
    named as the command line spells it."""
    field, sep, reason = line.partition(": ")
    option = OPTIONS.get(field)
    return f"{option}: {reason}" if sep and option else line


def print_warning(message: Warning | str, *_: object, **__: object) -> None:
    """A warning as one line on stderr (also with ``--quiet``), a library argument named
    as its option (:func:`as_option`): for ``warnings.showwarning``."""
    print(f"pronet: warning: {as_option(str(message))}", file=sys.stderr)


def experiment_result(show: Output, folder: Path, start: float) -> None:
    """Print a written experiment folder's tables (or, with --json, its metrics)."""
    show.result(
        (folder / "table.md").read_text()
        + f"\nresults written to {folder} in {time.perf_counter() - start:.0f} s",
        {"folder": str(folder), "metrics": json.loads((folder / "metrics.json").read_text())},
    )


def out_path(text: str) -> str:
    """An ``--out`` path as given, or the error argparse reports for an empty one (it
    fell back to the default folder without a word)."""
    if not text.strip():
        raise argparse.ArgumentTypeError(
            f"expected a path, got {text!r}; leave the option out for its default"
        )
    return text


def add_result_folder(parser: argparse.ArgumentParser, command: str) -> None:
    """--out: the result folder of an experiment command (default results/COMMAND-<time>)."""
    parser.add_argument(
        "--out",
        metavar="PATH",
        type=out_path,
        default=None,
        help=f"result folder (default results/{command}-<time>)",
    )


def add_output_flags(parser: argparse.ArgumentParser) -> None:
    """--quiet and --json."""
    parser.add_argument("--quiet", action="store_true", help="no progress bars or messages")
    parser.add_argument(
        "--json",
        action="store_true",
        help="print the result as one JSON document on stdout (messages go to stderr)",
    )


def add_monte_carlo_args(parser: argparse.ArgumentParser) -> None:
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
        "--threads",
        metavar="N",
        type=int,
        default=None,
        help="worker threads (default: one per core, or RAYON_NUM_THREADS; at most 8 per core)",
    )


def add_tuning_period(parser: argparse.ArgumentParser) -> None:
    """--tuning-period."""
    parser.add_argument(
        "--tuning-period",
        metavar="SECONDS",
        type=float,
        default=1.0,
        help="seconds between the learned rows' regressor calls, and detvar's estimates "
        "(default 1 s)",
    )


def add_no_plots(parser: argparse.ArgumentParser) -> None:
    """--no-plots."""
    parser.add_argument(
        "--no-plots",
        action="store_true",
        help="tables and metrics only (the plots take most of the time of a short run)",
    )


def add_dataset_args(parser: argparse.ArgumentParser) -> None:
    """--dataset and --data-seed, as train and evaluate take them."""
    parser.add_argument(
        "--dataset",
        metavar="FILE",
        default=None,
        help="dataset .npz (default: regenerate from --data-seed)",
    )
    parser.add_argument(
        "--data-seed",
        metavar="N",
        type=int,
        default=None,
        help="seed of the regenerated dataset (default 0); train --simulated: of the first "
        "simulated recording",
    )


def dataset_for(args: argparse.Namespace) -> tuple[Dataset, DatasetParams]:
    """The dataset named by ``--dataset``, or the default one regenerated from
    ``--data-seed``."""
    from pronet.learn import dataset

    if args.dataset:
        try:
            return dataset.load_dataset(args.dataset), dataset.load_params(args.dataset)
        except ValueError as exc:  # the library names its argument, path
            raise ValueError(f"--dataset: {str(exc).removeprefix('path: ')}") from None
    if args.data_seed is not None and args.data_seed < 0:
        raise ValueError(f"--data-seed: must be >= 0, got {args.data_seed}")
    params = dataset.DatasetParams(seed=0 if args.data_seed is None else args.data_seed)
    Output(args).say(f"generating the dataset (seed {params.seed}) ...")
    return dataset.build_dataset(params), params


def vector3(text: str) -> tuple[float, float, float]:
    """``x,y,z`` as three floats [m], or the error argparse reports."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected x,y,z in metres, got {text!r}") from None
    if len(values) != 3:
        raise argparse.ArgumentTypeError(f"expected three comma-separated numbers, got {text!r}")
    return values[0], values[1], values[2]


def origin_arg(text: str) -> tuple[float, float, float]:
    """``lat,lon,height`` [deg, deg, m] as three floats, or the error argparse reports."""
    try:
        return vector3(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"expected LAT,LON,HEIGHT in deg, deg, m, got {text!r}"
        ) from None


def add_bag_options(parser: argparse.ArgumentParser) -> None:
    """The options of ``--format bag`` (:class:`pronet.recorded.bags.BagTopics`)."""
    bag = parser.add_argument_group("ROS bags (--format bag; pip install 'pronet[rosbags]')")
    defaults = BagTopics()
    for name, what, types in (
        ("imu", "IMU", "sensor_msgs/msg/Imu"),
        ("dvl", "DVL", "geometry_msgs/msg/TwistWithCovarianceStamped or TwistStamped"),
        ("truth", "ground truth", "nav_msgs/msg/Odometry or geometry_msgs/msg/PoseStamped"),
        ("depth", "depth (pressure)", "sensor_msgs/msg/FluidPressure"),
        ("fix", "position-fix", "sensor_msgs/msg/NavSatFix"),
        (
            "heading",
            "heading",
            "the orientation of sensor_msgs/msg/Imu (may be the IMU topic: an AHRS's), "
            "geometry_msgs/msg/QuaternionStamped, PoseStamped or PoseWithCovarianceStamped",
        ),
    ):
        bag.add_argument(
            f"--{name}-topic",
            metavar="TOPIC",
            default=None,
            help=f"the {what} topic, {types} (default {getattr(defaults, name) or 'none read'})",
        )
    bag.add_argument(
        "--water-density",
        metavar="KG_M3",
        type=float,
        default=None,
        help=f"the water's density of the pressure-to-depth conversion (default "
        f"{defaults.water_density:g}, sea water)",
    )
    bag.add_argument(
        "--surface-pressure",
        metavar="PA",
        type=float,
        default=None,
        help=f"the pressure at the surface taken off the depth topic's (default "
        f"{defaults.surface_pressure:g}, the standard atmosphere; 0 for a gauge sensor)",
    )
    bag.add_argument(
        "--heading-magnetic",
        action="store_true",
        default=None,
        help="the heading topic's yaw is from magnetic north (turned true with --declination)",
    )
    bag.add_argument(
        "--origin",
        metavar="LAT,LON,HEIGHT",
        type=origin_arg,
        default=None,
        help="the geodetic origin [deg, deg, m up] of the truth's local positions (required "
        "with --format bag: a bag's poses are metres in a local frame)",
    )
    bag.add_argument(
        "--body-frame",
        choices=("flu", "frd"),
        default=None,
        help="the IMU's, DVL's and truth's body frame (default flu, REP-103)",
    )
    bag.add_argument(
        "--world-frame",
        choices=("enu", "ned"),
        default=None,
        help="the truth's local world frame (default enu, REP-103)",
    )


def bag_topics(args: argparse.Namespace) -> BagTopics | None:
    """The bag's topics and frames from the options (None unless ``--format bag``);
    ValueError for a bag option with another format."""
    options = {  # field: (option, value)
        "imu": ("--imu-topic", args.imu_topic),
        "dvl": ("--dvl-topic", args.dvl_topic),
        "truth": ("--truth-topic", args.truth_topic),
        "origin": ("--origin", args.origin),
        "body_frame": ("--body-frame", args.body_frame),
        "world_frame": ("--world-frame", args.world_frame),
        "depth": ("--depth-topic", args.depth_topic),
        "fix": ("--fix-topic", args.fix_topic),
        "heading": ("--heading-topic", args.heading_topic),
        "heading_magnetic": ("--heading-magnetic", args.heading_magnetic),
        "water_density": ("--water-density", args.water_density),
        "surface_pressure": ("--surface-pressure", args.surface_pressure),
    }
    given = {k: value for k, (_, value) in options.items() if value is not None}
    if args.format != "bag":
        if given:
            names = ", ".join(options[k][0] for k in given)
            raise ValueError(f"{names}: only with --format bag")
        return None
    if args.no_dvl:
        given["dvl"] = None
    if args.no_heading:
        given["heading"] = None
    return BagTopics(**given)
