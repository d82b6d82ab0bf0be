"""Every section of ``pronet real`` read, checked and aligned side by side on the usable
cores, before any filter runs (:func:`read_sections`): a section that cannot be (a
corrupt bag, implausible data, no ground truth) is its one-line reason, naming the
file, beside the others, which are read all the same. A Snapir section carries its
truth's stated velocity error (:mod:`pronet.recorded.trutherror`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import closing
from dataclasses import replace
from pathlib import Path

from pronet._util.cores import usable_cores
from pronet._util.waiting import results_in_order
from pronet.recorded.aiding import AidingTuning
from pronet.recorded.alignment import (
    NO_TRUTH_FOR_REAL,
    Format,
    Section,
    load_section,
    section_name,
)
from pronet.recorded.passes import aided_section
from pronet.recorded.trutherror import SNAPIR_TRUTH_VELOCITY_SIGMA


def read_sections(
    paths: Sequence[Path],
    fmt: Format,
    arms: tuple[tuple[float, float, float], tuple[float, float, float] | None],
    clock_declination: tuple[str, float | None],
    aiding: AidingTuning,
    on_done: Callable[[str], None] | None,
) -> tuple[list[tuple[Section, Section]], dict[str, str]]:
    """Every section under ``paths`` read and aligned on the usable cores, in order, with
    the streams ``aiding`` leaves (``--no-dvl``/``--no-depth``/``--no-fixes``/
    ``--no-heading``) and their σ: the sections read, and the reason (naming the file)
    for each one that could not be (or has no ground truth to score against), by
    section name. ``arms``: the IMU's and the DVL's lever arm [m, body FRD], the DVL's
    None where its readings go unused; ``clock_declination``: the depth, fixes and
    heading's clock and a magnetic heading's declination [deg]."""

    def read(path: Path) -> tuple[Section, Section] | str:
        try:
            return load_section(
                path,
                fmt,
                imu_lever_arm=arms[0],
                dvl_lever_arm=arms[1],
                aiding_clock=clock_declination[0],
                declination=clock_declination[1],
                read_heading=aiding.use_heading,
            )
        except (ValueError, OSError) as exc:  # the reason (it names the file)
            return str(exc)

    loaded: list[tuple[Section, Section]] = []
    unread: dict[str, str] = {}
    with (
        ThreadPoolExecutor(max_workers=usable_cores()) as pool,
        closing(results_in_order([pool.submit(read, path) for path in paths])) as reading,
    ):  # closed however the loop ends: the reads not yet started are cancelled
        for path, section in zip(paths, reading, strict=True):  # in order
            try:
                if isinstance(section, str):
                    raise ValueError(section)
                if not section[0].has_truth:
                    raise ValueError(f"no ground truth: {NO_TRUTH_FOR_REAL}")
                loaded.append(
                    (
                        aided_section(stated_truth_error(section[0], fmt), aiding),
                        aided_section(stated_truth_error(section[1], fmt), aiding),
                    )
                )
            except ValueError as exc:
                unread[section_name(path)] = str(exc)
            if on_done is not None:
                on_done(path.name)
    return loaded, unread


def stated_truth_error(section: Section, fmt: Format) -> Section:
    """``section`` with the truth's velocity error its format states: the Snapir
    truth's (:data:`pronet.recorded.trutherror.SNAPIR_TRUTH_VELOCITY_SIGMA`) for the
    ``snapir`` format, none for the others (their truth's error is not known here)."""
    if fmt != "snapir" or not section.has_truth:
        return section
    return replace(section, truth_velocity_sigma=SNAPIR_TRUTH_VELOCITY_SIGMA)
