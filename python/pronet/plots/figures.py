"""Figures, one function each, drawn with matplotlib's Agg canvas (no display, no global
pyplot state) and written as PNG atomically. The CLI uses the same functions."""

from __future__ import annotations

import io
import math
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from pronet._util.files import atomic_write
from pronet._util.validate import real_array

if TYPE_CHECKING:  # matplotlib loads only when a figure is drawn
    import pandas as pd
    from matplotlib.figure import Figure


def _figure(width: float, height: float) -> Figure:
    """A ``width`` × ``height`` [in] figure whose panels constrained layout places."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=120, layout="constrained")
    FigureCanvasAgg(fig)
    return fig


#: Exponent digits as superscripts: "10⁻⁵" in plain text.
_SUPERSCRIPT = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def _power_of_ten(value: float) -> str:
    """A log axis's tick label in plain text: "10⁻⁵", or "2×10⁻⁵" between decades;
    nothing for a value that is not finite and positive."""
    if not (value > 0 and math.isfinite(value)):
        return ""
    exponent = math.floor(math.log10(value) + 1e-9)
    coeff = value / 10.0**exponent
    power = "10" + str(exponent).translate(_SUPERSCRIPT)
    if math.isclose(coeff, 1.0, rel_tol=1e-9):
        return power
    return f"{coeff:.3g}×{power}"


def _log_y(ax) -> None:  # ax: matplotlib Axes
    """A log y axis labelled in plain text ("10⁻⁵", "2×10⁻⁵"): matplotlib's own labels
    are mathtext, whose parser took a fifth of ``sectionplots.section_q``'s drawing time. Which
    ticks get a label is matplotlib's choice, as before: the decades, and the ticks
    between them where the axis spans too few decades to show any."""
    from matplotlib.ticker import LogFormatter

    class PlainLog(LogFormatter):
        def _num_to_string(self, x: float, vmin: float, vmax: float) -> str:
            return _power_of_ten(x)

    ax.set_yscale("log")
    ax.yaxis.set_major_formatter(PlainLog())
    ax.yaxis.set_minor_formatter(PlainLog(labelOnlyBase=False))


def png_bytes(fig) -> bytes:  # fig: matplotlib Figure
    """``fig`` as PNG bytes, zlib level 1. pronet's own figures (a plain Agg canvas,
    :func:`_figure`) are drawn at the figure's dpi and written RGB where every pixel
    is opaque (a quarter fewer bytes to compress than matplotlib's RGBA, the same
    picture), RGBA otherwise; matplotlib's ``savefig.*`` settings do not apply to
    them. A figure on any other canvas (pyplot's, another backend's) goes through
    ``savefig``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    if type(fig.canvas) is not FigureCanvasAgg:
        buf = io.BytesIO()
        fig.savefig(buf, format="png", pil_kwargs={"compress_level": 1})
        return buf.getvalue()
    return _encode_png(_drawn(fig), fig.dpi)


def _drawn(fig) -> np.ndarray:  # fig: matplotlib Figure on an Agg canvas
    """``fig`` drawn: its canvas's ``(height, width, 4)`` pixels (a view, writable)."""
    fig.canvas.draw()
    return np.asarray(fig.canvas.buffer_rgba())


def _encode_png(rgba: np.ndarray, dpi: float) -> bytes:
    """An Agg canvas's ``(height, width, 4)`` pixels as :func:`png_bytes` writes them."""
    from PIL import Image

    buf = io.BytesIO()
    height, width = rgba.shape[:2]
    if (rgba[..., 3] == 255).all():  # PIL's raw decoder drops the 4th byte as it reads
        image = Image.frombytes("RGB", (width, height), rgba, "raw", "RGBX")
    else:
        image = Image.fromarray(rgba)
    image.save(buf, format="png", compress_level=1, dpi=(dpi, dpi))
    return buf.getvalue()


def save_png(fig, path: str | os.PathLike[str]) -> Path:  # fig: matplotlib Figure
    """Render ``fig`` to ``path`` as PNG (:func:`png_bytes`), atomically; returns the
    path."""
    return _write_png(path, png_bytes(fig))


def _write_png(path: str | os.PathLike[str], png: bytes) -> Path:
    """``png`` written to ``path`` atomically (its folder made as needed); the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, png)
    return path


def predicted_vs_true(
    panels: Mapping[str, tuple[ArrayLike, ArrayLike]], path: str | os.PathLike[str]
) -> Path:
    """The paper's Fig. 8: predicted against true q on the test set, one panel per model.

    Args:
        panels: model name → ``(q_true, q_pred)``, each ``(n,)`` per-sample variances.
        path: PNG file to write.

    Test points are grey, the mean prediction per true q blue, the identity line red.
    """
    if not panels:
        raise ValueError("panels: need at least one model")
    checked = {}
    for name, pair in panels.items():
        where = f"panels[{name!r}]"
        if not (isinstance(pair, tuple | list) and len(pair) == 2):
            raise ValueError(f"{where}: expected a pair (q_true, q_pred)")
        q_true = real_array(pair[0], where).astype(float)
        q_pred = real_array(pair[1], where).astype(float)
        if q_true.shape != q_pred.shape or q_true.ndim != 1 or q_true.size == 0:
            raise ValueError(f"{where}: q_true and q_pred must be equal, non-empty 1-D arrays")
        if not (np.isfinite(q_true).all() and np.isfinite(q_pred).any()):
            raise ValueError(f"{where}: q_true must be finite and q_pred finite somewhere")
        checked[name] = (q_true, q_pred)
    fig = _figure(4.0 * len(checked), 4.0)
    axes = fig.subplots(1, len(checked), squeeze=False)[0]
    for ax, (name, (q_true, q_pred)) in zip(axes, checked.items(), strict=True):
        levels = np.unique(q_true)
        means = [np.nanmean(q_pred[q_true == lev]) for lev in levels]
        ax.scatter(q_true, q_pred, s=3, color="0.6", alpha=0.3, label="test windows")
        ax.plot(levels, means, "o-", color="tab:blue", ms=4, label="mean per true q")
        finite = q_pred[np.isfinite(q_pred)]
        low = min(0.0, float(levels.min()), float(finite.min()))
        high = float(max(levels.max(), finite.max()))
        # a margin above the data; a span that is empty or overflows gets a usable one
        high = high + 0.1 * (high - low) if np.isfinite(high - low) else high
        lim = [low, high] if high > low else [low, low + 1.0]
        ax.plot(lim, lim, color="tab:red", lw=1.2, label="identity")
        ax.set(xlim=lim, ylim=lim, title=name, xlabel="true q [unit² per sample]")
        ax.set_aspect("equal")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("predicted q [unit² per sample]")
    axes[0].legend(loc="upper left", fontsize=8)
    return save_png(fig, path)


def velocity_error(rows, path: str | os.PathLike[str], title: str, run: int = 0) -> Path:
    """Velocity error of one run against time with the filter's ±3σ, one panel per
    strategy (``rows``: :class:`pronet.run.Row` with histories recorded)."""
    n = len(rows)
    cols = 2
    fig = _figure(11.0, 2.4 * ((n + cols - 1) // cols) + 0.6)
    axes = fig.subplots((n + cols - 1) // cols, cols, squeeze=False, sharex=True).ravel()
    for ax, row in zip(axes, rows, strict=False):
        r = row.result
        if r.error is None or r.sigma is None:
            raise ValueError("rows: need error and sigma histories (record_every > 0)")
        t = r.record_time
        for axis, (name, color) in enumerate(
            (("north", "tab:blue"), ("east", "tab:orange"), ("down", "tab:green"))
        ):
            ax.plot(t, r.error[run, :, 3 + axis], color=color, lw=0.8, label=f"δv {name}")
            ax.plot(t, 3 * r.sigma[run, :, 3 + axis], color=color, lw=0.6, ls="--")
            ax.plot(t, -3 * r.sigma[run, :, 3 + axis], color=color, lw=0.6, ls="--")
        ax.set_title(row.label, fontsize=9)
        ax.set_ylabel("velocity error [m/s]")
        ax.grid(alpha=0.3)
    for ax in axes[n:]:
        ax.set_visible(False)
    for ax in axes[max(0, n - cols) : n]:
        ax.set_xlabel("time [s]")
        ax.tick_params(labelbottom=True)  # shared x hides them above an empty panel
    axes[0].legend(loc="upper right", fontsize=7, title="dashed: ±3σ", title_fontsize=7)
    fig.suptitle(f"{title}: velocity error of run {run}")
    return save_png(fig, path)


def q_tracking(
    rows,
    schedule_time: ArrayLike,
    schedule_q: ArrayLike,
    path: str | os.PathLike[str],
    title: str,
    run: int = 0,
) -> Path:
    """The q each adaptive strategy used (run ``run``) against the true noise schedule,
    one panel per IMU channel, log scale."""
    names = (
        "f_x [(m/s²)²]",
        "f_y [(m/s²)²]",
        "f_z [(m/s²)²]",
        "ω_x [(rad/s)²]",
        "ω_y [(rad/s)²]",
        "ω_z [(rad/s)²]",
    )
    times, sq = np.asarray(schedule_time, float), np.asarray(schedule_q, float)
    fig = _figure(12.0, 6.5)
    axes = fig.subplots(2, 3, sharex=True).ravel()
    for c, ax in enumerate(axes):
        for row in rows:
            r = row.result
            if r.q is None or row.hybrid is None:
                continue
            ax.plot(r.record_time, r.q[run, :, c], lw=0.9, label=row.label)
        end = rows[0].result.record_time[-1]
        ax.step(
            np.append(times, end),
            np.append(sq[:, c], sq[-1, c]),
            where="post",
            color="black",
            lw=1.2,
            label="true q",
        )
        _log_y(ax)
        ax.set_title(names[c], fontsize=9)
        ax.grid(alpha=0.3, which="both")
    for ax in axes[3:]:
        ax.set_xlabel("time [s]")
    axes[0].set_ylabel("noise variance per sample")
    axes[3].set_ylabel("noise variance per sample")
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{title}: learned q (run {run}) against the true schedule")
    return save_png(fig, path)


def trajectory(traj, path: str | os.PathLike[str], title: str) -> Path:
    """North-east track and depth of a trajectory (``pronet.Trajectory``)."""
    from pronet import earth_radii

    lla = np.asarray(traj.lla)
    r_n, r_e = earth_radii(float(lla[0, 0]))
    north = (lla[:, 0] - lla[0, 0]) * (r_n + lla[0, 2])
    east = (lla[:, 1] - lla[0, 1]) * (r_e + lla[0, 2]) * np.cos(lla[0, 0])
    fig = _figure(10.0, 4.0)
    ax1, ax2 = fig.subplots(1, 2)
    ax1.plot(east, north, color="tab:blue")
    ax1.plot(east[0], north[0], "o", color="tab:green", label="start")
    ax1.plot(east[-1], north[-1], "s", color="tab:red", label="end")
    ax1.set(xlabel="east [m]", ylabel="north [m]", title="track")
    ax1.set_aspect("equal", adjustable="datalim")
    ax1.legend(fontsize=8)
    ax1.grid(alpha=0.3)
    ax2.plot(traj.time, -lla[:, 2], color="tab:blue")
    ax2.invert_yaxis()
    ax2.set(xlabel="time [s]", ylabel="depth [m]", title="depth")
    ax2.grid(alpha=0.3)
    fig.suptitle(title)
    return save_png(fig, path)


def metrics_with_ci(tables, path: str | os.PathLike[str]) -> Path:
    """SRMSE and SMAE per strategy with 95 % CIs, one row of panels per scenario
    (``tables``: scenario title → list of :class:`pronet.run.Row`)."""
    fig = _figure(11.0, 3.2 * len(tables) + 0.4)
    axes = fig.subplots(len(tables), 2, squeeze=False)
    for (title, rows), pair in zip(tables.items(), axes, strict=True):
        for ax, metric in zip(pair, ("srmse", "smae"), strict=True):
            cis = [getattr(row, metric) for row in rows]
            y = np.arange(len(rows))[::-1]
            mean = np.array([c.mean for c in cis])
            low = np.array([c.low for c in cis])
            high = np.array([c.high for c in cis])
            scale = ""
            finite = mean[np.isfinite(mean) & (mean > 0)]
            # one diverging strategy would squash the others into a dot: log scale,
            # with a lower bound at or below zero drawn to the axis edge
            if finite.size and finite.max() > 20 * finite.min():
                ax.set_xscale("log")
                low = np.where(low <= 0, finite.min() / 10, low)  # NaN stays NaN
                scale = ", log scale"
            # a CI that could not be computed (a single run): the point alone
            err = np.nan_to_num(np.stack([mean - low, high - mean]), nan=0.0)
            ax.errorbar(mean, y, xerr=err, fmt="o", color="tab:blue", capsize=3)
            ax.set_yticks(y, [row.label for row in rows], fontsize=8)
            ax.set_xlabel(f"{metric.upper()} [m/s] (mean, 95 % CI{scale})")
            ax.set_title(title, fontsize=9)
            ax.grid(alpha=0.3, axis="x")
    return save_png(fig, path)


def sweep_metric(
    summary: pd.DataFrame, x: str, path: str | os.PathLike[str], metric: str = "srmse"
) -> Path:
    """A sweep's ``metric`` (mean and 95 % CI over runs) against one grid axis, one
    panel per scenario, one line per other grid setting (drawn slightly apart
    sideways, so that lines with equal values stay visible).

    Args:
        summary: :meth:`pronet.experiments.sweep.SweepResult.to_dataframe` (or its ``summary.csv``).
        x: ``"noise_level"`` (every strategy) or ``"tuning_period_s"`` (the learned
            strategies, one line per noise level).
        path: PNG file to write.
        metric: a per-run metric column (``srmse`` [m/s], ``smae`` [m/s],
            ``final_horizontal_error`` [m] ...).
    """
    units = {"srmse": "m/s", "smae": "m/s", "mean_nis": "-"}
    axes_names = {
        "noise_level": "IMU noise level [x true variance]",
        "tuning_period_s": "tuning period [s]",
    }
    if x not in axes_names:
        raise ValueError(f"x: expected one of {', '.join(axes_names)}, got {x!r}")
    if metric not in summary.columns:
        raise ValueError(f"metric: {metric!r} is not a column of the summary")
    data = summary if x == "noise_level" else summary[summary["tuning_period_s"].notna()]
    if data.empty:
        raise ValueError(f"summary: no rows to plot against {x}")
    scenarios = list(dict.fromkeys(data["scenario"]))
    fig = _figure(5.5 * len(scenarios), 4.0)
    axes = fig.subplots(1, len(scenarios), squeeze=False)[0]
    other = "tuning_period_s" if x == "noise_level" else "noise_level"
    markers = "osD^vP*X"
    for ax, scenario in zip(axes, scenarios, strict=True):
        mine = data[data["scenario"] == scenario]
        lines = list(mine.groupby(["strategy", other], sort=False, dropna=False))
        for i, ((strategy, setting), line) in enumerate(lines):
            line = line.sort_values(x)
            # lines side by side (x ±2 % each), so equal values do not hide each other
            dodge = 1 + 0.02 * (i - (len(lines) - 1) / 2)
            label = str(strategy)
            if setting == setting:  # not NaN: the line's fixed value of the other axis
                label += (
                    f", tuning {setting:g} s"
                    if other == "tuning_period_s"
                    else (f", noise x{setting:g}")
                )
            mean = line[metric].to_numpy(float)
            err = np.stack([mean - line[f"{metric}_low"], line[f"{metric}_high"] - mean])
            ax.errorbar(
                line[x].to_numpy(float) * dodge,
                mean,
                yerr=err,
                marker=markers[i % len(markers)],
                capsize=3,
                label=label,
            )
        if x == "noise_level" and mine[x].max() / mine[x].min() >= 10:
            ax.set_xscale("log")
        unit = units.get(metric, "m")
        ax.set(xlabel=axes_names[x], ylabel=f"{metric.upper()} [{unit}] (mean, 95 % CI)")
        ax.set_title(scenario)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    return save_png(fig, path)


def study_figure(table, path: str | os.PathLike[str]) -> Path:
    """The study at a glance: per scenario, each strategy's SRMSE difference from the
    constant told the truth [% of its SRMSE] with the paired 95 % CI; the oracle's as a
    dashed line (the ceiling), diverged runs in the labels (``table``: ``study.csv``)."""
    names = list(dict.fromkeys(table["scenario"]))
    fig = _figure(3.4 * len(names) + 1.6, 4.2)
    axes = fig.subplots(1, len(names), squeeze=False, sharey=True)[0]
    for ax, name in zip(axes, names, strict=True):
        part = table[table["scenario"] == name]
        ref = float(part["srmse"].iloc[0])
        y = np.arange(len(part))[::-1]
        pct = 100 * part["srmse_diff"].to_numpy() / ref
        low = 100 * part["srmse_diff_low"].to_numpy() / ref
        high = 100 * part["srmse_diff_high"].to_numpy() / ref
        err = np.nan_to_num(np.stack([pct - low, high - pct]), nan=0.0)
        oracle = part["strategy"].to_numpy() == "oracle"
        colours = np.where(oracle, "tab:green", "tab:blue")
        for i in range(len(part)):
            ax.errorbar(pct[i], y[i], xerr=err[:, i : i + 1], fmt="o", color=colours[i], capsize=3)
        if oracle.any():
            ax.axvline(pct[oracle][0], color="tab:green", ls="--", lw=1, label="oracle")
        ax.axvline(0.0, color="k", lw=0.8)
        finite = pct[np.isfinite(pct)]
        if finite.size and np.abs(finite).max() > 100:  # one diverging row squashes the rest
            ax.set_xscale("symlog", linthresh=10)
        labels = [
            f"{s} ({d} div.)" if d else s
            for s, d in zip(part["strategy"], part["diverged_runs"], strict=True)
        ]
        ax.set_yticks(y, labels, fontsize=8)
        ax.set_xlabel("ΔSRMSE vs constant (true q) [%]\n(mean, paired 95 % CI)", fontsize=8)
        ax.set_title(f"{name} (ref. {ref:.3g} m/s)", fontsize=9)
        ax.grid(alpha=0.3, axis="x")
    axes[0].legend(fontsize=7, loc="lower right")
    fig.suptitle(
        "When does adaptive Q pay? (left of 0: better than the constant told the truth)",
        fontsize=10,
    )
    return save_png(fig, path)
