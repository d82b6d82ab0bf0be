"""The domain rules live in the Rust core, once: the latitude rule, the gravity height
limit, the mechanization overflow check, the tuning instants and the shared limits.

Each error text below is the one the core's own unit tests expect from a pure-Rust call
(``earth::tests``, ``mechanization::tests``, ``ekf::recorded::tests``,
``ensemble::tests``): a Rust caller and a Python caller get the same error. The hybrid
loop on recorded data takes its tuning instants from ``_core.tuning_instants``, the rule
the Ensemble stops at, instead of a Python copy of it.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

import pronet
from pronet import _core, montecarlo
from pronet._util import validate
from pronet.learn import hybrid

from conftest import PAPER_Q

LATITUDE = "lla0: latitude must be within ±89° (given in radians; NED is singular at the poles)"
POLAR = (math.radians(89.5), 0.0, 0.0)
SOUTH = (-1.56, 0.0, 0.0)


def short_trajectory() -> pronet.Trajectory:
    return pronet.trajectory_from_segments(
        [[2.0, 0, 0, 0]], lla0=(math.radians(32), math.radians(34), -5.0), speed0=1.0
    )


# ---------------------------------------------------------------- the same error texts


@pytest.mark.parametrize("lla0", [POLAR, SOUTH])
def test_latitude_rule_is_the_cores_for_every_entry_point(lla0) -> None:
    zeros = np.tile([0.0, 0.0, -9.8, 0.0, 0.0, 0.0], (2, 1))  # at rest: a plausible IMU
    with pytest.raises(ValueError) as mech:
        pronet.mechanize(zeros, 0.01, lla0, (0, 0, 0), (0, 0, 0))
    with pytest.raises(ValueError) as filt:
        pronet.run_filter(
            zeros,
            [0.01, 0.02],
            t0=0.0,
            lla0=lla0,
            vel0=(0, 0, 0),
            rpy0=(0, 0, 0),
            strategy=pronet.Strategy.constant(PAPER_Q),
        )
    with pytest.raises(ValueError) as traj:
        pronet.trajectory_from_segments([[1.0, 0, 0, 0]], lla0=lla0, speed0=1.0)
    assert str(mech.value) == str(filt.value) == str(traj.value) == LATITUDE
    # 89° itself is allowed (the limit is exported from the core).
    assert _core.MAX_LATITUDE_DEG == 89.0
    edge = (math.radians(_core.MAX_LATITUDE_DEG), 0.0, 0.0)
    assert pronet.mechanize(zeros, 0.01, edge, (0, 0, 0), (0, 0, 0)).lla.shape == (3, 3)


def test_gravity_height_rule_is_the_cores() -> None:
    with pytest.raises(ValueError) as exc:
        pronet.normal_gravity(0.5, 100_001.0)
    assert str(exc.value) == "h: normal gravity holds within ±100000 m of the ellipsoid, got 100001"
    assert _core.MAX_GRAVITY_HEIGHT == 100_000.0
    top = pronet.normal_gravity(0.5, -_core.MAX_GRAVITY_HEIGHT)
    assert top > pronet.normal_gravity(0.5, 0.0)
    with pytest.raises(ValueError, match=r"^lat: must be finite, got NaN$"):
        pronet.normal_gravity(math.nan)
    with pytest.raises(ValueError, match=r"^lat: must be finite, got inf$"):
        pronet.earth_radii(math.inf)


def test_mechanization_overflow_rule_is_the_cores() -> None:
    lla0 = (0.5, 0.6, 0.0)
    with pytest.raises(ValueError, match=r"^imu, dt, lla0, vel0: the mechanization overflows"):
        pronet.mechanize(np.full((3, 6), 1e300), 0.01, lla0, (0, 0, 0), (0, 0, 0))
    bad = np.zeros((3, 6))
    bad[2, 4] = math.nan
    with pytest.raises(ValueError, match=r"^imu: row 2 is not finite$"):
        pronet.mechanize(bad, 0.01, lla0, (0, 0, 0), (0, 0, 0))
    with pytest.raises(ValueError, match=r"^dt: must be finite and > 0, got 0$"):
        pronet.mechanize(np.zeros((3, 6)), 0.0, lla0, (0, 0, 0), (0, 0, 0))


TUNING_ERRORS = [
    ((5, 1.0, 1, 0.0), "tuning_period: must be finite and > 0 s, got 0"),
    ((5, 1.0, 1, math.nan), "tuning_period: must be finite and > 0 s, got NaN"),
    ((5, 1.0, 0, 1.0), "window: must be at least 1 sample, got 0"),
    ((5, -1.0, 1, 1.0), "dt: must be finite and > 0, got -1"),
]


@pytest.mark.parametrize(("args", "text"), TUNING_ERRORS)
def test_tuning_instant_rule_gives_the_cores_error(args, text) -> None:
    with pytest.raises(ValueError) as exc:
        _core.tuning_instants(*args)
    assert str(exc.value) == text


@pytest.mark.parametrize(("period", "text"), [(p, t) for (_, _, _, p), t in TUNING_ERRORS[:2]])
def test_q_schedule_and_ensemble_give_the_same_tuning_error(period, text) -> None:
    imu, t = np.zeros((50, 6)), np.arange(1.0, 51.0)
    regressor = hybrid.ConstantRegressor(PAPER_Q)
    with pytest.raises(ValueError) as sched:
        hybrid.q_schedule(regressor, imu, t, prior_q=PAPER_Q, window=3, tuning_period=period)
    with pytest.raises(ValueError) as ens:
        pronet.Ensemble(
            short_trajectory(),
            PAPER_Q,
            sensors=pronet.SensorConfig(),
            config=pronet.FilterConfig(),
            n_runs=1,
            window=3,
            tuning_period=period,
        )
    assert str(sched.value) == str(ens.value) == text


# ---------------------------------------------------------------- the tuning instants


HALF_WAY = [
    # (samples, window, period / Δt, instants): halves round away from zero, as Rust's
    # f64::round (Python's round() takes them to even and would put them elsewhere).
    (10, 1, 2.5, [3, 6, 9]),
    (10, 4, 1.5, [4, 6, 8]),
    (10, 1, 0.5, [1, 2, 3, 4, 5, 6, 7, 8, 9]),
    (12, 5, 3.5, [8]),
    (5, 5, 1.0, []),  # the window fills at the last sample: nothing left to tune
    (5, 1, 1e300, []),
]


@pytest.mark.parametrize(("n", "window", "ratio", "want"), HALF_WAY)
def test_tuning_instants_round_half_away_from_zero(n, window, ratio, want) -> None:
    assert _core.tuning_instants(n, 1.0, window, ratio).tolist() == want
    # q_schedule evaluates its regressor there: window ends at sample k - 1.
    times = 0.5 + np.arange(1.0, n + 1)
    imu = np.random.default_rng(0).normal(size=(n, 6))
    s = hybrid.q_schedule(
        hybrid.ConstantRegressor(PAPER_Q),
        imu,
        times,
        prior_q=PAPER_Q,
        window=window,
        tuning_period=ratio,
    )
    np.testing.assert_array_equal(s.time, times[np.array(want, dtype=np.int64) - 1])


def test_a_tuning_period_of_no_whole_step_is_refused() -> None:
    """Just under half a step rounds to none: refused, by the core and so by the loop's
    schedule, where it once ran the regressor at every sample."""
    with pytest.raises(ValueError, match="tuning_period: must be at least one IMU period"):
        _core.tuning_instants(5, 1.0, 1, 0.49999999999999994)
    with pytest.raises(ValueError, match="tuning_period: must be at least one IMU period"):
        hybrid.q_schedule(hybrid.ConstantRegressor(PAPER_Q), np.zeros((5, 6)),
                          np.arange(1.0, 6.0), prior_q=PAPER_Q, window=1,
                          tuning_period=1e-9)  # fmt: skip


def test_q_schedule_takes_its_instants_from_the_core(monkeypatch) -> None:
    calls = []

    def fake(n_samples, dt, window, tuning_period):
        calls.append((n_samples, dt, window, tuning_period))
        return np.array([7, 19], dtype=np.int64)

    monkeypatch.setattr(hybrid._core, "tuning_instants", fake)
    t = np.arange(1.0, 31.0) * 0.01
    s = hybrid.q_schedule(
        hybrid.ConstantRegressor(PAPER_Q),
        np.zeros((30, 6)),
        t,
        prior_q=PAPER_Q,
        window=5,
        tuning_period=0.05,
    )
    assert len(calls) == 1 and calls[0][0] == 30 and calls[0][2:] == (5, 0.05)
    assert calls[0][1] == pytest.approx(0.01)
    np.testing.assert_array_equal(s.time, t[[6, 18]])


def test_python_holds_no_copy_of_the_rounding_rule() -> None:
    source = Path(hybrid.__file__).parent
    copies = [
        f"{path.name}: {line.strip()}"
        for path in sorted(source.glob("*.py"))
        for line in path.read_text().splitlines()
        if re.search(r"floor\(.*\+\s*0\.5", line)
    ]
    assert not copies, copies


def test_ensemble_stops_at_the_tuning_instants() -> None:
    traj = short_trajectory()
    ens = pronet.Ensemble(
        traj,
        PAPER_Q,
        sensors=pronet.SensorConfig(),
        config=pronet.FilterConfig(),
        n_runs=1,
        window=30,
        tuning_period=0.125,  # 12.5 samples: 13, not 12
    )
    stops = []
    while ens.advance() is not None:
        stops.append(ens.steps)
    want = _core.tuning_instants(traj.n_samples, traj.dt, 30, 0.125).tolist()
    assert stops == want and stops[:2] == [39, 52]


# ---------------------------------------------------------------- shared limits


def test_python_uses_the_cores_limits() -> None:
    assert validate.MAX_THREADS == _core.MAX_THREADS == 1024
    assert montecarlo.MAX_RUN_INDEX == _core.MAX_RUN_INDEX == 2**62
    most = _core.max_threads()
    assert _core.THREADS_PER_CORE == 8 and 8 <= most <= 1024 and (most % 8 == 0 or most == 1024)
    refused = rf"^threads: must be 1 to {most} \(8 per core .*got 1025$"
    with pytest.raises(ValueError, match=refused):
        pronet.monte_carlo(
            short_trajectory(), pronet.Strategy.constant(PAPER_Q), n_runs=1, threads=1025
        )
    for python_side in (most + 1, 0):
        with pytest.raises(ValueError, match=rf"^--threads: expected 1 to {most} "):
            validate.threads(python_side, "--threads")
    assert validate.threads(most, "--threads") == most
    assert validate.threads(1024, "threads", per_core=False) == 1024
    with pytest.raises(ValueError, match=r"^first_run: first_run \+ n_runs must be at most 2\^62"):
        pronet.monte_carlo(
            short_trajectory(),
            pronet.Strategy.constant(PAPER_Q),
            n_runs=2,
            first_run=_core.MAX_RUN_INDEX - 1,
        )
