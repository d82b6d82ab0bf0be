"""What a navigated recording (:class:`pronet.recorded.solution.Navigation`) looks like:
three figures and ``report.md``, which :func:`pronet.recorded.export.write_all` writes
beside the trajectory.

Figures (matplotlib's Agg canvas, as :mod:`pronet.plots` draws; one PNG each):

- ``track.png`` (:func:`track_figure`): each solution's track in local north-east metres
  about the forward solution's first position, its 3σ ellipses at
  :data:`ELLIPSES` epochs spread over the run, and the position fixes. The ellipses are
  axis-aligned, semi-axes 3σ_E and 3σ_N: a solution holds the position's σ, not the
  north-east correlation that would turn them;
- ``depth_heading.png`` (:func:`depth_heading_figure`): depth and heading (yaw) over
  time with ±3σ bands (``sigma_d``, and ``sigma_yaw`` of
  :func:`pronet.recorded.attitude.attitude_sigma`) and the depth and heading readings;
- ``innovations.png`` (:func:`innovations_figure`): each stream's NIS / dof per reading
  over time (log scale) with the 95 % band of one reading (χ² of ``dof`` degrees of
  freedom, over ``dof``), the mean and its 95 % band, and the readings the innovation
  gate rejected marked (red triangles at the top).

``report.md`` (:func:`report_markdown`): the recording, the solutions' final σ, the
initial state and the method of each part, per stream the readings applied, rejected
and skipped, the mean NIS against its band and the flag, the surface pressure and where
it came from, the notes, the score against a truth when there is one, and the files.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from pronet._util.files import atomic_write
from pronet.plots.figures import _figure, _log_y, png_bytes
from pronet.plots.sections import TAB10
from pronet.recorded.attitude import attitude_sigma, yaw_degrees

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from pronet.recorded.odometry import OdometryOptions
    from pronet.recorded.solution import Navigation, Solution
    from pronet.stats import StreamReport

F64 = NDArray[np.float64]

#: The report's file name.
REPORT = "report.md"
#: The figures, in the order written.
FIGURES = ("track.png", "depth_heading.png", "innovations.png")
#: 3σ ellipses drawn per solution on ``track.png``.
ELLIPSES = 30
#: Points per line beyond which a series is drawn thinned (every k-th, the last kept).
MAX_LINE_POINTS = 4000
#: Colours of the forward and the smoothed solution.
COLOURS = {"forward": TAB10[0], "smoothed": TAB10[1]}


def _thin(n: int) -> NDArray[np.intp]:
    """Indices of ``n`` samples drawn: every k-th and the last, about
    :data:`MAX_LINE_POINTS` at most."""
    k = max(1, -(-n // MAX_LINE_POINTS))
    return np.unique(np.r_[np.arange(0, n, k), n - 1]) if n else np.arange(0)


def _spread(n: int, most: int) -> NDArray[np.intp]:
    """At most ``most`` indices of ``n`` spread evenly."""
    return np.unique(np.linspace(0, n - 1, min(n, most)).round().astype(np.intp))


def chi2_quantile(p: float, dof: float) -> float:
    """The ``p`` quantile of χ² with ``dof`` (> 0, not necessarily whole) degrees of
    freedom: the regularised lower incomplete gamma ``P(dof/2, x/2)`` by its series,
    inverted by bisection (to 1e-12 relative)."""
    a = dof / 2.0

    def cdf(x: float) -> float:
        if x <= 0.0:
            return 0.0
        y, term, total, k = x / 2.0, 1.0 / a, 1.0 / a, 0
        while term > total * 1e-17 and k < 10_000:
            k += 1
            term *= y / (a + k)
            total += term
        return min(1.0, total * math.exp(-y + a * math.log(y) - math.lgamma(a)))

    lo, hi = 0.0, dof + 40.0 * math.sqrt(2.0 * dof) + 40.0
    while hi - lo > 1e-12 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if cdf(mid) < p else (lo, mid)
    return 0.5 * (lo + hi)


def _east_north(lla: F64, origin: F64) -> F64:
    """``(n, 2)`` east, north [m] of ``lla`` about ``origin`` (NaN where not finite)."""
    from pronet.navigation import local_ned

    out = np.full((len(lla), 2), np.nan)
    ok = np.isfinite(lla).all(axis=1)
    if ok.any():
        out[ok] = local_ned(lla[ok], origin)[:, [1, 0]]
    return out


def track_figure(navigation: Navigation) -> Figure:
    """``track.png``'s figure (module docstring)."""
    from matplotlib.collections import EllipseCollection

    fig = _figure(7.5, 7.0)
    ax = fig.subplots()
    fwd = np.asarray(navigation.forward.lla, dtype=np.float64)
    origin = fwd[np.flatnonzero(np.isfinite(fwd).all(axis=1))[0]]
    for sol in navigation.solutions:
        en = _east_north(np.asarray(sol.lla, dtype=np.float64), origin)
        colour = COLOURS[sol.label]
        rows = _thin(len(en))
        ax.plot(en[rows, 0], en[rows, 1], color=colour, lw=1.0, label=sol.label)
        at = _spread(len(en), ELLIPSES)
        sigma = np.asarray(sol.sigma, dtype=np.float64)[at]
        ax.add_collection(
            EllipseCollection(
                6.0 * sigma[:, 1],
                6.0 * sigma[:, 0],
                np.zeros(len(at)),
                units="xy",
                offsets=en[at],
                offset_transform=ax.transData,
                facecolors="none",
                edgecolors=colour,
                linewidths=0.8,
                alpha=0.7,
            )
        )
        ax.plot([], [], "o", mfc="none", color=colour, label=f"{sol.label} 3σ (σ_E, σ_N)")
    if "fix" in navigation.readings:
        fixes = _east_north(np.asarray(navigation.readings["fix"][1], dtype=np.float64), origin)
        ax.plot(fixes[:, 0], fixes[:, 1], "+", color="black", ms=5, label="fixes")
    ax.plot(0.0, 0.0, "o", color="tab:green", label="start")
    ax.set(xlabel="east [m]", ylabel="north [m]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    fig.suptitle(
        f"{navigation.name}: track about the first position, 3σ ellipses axis-aligned "
        "(σ_N, σ_E; the correlation is not in the solution)",
        fontsize=9,
    )
    return fig


def _band(ax: Any, time: F64, value: F64, sigma: F64, colour: str, label: str) -> None:
    """A thinned line and its ±3σ band."""
    rows = _thin(len(time))
    t, v, s = time[rows], value[rows], sigma[rows]
    ax.plot(t, v, color=colour, lw=1.0, label=label)
    ax.fill_between(t, v - 3 * s, v + 3 * s, color=colour, alpha=0.2, lw=0, label=f"{label} ±3σ")


def _continuous_yaw(sol: Solution) -> F64:
    """The yaw [deg] unwrapped, its first value in [0, 360)."""
    yaw = np.degrees(np.unwrap(np.asarray(sol.rpy, dtype=np.float64)[:, 2]))
    return yaw - 360.0 * np.floor(yaw[0] / 360.0)


def depth_heading_figure(navigation: Navigation) -> Figure:
    """``depth_heading.png``'s figure (module docstring)."""
    fig = _figure(11.0, 7.0)
    ax_d, ax_h = fig.subplots(2, 1, sharex=True)
    for sol in navigation.solutions:
        time = np.asarray(sol.time, dtype=np.float64)
        lla = np.asarray(sol.lla, dtype=np.float64)
        sigma = np.asarray(sol.sigma, dtype=np.float64)
        colour = COLOURS[sol.label]
        _band(ax_d, time, -lla[:, 2], sigma[:, 2], colour, sol.label)
        yaw_sigma = np.degrees(attitude_sigma(np.asarray(sol.rpy, float), sigma[:, 6:9])[:, 2])
        _band(ax_h, time, _continuous_yaw(sol), yaw_sigma, colour, sol.label)
    if "depth" in navigation.readings:
        t, depth = navigation.readings["depth"]
        ax_d.plot(t, depth, ".", color="black", ms=2, label="depth readings")
    if "heading" in navigation.readings:
        t, heading = (np.asarray(a, dtype=np.float64) for a in navigation.readings["heading"])
        fwd = navigation.forward
        near = np.interp(t, np.asarray(fwd.time, float), _continuous_yaw(fwd))
        deg = np.degrees(heading)
        deg += 360.0 * np.round((near - deg) / 360.0)  # the turn nearest the solution's
        ax_h.plot(t, deg, ".", color="black", ms=2, label="heading readings")
    ax_d.set_ylabel("depth [m]")
    ax_d.invert_yaxis()
    ax_h.set(ylabel="yaw [deg, from true north, unwrapped]", xlabel="time [s, IMU clock]")
    for ax in (ax_d, ax_h):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="upper right")
    fig.suptitle(f"{navigation.name}: depth and heading with ±3σ", fontsize=9)
    return fig


def _rejected(report: StreamReport) -> NDArray[np.bool_]:
    """Which readings the innovation gate rejected: not ``accepted`` although inside
    the pass (a finite NIS), as :attr:`pronet.StreamResult.accepted` and ``nis`` tell
    it. A report without ``accepted`` marks none."""
    accepted = getattr(report, "accepted", None)
    if accepted is None:
        return np.zeros(len(report.time), dtype=bool)
    return ~np.asarray(accepted, dtype=bool) & np.isfinite(np.asarray(report.nis, float))


def _innovation_panel(ax: Any, report: StreamReport) -> None:
    """One stream's NIS / dof, bands and rejected readings."""
    from matplotlib.transforms import blended_transform_factory

    dof = report.dof if math.isfinite(report.dof) and report.dof > 0 else 1.0
    time, nis = np.asarray(report.time, float), np.asarray(report.nis, float) / dof
    rejected = _rejected(report)
    shown = np.isfinite(nis) & (nis > 0) & ~rejected
    ax.plot(time[shown], nis[shown], ".", ms=2, color=TAB10[0], label="NIS / dof")
    lo, hi = (chi2_quantile(p, dof) / dof for p in (0.025, 0.975))
    ax.axhline(lo, color="gray", ls="--", lw=0.8, label=f"95 % of one reading (dof {dof:g})")
    ax.axhline(hi, color="gray", ls="--", lw=0.8)
    if math.isfinite(report.mean_nis):
        band = np.asarray(report.band, dtype=np.float64) / dof
        ax.axhspan(band[0], band[1], color=TAB10[2], alpha=0.25, lw=0, label="mean's 95 % band")
        ax.axhline(report.mean_nis / dof, color=TAB10[2], lw=1.2, label="mean NIS / dof")
    if rejected.any():  # at their NIS and, to be seen however far out, at the top
        ax.plot(time[rejected], nis[rejected], "x", color="tab:red", ms=4, label="rejected")
        top = blended_transform_factory(ax.transData, ax.transAxes)
        ones = np.full(int(rejected.sum()), 0.97)
        ax.plot(time[rejected], ones, "v", color="tab:red", ms=4, transform=top)
    _log_y(ax)
    ax.grid(alpha=0.3, which="both")
    ax.set_ylabel(f"{report.name} NIS / dof")
    ax.set_title(
        f"{report.name} ({report.kind}): {report.applied} applied, {report.rejected} rejected"
        + (f"; {report.flag}" if report.flag else ""),
        fontsize=8,
    )
    ax.legend(fontsize=6, loc="lower right")


def innovations_figure(navigation: Navigation) -> Figure:
    """``innovations.png``'s figure (module docstring)."""
    streams = navigation.streams
    fig = _figure(11.0, 1.0 + 2.4 * max(1, len(streams)))
    axes = fig.subplots(max(1, len(streams)), 1, sharex=True, squeeze=False)[:, 0]
    if not streams:
        axes[0].text(0.5, 0.5, "no aiding stream", ha="center", transform=axes[0].transAxes)
    for ax, report in zip(axes, streams, strict=False):
        _innovation_panel(ax, report)
    axes[-1].set_xlabel("time [s, IMU clock]")
    fig.suptitle(f"{navigation.name}: normalised innovations per stream", fontsize=9)
    return fig


def figure_bytes(navigation: Navigation) -> list[tuple[str, bytes]]:
    """Each of :data:`FIGURES` drawn: its name and PNG bytes."""
    draws = (track_figure, depth_heading_figure, innovations_figure)
    return [(name, png_bytes(draw(navigation))) for name, draw in zip(FIGURES, draws, strict=True)]


def drawn_figures(navigation: Navigation) -> tuple[list[tuple[str, bytes]], list[str]]:
    """Each of :data:`FIGURES` that could be drawn (its name and PNG bytes), and one
    line for each that could not (its name, the exception's type and message): a figure
    never takes the solution's files with it."""
    draws = (track_figure, depth_heading_figure, innovations_figure)
    drawn, failed = [], []
    for name, draw in zip(FIGURES, draws, strict=True):
        try:
            drawn.append((name, png_bytes(draw(navigation))))
        except Exception as exc:  # noqa: BLE001 - reported, the other files written
            failed.append(f"figure {name} could not be drawn ({type(exc).__name__}: {exc})")
    return drawn, failed


def write_figures(navigation: Navigation, out_dir: str | Path) -> list[Path]:
    """Write :data:`FIGURES` into ``out_dir`` atomically; their paths."""
    paths = []
    for name, png in figure_bytes(navigation):
        path = Path(out_dir) / name
        atomic_write(path, png)
        paths.append(path)
    return paths


def _g(value: float, spec: str = ".4g") -> str:
    """A number for a table, "—" when it is not finite."""
    return format(value, spec) if math.isfinite(value) else "—"


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """A Markdown table's lines."""
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    return lines + ["| " + " | ".join(row) + " |" for row in rows]


def _solutions_section(navigation: Navigation) -> list[str]:
    """Each solution's span and final σ."""
    rows = []
    for sol in navigation.solutions:
        time = np.asarray(sol.time, dtype=np.float64)
        sigma = np.asarray(sol.sigma, dtype=np.float64)
        horizontal = np.hypot(sigma[:, 0], sigma[:, 1])
        yaw = np.degrees(attitude_sigma(np.asarray(sol.rpy, float)[-1:], sigma[-1:, 6:9]))
        rows.append(
            [
                sol.label,
                str(len(time)),
                f"{time[0]:.3f} – {time[-1]:.3f}",
                f"{sol.epoch + time[0]:.3f}",
                _g(float(horizontal[-1])),
                _g(float(np.nanmax(horizontal))),
                _g(float(sigma[-1, 2])),
                _g(float(yaw[0, 2])),
            ]
        )
    header = (
        "solution", "epochs", "time [s]", "first stamp [s]", "final σ_H [m]",
        "max σ_H [m]", "final σ depth [m]", "final σ yaw [deg]",
    )  # fmt: skip
    note = "σ_H = √(σ_N² + σ_E²), the horizontal error's RMS radius."
    return ["## Solutions", "", *_table(header, rows), "", note, ""]


def _initial_section(navigation: Navigation) -> list[str]:
    """The initial state, its 1σ (the filter's P0) and each part's method."""
    init = navigation.initial
    lla, vel, rpy = (np.asarray(a, dtype=np.float64) for a in (init.lla, init.vel, init.rpy))
    s = np.asarray(init.p0_sigma, dtype=np.float64)
    deg = np.degrees(s[6:9])
    rows = [
        ("position", f"{math.degrees(lla[0]):.7f}°, {math.degrees(lla[1]):.7f}°",
         f"N {_g(s[0])} m, E {_g(s[1])} m"),
        ("depth", f"{-lla[2]:.3f} m", f"{_g(s[2])} m"),
        ("velocity", ", ".join(f"{v:.3f}" for v in vel) + " m/s (N, E, D)",
         ", ".join(_g(v) for v in s[3:6]) + " m/s"),
        ("attitude", f"roll {math.degrees(rpy[0]):.3f}°, pitch {math.degrees(rpy[1]):.3f}°",
         f"ψ_N {_g(deg[0])}°, ψ_E {_g(deg[1])}°"),
        ("heading", f"{float(yaw_degrees(rpy[2:3])[0]):.3f}°", f"ψ_D {_g(deg[2])}°"),
    ]  # fmt: skip
    table = [[part, value, sigma, init.methods.get(part, "—")] for part, value, sigma in rows]
    return [
        "## Initial state",
        "",
        f"At {init.t0:.3f} s (IMU clock), the IMU's position (latitude, longitude WGS-84).",
        "",
        *_table(("part", "value", "1σ", "method"), table),
        "",
    ]


def _streams_section(navigation: Navigation) -> list[str]:
    """Per stream: readings, applied, rejected, skipped, mean NIS and its band; flags."""
    rows, flags = [], []
    for r in navigation.streams:
        skipped = ", ".join(f"{why} {n}" for why, n in r.skipped.items() if n) or "none"
        band = f"{_g(r.band[0], '.3f')} – {_g(r.band[1], '.3f')}"
        inside = "—" if not math.isfinite(r.mean_nis) else "no"
        if math.isfinite(r.mean_nis) and r.band[0] <= r.mean_nis <= r.band[1]:
            inside = "yes"
        rows.append(
            [r.name, r.kind, str(r.rows), str(r.applied), str(r.rejected), skipped,
             _g(r.mean_nis, ".3f"), band, inside, _g(r.dof, ".3g")]
        )  # fmt: skip
        if r.flag:
            flags.append(f"- {r.name}: {r.flag}")
    header = ("stream", "kind", "readings", "applied", "rejected", "skipped", "mean NIS",
              "95 % band", "in band", "dof")  # fmt: skip
    if not rows:
        return ["## Sensors", "", "No aiding stream was used.", ""]
    said = ["Flagged:", *flags] if flags else ["No stream is flagged."]
    return ["## Sensors", "", *_table(header, rows), "", *said, ""]


def surface_pressure(config: Mapping[str, Any]) -> tuple[float | None, str]:
    """The surface pressure [Pa] and where it came from, as ``navigation.config`` states
    them: ``surface_pressure_pa`` and ``surface_pressure_source``, or a mapping
    ``surface_pressure: {"pa": …, "source": …}``; ``(None, "not stated")`` without."""
    entry = config.get("surface_pressure")
    if isinstance(entry, Mapping):
        value, source = entry.get("pa"), entry.get("source")
    else:
        value = entry if entry is not None else config.get("surface_pressure_pa")
        source = config.get("surface_pressure_source")
    number = float(value) if isinstance(value, int | float) else None
    return number, str(source) if source else "not stated"


def pressure_text(config: Mapping[str, Any]) -> str:
    """The report's line on the depth's surface reference: the surface pressure and
    where it came from; for depths read in metres (a CSV's, no pressure to state: the
    entry's ``offset_m`` set, ``pa`` not), the offset measured at the surface and taken
    off every reading, or the note that none was."""
    value, source = surface_pressure(config)
    if value is not None:
        return f"{value:.1f} Pa, {source}."
    entry = config.get("surface_pressure")
    offset = entry.get("offset_m") if isinstance(entry, Mapping) else None
    if isinstance(offset, int | float):
        taken = ", taken off every depth reading" if offset != 0.0 else ""
        return f"None: the depths were read in metres; {source}{taken}."
    return f"Not in the configuration ({source}): no depth from pressure, or not recorded."


def _pressure_section(navigation: Navigation) -> list[str]:
    return ["## Surface pressure", "", pressure_text(navigation.config), ""]


def _score_section(navigation: Navigation) -> list[str]:
    """The errors against a ground truth, one column per solution."""
    if not navigation.score:
        return []
    labels = list(navigation.score)
    keys = list(dict.fromkeys(k for scores in navigation.score.values() for k in scores))
    rows = [
        [key] + [_g(float(navigation.score[lb].get(key, math.nan))) for lb in labels]
        for key in keys
    ]
    return ["## Score against the ground truth", "", *_table(["metric", *labels], rows), ""]


#: What each file :func:`pronet.recorded.export.write_all` writes holds.
FILE_NOTES = {
    "trajectory.csv": "every epoch of each solution, with the 1σ of each quantity",
    "track.geojson": "the track, σ per point and the fixes, for GIS tools (RFC 7946)",
    "config.json": "the configuration: tuning, lever arms, streams, initial state",
    "track.png": "the track with 3σ ellipses and the fixes",
    "depth_heading.png": "depth and heading over time with ±3σ and the readings",
    "innovations.png": "each stream's normalised innovations, rejected readings marked",
    REPORT: "this report",
}


def _files_section(
    files: Sequence[str],
    origin: tuple[float, float, float] | None,
    options: OdometryOptions | None,
) -> list[str]:
    lines = ["## Files", ""]
    for name in files:
        note = FILE_NOTES.get(name)
        if note is None and origin is not None and options is not None:
            topics = ", ".join(f"`{t}`" for t in (options.topic, options.smoothed_topic))
            note = (
                f"`nav_msgs/Odometry` on {topics} in the local {options.world_frame.upper()} "
                f"frame `{options.frame_id}` about {origin[0]:.8f}°, {origin[1]:.8f}°, "
                f"{origin[2]:.3f} m (body {options.body_frame.upper()})"
            )
        lines.append(f"- `{name}`" + (f": {note}" if note else ""))
    return [*lines, ""]


def report_markdown(
    navigation: Navigation,
    files: Sequence[str],
    bag_origin: tuple[float, float, float] | None = None,
    bag_options: OdometryOptions | None = None,
) -> str:
    """``report.md``'s text (module docstring). ``files``: the names written;
    ``bag_origin`` (latitude, longitude [deg], height [m]) and ``bag_options``: the
    odometry bag's local frame, when one was written."""
    notes = [f"- {note}" for note in navigation.notes] or ["None."]
    lines = [
        f"# Navigation of {navigation.name}",
        "",
        f"Recording: `{navigation.source}`.",
        "",
        *_solutions_section(navigation),
        *_initial_section(navigation),
        *_streams_section(navigation),
        *_pressure_section(navigation),
        "## Notes",
        "",
        *notes,
        "",
        *_score_section(navigation),
        *_files_section(files, bag_origin, bag_options),
    ]
    return "\n".join(lines).rstrip("\n") + "\n"
