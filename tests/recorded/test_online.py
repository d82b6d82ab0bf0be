"""pronet.recorded.online: the navigator fed as the data arrives against the batch pass
(``run_filter``) on a simulated survey with a DVL, depth, fixes and a compass."""

from __future__ import annotations

import re
from dataclasses import replace

import numpy as np
import pytest
from mission_recording import Mission, simulate_mission, write_generic, write_vehicle_file

import pronet
from pronet import _core
from pronet._util.plausibility import PlausibilityWarning
from pronet.learn.hybrid import q_schedule
from pronet.recorded.alignment import load_section
from pronet.recorded.navigate import NavigateOptions, lever_arms, navigate
from pronet.recorded.online import Navigator, navigator_for, readings_of
from pronet.recorded.solution import InitialState
from pronet.recorded.vehicle import load_vehicle
from pronet.strategies import Learned, StrategySpec, strategy

Q = (1e-4, 1e-4, 1e-4, 1e-8, 1e-8, 1e-8)
P0 = (2.0, 2.0, 1.0, 0.1, 0.1, 0.1, 0.01, 0.01, 0.05, 0.02, 0.02, 0.02, 1e-3, 1e-3, 1e-3)
CONFIG = _core.FilterConfig(
    p0_sigma=P0, dvl_variance=[0.02**2] * 3, lever_arm=[0.3, 0.0, 0.4], imu_dt=0.005
)


@pytest.fixture(scope="module")
def mission() -> Mission:
    return simulate_mission(0, minutes=3.0)


def _streams(m: Mission, rows: bool = True) -> list[pronet.Stream]:
    """The survey's streams in order: DVL, depth, fixes, heading (empty with ``rows``
    False, the navigator's sensors)."""
    valid = m.dvl_valid
    arms = m.lever_arms
    take = (lambda a: a) if rows else (lambda a: a[:0])
    return [
        pronet.Dvl(take(m.dvl_time[valid]), take(m.dvl[valid])),
        pronet.Depth(take(m.depth_time), take(m.depth()), sigma=0.05, lever_arm=arms.depth),
        pronet.Fix(take(m.fix_time), take(m.fix_lla), sigma=(1.5, 1.5, 1.5), lever_arm=arms.fix),
        pronet.Heading(take(m.heading_time), take(m.true_heading()), sigma=np.radians(1.0)),
    ]


def _initial(m: Mission) -> InitialState:
    t = m.truth
    return InitialState(t0=m.t0, lla=t.lla[0], vel=t.vel[0], rpy=t.rpy[0], p0_sigma=np.array(P0))


def _arrivals(
    m: Mission, delay: np.ndarray | None = None
) -> list[tuple[float, int, float, np.ndarray]]:
    """Every reading as ``(arrival, stream, stamp, value)``, in order of arrival."""
    out = []
    for s, stream in enumerate(_streams(m)):
        values = {0: "velocity", 1: "depth", 2: "lla", 3: "heading"}[s]
        for t, v in zip(stream.time, getattr(stream, values), strict=True):
            out.append((t, s, t, v))
    if delay is not None:
        out = [(a + d, s, t, v) for (a, s, t, v), d in zip(out, delay, strict=True)]
    out.sort(key=lambda r: r[0])
    return out


def _feed(nav: Navigator, m: Mission, arrivals: list, each=None) -> list[str]:
    """Feed ``m`` sample by sample, each reading once the IMU has passed its arrival;
    ``each(nav, k)`` sees epoch k once every reading up to the next sample has come."""
    fates, i = [], 0
    for k, (t, raw) in enumerate(zip(m.imu_time, m.imu, strict=True)):
        while i < len(arrivals) and arrivals[i][0] <= t:
            _, s, stamp, v = arrivals[i]
            fates.append(nav.reading(s, stamp, v))
            i += 1
        if each is not None and k > 0:
            each(nav, k)
        nav.imu(t, raw)
    for _, s, stamp, v in arrivals[i:]:
        fates.append(nav.reading(s, stamp, v))
    if each is not None:
        each(nav, len(m.imu))
    return fates


def _batch(m: Mission, strat, q_time=None, q=None) -> pronet.FilterResult:
    t = m.truth
    return pronet.run_filter(
        m.imu, m.imu_time, _streams(m), t0=m.t0, lla0=t.lla[0], vel0=t.vel[0], rpy0=t.rpy[0],
        config=CONFIG, strategy=strat, q_time=q_time, q=q,
    )  # fmt: skip


NATIVE = {
    "constant": _core.Strategy.constant(Q),
    "adaptive": _core.Strategy.adaptive(20, Q),
    "mehra": _core.Strategy.mehra(20, Q),
}


@pytest.mark.parametrize("name", list(NATIVE))
def test_fed_in_time_order_every_epoch_is_run_filter_s(mission, name) -> None:
    m, strat = mission, NATIVE[name]
    batch = _batch(m, strat)
    nav = Navigator(_streams(m, rows=False), initial=_initial(m), strategy=strat, config=CONFIG)
    checked = []

    def each(nav: Navigator, k: int) -> None:
        if k % 97 == 0 or k == len(m.imu):
            s = nav.state()
            assert s.epoch == k
            np.testing.assert_array_equal(s.lla, batch.lla[k])
            np.testing.assert_array_equal(s.vel, batch.vel[k])
            np.testing.assert_array_equal(s.rpy, batch.rpy[k])
            np.testing.assert_array_equal(s.bias, batch.bias[k])
            checked.append(k)

    _feed(nav, m, _arrivals(m), each)
    assert len(checked) > 100
    np.testing.assert_array_equal(nav.state().sigma, batch.sigma[-1])
    for tally, result in zip(nav.tally(), batch.streams, strict=True):
        applied = int((result.epoch >= 0).sum())
        assert tally.accepted + tally.rejected == applied
        assert tally.refused == tally.queued == tally.late == 0
        nis = result.nis[np.isfinite(result.nis)].sum()
        assert tally.nis_sum == pytest.approx(nis, rel=1e-12)


def test_the_learned_loop_live_is_the_batch_schedule(mission) -> None:
    m = mission
    learned = strategy(StrategySpec.parse("learned:detrend"), Q, tuning_period=1.0)
    dt = float(np.median(np.diff(m.imu_time)))
    schedule = q_schedule(learned.regressor, m.imu, m.imu_time, prior_q=Q, tuning_period=1.0)
    batch = _batch(m, _core.Strategy.external(Q), schedule.time, schedule.q)
    nav = Navigator(
        _streams(m, rows=False), initial=_initial(m), strategy=learned, config=CONFIG, imu_dt=dt
    )
    _feed(nav, m, _arrivals(m))
    s = nav.state()
    np.testing.assert_array_equal(s.lla, batch.lla[-1])
    np.testing.assert_array_equal(s.rpy, batch.rpy[-1])
    np.testing.assert_array_equal(s.sigma, batch.sigma[-1])
    # One more instant after the last sample than the batch schedule (which ends there).
    assert len(nav.q_history) == len(schedule.time) + 1
    np.testing.assert_array_equal(np.array([q for _, q in list(nav.q_history)[:-1]]), schedule.q)


def test_readings_up_to_half_a_second_late_give_the_in_order_result(mission) -> None:
    m = mission
    strat = NATIVE["constant"]
    batch = _batch(m, strat)
    arrivals = _arrivals(m)
    delay = np.random.default_rng(1).uniform(0.0, 0.5, len(arrivals))
    nav = Navigator(_streams(m, rows=False), initial=_initial(m), strategy=strat, config=CONFIG)
    fates = _feed(nav, m, _arrivals(m, delay))
    assert fates.count("late") > len(fates) // 2 and "refused" not in fates
    s = nav.state()
    # Within the filter's own σ/100 (the bound); here they are equal.
    sigma_pos = batch.sigma[-1][:3]
    assert np.all(np.abs(s.lla - batch.lla[-1]) <= 0.0)
    assert np.all(np.abs(s.sigma[:3] - sigma_pos) <= sigma_pos / 100)


def test_readings_beyond_the_lag_are_refused_and_counted(mission) -> None:
    m = mission
    arrivals = _arrivals(m)
    delay = np.random.default_rng(2).uniform(0.0, 0.5, len(arrivals))
    nav = Navigator(
        _streams(m, rows=False),
        initial=_initial(m),
        strategy=NATIVE["constant"],
        config=CONFIG,
        lag=0.2,
    )
    fates = _feed(nav, m, _arrivals(m, delay))
    tally = nav.tally()
    assert sum(t.refused for t in tally) == fates.count("refused") > 0
    assert sum(t.received for t in tally) == len(arrivals)
    settled = sum(t.accepted + t.rejected + t.refused + t.skipped + t.queued for t in tally)
    assert settled == len(arrivals)


def test_blocks_are_one_sample_at_a_time(mission) -> None:
    m = mission
    learned = strategy(StrategySpec.parse("learned:detrend"), Q, tuning_period=1.0)
    dt = float(np.median(np.diff(m.imu_time)))
    sensors = _streams(m, rows=False)
    navs = [
        Navigator(sensors, initial=_initial(m), strategy=learned, config=CONFIG, imu_dt=dt)
        for _ in range(2)
    ]
    # Readings all given first (queued), then the IMU one by one, or in blocks of 1000.
    for nav in navs:
        for _, s, stamp, v in _arrivals(m):
            assert nav.reading(s, stamp, v) == "queued"
    for t, raw in zip(m.imu_time, m.imu, strict=True):
        navs[0].imu(t, raw)
    for i in range(0, len(m.imu), 1000):
        navs[1].imu_block(m.imu_time[i : i + 1000], m.imu[i : i + 1000])
    a, b = navs[0].state(), navs[1].state()
    np.testing.assert_array_equal(a.lla, b.lla)
    np.testing.assert_array_equal(a.sigma, b.sigma)
    assert navs[0].q_history and len(navs[0].q_history) == len(navs[1].q_history)


def test_the_q_history_keeps_the_latest_instants_only(mission) -> None:
    """A learned loop's q history is bounded (a vehicle's navigator runs for days): the
    latest ``q_history`` instants, those of an unbounded run's end."""
    m = mission
    learned = strategy(StrategySpec.parse("learned:detrend"), Q, tuning_period=1.0)
    dt = float(np.median(np.diff(m.imu_time)))
    navs = [
        Navigator(
            _streams(m, rows=False),
            initial=_initial(m),
            strategy=learned,
            config=CONFIG,
            imu_dt=dt,
            q_history=kept,
        )  # fmt: skip
        for kept in (4, 10**6)
    ]
    for nav in navs:
        nav.imu_block(m.imu_time, m.imu)
    whole = list(navs[1].q_history)
    assert len(whole) > 4 and len(navs[0].q_history) == 4
    assert [e for e, _ in navs[0].q_history] == [e for e, _ in whole[-4:]]
    for (_, a), (_, b) in zip(navs[0].q_history, whole[-4:], strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="q_history: must be at least 1"):
        Navigator(_streams(m, rows=False), initial=_initial(m), strategy=learned, config=CONFIG,
                  imu_dt=dt, q_history=0)  # fmt: skip


def test_bad_input_is_one_line_naming_it(mission) -> None:
    m = mission
    nav = Navigator(
        _streams(m, rows=False), initial=_initial(m), strategy=NATIVE["constant"], config=CONFIG
    )
    with pytest.raises(ValueError, match="^streams\\[0\\]: a navigator's stream describes"):
        Navigator(_streams(m), initial=_initial(m), strategy=NATIVE["constant"], config=CONFIG)
    with pytest.raises(ValueError, match="^imu_dt: a learned strategy"):
        learned = strategy(StrategySpec.parse("learned:detrend"), Q)
        Navigator(_streams(m, rows=False), initial=_initial(m), strategy=learned)
    nav.imu(m.imu_time[0], m.imu[0])
    with pytest.raises(ValueError, match="^imu_time: "):
        nav.imu(m.imu_time[0], m.imu[1])
    with pytest.raises(ValueError, match="^imu: "):
        nav.imu(m.imu_time[1], [1.0, 2.0])
    with pytest.raises(ValueError, match="^imu: the sample at .* beyond any IMU's range"):
        nav.imu(m.imu_time[1], [1e300, 0.0, -9.8, 0.0, 0.0, 0.0])
    block = m.imu[1:11].copy()
    block[5, 4] = np.nan  # a bad row feeds none of its block
    with pytest.raises(ValueError, match="^imu: row 5 .* is not finite: .*; none fed$"):
        nav.imu_block(m.imu_time[1:11], block)
    with pytest.raises(ValueError, match="^streams\\[0\\]: the reading at .* s: 1 reading"):
        nav.reading(0, m.imu_time[1], 1.0)
    with pytest.raises(ValueError, match="^stream: must be the index"):
        nav.reading(7, m.imu_time[1], 1.0)
    with pytest.raises(ValueError, match="^strategy: "):
        nav._native.set_q(Q)
    with pytest.raises(ValueError, match="^lag: "):
        Navigator([], initial=_initial(m), strategy=NATIVE["constant"], lag=-1.0)
    assert nav.failure is None and nav.epoch == 1


def test_unit_and_frame_slips_are_refused_before_anything_is_fed(mission) -> None:
    """The physical bounds for the navigator: what run_filter's plausibility checks refuse."""
    m = mission

    def fresh(initial: InitialState | None = None, **kw) -> Navigator:
        start = _initial(m) if initial is None else initial
        return Navigator(
            _streams(m, rows=False), initial=start, strategy=NATIVE["constant"], config=CONFIG, **kw
        )

    degrees = replace(_initial(m), lla=np.array([32.0, 34.0, -5.0]))
    with pytest.raises(ValueError, match=r"^initial.lla: latitude 32 is beyond .* in degrees\?"):
        fresh(degrees)
    turned = replace(_initial(m), rpy=np.array([0.0, 0.0, 90.0]))
    with pytest.raises(ValueError, match=r"^initial.rpy: yaw 90 is beyond .* in degrees\?"):
        fresh(turned)
    flu = m.imu[:200] * [1, -1, -1, 1, -1, -1]
    for feed in (
        lambda nav: nav.imu(m.imu_time[0], flu[0]),
        lambda nav: nav.imu_block(m.imu_time[:200], flu),
    ):
        nav = fresh()
        with pytest.raises(ValueError, match=r"^imu, rpy0: the specific force .* in FLU"):
            feed(nav)
        assert nav.epoch == 0
    nav = fresh()
    with pytest.raises(
        ValueError, match=r"^imu: the mean specific force is 0.99\d* m/s², not near gravity"
    ):
        nav.imu_block(m.imu_time[:1000], m.imu[:1000] / 9.81)  # in g, over seconds
    dt = float(np.median(np.diff(m.imu_time)))
    nav = fresh(imu_dt=dt)
    unix = m.imu_time + 1.7e9  # stamps in Unix time, t0 relative
    with pytest.raises(ValueError, match=r"^imu_time: the first sample .* on one clock"):
        nav.imu(unix[0], m.imu[0])
    nav = fresh()
    nav.imu_block(m.imu_time[:200], m.imu[:200])  # the same data, right: accepted
    pascals = float(m.depth()[0]) * 1025 * 9.80665 + 101325.0
    with pytest.raises(
        ValueError, match=r"^streams\[1\]: the reading at .* s: depth row 0 .* pascals"
    ):
        nav.reading(1, m.imu_time[199], pascals)
    assert nav.reading(1, m.imu_time[199], float(m.depth()[0])) in ("current", "late")


@pytest.mark.parametrize("spec", ["constant", "mehra:20", "learned:detrend"])
def test_navigator_for_a_recording_is_navigate_s_forward_pass(tmp_path, mission, spec) -> None:
    m = mission
    write_generic(m, tmp_path / "mission")
    vehicle = load_vehicle(write_vehicle_file(tmp_path, m))
    arms = lever_arms(vehicle)
    options = NavigateOptions(
        surface_depth=vehicle.surface_depth or 0.0, smooth=False, strategy=spec
    )
    section, _ = load_section(
        tmp_path / "mission", "generic", imu_lever_arm=arms.imu, dvl_lever_arm=arms.dvl
    )
    batch = navigate(section, vehicle, arms, options)
    nav, made = navigator_for(section, vehicle, arms, options)
    assert made.initial.t0 == batch.initial.t0
    take = section.imu_time > made.initial.t0
    readings = readings_of(made)
    assert {r.stream for r in readings} == {0, 1, 2, 3}
    i = 0
    for t, raw in zip(section.imu_time[take], section.imu[take], strict=True):
        while i < len(readings) and readings[i].time <= t:
            r = readings[i]
            nav.reading(r.stream, r.time, r.value, r.sigma)
            i += 1
        nav.imu(t, raw)
    for r in readings[i:]:
        nav.reading(r.stream, r.time, r.value, r.sigma)
    s = nav.state()
    np.testing.assert_array_equal(s.lla, batch.forward.lla[-1])
    np.testing.assert_array_equal(s.rpy, batch.forward.rpy[-1])
    np.testing.assert_array_equal(s.sigma, batch.forward.sigma[-1])
    applied = [t.accepted + t.rejected for t in nav.tally()]
    assert applied == [r.applied for r in batch.streams]
    assert [t.name for t in nav.tally()] == [r.name for r in batch.streams]  # dvl, depth, …


def test_a_refused_reading_is_named_by_its_stream_and_time(mission) -> None:
    """A reading the navigator refuses named ``streams[i]`` (``streams[1]: must be
    finite, element 0 is NaN``; ``streams[2]_sigma: …``), neither the sensor the user
    knows nor which reading: now the stream's name (``names``, as ``run_filter``'s)
    and the reading's time, in the error, the tally and the findings."""
    m = mission
    names = ["dvl", "depth", "usbl", "compass"]
    nav = Navigator(
        _streams(m, rows=False), initial=_initial(m), strategy=NATIVE["constant"],
        config=CONFIG, names=names,
    )  # fmt: skip
    nav.imu_block(m.imu_time[:200], m.imu[:200])
    t = float(m.imu_time[150])
    for stream, value, sigma, said in (
        (1, np.nan, None, f"depth: the reading at {t:.10g} s: must be finite, element 0 is NaN"),
        (2, m.fix_lla[0], [1.0, 1.0], f"usbl: the reading at {t:.10g} s: sigma: a reading's σ"),
        (3, 400.0, None, f"compass: the reading at {t:.10g} s: row 0 must be a heading in rad"),
        (0, [np.nan, 0.0, 0.0], None, f"dvl: the reading at {t:.10g} s: row 0 is not finite"),
    ):
        with pytest.raises(ValueError) as refused:
            nav.reading(stream, t, value, sigma)
        assert str(refused.value).startswith(said), refused.value
    with pytest.raises(ValueError, match=r"^depth: the reading at nan s: time: must be finite"):
        nav.reading(1, float("nan"), 1.0)
    with pytest.raises(ValueError, match=r"^stream: must be the index of one of the 4"):
        nav.reading(4, t, 1.0)
    assert [s.name for s in nav.tally()] == names
    assert all(not line.startswith("streams[") for line in nav.findings())
    with pytest.raises(ValueError, match=r"^names: expected 4 non-empty strings"):
        Navigator(_streams(m, rows=False), initial=_initial(m),
                  strategy=NATIVE["constant"], names=["dvl"])  # fmt: skip


def test_a_stream_index_of_the_wrong_type_is_one_line_naming_it(mission) -> None:
    """``reading(stream=[1])`` raised a bare ``TypeError: unhashable type: 'list'`` from
    the depth streams' set, and ``stream=True`` (equal to 1) was named as the depth
    stream; a NumPy index (``np.int64(1)``) was taken, but its refused reading said
    ``streams[1]: …``, not the stream's name and time. Now the one line other bad
    indices get, and a NumPy index named as an int is."""
    m = mission
    nav = Navigator(
        _streams(m, rows=False), initial=_initial(m), strategy=NATIVE["constant"],
        config=CONFIG, names=["dvl", "depth", "usbl", "compass"],
    )  # fmt: skip
    nav.imu_block(m.imu_time[:200], m.imu[:200])
    t = float(m.imu_time[150])
    for stream, kind in (([1], "list"), ({1: 2}, "dict"), (True, "bool"), (1.0, "float")):
        with pytest.raises(ValueError) as refused:
            nav.reading(stream, t, 1.0)  # type: ignore[arg-type]
        assert str(refused.value) == f"stream: expected a whole number, got {kind}"
    with pytest.raises(ValueError, match=rf"^depth: the reading at {t:.10g} s: must be finite"):
        nav.reading(np.int64(1), t, np.nan)  # type: ignore[arg-type]
    assert nav.reading(np.int64(1), t, 1.0) == "late"  # type: ignore[arg-type]


class _WindowVariance:
    """A user's own model, called back from the loop: q from each window's variance."""

    def predict(self, windows: np.ndarray) -> np.ndarray:
        return 1e-3 * np.var(np.asarray(windows, dtype=np.float64), axis=-1) + 1e-8


def test_a_user_s_python_model_runs_live_as_in_the_batch_loop(mission) -> None:
    m = mission
    learned = Learned(_WindowVariance(), Q, tuning_period=0.5)
    dt = float(np.median(np.diff(m.imu_time)))
    schedule = q_schedule(learned.regressor, m.imu, m.imu_time, prior_q=Q, tuning_period=0.5)
    batch = _batch(m, _core.Strategy.external(Q), schedule.time, schedule.q)
    sensors = _streams(m, rows=False)
    nav = Navigator(sensors, initial=_initial(m), strategy=learned, config=CONFIG, imu_dt=dt)
    _feed(nav, m, _arrivals(m))
    np.testing.assert_array_equal(nav.state().lla, batch.lla[-1])
    np.testing.assert_array_equal(np.array([q for _, q in list(nav.q_history)[:-1]]), schedule.q)


def test_findings_say_what_the_batch_pass_s_health_says(mission) -> None:
    """A DVL told a σ ten times too small and no compass, the vertical gyro bias known
    to 0.005 rad/s only: the navigator says, as the batch pass's health does, that the
    heading σ passed 5° (from the same time) and that the DVL's mean NIS is above its
    band (the same mean); with the survey's own tuning, what the batch pass says of
    each stream (its σ told larger than the readings' scatter)."""
    m = mission
    p0 = list(P0)
    p0[14] = 0.005
    config = _core.FilterConfig(
        p0_sigma=p0, dvl_variance=[0.002**2] * 3, lever_arm=[0.3, 0.0, 0.4], imu_dt=0.005
    )
    dvl = _streams(m)[:1]
    t = m.truth
    batch = pronet.run_filter(
        m.imu, m.imu_time, dvl, t0=m.t0, lla0=t.lla[0], vel0=t.vel[0], rpy0=t.rpy[0],
        config=config, strategy=NATIVE["constant"], warn=False,
    )  # fmt: skip
    initial = replace(_initial(m), p0_sigma=np.array(p0))
    nav = Navigator(_streams(m, rows=False)[:1], initial=initial, strategy=NATIVE["constant"],
                    config=config)  # fmt: skip
    _feed(nav, m, [a for a in _arrivals(m) if a[1] == 0])
    heading, dvl_line = nav.findings()
    since = re.search(r"\(over 5° from t = \S+ s\)", batch.health.heading)
    assert since is not None and since.group(0) in heading
    report = batch.health.streams[0]
    assert report.flag.startswith(f"streams[0] (dvl): mean NIS {report.mean_nis:.3g} (")
    assert f": mean NIS {report.mean_nis:.3g} (" in dvl_line and dvl_line.startswith("streams[0]")
    quiet = Navigator(_streams(m, rows=False), initial=_initial(m), strategy=NATIVE["constant"],
                      config=CONFIG)  # fmt: skip
    _feed(quiet, m, _arrivals(m))
    told = _batch(m, NATIVE["constant"]).health
    said = quiet.findings()
    assert len(said) == len(told.flags) > 0
    for line, report in zip(said, [r for r in told.streams if r.flag], strict=True):
        assert f": mean NIS {report.mean_nis:.3g} (" in line and report.name.startswith(
            line.split(":")[0]
        )


def test_a_stopped_navigator_answers_its_state_with_its_failure(mission) -> None:
    """A process noise that overflows the covariance stops the navigator; its state is
    then its failure (it answered the stopped filter's non-finite numbers), as every
    feed is."""
    m = mission
    huge = _core.Strategy.constant([1e307] * 6)
    nav = Navigator(_streams(m, rows=False), initial=_initial(m), strategy=huge, config=CONFIG)
    with pytest.raises(ValueError, match="^numerical failure: .*the navigator stopped"):
        for t, raw in zip(m.imu_time, m.imu, strict=True):
            nav.imu(t, raw)
    assert nav.failure is not None
    for call in (nav.state, lambda: nav.imu(m.imu_time[-1] + 1.0, m.imu[0])):
        with pytest.raises(ValueError, match="^numerical failure: "):
            call()


def test_a_window_the_regressor_cannot_read_is_refused_when_made(mission) -> None:
    """``window=1`` for the detrended variance (which needs 3 samples) was accepted and
    failed at the first tuning instant, mid-run: refused when the navigator is made."""
    detvar = strategy(StrategySpec.parse("detvar"), Q)
    with pytest.raises(ValueError, match="^window: the strategy's regressor cannot read a"):
        Navigator(_streams(mission, rows=False), initial=_initial(mission), strategy=detvar,
                  imu_dt=0.005, window=1)  # fmt: skip
    Navigator(_streams(mission, rows=False), initial=_initial(mission), strategy=detvar,
              imu_dt=0.005)  # fmt: skip


@pytest.mark.filterwarnings("ignore::pronet.stats.FilterHealthWarning")
def test_an_imu_gap_is_a_finding_as_run_filter_warns_of_it(mission) -> None:
    """Three seconds of IMU samples lost mid-run (and, apart, a clock that jumps by
    1e6 s): the navigator says so first among its findings, naming the gap's length
    and the sample after it, as ``run_filter`` warns of the same stamps; fed without
    the hole, it says nothing of gaps. Told the default ``imu_dt`` (0.01 s) for this
    200 Hz IMU, it says that instead, as ``run_filter`` warns."""
    m = mission
    keep = np.ones(len(m.imu), bool)
    keep[6000:6300] = False
    time, imu = m.imu_time[keep], m.imu[keep]
    nav = Navigator(_streams(m, rows=False)[:2], initial=_initial(m), strategy=NATIVE["constant"],
                    config=CONFIG)  # fmt: skip
    nav.imu_block(time, imu)
    gaps, end, length, longest, usual = nav._native.imu_gaps()
    assert (gaps, end, length, longest) == (1, m.imu_time[6300], length, length)
    assert length == pytest.approx(m.imu_time[6300] - m.imu_time[5999], rel=1e-12)
    assert usual == pytest.approx(np.diff(m.imu_time).mean(), rel=1e-9)
    first = nav.findings()[0]
    assert first.startswith(f"imu: a gap of {length:.4g} s before the sample at {end:.10g} s")
    t = m.truth
    with pytest.warns(PlausibilityWarning, match=rf"a gap of {length:.4g} s after row 5999"):
        pronet.run_filter(imu, time, _streams(m)[:2], t0=m.t0, lla0=t.lla[0], vel0=t.vel[0],
                          rpy0=t.rpy[0], config=CONFIG, strategy=NATIVE["constant"])  # fmt: skip
    steady = Navigator([], initial=_initial(m), strategy=NATIVE["constant"], config=CONFIG)
    steady.imu_block(m.imu_time[:3000], m.imu[:3000])
    assert not any(line.startswith("imu:") for line in steady.findings())
    steady.imu(m.imu_time[2999] + 1e6, m.imu[3000])
    steady.imu(m.imu_time[2999] + 1e6 + 0.01, m.imu[3001])
    said = steady.findings()
    assert said[0].startswith("imu: a gap of 1e+06 s before the sample at")
    assert said[1].startswith("the pass diverged"), said
    told = Navigator([], initial=_initial(m), strategy=NATIVE["constant"],
                     config=_core.FilterConfig(p0_sigma=P0))  # fmt: skip
    told.imu_block(m.imu_time[:3000], m.imu[:3000])
    period, *_ = told.findings()
    assert period.startswith("config.imu_dt: 0.01 s, but the IMU stamps step 0.005 s: ")
