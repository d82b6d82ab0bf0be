"""The figures of a recorded section (``pronet real``): its track, velocity error and
process noise per strategy, drawn from :class:`SectionCurves` (small arrays that
:func:`pronet.recorded.figures.section_curves` takes from the runs) on kept figures
(:class:`SectionFigure`), which ``pronet real``'s figure workers draw every section on.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from pronet.plots.figures import _drawn, _encode_png, _log_y, _write_png

if TYPE_CHECKING:  # matplotlib loads only when a figure is drawn
    from matplotlib.figure import Figure


#: matplotlib's default ten line colours ("tab10").
TAB10 = tuple(f"tab:{c}" for c in "blue orange green red purple brown pink gray olive cyan".split())

#: Width [in] kept right of the panels of :func:`_legend_figure` for the legend: the
#: longest label of ``pronet real``'s rows at 7 pt, and its line.
LEGEND_WIDTH = 3.3


def _legend_figure(width: float, height: float, rows: int) -> tuple[Figure, list]:
    """A figure of ``rows`` panels sharing x, ``width`` × ``height`` [in] plus
    :data:`LEGEND_WIDTH` on the right for :func:`_legend_beside`, with fixed margins
    (room for tick labels down to 1e-12, a y label, a title): constrained layout's
    solver would take a third of the drawing time of each of ``pronet real``'s 33
    figures."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    total = width + LEGEND_WIDTH
    fig = Figure(figsize=(total, height), dpi=120)
    FigureCanvasAgg(fig)
    fig.subplots_adjust(
        left=0.9 / total,
        right=(width - 0.1) / total,
        bottom=0.55 / height,
        top=1 - 0.45 / height,
        hspace=0.08,
    )
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    for ax in axes:
        _restart_styles(ax)
    return fig, list(axes)


def _restart_styles(ax) -> None:  # ax: matplotlib Axes
    """Start ``ax``'s line styles over: ten colours solid, then the same ten dashed, so
    that no two of ``pronet real``'s rows look alike."""
    from cycler import cycler

    ax.set_prop_cycle(cycler(linestyle=["-", "--"]) * cycler(color=TAB10))


def _legend_beside(fig, ax) -> None:  # fig: matplotlib Figure, ax: its Axes
    """``ax``'s legend right of the panels of a :func:`_legend_figure`: inside, a legend
    of many rows hides lines, and matplotlib's search for the emptiest corner ("best")
    is a third of a figure's drawing time."""
    fig.legend(
        *ax.get_legend_handles_labels(),
        loc="upper left",
        bbox_to_anchor=(fig.subplotpars.right + 0.08 / fig.get_figwidth(), fig.subplotpars.top),
        borderaxespad=0.0,
        fontsize=7,
    )


@dataclass(frozen=True)
class SectionCurves:
    """What the three figures of one recorded section show, as small arrays
    (:func:`pronet.recorded.figures.section_curves` takes them from the runs; long series
    are thinned).

    Attributes:
        name: the section.
        track: ``(label, east, north)`` [m from the start], the ground truth first.
        velocity_error: ``(label, time, δv)``: time [s, IMU clock] ``(n,)`` and the NED
            velocity error [m/s] ``(n, 3)`` of each strategy at the truth rows.
        q: ``(label, time, accelerometer q, gyro q)``: the mean per-sample variance of
            the three channels [(m/s²)², (rad/s)²] from each time [s] on.
    """

    name: str
    track: list[tuple[str, np.ndarray, np.ndarray]]
    velocity_error: list[tuple[str, np.ndarray, np.ndarray]]
    q: list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]


#: The figures of a recorded section, by kind (:class:`SectionFigure`).
SECTION_FIGURES = ("track", "velocity_error", "q")


class SectionFigure:
    """One of the figures of recorded sections (``kind`` in :data:`SECTION_FIGURES`),
    kept to be drawn again: :meth:`png` removes the last section's lines and legend
    and draws the next one's on the same axes, whose ticks, labels and grid matplotlib
    then only updates. The pixels are those of a new figure (tested), at less cost;
    ``pronet real``'s figure workers keep one of each kind. Not for two threads at once."""

    def __init__(self, kind: str) -> None:
        if kind not in SECTION_FIGURES:
            raise ValueError(f"kind: expected one of {', '.join(SECTION_FIGURES)}, got {kind!r}")
        self.kind = kind
        self._new_figure()

    def _new_figure(self) -> None:
        """The empty figure: panels, labels, grids, scales; no data, not yet drawn."""
        width, height, rows = {"track": (7.0, 6.0, 1), "velocity_error": (11.0, 7.0, 3)}.get(
            self.kind, (11.0, 5.5, 2)
        )
        self.fig, self.axes = _legend_figure(width, height, rows)
        self._used = False
        if self.kind == "track":
            self.axes[0].set(xlabel="east [m]", ylabel="north [m]")
            self.axes[0].set_aspect("equal", adjustable="datalim")
            self.axes[0].grid(alpha=0.3)
        elif self.kind == "velocity_error":
            for ax, name in zip(self.axes, ("north", "east", "down"), strict=True):
                ax.set_ylabel(f"δv {name} [m/s]")
                ax.grid(alpha=0.3)
        else:
            units = ("accelerometer q [(m/s²)²]", "gyro q [(rad/s)²]")
            for ax, unit in zip(self.axes, units, strict=True):
                _log_y(ax)
                ax.set_ylabel(unit)
                ax.grid(alpha=0.3, which="both")
        if self.kind != "track":
            self.axes[-1].set_xlabel("time [s, IMU clock]")

    def png(self, curves: SectionCurves) -> bytes:
        """The figure of ``curves``, as PNG bytes (:func:`png_bytes`)."""
        used, self._used = self._used, True
        if used:  # back to no data (also after a draw that failed half-way)
            for ax in self.axes:
                for line in list(ax.lines):
                    line.remove()
                _restart_styles(ax)
                ax.relim()
            for legend in list(self.fig.legends):
                legend.remove()
        self._draw(curves)
        if used and not all(np.isfinite(ax.dataLim.get_points()).all() for ax in self.axes):
            # matplotlib scales an axis without data to the limits it was last drawn
            # with, a new figure's to its defaults: this one goes on a new figure
            self._new_figure()
            self._used = True
            self._draw(curves)
        return _encode_png(_drawn(self.fig), self.fig.dpi)

    def _draw(self, curves: SectionCurves) -> None:
        """``curves``' lines, legend and title on the figure's empty panels."""
        draw = {"track": _track, "velocity_error": _velocity_error, "q": _q}[self.kind]
        draw(self.axes, curves)
        _legend_beside(self.fig, self.axes[0])
        title = {
            "track": "north-east track, estimate against truth",
            "velocity_error": "velocity error against the ground truth",
            "q": "process noise per strategy (mean over 3 channels)",
        }[self.kind]
        self.fig.suptitle(f"{curves.name}: {title}")


def _track(axes: list, curves: SectionCurves) -> None:
    (ax,) = axes
    (_, east, north), *runs = curves.track
    ax.plot(east, north, color="black", lw=2.2, label="ground truth")
    for label, e, n in runs:
        ax.plot(e, n, lw=0.9, label=label)
    ax.plot(east[0], north[0], "o", color="tab:green", label="start")


def _velocity_error(axes: list, curves: SectionCurves) -> None:
    span = 0.0
    for k, (label, time, dv) in enumerate(curves.velocity_error):
        if k == 0:
            span = 3 * float(np.nanmax(np.abs(dv), initial=0.0)) or 1.0
        for axis, ax in enumerate(axes):
            ax.plot(time, dv[:, axis], lw=0.8, label=label)
    for ax in axes:
        ax.set_ylim(-span, span)


def _q(axes: list, curves: SectionCurves) -> None:
    for label, t, acc, gyro in curves.q:
        axes[0].step(t, acc, where="post", lw=0.9, label=label)
        axes[1].step(t, gyro, where="post", lw=0.9, label=label)


def section_track(curves: SectionCurves, path: str | os.PathLike[str]) -> Path:
    """North-east track of each strategy's estimate against the truth (black, thick) on
    one recorded section, metres from the start."""
    return _write_png(path, SectionFigure("track").png(curves))


def section_velocity_error(curves: SectionCurves, path: str | os.PathLike[str]) -> Path:
    """Velocity error (north, east, down) against time of each strategy on one
    recorded section, at the ground-truth rows; the y range follows the first strategy
    so that a diverging row does not flatten the others."""
    return _write_png(path, SectionFigure("velocity_error").png(curves))


def section_q(curves: SectionCurves, path: str | os.PathLike[str]) -> Path:
    """The process noise each strategy used on one recorded section, as the mean
    per-sample variance of the accelerometer and of the gyro channels, log scale;
    constant rows are flat lines."""
    return _write_png(path, SectionFigure("q").png(curves))
