"""What a pass says about its streams (:mod:`pronet.stats`): counts, the mean
NIS against its χ² band, and one line naming the likely causes when a stream disagrees
with the filter (fixes 300 m off, a DVL told a σ ten times too small, a magnetic heading
with its declination left out); none for streams told their true σ. (A heading in
degrees is refused when its stream is made.)"""

from __future__ import annotations

import functools
import json
import re
import warnings
from typing import Any

import numpy as np
import pytest

import pronet
from pronet.montecarlo import chance_bound, runs_flag, runs_outside_band
from pronet.recorded.alignment import dcm_from_euler
from pronet.sim.scenarios import SCENARIOS
from pronet.stats import (
    Extent,
    FilterHealthWarning,
    StreamReport,
    StreamSource,
    divergence,
    heading_linearity,
    pass_health,
    stream_report,
)

SECONDS = 120.0
Q = np.array([1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6])


def _streams(rng: np.random.Generator, *, fix_offset: float = 0.0, dvl_told: float = 0.1,
             heading_offset: float = 0.0) -> tuple[list, dict]:  # fmt: skip
    """The paper trajectory's first ``SECONDS``: a 1 Hz DVL (σ 0.1 m/s, told
    ``dvl_told``), fixes every 5 s (σ 1 m, moved ``fix_offset`` m north), a 2 Hz heading
    (σ 0.01 rad, ``heading_offset`` rad off: a magnetic heading taken for a true one)."""
    traj = pronet.builtin_trajectory("paper")
    k = np.arange(100, int(SECONDS * 100) + 1, 100)
    c = dcm_from_euler(traj.rpy[k])
    dvl = np.einsum("kji,kj->ki", c, traj.vel_ned[k]) + rng.normal(size=(len(k), 3)) * 0.1
    f = np.arange(500, int(SECONDS * 100) + 1, 500)
    ned = rng.normal(size=(len(f), 3)) * 1.0 + [fix_offset, 0.0, 0.0]
    fix = np.array([pronet.lla_from_ned(o, p) for o, p in zip(ned, traj.lla[f], strict=True)])
    fix[1::2, 2] = np.nan  # every other fix horizontal: 2 dof
    h = np.arange(50, int(SECONDS * 100) + 1, 50)
    heading = traj.rpy[h, 2] + rng.normal(size=len(h)) * 0.01 + heading_offset
    streams = [
        pronet.Dvl(traj.time[k], dvl, sigma=dvl_told),
        pronet.Fix(traj.time[f], fix, sigma=[1.0, 1.0, 1.0]),
        pronet.Heading(traj.time[h], heading, sigma=0.01),
    ]
    return streams, {"fix": fix}


def _pass(streams: list) -> pronet.FilterResult:
    traj = pronet.builtin_trajectory("paper")
    n = int(SECONDS * 100)
    imu = traj.imu[:n] + np.random.default_rng(1).normal(size=(n, 6)) * np.sqrt(Q)
    return pronet.run_filter(
        imu, traj.time[1 : n + 1], streams, t0=0.0, lla0=traj.lla[0], vel0=traj.vel_ned[0],
        rpy0=traj.rpy[0], strategy=pronet.Strategy.constant(Q),
        config=pronet.FilterConfig(accel_bias_psd=1e-10, gyro_bias_psd=1e-14),
    )  # fmt: skip


def _reports(**kw) -> dict[str, StreamReport]:
    streams, rows = _streams(np.random.default_rng(3), **kw)
    out = _pass(streams)
    sources = [
        StreamSource("dvl", streams[0].time),
        StreamSource("fix", streams[1].time, lla=rows["fix"]),
        StreamSource("heading", streams[2].time),
    ]
    health = pass_health(
        out.streams, sources, lla=out.lla, vel=out.vel, sigma=out.sigma, time=out.time
    )
    assert health.divergence == ""
    return {r.name: r for r in health.streams}


def test_streams_told_their_sigma_are_in_band_and_counted() -> None:
    r = _reports()
    assert (r["dvl"].applied, r["fix"].applied, r["heading"].applied) == (120, 24, 240)
    assert r["dvl"].dof == 3.0 and r["heading"].dof == 1.0
    assert r["fix"].dof == pytest.approx(2.5)  # half the fixes horizontal
    for rep in r.values():
        lo, hi = rep.band
        assert lo < rep.mean_nis < hi and rep.flag == "", rep
        assert rep.rejected == 0 and rep.skipped == {}
        assert np.isfinite(rep.nis).all() and len(rep.time) == rep.rows


def test_one_outlier_that_holds_most_of_a_stream_s_nis_is_named() -> None:
    """One USBL fix 550 m north of the rest (a multipath echo): the fix stream's mean NIS
    is above its band, and the line blamed the σ, datum or units of every fix; it now
    names the one reading, its time and share, and the mean without it (outside the
    band too: the ungated outlier pulled the filter, and the fixes after it disagree).
    Fixes all 300 m off (a datum) leave no reading holding over half: no such clause."""
    streams, rows = _streams(np.random.default_rng(3))
    fix = streams[1]
    lla = np.array(rows["fix"])
    lla[10] = pronet.lla_from_ned(np.array([550.0, 0.0, 0.0]), lla[10])
    streams[1] = pronet.Fix(fix.time, lla, sigma=[1.0, 1.0, 1.0])
    out = _pass(streams)
    sources = [StreamSource("fix", fix.time, lla=lla)]
    (report,) = pass_health(out.streams[1:2], sources, lla=out.lla, vel=out.vel,
                            sigma=out.sigma, time=out.time).streams  # fmt: skip
    assert report.mean_nis > report.band[1]
    clause = re.search(
        rf"; one reading, at {fix.time[10]:.10g} s, holds (\d+)% of it \(NIS \S+; without it "
        r"the mean is \S+, (within|outside) the band\): an outlier, and fix readings have no gate: "
        r"leave it out of the stream$",
        report.flag,
    )  # fmt: skip
    assert clause is not None and int(clause.group(1)) > 50, report.flag
    assert "one reading" not in _reports(fix_offset=300.0)["fix"].flag


@pytest.mark.parametrize(
    ("kw", "stream", "words"),
    [
        ({"fix_offset": 300.0}, "fix", "the antenna's lever arm"),
        ({"dvl_told": 0.01}, "dvl", "the DVL's σ too small"),
        ({"heading_offset": 0.2}, "heading", "a magnetic heading without its declination"),
    ],
)
def test_a_stream_that_disagrees_with_the_filter_is_named_with_its_causes(
    kw: dict, stream: str, words: str
) -> None:
    rep = _reports(**kw)[stream]
    assert rep.mean_nis > rep.band[1]
    assert rep.flag.startswith(f"{stream}: mean NIS ") and words in rep.flag, rep.flag
    assert "\n" not in rep.flag


def test_a_sigma_too_large_reads_below_the_band_and_outside_rows_are_skipped() -> None:
    streams, _ = _streams(np.random.default_rng(3), dvl_told=1.0)
    late = pronet.Heading([500.0, 501.0], [0.1, 0.1], sigma=0.01)  # past the pass
    out = _pass([streams[0], late])
    dvl = stream_report("dvl", out.streams[0], streams[0].time)
    assert dvl.mean_nis < dvl.band[0] and "larger than the readings' scatter" in dvl.flag
    rep = stream_report("heading", out.streams[1], late.time, skipped={"nan": 3})
    assert rep.applied == 0 and rep.flag == "heading: no reading applied"
    assert rep.skipped == {"nan": 3, "outside the pass": 2} and rep.rows == 5
    with pytest.raises(ValueError, match="^sources: one per stream"):
        pass_health(
            out.streams, [StreamSource("dvl", streams[0].time)],
            lla=out.lla, vel=out.vel, sigma=out.sigma, time=out.time,
        )  # fmt: skip


def test_rejected_readings_keep_their_nis_and_are_marked() -> None:
    streams, _ = _streams(np.random.default_rng(3))
    gated = pronet.Dvl(streams[0].time, streams[0].velocity, sigma=0.1, gate=3.0)
    out = _pass([gated])
    rep = stream_report("dvl", out.streams[0], gated.time)
    assert rep.accepted is not None and 0 < rep.rejected == int((~rep.accepted).sum())
    assert np.isfinite(rep.nis).all()  # a rejected reading's NIS too
    assert (rep.nis[~rep.accepted] > 3.0).all() and (rep.nis[rep.accepted] <= 3.0).all()
    assert rep.applied == int(rep.accepted.sum()) and "gate rejected" in rep.flag


def _warned(streams: list, **config) -> list[str]:
    """The FilterHealthWarning lines of ``run_filter`` over ``streams``."""
    traj = pronet.builtin_trajectory("paper")
    n = int(SECONDS * 100)
    imu = traj.imu[:n] + np.random.default_rng(1).normal(size=(n, 6)) * np.sqrt(Q)
    cfg = pronet.FilterConfig(accel_bias_psd=1e-10, gyro_bias_psd=1e-14, **config)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        out = pronet.run_filter(
            imu, traj.time[1 : n + 1], streams, t0=0.0, lla0=traj.lla[0],
            vel0=traj.vel_ned[0], rpy0=traj.rpy[0], strategy=pronet.Strategy.constant(Q),
            config=cfg,
        )  # fmt: skip
    lines = [str(w.message) for w in caught if issubclass(w.category, FilterHealthWarning)]
    assert lines == [f"run_filter: {flag}" for flag in out.health.flags]
    return lines


def test_run_filter_says_nothing_of_streams_told_their_sigma() -> None:
    streams, _ = _streams(np.random.default_rng(3))
    assert _warned(streams) == []


@pytest.mark.parametrize(
    ("case", "words"),
    [
        ("fixes 300 m north", "streams[1] (fix): mean NIS"),
        ("a placeholder covariance 99999 taken as R", "below its 95 % band"),
        ("a gate of 0.01 (a probability)", "the innovation gate rejected 120 of 120"),
        ("an ENU velocity read as NED", "a NED world read as ENU"),
        ("a depth in kPa (absolute)", "streams[3] (depth): mean NIS"),
    ],
)
def test_run_filter_names_a_stream_the_filter_knows_is_wrong(case: str, words: str) -> None:
    rng = np.random.default_rng(3)
    streams, _ = _streams(rng, fix_offset=300.0 if "300 m" in case else 0.0)
    dvl = streams[0]
    if "99999" in case:
        streams[0] = pronet.Dvl(dvl.time, dvl.velocity, sigma=np.sqrt(99999.0))
    if "gate" in case:
        streams[0] = pronet.Dvl(dvl.time, dvl.velocity, sigma=0.1, gate=0.01)
    if "ENU" in case:
        traj = pronet.builtin_trajectory("paper")
        ned = traj.vel_ned[np.round(dvl.time * 100).astype(int)]
        enu = ned[:, [1, 0, 2]] * [1.0, 1.0, -1.0] + rng.normal(size=ned.shape) * 0.1
        streams[0] = pronet.Dvl(dvl.time, enu, sigma=0.1, frame="ned")
    if "kPa" in case:  # inside the 11 km check: 101 kPa at the surface, +10 kPa a metre
        depth = -pronet.builtin_trajectory("paper").lla[np.round(dvl.time * 100).astype(int), 2]
        streams.append(pronet.Depth(dvl.time, (depth * 1025 * 9.80665 + 101325) / 1e3, sigma=0.1))
    lines = _warned(streams)
    assert any(words in line for line in lines), (case, lines)


def test_a_diverged_pass_is_named_with_its_first_epoch() -> None:
    # An accelerometer 5 m/s² off forward, no aiding: 100 m/s within 20 s. A pass that
    # keeps its last epoch only, or one epoch in 7 s, names the same epoch.
    traj = pronet.builtin_trajectory("paper")
    n = 3000
    imu = traj.imu[:n] + [5.0, 0.0, 0.0, 0.0, 0.0, 0.0]

    def run(warn: bool, **options: object) -> pronet.FilterResult:
        return pronet.run_filter(
            imu, traj.time[1 : n + 1], t0=0.0, lla0=traj.lla[0], vel0=traj.vel_ned[0],
            rpy0=traj.rpy[0], strategy=pronet.Strategy.constant(Q), warn=warn, **options,
        )  # fmt: skip

    with pytest.warns(FilterHealthWarning, match="the pass diverged: its solution"):
        out = run(warn=True)
    fast = np.linalg.norm(out.vel, axis=1) > 100.0
    k = int(np.argmax(fast))
    assert fast.any() and 0 < out.time[k] < 20.0
    assert f"moves faster than 100 m/s from t = {out.time[k]:.6g} s:" in out.health.divergence
    assert divergence(_read(out)) == out.health.divergence
    for options in ({"epochs": "last"}, {"output_step": 7.0}):
        kept = run(warn=False, **options)
        assert kept.health.divergence == out.health.divergence, options


def _heading_pass(given: list, *, warn: bool = False, **options: object) -> pronet.FilterResult:
    """The paper trajectory's first ``SECONDS`` with a vertical gyro bias known to
    0.005 rad/s (1,000 °/h) only: with the DVL alone its heading σ passes 5° within
    20 s. ``options``: ``covariance_step``, and ``run_filter``'s epochs."""
    traj = pronet.builtin_trajectory("paper")
    n = int(SECONDS * 100)
    config = _loose_config(float(options.pop("covariance_step", 0.1)))  # type: ignore[arg-type]
    return pronet.run_filter(
        traj.imu[:n], traj.time[1 : n + 1], given, t0=0.0, lla0=traj.lla[0],
        vel0=traj.vel_ned[0], rpy0=traj.rpy[0], strategy=pronet.Strategy.constant(Q),
        config=config, warn=warn, **options,
    )  # fmt: skip


def _loose_config(step: float) -> pronet.FilterConfig:
    """A filter whose vertical gyro bias is known to 0.005 rad/s only, at the
    covariance ``step`` [s]."""
    p0 = list(pronet.FilterConfig().p0_sigma)
    p0[14] = 0.005
    return pronet.FilterConfig(
        accel_bias_psd=1e-10, gyro_bias_psd=1e-14, p0_sigma=p0, covariance_step=step
    )


def _read(out: pronet.FilterResult) -> Extent:
    """The :class:`Extent` of a pass's kept epochs, read from its arrays."""
    return Extent.of(out.lla, out.vel, out.sigma, out.time)


def _heading_over(health: pronet.FilterResult) -> float:
    """The time [s] a pass's heading finding names."""
    found = re.search(r"from t = (\S+) s\)", health.health.heading)
    assert found is not None, health.health.heading
    return float(found.group(1))


def test_a_heading_sigma_past_its_linear_range_is_named_and_a_compass_keeps_it_in() -> None:
    """The DVL alone: the heading's σ passes 5° within 20 s, and the pass says from
    when; with the 2 Hz heading it stays under 1°, and nothing is said."""
    streams, _ = _streams(np.random.default_rng(3))
    with pytest.warns(FilterHealthWarning, match="the heading's 1σ reached"):
        alone = _heading_pass(streams[:1], warn=True)
    assert alone.health.heading in alone.health.flags
    # The core watched P where it stood (each close of the 0.1 s step, after each
    # epoch's updates): the first kept epoch past 5° lies within that close's step.
    k = int(np.argmax(alone.sigma[:, 8] > np.radians(5.0)))
    # (the message's time has 6 significant digits: 1e-4 s of slack)
    assert 0 < alone.time[k] - 1e-4 <= _heading_over(alone) < alone.time[k] + 0.1 < 20.0
    # P propagated at every sample and every epoch kept: the arrays read again say
    # what the core watched, to the letter.
    every = _heading_pass(streams[:1], covariance_step=0.0)
    assert every.health.heading == heading_linearity(_read(every)) != ""
    aided = _heading_pass([streams[0], streams[2]])
    assert np.nanmax(aided.sigma[:, 8]) < np.radians(1.0)
    assert aided.health.heading == "" == heading_linearity(_read(aided))


def test_a_heading_sigma_that_passed_5_degrees_and_came_back_is_named_from_the_last_epoch() -> None:
    """The DVL alone for 40 s, then the compass too: the σ passes 5° and falls back
    under 1°. A pass that keeps only its last epoch, or one epoch in 30 s, still says
    when it passed (the core watches every epoch); its arrays alone cannot."""
    streams, _ = _streams(np.random.default_rng(3))
    compass = streams[2]
    late = compass.time > 40.0
    given = [streams[0], pronet.Heading(compass.time[late], compass.heading[late], sigma=0.01)]
    every = _heading_pass(given)
    over = _heading_over(every)
    assert 0 < over < 20.0 and every.sigma[-1, 8] < np.radians(1.0)
    for options in ({"epochs": "last"}, {"output_step": 30.0}):
        kept = _heading_pass(given, **options)
        assert kept.health.heading == every.health.heading, options
    last = _heading_pass(given, epochs="last")
    assert heading_linearity(_read(last)) == ""


def test_the_extent_the_core_gathers_is_the_one_its_arrays_give() -> None:
    # Every epoch at each sample and inside a covariance step (σ written when the step
    # closes), thinned, the last alone; with the compass and fixes, and with the DVL
    # alone and a loose vertical gyro bias (the heading σ passes 5°); and a pass that
    # left its bounds (5 m/s² off). The core watches every epoch, kept or not: where
    # every epoch is kept, the speed bound broken and when are the arrays'; the heading,
    # watched where P stood, is never below the kept σ (equal where P is current at every
    # epoch), and passes 5° at the close ending the step in which a kept σ did.
    traj = pronet.builtin_trajectory("paper")
    n = 3000
    streams, _ = _streams(np.random.default_rng(5))
    drifted = traj.imu[:n] + [5.0, 0.0, 0.0, 0.0, 0.0, 0.0]
    every, thinned, last = {}, {"output_step": 0.37}, {"epochs": "last"}
    cases = [
        (traj.imu[:n], streams, 0.0, every, False),
        *((traj.imu[:n], streams, 0.1, kept, False) for kept in (every, thinned, last)),
        *((traj.imu[:n], streams[:1], 0.1, kept, True) for kept in (every, thinned, last)),
        (drifted, [], 0.0, every, False),
    ]
    for imu, given, step, options, loose in cases:
        config = _loose_config(step) if loose else pronet.FilterConfig(covariance_step=step)
        out = pronet._core.run_filter(
            imu, traj.time[1 : n + 1], given, t0=0.0, lla0=traj.lla[0], vel0=traj.vel_ned[0],
            rpy0=traj.rpy[0], strategy=pronet.Strategy.constant(Q), config=config, **options,
        )  # fmt: skip
        case = (step, options, loose)
        gathered = Extent(*out["extent"])
        read = Extent.of(out["lla"], out["vel"], out["sigma"], out["time"])
        assert gathered.out_of_bounds == ("speed" if imu is drifted else ""), case
        if options is every:
            assert gathered.out_of_bounds == read.out_of_bounds, case
            np.testing.assert_equal(gathered.out_of_bounds_at, read.out_of_bounds_at)
        g, r = gathered.heading_over, read.heading_over
        assert np.isnan(g) == (given is streams), case  # the compass keeps it under 5°
        if step == 0.0:
            assert gathered.heading2 == pytest.approx(read.heading2, rel=1e-14), case
            np.testing.assert_equal(g, r)
            continue
        assert gathered.heading2 >= read.heading2 * (1 - 1e-14), case
        if options is every:
            assert np.isnan(g) == np.isnan(r), case
            assert not (r > g or g >= r + step), case
        elif not np.isnan(r):
            assert g < r + step, case


def test_a_filter_told_the_simulation_s_model_flags_no_more_runs_than_chance() -> None:
    sc = SCENARIOS["matched"](0)
    result = pronet.monte_carlo(
        sc.trajectory, pronet.Strategy.constant(sc.q_nominal), sensors=sc.sensors,
        config=sc.config, n_runs=100, seed=0,
    )  # fmt: skip
    outside = runs_outside_band(result.nis)
    assert outside.sum() <= chance_bound(100) and runs_flag("constant", outside) == ""
    # A run's band is its own: a mean at the band's edge is in, beyond it out.
    lo, hi = pronet.stats.chi2_mean_band(3, 4)
    nis = np.array([[hi * 0.999] * 4 + [np.nan], [hi * 1.001] * 4 + [np.nan], [np.nan] * 5])
    assert runs_outside_band(nis).tolist() == [False, True, False]
    assert chance_bound(100) == 11 and chance_bound(1) == 1


def test_simulate_names_a_row_whose_runs_leave_their_band(tmp_path) -> None:
    from pronet.experiments.simulation import simulate

    told = tmp_path / "told.toml"  # the DVL's R told 100 times too small
    told.write_text("dvl_variance = [1e-6, 1e-6, 1e-6]\n")
    said: list[str] = []
    folder = simulate("matched", ["constant"], tmp_path / "out", filter_config=told,
                      n_runs=10, plots=False, say=said.append)  # fmt: skip
    config = json.loads((folder / "config.json").read_text())
    assert config["health"]["constant"]["runs_nis_outside_band"] == 10
    (note,) = config["notes"]
    assert note.startswith("constant: 10 of 10 runs' mean DVL NIS outside") and note in said
    assert f"- {note}" in (folder / "table.md").read_text()


def test_a_failed_runs_partial_nis_is_no_runs_verdict(tmp_path, monkeypatch) -> None:
    """The runs-out-of-band count reads the runs that finished: five of ten runs made
    to fail, their NIS so far far above the band, are counted as failed, not as runs
    outside it (the probe's find: they flagged a consistent row)."""
    from dataclasses import replace

    from pronet.experiments import simulation

    real = simulation.run_strategies

    def five_fail(*args, **kwargs):
        rows = real(*args, **kwargs)
        res = rows[0].result
        nis = res.nis.copy()
        nis[:5] = 1e3
        failure = ["t = 1 s: numerical failure"] * 5 + list(res.failure[5:])
        return [replace(rows[0], result=replace(res, nis=nis, failure=failure)), *rows[1:]]

    monkeypatch.setattr(simulation, "run_strategies", five_fail)
    folder = simulation.simulate("matched", ["constant"], tmp_path / "out", n_runs=10,
                                 plots=False, say=lambda _: None)  # fmt: skip
    config = json.loads((folder / "config.json").read_text())
    health = config["health"]["constant"]
    assert health["failed_runs"] == 5 and health["runs"] == 5
    assert health["runs_nis_outside_band"] <= health["chance_allows"] and not config["notes"]


def test_white_innovations_pass_the_whiteness_test_at_its_nominal_rate() -> None:
    """The lag-one autocorrelation of the whitened DVL innovations
    (:func:`pronet.stats.whiteness`) of a filter told its DVL's white noise lies outside
    its 95 % band in no more of 100 passes than chance allows, so does each axis's over
    the 300 axes, and none is flagged; a 5 Hz
    DVL with a correlated error beside its white noise (a first-order Gauss–Markov bias
    of 0.1 m/s, τ = 20 s, its variance added to R) is flagged by name in every pass."""
    outside, axes_outside, flagged = 0, 0, 0
    for seed in range(100):
        streams, _ = _streams(np.random.default_rng(100 + seed))
        dvl = _pass(streams[:1]).health.streams[0]
        assert np.isfinite(dvl.autocorrelation) and dvl.autocorrelation_band > 0
        outside += abs(dvl.autocorrelation) > dvl.autocorrelation_band
        # the same test per axis, each innovation over its own σ
        assert len(dvl.axis_autocorrelation) == 3
        assert dvl.axis_autocorrelation_band == pytest.approx(np.sqrt(3) * dvl.autocorrelation_band)
        axes_outside += int(
            np.sum(np.abs(dvl.axis_autocorrelation) > dvl.axis_autocorrelation_band)
        )
        flagged += "correlated" in dvl.flag
    assert outside <= chance_bound(100) and axes_outside <= chance_bound(300) and flagged == 0
    traj = pronet.builtin_trajectory("paper")
    k = np.arange(20, int(SECONDS * 100) + 1, 20)
    body = np.einsum("kji,kj->ki", dcm_from_euler(traj.rpy[k]), traj.vel_ned[k])
    a = np.exp(-0.2 / 20.0)
    for seed in range(5):
        rng = np.random.default_rng(seed)
        bias = np.zeros((len(k), 3))
        for i in range(1, len(k)):
            bias[i] = a * bias[i - 1] + rng.normal(size=3) * 0.1 * np.sqrt(1 - a * a)
        z = body + bias + rng.normal(size=body.shape) * 0.1
        report = _pass([pronet.Dvl(traj.time[k], z, sigma=np.hypot(0.1, 0.1))]).health
        (line,) = report.flags
        assert line.startswith("streams[0] (dvl): ") and "innovations are correlated" in line


def test_pronet_real_notes_a_heading_sigma_past_5_degrees_once_per_section() -> None:
    """``pronet real``'s notes (``table.md``, ``config.json``): the rows of a section
    whose heading σ passed 5° in one line, the first row's finding and the rows that
    share it; a section whose rows stayed under it says nothing."""
    from types import SimpleNamespace

    from pronet.recorded.runs import RealRuns
    from pronet.stats import PassHealth

    said = "the heading's 1σ reached 9.1° (over 5° from t = 812 s): a heading error …"

    def run(section: str, label: str, heading: str) -> SimpleNamespace:
        result = SimpleNamespace(health=PassHealth(heading=heading))
        return SimpleNamespace(section=section, label=label, result=result, unfilled=None)

    runs: list[Any] = [
        run("a", "constant", said), run("a", "constant, smoothed", said),
        run("a", "detvar", said.replace("9.1", "8.7")), run("a", "adaptive", ""),
        run("b", "constant", ""),
    ]  # fmt: skip
    real = RealRuns(sections=[], runs=runs, stamped=[], inertial=[], q_estimated={},
                    constants={})  # fmt: skip
    assert real.notes == [f"section a: {said} (row constant; 2 of 3 rows: constant; detvar)"]


def test_a_lever_arm_beyond_10_m_is_warned_of_by_name() -> None:
    """Arms typed in cm, a depth sensor's and the DVL's (the config's): each warned of,
    naming it, and the pass runs as told; with ``warn=False`` (a caller that checks its
    arms its own way, as ``pronet navigate`` and ``pronet real`` do) nothing is said."""
    from pronet import PlausibilityWarning

    traj = pronet.builtin_trajectory("paper")
    n = 500
    depth = pronet.Depth(traj.time[100:n:100], -traj.lla[100:n:100, 2], sigma=0.1,
                         lever_arm=(0.0, 0.0, 150.0))  # fmt: skip

    def run(warn: bool) -> pronet.FilterResult:
        return pronet.run_filter(
            traj.imu[:n], traj.time[1 : n + 1], [depth], t0=0.0, lla0=traj.lla[0],
            vel0=traj.vel_ned[0], rpy0=traj.rpy[0], strategy=pronet.Strategy.constant(Q),
            config=pronet.FilterConfig(lever_arm=[-185.0, -3.0, 12.0]), warn=warn,
        )  # fmt: skip

    with pytest.warns(PlausibilityWarning) as said:
        run(warn=True)
    lines = [str(w.message) for w in said if w.category is PlausibilityWarning]
    for start in (
        "config.lever_arm: -185,-3,12 m (185 m long): its x of -185",
        "streams[0].lever_arm: 0,0,150 m (150 m long): its z of",
    ):
        assert any(line.startswith(start) for line in lines)
    with warnings.catch_warnings():
        warnings.simplefilter("error", PlausibilityWarning)
        run(warn=False)


def test_imu_stamps_that_jitter_or_leave_a_gap_are_warned_of() -> None:
    """Stamps jittering by ±20 % of a step (35 % at the 99th percentile of the steps: a
    logger's clock) and a 2 s gap: each warned of by ``run_filter``, naming
    ``imu_time``, and the pass runs as given; the paper's steady 100 Hz stamps say
    nothing."""
    from pronet import PlausibilityWarning

    traj = pronet.builtin_trajectory("paper")
    n = 1000
    steady = traj.time[1 : n + 1]
    shaky = steady + np.random.default_rng(0).uniform(-0.002, 0.002, n)
    gap = steady + np.where(np.arange(n) >= 500, 2.0, 0.0)

    def said(stamps: np.ndarray) -> list[str]:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            pronet.run_filter(traj.imu[:n], stamps, t0=0.0, lla0=traj.lla[0],
                              vel0=traj.vel_ned[0], rpy0=traj.rpy[0],
                              strategy=pronet.Strategy.constant(Q))  # fmt: skip
        return [str(w.message) for w in caught if w.category is PlausibilityWarning]

    assert said(steady) == []
    (jitter,) = said(shaky)
    assert jitter.startswith("imu_time: the IMU steps jitter by 35 % of the median step")
    (hole,) = said(gap)
    assert hole.startswith("imu_time: a gap of 2.01 s after row 499 (the median step is 0.01 s)")


def test_an_imu_dt_other_than_the_stamps_step_is_warned_of() -> None:
    """The paper's 100 Hz samples stamped 5 ms apart (a 200 Hz IMU) under the default
    ``imu_dt`` of 0.01 s: the filter's process noise is twice what ``q`` per sample
    gives, warned of naming ``config.imu_dt`` and the step, steady stamps or jittering;
    ``imu_dt`` set to the step (or within 15 % of it) says nothing."""
    from pronet import PlausibilityWarning

    traj = pronet.builtin_trajectory("paper")
    n = 1000
    fast = 0.5 * traj.time[1 : n + 1]
    shaky = fast + np.random.default_rng(0).uniform(-0.001, 0.001, n)

    def said(stamps: np.ndarray, imu_dt: float) -> list[str]:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            pronet.run_filter(traj.imu[:n], stamps, t0=0.0, lla0=traj.lla[0],
                              vel0=traj.vel_ned[0], rpy0=traj.rpy[0],
                              config=pronet.FilterConfig(imu_dt=imu_dt),
                              strategy=pronet.Strategy.constant(Q))  # fmt: skip
        return [str(w.message) for w in caught if w.category is PlausibilityWarning]

    (steady,) = said(fast, 0.01)
    assert steady.startswith("config.imu_dt: 0.01 s, but the IMU stamps step 0.005 s")
    assert "its process noise is 2× what samples 0.005 s apart" in steady
    period = [line for line in said(shaky, 0.01) if line.startswith("config.imu_dt")]
    assert len(period) == 1 and "process noise is 2.01× what samples 0.004979 s" in period[0]
    assert said(fast, 0.005) == said(fast, 0.0057) == []
    assert said(traj.time[1 : n + 1], 0.0114) == []


def test_an_adaptive_window_the_pass_never_fills_is_warned_of() -> None:
    """Mehra's and the adaptive strategy's windows of 1,000 updates over a pass of 120
    DVL updates: each ran on its prior q throughout, warned of naming ``strategy`` and
    the count; a window of 60 (filled) and the constant strategy say nothing."""
    from pronet import PlausibilityWarning

    streams, _ = _streams(np.random.default_rng(0))
    traj = pronet.builtin_trajectory("paper")
    n = int(SECONDS * 100)

    def said(strategy: pronet.Strategy) -> list[str]:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            pronet.run_filter(traj.imu[:n], traj.time[1 : n + 1], streams[:1], t0=0.0,
                              lla0=traj.lla[0], vel0=traj.vel_ned[0], rpy0=traj.rpy[0],
                              strategy=strategy)  # fmt: skip
        return [str(w.message) for w in caught if w.category is PlausibilityWarning]

    for kind in ("mehra", "adaptive"):
        (line,) = said(getattr(pronet.Strategy, kind)(1000, Q))
        assert line.startswith(
            f"strategy: {kind}'s window of 1000 velocity updates was never filled "
            "(120 accepted in the pass): it ran on its prior q throughout"
        )
        assert said(getattr(pronet.Strategy, kind)(60, Q)) == []
    assert said(pronet.Strategy.constant(Q)) == []


def test_an_initial_attitude_in_degrees_is_refused_by_name() -> None:
    """``rpy0=(0, 0, 90)``, degrees for radians: it ran, saying only that the DVL
    disagreed; refused, naming the angle, before anything is computed."""
    traj = pronet.builtin_trajectory("paper")
    n = 200
    for rpy0, what in (((0.0, 0.0, 90.0), "yaw 90"), ((10.0, 0.0, 0.0), "roll 10")):
        with pytest.raises(ValueError, match=f"^rpy0: {what} is beyond .* in degrees"):
            pronet.run_filter(traj.imu[:n], traj.time[1 : n + 1], t0=0.0, lla0=traj.lla[0],
                              vel0=traj.vel_ned[0], rpy0=rpy0,
                              strategy=pronet.Strategy.constant(Q))  # fmt: skip


def test_names_name_the_streams_in_the_checks_warnings_and_health() -> None:
    """``names``: a caller's own names for its streams (a command's "dvl", a file)
    replace ``streams[i]`` in the depth check, the warning of a stream outside the run
    and the health's lines; the default keeps ``streams[i]``; a wrong count is refused."""
    from pronet import PlausibilityWarning

    streams, _ = _streams(np.random.default_rng(0))
    traj = pronet.builtin_trajectory("paper")
    n = int(SECONDS * 100)
    run = functools.partial(
        pronet.run_filter, traj.imu[:n], traj.time[1 : n + 1], t0=0.0, lla0=traj.lla[0],
        vel0=traj.vel_ned[0], rpy0=traj.rpy[0], strategy=pronet.Strategy.constant(Q),
        warn=False,
    )  # fmt: skip
    late = pronet.Heading(np.array([SECONDS + 10.0]), np.array([0.1]), sigma=0.1)
    with pytest.warns(PlausibilityWarning, match=r"^heading\.csv: none of its 1 row \("):
        out = run([streams[0], late], names=["port dvl", "heading.csv"])
    assert [r.name for r in out.health.streams] == ["port dvl", "heading.csv"]
    with pytest.warns(PlausibilityWarning, match=r"^streams\[1\] \(Heading\): none of its"):
        out = run([streams[0], late])
    assert [r.name for r in out.health.streams] == ["streams[0] (dvl)", "streams[1] (heading)"]
    pascals = pronet.Depth(np.arange(1.0, 30.0), np.full(29, 150_000.0), sigma=0.1)
    with pytest.raises(ValueError, match=r"^depth\.csv: depth row 0 is 150000 m, beyond"):
        run([streams[0], pascals], names=["dvl", "depth.csv"])
    with pytest.raises(ValueError, match=r"^names: expected 2 non-empty strings, one per"):
        run([streams[0], late], names=["dvl"])


def test_a_slow_error_on_one_axis_is_named_where_the_whitened_vector_hides_it() -> None:
    """Innovations whose x component is an AR(1) with φ = 0.5 (a slow error there) and
    whose y component alternates (φ = −0.7) with ten times its spread, S the identity:
    the whitened vector's lag-one autocorrelation is negative and flagged as such, and
    the clause also names x, with its autocorrelation; where the vector itself reads
    correlated, or no axis is beyond the flag, no axis is named; a scalar stream's
    vector is its axis."""
    from pronet._util.whiteness import axis_whiteness, whiteness_clause
    from pronet.stats import whiteness

    rng = np.random.default_rng(11)
    n = 2000
    nu = rng.normal(size=(n, 3))
    for k in range(1, n):
        nu[k, 0] = 0.5 * nu[k - 1, 0] + np.sqrt(0.75) * nu[k, 0]
        nu[k, 1] = -0.7 * nu[k - 1, 1] + np.sqrt(0.51) * nu[k, 1]
    nu[:, 1] *= 10.0
    cov = np.broadcast_to(np.eye(3), (n, 3, 3)).copy()
    used = np.ones(n, dtype=bool)
    rho, half = whiteness(nu, cov, used)
    axes, band = axis_whiteness(nu, cov, used)
    assert band == pytest.approx(1.96 / np.sqrt(n - 1))
    assert rho < -0.5 and abs(axes[0] - 0.5) < 0.05 and abs(axes[1] + 0.7) < 0.05
    said = whiteness_clause(rho, half, axes, band)
    assert said.startswith("its whitened innovations are anti-correlated")
    assert f"its innovations along x ({axes[0]:+.2f}) (each" in said and "y (" not in said
    assert "hides" in said and "x is forward" in said
    assert "along x" not in whiteness_clause(0.3, half, axes, band)  # the vector says it
    assert whiteness_clause(0.0, half, np.zeros(3), band) == ""
    # beyond the vector's band but inside the axis's own (√3 wider): not named
    assert whiteness_clause(0.0, half, np.array([2.5 * half, 0, 0]), band) == ""
    assert whiteness_clause(0.0, half, np.array([0.5]), band) == ""  # one axis: the vector
    few = axis_whiteness(nu[:2], cov[:2], used[:2])
    assert np.isnan(few[1]) and np.isnan(few[0]).all()
    # A reading whose predicted σ on an axis is 0 is left out, not divided by.
    zero = cov.copy()
    zero[5, 2, 2] = 0.0
    assert axis_whiteness(nu, zero, used)[1] == pytest.approx(1.96 / np.sqrt(n - 2))
    # End to end: a velocity stream's report carries the clause and the per-axis test.
    from types import SimpleNamespace

    from pronet.stats import stream_report

    nis = np.einsum("ki,ki->k", nu, nu)
    rows = SimpleNamespace(kind="velocity", epoch=np.arange(n), nis=nis, accepted=None,
                           innovation=nu, innovation_cov=cov)  # fmt: skip
    report = stream_report("dvl", rows, np.arange(n, dtype=np.float64))
    assert f"along x ({axes[0]:+.2f})" in report.flag and report.flag.startswith("dvl: ")
    np.testing.assert_allclose(report.axis_autocorrelation, axes)
    assert report.axis_autocorrelation_band == pytest.approx(band)
