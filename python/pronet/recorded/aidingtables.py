"""The tables and records of ``pronet real`` (:mod:`pronet.recorded.real`) about a
section's depth readings, position fixes and heading: the Markdown tables of
``table.md`` (:func:`aiding_table`, :func:`heading_table`) and ``config.json``'s
``aiding`` entry (:func:`aiding_record`)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from pronet.filter import FilterResult
from pronet.recorded.aiding import AidingTuning, DepthReadings, PositionFixes
from pronet.results import markdown
from pronet.stats import format_number

if TYPE_CHECKING:
    from pronet.recorded.runs import RealRuns


def _first_result(done: RealRuns, name: str) -> FilterResult | None:
    """Section ``name``'s first strategy row's result (every aided row applies the same
    depth readings and fixes at the same epochs), or None without a row."""
    return next((r.result for r in done.runs if r.section == name), None)


def _outside_run(epochs: NDArray[np.int64] | None) -> int | None:
    """The rows applied at no epoch (``depth_epoch``/``fix_epoch`` −1: stamped before
    the run's start or after its end), or None without a result."""
    return None if epochs is None else int(np.sum(epochs < 0))


def aiding_record(tuning: AidingTuning, done: RealRuns) -> dict[str, object]:
    """``config.json``'s ``aiding``: what was used, the default σ, and per section of
    ``done`` each stream's rows read (``rows``), those skipped as missing values (not
    among ``rows``), those of ``rows`` outside the run (``outside_run``: stamped before
    its start or after its end, applied at no epoch) and their median σ [m]."""

    def stream(
        x: DepthReadings | PositionFixes | None, epochs: NDArray[np.int64] | None
    ) -> dict[str, object] | None:
        if x is None:
            return None
        sigma = None if x.sigma is None else np.median(x.sigma, axis=0).tolist()
        rows = {"rows": len(x.time), "skipped": len(x.skipped_time)}
        return {**rows, "outside_run": _outside_run(epochs), "sigma_m": sigma}

    sections: dict[str, dict[str, object]] = {}
    for a, _ in done.sections:
        first = _first_result(done, a.name)
        sections[a.name] = {
            "depth": stream(a.depth, None if first is None else first.depth_epoch),
            "fixes": stream(a.fixes, None if first is None else first.fix_epoch),
        }
        if a.heading is not None:  # [deg]; only where a section has one
            epochs, _ = _heading_updates(first)
            sigma = None if a.heading.sigma is None else math.degrees(np.median(a.heading.sigma))
            rows = {"rows": len(a.heading.time), "skipped": len(a.heading.skipped_time)}
            sections[a.name]["heading"] = {
                **rows,
                "outside_run": _outside_run(epochs),
                "sigma_deg": sigma,
            }
    sigma = tuning.heading_sigma
    return {
        "use_depth": tuning.use_depth,
        "use_fixes": tuning.use_fixes,
        "use_dvl": tuning.use_dvl,
        "use_heading": tuning.use_heading,
        "depth_sigma_m": tuning.depth_sigma,
        "fix_sigma_m": list(tuning.fix_sigma),
        "heading_sigma_deg": None if sigma is None else math.degrees(sigma),
        "sections": sections,
    }


def _heading_updates(
    first: FilterResult | None,
) -> tuple[NDArray[np.int64] | None, NDArray[np.float64] | None]:
    """The epochs and NIS of ``first``'s heading stream, or None, None."""
    found = None if first is None else next((s for s in first.streams if s.kind == "heading"), None)
    return (None, None) if found is None else (found.epoch, found.nis)


def heading_table(done: RealRuns) -> str:
    """Markdown: each section's heading readings (rows read, skipped as missing values,
    outside the run), their median σ and the first strategy row's mean NIS (χ² of 1 dof
    when the filter is consistent)."""
    lines = []
    for aligned, _ in done.sections:
        if aligned.heading is None:
            continue
        epochs, nis = _heading_updates(_first_result(done, aligned.name))
        h = aligned.heading
        sigma = "" if h.sigma is None else f"{math.degrees(np.median(h.sigma)):.3g}"
        finite = np.empty(0) if nis is None else nis[np.isfinite(nis)]
        mean = format_number(float(np.mean(finite)), "{:.2f}") if len(finite) else "undefined"
        outside = _outside_run(epochs)
        rows = f"{len(h.time)} ({len(h.skipped_time)} skipped, "
        rows += "outside the run unknown)" if outside is None else f"{outside} outside the run)"
        lines.append([aligned.name, rows, sigma, mean])
    header = ["section", "heading rows", "heading σ [deg]", "heading mean NIS"]
    return markdown(header, lines, f"Heading (mean NIS: {done.runs[0].label})")


def aiding_table(done: RealRuns) -> str:
    """Markdown: each section's depth readings and position fixes (rows read, those
    skipped as missing values, those outside the run: applied at no epoch), their
    median σ and the first strategy row's mean NIS of each (χ² of 1 dof for a depth, 2
    or 3 for a fix when the filter is consistent)."""
    lines = []
    for aligned, _ in done.sections:
        first = _first_result(done, aligned.name)
        cells: list[str] = [aligned.name]
        for stream, epochs, nis in (
            (aligned.depth, *((first.depth_epoch, first.depth_nis) if first else (None, None))),
            (aligned.fixes, *((first.fix_epoch, first.fix_nis) if first else (None, None))),
        ):
            if stream is None:
                cells += ["—", "—", "—"]
                continue
            sigma = "" if stream.sigma is None else np.median(stream.sigma, axis=0)
            shown = " / ".join(f"{v:.3g}" for v in np.atleast_1d(sigma))
            finite = np.empty(0) if nis is None else nis[np.isfinite(nis)]
            mean = format_number(float(np.mean(finite)), "{:.2f}") if len(finite) else "undefined"
            outside = _outside_run(epochs)
            rows = f"{len(stream.time)} ({len(stream.skipped_time)} skipped, "
            rows += "outside the run unknown)" if outside is None else f"{outside} outside the run)"
            cells += [rows, shown, mean]
        lines.append(cells)
    header = ["section", "depth rows", "depth σ [m]", "depth mean NIS",
              "fixes", "fix σ N / E / D [m]", "fix mean NIS"]  # fmt: skip
    title = f"Depth and position fixes (mean NIS: {done.runs[0].label})"
    return markdown(header, lines, title)
