"""The deprecated form of :func:`pronet.run_filter`, ``run_filter(imu, imu_time, dvl,
dvl_time, *, depth=, depth_time=, depth_sigma=, fix=, fix_time=, fix_sigma=)``, turned
into the streams it stands for (kept for one release)."""

from __future__ import annotations

import warnings
from typing import Any, TypeAlias

from pronet import _core
from pronet._util.validate import float_array, scalar

#: An aiding sensor's stream, as :func:`pronet.run_filter` takes them.
Stream: TypeAlias = _core.Dvl | _core.Depth | _core.Fix | _core.Heading

#: The deprecated keywords of :func:`pronet.run_filter` (its arrays before streams).
DEPRECATED = (
    "dvl",
    "dvl_time",
    "depth",
    "depth_time",
    "depth_sigma",
    "fix",
    "fix_time",
    "fix_sigma",
)


def deprecated_streams(
    first: object, positional: tuple[object, ...], keywords: dict[str, Any]
) -> list[Stream]:
    """The streams of the deprecated form ``run_filter(imu, imu_time, dvl, dvl_time, *,
    depth=, depth_time=, depth_sigma=, fix=, fix_time=, fix_sigma=)``, with its warning;
    an error as Python's or the old form's own would be."""
    unknown = [k for k in keywords if k not in DEPRECATED]
    if unknown:
        raise TypeError(f"run_filter() got an unexpected keyword argument {unknown[0]!r}")
    if len(positional) > 1:
        raise TypeError(
            f"run_filter() takes from 2 to 4 positional arguments but {3 + len(positional)} "
            "were given"
        )
    old = dict(keywords)
    if positional:
        for name, value in (("dvl", first), ("dvl_time", positional[0])):
            if name in old:
                raise TypeError(f"run_filter() got multiple values for argument {name!r}")
            old[name] = value
    elif not (isinstance(first, tuple | list) and len(first) == 0):
        raise ValueError(
            "streams: give the sensors as streams or as the deprecated arrays "
            f"({', '.join(sorted(old))}), not both"
        )
    for name in ("dvl", "dvl_time"):
        if name not in old:
            raise TypeError(f"run_filter() missing required argument: {name!r}")
    warnings.warn(
        "run_filter(imu, imu_time, dvl, dvl_time, depth=..., fix=...) is deprecated: pass "
        "the sensors as streams, run_filter(imu, imu_time, [pronet.Dvl(dvl_time, dvl), "
        "pronet.Depth(depth_time, depth, sigma=depth_sigma), pronet.Fix(fix_time, fix, "
        "sigma=fix_sigma)], ...)",
        DeprecationWarning,
        stacklevel=3,
    )
    streams: list[Stream] = [
        _old_names(
            lambda: _core.Dvl(
                float_array(old["dvl_time"], "dvl_time", (None,)),
                float_array(old["dvl"], "dvl", (None, 3)),
            ),
            {"time": "dvl_time", "velocity": "dvl"},
        )
    ]
    if _group(old, "depth"):
        streams.append(
            _old_names(
                lambda: _core.Depth(
                    float_array(old["depth_time"], "depth_time", (None,)),
                    float_array(old["depth"], "depth", (None,)),
                    sigma=scalar(old["depth_sigma"], "depth_sigma"),
                ),
                {"time": "depth_time", "sigma": "depth_sigma"},
            )
        )
    if _group(old, "fix"):
        streams.append(
            _old_names(
                lambda: _core.Fix(
                    float_array(old["fix_time"], "fix_time", (None,)),
                    float_array(old["fix"], "fix", (None, 3)),
                    sigma=float_array(old["fix_sigma"], "fix_sigma", (None, 3)),
                ),
                {"time": "fix_time", "lla": "fix", "sigma": "fix_sigma"},
            )
        )
    return streams


def _group(old: dict[str, Any], name: str) -> bool:
    """Whether the deprecated keywords ``old`` give the group ``name`` (``name``,
    ``name_time``, ``name_sigma``: all three or none, else ``ValueError``)."""
    names = (name, f"{name}_time", f"{name}_sigma")
    given = [old.get(n) is not None for n in names]
    if any(given) and not all(given):
        raise ValueError(
            f"{name}: {name}, {name}_time and {name}_sigma go together: give all three or none"
        )
    return all(given)


def _old_names(make: Any, names: dict[str, str]) -> Stream:
    """``make()``, its ``ValueError`` naming the deprecated form's argument (``names``:
    the stream's argument to it)."""
    try:
        stream: Stream = make()
    except ValueError as e:
        arg, sep, reason = str(e).partition(": ")
        if sep and arg in names:
            raise ValueError(f"{names[arg]}: {reason}") from None
        raise
    return stream
