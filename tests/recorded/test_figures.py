"""The figures of ``pronet real``: the curves taken from a section's runs, and their
drawing in worker processes."""

from __future__ import annotations

import io
import signal
import threading
from dataclasses import replace

import numpy as np
import pytest

from pronet.learn.hybrid import ConstantRegressor
from pronet.recorded import alignment, figures, real
from pronet.recorded.alignment import align, estimate_alignment
from pronet.recorded.metrics import section_metrics
from pronet.recorded.runs import kept_for_tables
from pronet.recorded.tuning import real_filter_config

from synthetic_recording import synthetic_recording

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def ran():
    """A 70 s synthetic section and every row of ``pronet real`` on it (a constant
    regressor stands in for the learned ones), with the figures' curves."""
    rec = synthetic_recording(seed=3, duration=70.0, name="sec").recording
    pairs = [(align(rec, estimate_alignment(rec)), align(rec, alignment.Alignment(how="none")))]
    seen = []
    model = ConstantRegressor([1e-4, 1e-4, 1e-4, 1e-8, 1e-8, 1e-8])
    done = real.run_sections(
        pairs, {"detrend": model}, 1.0, on_section=lambda *args: seen.append(args)
    )
    return pairs[0][0], done, seen


def test_each_section_is_handed_over_once_with_its_rows_and_constants(ran):
    section, done, seen = ran
    assert len(seen) == 1
    aligned, runs, constants = seen[0]
    assert aligned is section and runs == done.runs
    assert constants == done.constants[section.name] and constants


def test_the_curves_hold_what_the_figures_show(ran):
    section, done, _ = ran
    imu_dt = real_filter_config((0.0, 0.0, 0.0)).imu_dt
    curves = figures.section_curves(section, done.runs, done.constants[section.name], imu_dt)
    assert curves.name == section.name
    labels = [r.label for r in done.runs]
    assert [c[0] for c in curves.track] == ["ground truth", *labels]
    assert [c[0] for c in curves.velocity_error] == labels
    (_, east, north), *_ = curves.track
    assert east[0] == north[0] == 0.0  # metres from the start
    for _, e, n in curves.track:  # 7,000 IMU samples thinned to at most ~MAX_LINE_POINTS
        assert len(e) == len(n) <= figures.MAX_LINE_POINTS + 1
    first = done.runs[0]
    _, time, dv = curves.velocity_error[0]
    rows = (section.truth_time > first.result.time[0]) & (
        section.truth_time <= first.result.time[-1]
    )
    assert dv.shape == (len(time), 3) and len(time) == rows.sum()
    # the velocity error is the one section_metrics scores
    assert np.sqrt(np.mean(np.sum(dv**2, axis=1))) == pytest.approx(first.metrics.srmse)
    q = {label: (t, acc, gyro) for label, t, acc, gyro in curves.q}
    constant = done.constants[section.name]
    for label, values in constant.items():  # constant rows: flat over the run
        t, acc, gyro = q[label]
        assert acc == pytest.approx([np.mean(values[:3])] * 2)
        assert gyro == pytest.approx([np.mean(values[3:])] * 2)
    learned = [r for r in done.runs if r.schedule is not None]
    for r in learned:  # the q each tuning instant set, from then on
        t, acc, gyro = q[r.label]
        np.testing.assert_array_equal(t, r.schedule.time)
        assert acc == pytest.approx(r.schedule.q[:, :3].mean(axis=1))
    stand_in = [q[r.label] for r in learned if np.all(r.schedule.q == r.schedule.q[0])]
    assert stand_in and all(c[1] == pytest.approx(1e-4) for c in stand_in)
    adaptive = [r for r in done.runs if np.isfinite(r.result.adaptive_q).any()]
    for r in adaptive:  # Mehra's Q_d at each applied update, as the equivalent q
        t, acc, gyro = q[r.label]
        assert len(t) == np.sum(r.result.dvl_epoch >= 0) == len(acc) == len(gyro)
        filled = np.isfinite(acc)  # NaN (not drawn) until the window fills, then q >= 0
        assert filled.any() and np.all(filled[np.argmax(filled) :])
        assert np.all(acc[filled] >= 0) and np.all(gyro[filled] >= 0)
    assert adaptive


def test_a_row_kept_for_the_tables_scores_and_draws_as_the_whole(ran):
    """Memory: a row thinned to the epochs the tables read keeps a fraction
    of them, gives the same metrics bit for bit, finds each update's epoch, and draws
    the same velocity error and Mehra's q at the same instants."""
    section, done, _ = ran
    imu_dt = real_filter_config((0.0, 0.0, 0.0)).imu_dt
    thin = [kept_for_tables(r, section) for r in done.runs]
    for whole, kept in zip(done.runs, thin, strict=True):
        r, k = whole.result, kept.result
        assert len(k.time) < len(r.time) / 4 and k.smoothed is None
        assert section_metrics(section, k) == section_metrics(section, r)
        applied = r.dvl_epoch[r.dvl_epoch >= 0]
        np.testing.assert_array_equal(k.time[k.rows_of(applied)], r.time[applied])
        assert kept_for_tables(kept, section) is kept  # already thinned
        assert k.gain.shape == r.gain.shape and k.gain.strides == (0, 0, 0)  # a NaN view
        assert np.isnan(k.gain).all()
    with pytest.raises(ValueError, match="^epochs: epoch 1 is not kept"):
        thin[0].result.rows_of([1])
    with pytest.raises(ValueError, match="^epochs: expected whole numbers"):
        done.runs[0].result.rows_of([1.5])
    constants = done.constants[section.name]
    a = figures.section_curves(section, done.runs, constants, imu_dt)
    b = figures.section_curves(section, thin, constants, imu_dt)
    for (_, t1, dv1), (_, t2, dv2) in zip(a.velocity_error, b.velocity_error, strict=True):
        np.testing.assert_array_equal(t1, t2)
        np.testing.assert_array_equal(dv1, dv2)
    for (l1, t1, acc1, _), (l2, t2, acc2, _) in zip(a.q, b.q, strict=True):
        assert l1 == l2
        np.testing.assert_array_equal(t1, t2)
        np.testing.assert_allclose(acc1, acc2, rtol=1e-9)


def test_figures_drawn_in_a_worker_are_the_ones_drawn_here(ran, tmp_path):
    section, done, _ = ran
    imu_dt = real_filter_config((0.0, 0.0, 0.0)).imu_dt
    curves = figures.section_curves(section, done.runs, done.constants[section.name], imu_dt)
    here = {
        figures.figure_name(kind, "sec"): figures.draw_figure(kind, curves)
        for kind in figures.FIGURES
    }
    assert sorted(here) == ["q_sec.png", "track_sec.png", "velocity_error_sec.png"]
    assert all(png.startswith(PNG) for png in here.values())
    steps = []
    with figures.FigurePool(1) as pool:
        pool.submit(curves)
        pool.write(tmp_path, ["sec"], steps.append)
    assert steps == ["sec"]
    for name, png in here.items():  # Agg draws the same pixels in any process
        assert (tmp_path / name).read_bytes() == png


def test_the_pool_defaults_to_half_the_cores_and_at_least_one_worker(monkeypatch):
    for cores, workers in [(1, 1), (2, 1), (3, 1), (8, 4), (64, 32)]:
        monkeypatch.setattr(figures, "usable_cores", lambda c=cores: c)
        assert figures.default_workers() == workers


def _varied(curves):
    """Sections unlike ``curves`` and each other: other rows, spans, names, no q."""
    track = [(lab, 3.0 * e - 40.0, 0.5 * n) for lab, e, n in curves.track]
    velocity = [(lab, t + 100.0, 20.0 * dv) for lab, t, dv in curves.velocity_error]
    q = [(lab, t, acc * 1e3, gyro * 1e-2) for lab, t, acc, gyro in curves.q]
    return [
        replace(curves, name="wide", track=track, velocity_error=velocity, q=q),
        replace(
            curves,
            name="few",
            track=curves.track[:3],
            velocity_error=curves.velocity_error[4:6],
            q=curves.q[1:2],
        ),
        replace(curves, name="no q", q=[]),
        replace(curves, name="no gyro q", q=[(lab, t, a, np.nan * g) for lab, t, a, g in q]),
        curves,
    ]


def test_a_kept_figure_draws_the_bytes_of_a_fresh_one(ran):
    """A worker draws every section on the same three figures: whatever was drawn on
    them before (other rows, spans, a log axis over other decades, a failed draw), the
    next section's PNG is byte for byte that of a new figure."""
    section, done, _ = ran
    imu_dt = real_filter_config((0.0, 0.0, 0.0)).imu_dt
    curves = figures.section_curves(section, done.runs, done.constants[section.name], imu_dt)
    kept: dict = {}
    # each fails after its first lines are drawn: mismatched lengths, infinite limits
    (label, time, dv), (_, e, n), (_, t, acc, gyro) = (
        curves.velocity_error[0],
        curves.track[0],
        curves.q[0],
    )
    broken = replace(
        curves,
        name="broken",
        track=[curves.track[0], (label, e, n[:-1])],
        velocity_error=[(label, time, np.where(np.arange(len(time))[:, None] == 3, np.inf, dv))],
        q=[curves.q[0], (label, t, acc[:-1], gyro)],
    )
    for kind in figures.FIGURES:
        for one in _varied(curves):
            again = figures.draw_figure(kind, one, kept)
            assert again == figures.draw_figure(kind, one), (kind, one.name)
            with pytest.raises(ValueError):
                figures.draw_figure(kind, broken, kept)
            assert kept[kind].axes[0].lines  # half drawn: the next one starts clean
    assert sorted(kept) == sorted(figures.FIGURES)
    with pytest.raises(ValueError, match="kind: expected one of track, velocity_error, q"):
        figures.draw_figure("speed", curves)


def test_png_bytes_drop_alpha_only_where_every_pixel_is_opaque():
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from PIL import Image

    from pronet.plots import png_bytes

    modes = []
    for face in ("white", (1.0, 1.0, 1.0, 0.5)):
        fig = Figure(figsize=(2, 1), dpi=50, facecolor=face)
        FigureCanvasAgg(fig)
        fig.add_subplot().plot([0, 1], [1, 0])
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())
        image = Image.open(io.BytesIO(png_bytes(fig)))
        modes.append(image.mode)
        np.testing.assert_array_equal(np.asarray(image.convert("RGBA")), rgba)
    assert modes == ["RGB", "RGBA"]


def _curves(ran):
    section, done, _ = ran
    imu_dt = real_filter_config((0.0, 0.0, 0.0)).imu_dt
    return figures.section_curves(section, done.runs, done.constants[section.name], imu_dt)


def test_a_worker_error_fails_its_figure_alone_with_its_traceback_kept(ran, tmp_path):
    """A figure the worker cannot draw: before, ``write`` raised (the caller's result
    folder lost with it); now the figure is returned as failed, its reason the worker
    exception's last line and its whole traceback kept on it, and the section's other
    figures are written; the worker goes on with the next."""
    curves = _curves(ran)
    broken = replace(curves, name="broken", track=[])  # no truth line to draw
    with figures.FigurePool(1) as pool:
        pool.submit(broken)
        failed = pool.write(tmp_path, ["broken"])
        pool.submit(curves)  # the worker goes on with the next figure
        assert pool.write(tmp_path, ["sec"]) == {}
    [(file, error)] = failed["broken"].items()
    assert list(failed) == ["broken"] and file == "track_broken.png"
    assert str(error) == "ValueError: not enough values to unpack (expected at least 1, got 0)"
    assert isinstance(error, figures.FigureError) and "Traceback" in error.traceback
    assert (tmp_path / "q_sec.png").read_bytes().startswith(PNG)
    assert not (tmp_path / "track_broken.png").exists()
    assert (tmp_path / "q_broken.png").read_bytes().startswith(PNG)


def test_a_worker_that_dies_fails_its_figures_without_raising(ran, tmp_path):
    """A worker killed (the OOM killer, say) before it draws: before, ``write`` raised;
    now each of the section's figures is returned as failed, named."""
    pool = figures.FigurePool(1)
    with pool:
        pool._workers[0].kill()
        pool._workers[0].wait()
        pool.submit(_curves(ran))
        failed = pool.write(tmp_path, ["sec"])
    assert sorted(failed["sec"]) == ["q_sec.png", "track_sec.png", "velocity_error_sec.png"]
    assert all(str(e).startswith("the figure worker stopped") for e in failed["sec"].values())


def test_curves_that_cannot_be_sent_fail_their_figures_instead_of_hanging(ran, tmp_path):
    """Curves a worker cannot be sent (pickling fails in the pool's feeder thread):
    before, the feeder thread died and ``write`` waited forever; now those figures
    fail with the reason and the next section's are drawn."""
    curves = _curves(ran)
    unsent = replace(curves, name="unsent", q=[("q", lambda: 0, None, None)])
    done: list[dict] = []
    with figures.FigurePool(1) as pool:
        pool.submit(unsent)
        pool.submit(curves)
        writer = threading.Thread(
            target=lambda: done.append(pool.write(tmp_path, ["unsent", "sec"])), daemon=True
        )
        writer.start()
        writer.join(60)
        assert not writer.is_alive(), "write hangs"
    [failed] = done
    assert list(failed) == ["unsent"] and len(failed["unsent"]) == 3
    assert all("cannot be sent" in str(e) for e in failed["unsent"].values())
    assert (tmp_path / "track_sec.png").read_bytes().startswith(PNG)


def test_leaving_on_an_error_kills_the_workers_mid_queue(ran):
    section, done, _ = ran
    imu_dt = real_filter_config((0.0, 0.0, 0.0)).imu_dt
    curves = figures.section_curves(section, done.runs, done.constants[section.name], imu_dt)
    pool = figures.FigurePool(2)
    with pytest.raises(KeyboardInterrupt), pool:
        for i in range(20):  # 60 figures queued, seconds of drawing
            pool.submit(replace(curves, name=f"s{i}"))
        raise KeyboardInterrupt
    assert all(w.returncode == -signal.SIGKILL for w in pool._workers)


@pytest.mark.parametrize(
    ("low", "high", "expected"),
    [(1e-12, 10.0, "10⁻⁶"), (2.5e-5, 4e-5, "3×10⁻⁵"), (1.2e-3, 2e-3, "1.5×10⁻³")],
)
def test_log_axes_are_labelled_in_plain_text(low, high, expected):
    """The q figures' log axes: "10⁻⁵" and "3×10⁻⁵" in plain text (no mathtext to
    parse), labelled where matplotlib labels them, also between decades when the axis
    spans less than one."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from pronet.plots.figures import _log_y, _power_of_ten

    fig = Figure()
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    ax.plot([0.0, 1.0], [low, high])
    _log_y(ax)
    fig.canvas.draw()
    shown = [
        t.get_text()
        for t in ax.get_yticklabels() + ax.get_yticklabels(minor=True)
        if t.get_text() and low <= t.get_position()[1] <= high * 1.0001
    ]
    assert expected in shown and not any("$" in t for t in shown)
    assert [_power_of_ten(v) for v in (1e-5, 2e-5, 1.0, 1e3)] == ["10⁻⁵", "2×10⁻⁵", "10⁰", "10³"]
    assert _power_of_ten(0.0) == _power_of_ten(-1.0) == _power_of_ten(float("inf")) == ""


def test_png_bytes_of_a_figure_on_another_canvas_go_through_savefig():
    """A figure without pronet's plain Agg canvas (pyplot's, another backend's) is
    written by matplotlib's own ``savefig``."""
    from matplotlib.backends.backend_svg import FigureCanvasSVG
    from matplotlib.figure import Figure
    from PIL import Image

    from pronet.plots import png_bytes

    bare, svg = Figure(figsize=(2, 1), dpi=50), Figure(figsize=(2, 1), dpi=50)
    FigureCanvasSVG(svg)
    for fig in (bare, svg):
        fig.add_subplot().plot([0, 1], [1, 0])
        image = Image.open(io.BytesIO(png_bytes(fig)))
        assert image.size == (100, 50) and image.mode == "RGBA"
