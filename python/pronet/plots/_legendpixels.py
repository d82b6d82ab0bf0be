"""A kept figure's legend, drawn once and pasted as pixels while it stays the same.

``pronet real`` draws a section's figures on kept figures
(:class:`pronet.plots.sections.SectionFigure`), and their legends (a row per strategy,
the same in every section of a run) were a third of the drawing: matplotlib renders
every glyph of every label again for each figure. A legend with the same entries at
the same place over the same plain background gives the same pixels, so they are kept
from the first drawing and pasted into the next ones, where the legend is not drawn.
The PNG is the same, byte for byte (tested against new figures).

Pasting is safe only where the legend covers nothing but the figure's background, so
both ends check it: pixels are kept only from a drawing where no other artist's extent
reaches the legend's region, and pasted only where that region, drawn without the
legend, is background alone; else the legend is drawn as usual.
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: Pixels kept around the legend's extent beside its frame's half line width: the
#: antialiased edge.
MARGIN = 2


def legend_key(legend: Any) -> tuple[Any, ...] | None:
    """What a legend's pixels depend on beside its place (``legend``: a matplotlib
    Legend): its figure's size [px] and dpi, its frame's style, its labels with their
    fonts and colours, and its handles' styles; None where a handle is not a line (its
    style is not read here, so its pixels are never kept)."""
    from matplotlib.colors import to_rgba
    from matplotlib.lines import Line2D

    if not all(type(h) is Line2D for h in legend.legend_handles):
        return None
    fig, frame = legend.get_figure(), legend.get_frame()
    place = (
        tuple(fig.bbox.bounds),
        fig.dpi,
        getattr(legend, "_loc", None),
        legend.get_bbox_to_anchor().bounds,
    )
    style = (
        to_rgba(frame.get_facecolor()),
        to_rgba(frame.get_edgecolor()),
        frame.get_linewidth(),
        frame.get_boxstyle().__class__.__name__,
        legend.get_alpha(),
    )
    texts = tuple(
        (t.get_text(), to_rgba(t.get_color()), t.get_fontproperties().get_fontconfig_pattern())
        for t in legend.get_texts()
    )
    lines = tuple(
        (
            to_rgba(h.get_color()),
            h.get_linestyle(),
            str(getattr(h, "_dash_pattern", None)),
            h.get_linewidth(),
            str(h.get_marker()),
            h.get_markersize(),
            h.get_markeredgewidth(),
            to_rgba(h.get_markerfacecolor()),
            to_rgba(h.get_markeredgecolor()),
            h.get_solid_capstyle(),
            h.get_dash_capstyle(),
            h.get_solid_joinstyle(),
            h.get_antialiased(),
            h.get_alpha(),
        )
        for h in legend.legend_handles
    )
    return place, style, texts, lines


class LegendPixels:
    """The kept pixels of one figure's legend (see the module docs)."""

    def __init__(self) -> None:
        self._key: tuple[Any, ...] | None = None
        self._rows = self._cols = slice(0)
        self._pixels = np.zeros((0, 0, 4), dtype=np.uint8)
        #: How many drawings had their legend pasted (for tests and profiles).
        self.pasted = 0

    def holds(self, legend: Any) -> bool:
        """Whether the pixels kept are those of ``legend``."""
        return self._key is not None and self._key == legend_key(legend)

    def paste(self, rgba: np.ndarray, background: np.ndarray) -> bool:
        """Paste the kept legend into ``rgba`` (a drawing without it) if its region
        there is ``background`` alone; whether it was."""
        region = rgba[self._rows, self._cols]
        if region.shape != self._pixels.shape or not (region == background).all():
            return False
        region[...] = self._pixels
        self.pasted += 1
        return True

    def keep(self, fig: Any, legend: Any, rgba: np.ndarray) -> None:
        """Keep ``legend``'s pixels from ``rgba`` (``fig`` drawn with it), unless a
        handle is not a line or another artist's extent reaches the pixels kept (and
        one more around them); then nothing is kept."""
        from matplotlib.transforms import Bbox

        self._key = None
        key = legend_key(legend)
        if key is None:
            return
        renderer = fig.canvas.get_renderer()
        half_line = legend.get_frame().get_linewidth() * fig.dpi / 72.0 / 2.0
        box = legend.get_window_extent(renderer).padded(MARGIN + half_line)
        height, width = rgba.shape[:2]
        x0, x1 = max(int(np.floor(box.x0)), 0), min(int(np.ceil(box.x1)), width)
        y0, y1 = max(int(np.floor(box.y0)), 0), min(int(np.ceil(box.y1)), height)
        reach = Bbox.from_extents(x0 - 1, y0 - 1, x1 + 1, y1 + 1)
        for artist in fig.get_children():  # the panels, the title, other legends
            if artist is fig.patch or artist is legend or not artist.get_visible():
                continue
            extent = artist.get_tightbbox(renderer)
            if extent is not None and extent.overlaps(reach):
                return
        self._rows, self._cols = slice(height - y1, height - y0), slice(x0, x1)  # rows top down
        self._pixels = rgba[self._rows, self._cols].copy()
        self._key = key
