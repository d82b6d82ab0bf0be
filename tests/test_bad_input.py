"""Bad input raises ValueError naming the argument, before any computation; no Rust
panic ever reaches Python."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

import pronet
from pronet import _core

from conftest import PAPER_Q

STRAT = pronet.Strategy.constant(PAPER_Q)
LLA0 = (math.radians(32), math.radians(34), -5.0)


def _filter_inputs(n: int = 300):
    traj = pronet.builtin_trajectory("paper")
    imu = traj.imu[:n].copy()
    t = traj.time[1 : n + 1].copy()
    dvl = np.tile([1.0, 0.0, 0.0], (n // 100, 1))
    dvl_t = np.arange(1, n // 100 + 1, dtype=float)
    return imu, t, dvl, dvl_t


def _run(**overrides):
    imu, t, dvl, dvl_t = _filter_inputs()
    args = dict(
        imu=imu,
        imu_time=t,
        dvl=dvl,
        dvl_time=dvl_t,
        t0=0.0,
        lla0=LLA0,
        vel0=(1.0, 0.0, 0.0),
        rpy0=(0.0, 0.0, 0.0),
        strategy=STRAT,
    )
    args.update(overrides)
    return pronet.run_filter(
        args.pop("imu"), args.pop("imu_time"), args.pop("dvl"), args.pop("dvl_time"), **args
    )


@pytest.mark.parametrize(
    ("overrides", "arg"),
    [
        ({"imu": np.zeros((300, 5))}, "imu"),
        ({"imu": np.zeros(300)}, "imu"),
        ({"imu": np.full((300, 6), "x")}, "imu"),
        ({"imu": np.zeros((300, 6), dtype=complex)}, "imu"),
        ({"imu": np.where(np.eye(300, 6) > 0, np.nan, 0.0)}, "imu"),
        ({"imu": np.full((300, 6), np.inf)}, "imu"),
        ({"dvl": np.zeros((3, 2))}, "dvl"),
        ({"dvl": np.array([[np.nan, 0, 0]] * 3)}, "dvl"),
        ({"imu_time": np.zeros(300)}, "imu_time"),
        ({"imu_time": np.arange(300.0)[::-1].copy()}, "imu_time"),
        ({"imu_time": np.arange(10.0)}, "imu_time"),
        ({"t0": 0.01}, "imu_time"),
        ({"t0": 5.0}, "imu_time"),
        ({"t0": math.nan}, "t0"),
        ({"t0": "zero"}, "t0"),
        ({"dvl_time": np.array([1.0, 1.0, 2.0])}, "dvl_time"),
        ({"lla0": (0.1, 0.2)}, "lla0"),
        ({"lla0": (math.nan, 0.2, 0.0)}, "lla0"),
        ({"lla0": (1.6, 0.2, 0.0)}, "lla0"),
        ({"vel0": "fast"}, "vel0"),
        ({"rpy0": (0.0, math.inf, 0.0)}, "rpy0"),
        ({"strategy": "constant"}, "strategy"),
        ({"config": {"aiding": "body"}}, "config"),
        ({"bias0": (0.0,) * 5}, "bias0"),
    ],
)
def test_run_filter_rejects_bad_arrays_naming_the_argument(overrides, arg) -> None:
    with pytest.raises(ValueError, match=rf"^{arg}\b"):
        _run(**overrides)


@pytest.mark.parametrize(
    ("make", "arg"),
    [
        (lambda: pronet.Strategy.constant([1e-4] * 5), "q"),
        (lambda: pronet.Strategy.constant([-1e-4] * 6), "q"),
        (lambda: pronet.Strategy.constant([math.nan] * 6), "q"),
        (lambda: pronet.Strategy.mehra(0, PAPER_Q), "window"),
        (lambda: pronet.Strategy.mehra(3, [-1.0] * 6), "prior_q"),
        (lambda: pronet.FilterConfig(dvl_variance=(0.01, -0.01, 0.01)), "dvl_variance"),
        (lambda: pronet.FilterConfig(dvl_variance=(0.01, 0.0, 0.01)), "dvl_variance"),
        (lambda: pronet.FilterConfig(accel_bias_psd=-1.0), "accel_bias_psd"),
        (lambda: pronet.FilterConfig(gyro_bias_psd=math.nan), "gyro_bias_psd"),
        (lambda: pronet.FilterConfig(p0_sigma=[1.0] * 14), "p0_sigma"),
        (lambda: pronet.FilterConfig(p0_sigma=[-1.0] * 15), "p0_sigma"),
        (lambda: pronet.FilterConfig(imu_dt=0.0), "imu_dt"),
        (lambda: pronet.FilterConfig(imu_dt=-0.01), "imu_dt"),
        (lambda: pronet.FilterConfig(aiding="sideways"), "aiding"),
        (lambda: pronet.SensorConfig(imu_variance=[-1.0] * 6), "imu_variance"),
        (lambda: pronet.SensorConfig(dvl_variance=[-1.0] * 3), "dvl_variance"),
        (lambda: pronet.SensorConfig(dvl_period=0.0), "dvl_period"),
        (
            lambda: pronet.SensorConfig(imu_variance=[[1e-3] * 6] * 2, imu_variance_times=[0, 0]),
            "imu_variance_times",
        ),
        (lambda: pronet.SensorConfig(imu_bias_psd=[-1.0] * 6), "imu_bias_psd"),
        (lambda: pronet.builtin_trajectory("nope"), "name"),
        (lambda: pronet.builtin_trajectory("paper", dt=0.0), "dt"),
        (lambda: pronet.builtin_trajectory("paper", dt=-0.01), "dt"),
        (lambda: pronet.trajectory_from_segments([[10, 0, 0]], lla0=LLA0, speed0=1), "segments"),
        (
            lambda: pronet.trajectory_from_segments([[-10, 0, 0, 0]], lla0=LLA0, speed0=1),
            "segments",
        ),
        (
            lambda: pronet.trajectory_from_segments([[10, 0, 0, 0.2]], lla0=LLA0, speed0=1),
            "segments",
        ),
        (
            lambda: pronet.trajectory_from_segments([[10, 0, 0, 0]], lla0=LLA0, speed0=math.nan),
            "speed0",
        ),
        (lambda: pronet.mechanize(np.zeros((3, 6)), 0.0, LLA0, (0, 0, 0), (0, 0, 0)), "dt"),
        (lambda: pronet.mechanize(np.zeros((3, 7)), 0.01, LLA0, (0, 0, 0), (0, 0, 0)), "imu"),
        (lambda: pronet.normal_gravity(math.nan), "lat"),
    ],
)
def test_configs_and_builders_reject_bad_values(make, arg) -> None:
    with pytest.raises(ValueError, match=rf"^{arg}\b"):
        make()


def test_monte_carlo_and_ensemble_reject_bad_values(paper_trajectory) -> None:
    for kwargs, arg in [
        ({"n_runs": 0}, "n_runs"),
        ({"n_runs": 2.5}, "n_runs"),
        ({"seed": -1}, "seed"),
        ({"record_every": -1}, "record_every"),
        ({"threads": 0}, "threads"),
        ({"sensors": pronet.SensorConfig(dvl_period=0.015)}, "dvl_period"),
    ]:
        with pytest.raises(ValueError, match=rf"^{arg}\b"):
            pronet.monte_carlo(paper_trajectory, STRAT, **{"n_runs": 1, **kwargs})
    with pytest.raises(ValueError, match="^trajectory"):
        pronet.monte_carlo("paper", STRAT)
    cfg = pronet.FilterConfig()
    sens = pronet.SensorConfig()
    with pytest.raises(ValueError, match="^window"):
        pronet.Ensemble(paper_trajectory, sens, cfg, PAPER_Q, n_runs=2, window=0)
    with pytest.raises(ValueError, match="^tuning_period"):
        pronet.Ensemble(paper_trajectory, sens, cfg, PAPER_Q, n_runs=2, tuning_period=0.0)
    ens = pronet.Ensemble(paper_trajectory, sens, cfg, PAPER_Q, n_runs=2, tuning_period=5.0)
    ens.advance()
    for q in (
        np.zeros((3, 6)),
        np.full((2, 6), -1.0),
        np.full((2, 6), np.nan),
        np.zeros((2, 6), dtype=np.float32),
        [[0.0] * 6] * 2,
    ):
        with pytest.raises(ValueError, match="^q"):
            ens.set_q(q)


def test_native_core_rejects_non_float64_arrays_naming_the_argument() -> None:
    imu, t, dvl, dvl_t = _filter_inputs()
    kwargs = dict(
        t0=0.0,
        lla0=LLA0,
        vel0=(1, 0, 0),
        rpy0=(0, 0, 0),
        config=pronet.FilterConfig(),
        strategy=STRAT,
    )
    with pytest.raises(ValueError, match="^imu: expected a float64"):
        _core.run_filter(imu.astype(np.float32), t, dvl, dvl_t, **kwargs)
    with pytest.raises(ValueError, match="^dvl_time: expected a float64"):
        _core.run_filter(imu, t, dvl, list(dvl_t), **kwargs)


def test_layouts_are_accepted_and_agree() -> None:
    """Fortran-ordered, strided and integer inputs give the same answer as C float64."""
    imu, t, dvl, dvl_t = _filter_inputs()
    ref = _run(imu=imu, imu_time=t)
    fortran = _run(imu=np.asfortranarray(imu), imu_time=t)
    strided = _run(imu=np.repeat(imu, 2, axis=0)[::2], imu_time=np.repeat(t, 2)[::2])
    np.testing.assert_array_equal(ref.vel, fortran.vel)
    np.testing.assert_array_equal(ref.vel, strided.vel)
    as_int = _run(dvl=dvl.astype(np.int64))
    np.testing.assert_array_equal(as_int.vel, _run(dvl=dvl.astype(float)).vel)


finite_or_not = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, -0.0, 1e300, -1e300, 1e-300, 5e-324]),
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    imu=hnp.arrays(
        np.float64, hnp.array_shapes(min_dims=1, max_dims=3, max_side=12), elements=finite_or_not
    ),
    t_step=finite_or_not,
    t0=finite_or_not,
    q=st.lists(finite_or_not, min_size=0, max_size=8),
)
def test_hostile_filter_inputs_work_or_raise_value_error(imu, t_step, t0, q) -> None:
    """Random shapes and values: the call either returns finite-shaped output or raises
    ValueError; never a panic, a crash or another exception type."""
    try:
        strategy = pronet.Strategy.constant(q)
    except ValueError:
        strategy = STRAT
    n = imu.shape[0] if imu.ndim >= 1 else 0
    with np.errstate(all="ignore"):  # hostile t0 and t_step overflow here on purpose
        times = t0 + t_step * np.arange(1, n + 1) if n else np.empty(0)
    try:
        with np.errstate(all="ignore"):
            out = pronet.run_filter(
                imu,
                times,
                np.empty((0, 3)),
                np.empty(0),
                t0=t0,
                lla0=LLA0,
                vel0=(0, 0, 0),
                rpy0=(0, 0, 0),
                strategy=strategy,
            )
    except ValueError:
        return
    assert out.vel.shape == (n + 1, 3)


@settings(max_examples=60, deadline=None)
@given(
    segments=hnp.arrays(
        np.float64, st.tuples(st.integers(0, 4), st.integers(3, 5)), elements=finite_or_not
    ),
    dt=finite_or_not,
    speed0=finite_or_not,
)
def test_hostile_segments_work_or_raise_value_error(segments, dt, speed0) -> None:
    try:
        traj = pronet.trajectory_from_segments(segments, lla0=LLA0, speed0=speed0, dt=dt)
    except ValueError:
        return
    assert np.isfinite(traj.imu).all()


def test_no_panic_exception_type_is_exposed() -> None:
    """The binding catches panics itself; no call above may raise pyo3's PanicException,
    which derives from BaseException and would slip past `except Exception`."""
    for bad in (
        lambda: _run(imu=np.full((300, 6), 1e308)),
        lambda: _run(imu_time=np.linspace(1e-300, 3e-300, 300)),
    ):
        try:
            bad()
        except ValueError:
            pass
        except BaseException as exc:  # noqa: BLE001 - the point of the test
            pytest.fail(f"{type(exc).__name__}: {exc}")
