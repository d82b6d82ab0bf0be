"""The one argument rule: every array argument of the public API, pronet's and its native
core's, takes a NumPy array and the same numbers as nested lists alike (same answer).

The walk: every parameter of ``_core.pyi`` typed ``ArrayLike`` or ``Any`` and every
``ArrayLike`` parameter of the callables in ``pronet.__all__`` belongs to an entry of
:data:`CALLS`, which calls it with its arrays in a given form; a new array argument
without an entry fails :func:`test_every_array_argument_is_walked`.
"""

from __future__ import annotations

import ast
import inspect
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import pronet
from pronet import _core
from pronet.learn import frozen
from pronet.learn.hcf import _ARRAYS, HCFEnsemble

from conftest import PAPER_Q

STUB = Path(pronet.__file__).resolve().parent / "_core.pyi"
LLA0 = (math.radians(32.0), math.radians(34.0), -5.0)
SEGMENTS = np.array([[2.0, 0.0, 0.0, 0.0], [1.0, 0.1, 0.01, 0.0]])
TRAJ = pronet.trajectory_from_segments(SEGMENTS, lla0=LLA0, speed0=1.0)
IMU, IMU_T = TRAJ.imu, TRAJ.time[1:]
DVL, DVL_T = np.tile([1.0, 0.0, 0.0], (2, 1)), np.array([1.0, 2.0])
NAV0 = {"lla0": TRAJ.lla[0], "vel0": TRAJ.vel_ned[0], "rpy0": TRAJ.rpy[0]}

Form = Callable[[Any], Any]


def as_is(x: Any) -> Any:
    return x


def as_lists(x: Any) -> Any:
    return np.asarray(x).tolist()


def _sensors(f: Form) -> Any:
    return _core.SensorConfig(
        imu_variance=f([PAPER_Q, [2e-4] * 6]),
        imu_variance_times=f([0.0, 1.0]),
        imu_bias=f([1e-3] * 6),
        imu_bias_psd=f([1e-9] * 6),
        dvl_variance=f([1e-4] * 3),
        lever_arm=f([0.1, 0.0, 0.2]),
        dvl_outages=f([[0.5, 0.7]]),
        dvl_misalignment=f([0.0, 0.01, 0.0]),
    )


def _filter_config(f: Form) -> Any:
    return _core.FilterConfig(
        p0_sigma=f([0.1] * 15),
        dvl_variance=f([1e-4] * 3),
        lever_arm=f([0.1, 0.0, 0.2]),
        dvl_calibration=True,
        dvl_misalignment_sigma=f([0.01] * 3),
    )


def _streams(f: Form) -> list[Any]:
    return [
        _core.Dvl(f(DVL_T), f(DVL), sigma=f([[0.1] * 3] * 2), lever_arm=f([0.1, 0.0, 0.2])),
        _core.Depth(f([1.5]), f([5.0]), sigma=f([0.1]), lever_arm=f([0.0, 0.0, 0.3])),
        _core.Fix(f([2.0]), f([LLA0]), sigma=f([2.0, 2.0, 2.0]), lever_arm=f([0.0, 0.0, -1.0])),
        _core.Heading(f([1.0, 2.5]), f([0.01, 0.02]), sigma=f([0.01, 0.02])),
    ]


def _run_filter(run: Callable[..., Any], f: Form) -> Any:
    return run(
        f(IMU), f(IMU_T), _streams(f), t0=0.0, **{k: f(v) for k, v in NAV0.items()},
        config=_core.FilterConfig(), strategy=_core.Strategy.external(f(PAPER_Q)),
        bias0=f([0.0] * 6), q_time=f([1.0]), q=f([[2e-4] * 6]), covariance_time=f([0.5, 1.0]),
    )  # fmt: skip


def _ensemble(make: Callable[..., Any], f: Form, native: bool) -> Any:
    args = (TRAJ, _core.SensorConfig(), _core.FilterConfig()) if native else (TRAJ,)
    ens = make(*args, f(PAPER_Q), n_runs=2, window=50, tuning_period=1.0)
    ens.advance()
    ens.set_q(f(np.full((2, 6), 2e-4)))
    out = ens.finish()
    return out["srmse"] if native else out.srmse


CONV_PARTS = ("conv.weight", "conv.bias", "norm.weight", "norm.bias")


def _conv_net(f: Form) -> Any:
    tensors, card, weights, card_file = frozen.read_model("detrend")
    arch = frozen.checked_architecture(card, tensors, weights, card_file)
    blocks = [
        tuple(f(tensors[f"features.{i}.{k}"]) for k in CONV_PARTS) + (int(stride), 1e-5)
        for i, stride in enumerate(arch["strides"])
    ]  # fmt: skip
    head = [
        (f(tensors[f"head.{2 * j}.weight"]), f(tensors[f"head.{2 * j}.bias"]))
        for j in range(len(arch["hidden"]) + 1)
    ]
    window = int(arch["window"])
    return _core.ConvNet(
        window=window, prepare="detrend", scaling=arch["scaling"], blocks=blocks, head=head,
        input_scale=float(arch["input_scale"]), q_scale=float(arch["q_scale"]),
        ramp=f(frozen.detrend_ramp(window)),
    )  # fmt: skip


def _hcf(f: Form) -> Any:
    tensors, card, weights, _ = frozen.read_model("paper-hcf")
    m = HCFEnsemble.from_tensors(tensors, card, weights)
    return _core.HcfEnsemble(
        window=m.window, gb=tuple(f(getattr(m.gb, k)) for k in _ARRAYS), gb_init=m.gb_init,
        gb_rate=m.gb_rate, rf=tuple(f(getattr(m.rf, k)) for k in _ARRAYS), target=m.target,
    )  # fmt: skip


WINDOWS = np.random.default_rng(0).normal(0.0, 0.01, size=(3, 200))


def _navigator(f: Form) -> Any:
    sensors = [_core.Dvl([], np.zeros((0, 3))), _core.Depth([], [], sigma=0.1)]
    nav0 = {k: f(v) for k, v in NAV0.items()}
    nav = _core.Navigator(
        sensors, t0=0.0, **nav0, config=_core.FilterConfig(),
        strategy=_core.Strategy.external(PAPER_Q), bias0=f([0.0] * 6),
    )  # fmt: skip
    nav.reading(0, 0.05, f([1.0, 0.0, 0.0]), sigma=f([0.1] * 3))
    nav.reading(1, 0.05, f(5.0), sigma=f([0.2]))
    nav.imu(float(IMU_T[0]), f(IMU[0]))
    nav.set_q(f(PAPER_Q))
    nav.imu_block(f(IMU_T[1:]), f(IMU[1:]))
    return nav.state()["lla"]


#: Each entry: the callables it covers and a call with every array argument in a form.
CALLS: dict[str, tuple[tuple[str, ...], Callable[[Form], Any]]] = {
    "trajectory": (
        ("_core.trajectory_from_segments", "pronet.trajectory_from_segments"),
        lambda f: (
            pronet.trajectory_from_segments(
                f(SEGMENTS), lla0=f(LLA0), speed0=1.0, rpy0=f([0.0, 0.0, 0.1])
            ).lla
        ),
    ),
    "mechanize": (
        ("_core.mechanize", "pronet.mechanize"),
        lambda f: (
            _core.mechanize(f(IMU), 0.01, *(f(v) for v in NAV0.values()))["vel"],
            pronet.mechanize(f(IMU), 0.01, *(f(v) for v in NAV0.values())).vel,
        ),
    ),
    "local_ned": (
        ("pronet.local_ned", "pronet.lla_from_ned"),
        lambda f: (
            pronet.local_ned(f(TRAJ.lla), f(LLA0)),
            pronet.lla_from_ned(f([[10.0, -5.0, 1.0]]), f(LLA0)),
        ),
    ),
    "configs": (
        ("_core.FilterConfig", "_core.SensorConfig"),
        lambda f: (repr(_filter_config(f)), repr(_sensors(f)), _sensors(f).dvl_outages),
    ),
    "strategies": (
        (
            "_core.Strategy.constant",
            "_core.Strategy.mehra",
            "_core.Strategy.adaptive",
            "_core.Strategy.external",
        ),
        lambda f: [
            repr(_core.Strategy.constant(f(PAPER_Q))),
            repr(_core.Strategy.mehra(3, f(PAPER_Q))),
            repr(_core.Strategy.adaptive(3, f(PAPER_Q))),
            repr(_core.Strategy.external(f(PAPER_Q))),
        ],
    ),  # fmt: skip
    "run_filter": (
        (
            "_core.run_filter",
            "pronet.run_filter",
            "_core.Dvl",
            "_core.Depth",
            "_core.Fix",
            "_core.Heading",
        ),
        lambda f: (
            _run_filter(_core.run_filter, f)["covariances"],
            _run_filter(pronet.run_filter, f).covariances,
        ),
    ),
    "rows_of": (
        ("pronet.FilterResult.rows_of",),
        lambda f: _run_filter(pronet.run_filter, as_is).rows_of(f([0, 3, 7])),
    ),
    "ensemble": (
        ("_core.Ensemble", "_core.Ensemble.set_q", "pronet.Ensemble", "pronet.Ensemble.set_q"),
        lambda f: (_ensemble(_core.Ensemble, f, True), _ensemble(pronet.Ensemble, f, False)),
    ),
    "navigator": (
        (
            "_core.Navigator",
            "_core.Navigator.imu",
            "_core.Navigator.imu_block",
            "_core.Navigator.reading",
            "_core.Navigator.set_q",
        ),
        _navigator,
    ),
    "convnet": (
        ("_core.ConvNet", "_core.ConvNet.predict"),
        lambda f: _conv_net(f).predict(f(WINDOWS.astype(np.float32))),
    ),
    "hcf": (
        ("_core.HcfEnsemble", "_core.HcfEnsemble.predict"),
        lambda f: _hcf(f).predict(f(WINDOWS)),
    ),
    "clock_costs": (
        ("_core.attitude_increment_costs",),
        lambda f: _core.attitude_increment_costs(
            f(np.linspace(0.0, 20.0, 21)),
            f(np.cumsum(np.full((21, 3), 0.01), axis=0)),
            f(np.linspace(0.0, 19.0, 20)),
            f(np.full((19, 3), 0.01)),
            f([0.0, 0.5]),
            1.0,
        ),
    ),  # fmt: skip
}


def _array_params(annotation: str) -> bool:
    return "ArrayLike" in annotation or annotation.startswith("Any") or "[Any" in annotation


def stub_array_callables() -> set[str]:
    """``_core.X`` / ``_core.X.method`` of the stub with an array-typed parameter."""
    out = set()
    for node in ast.parse(STUB.read_text(encoding="utf-8")).body:
        defs = [(node.name, node)] if isinstance(node, ast.FunctionDef) else []
        if isinstance(node, ast.ClassDef):
            defs = [
                (node.name if d.name == "__new__" else f"{node.name}.{d.name}", d)
                for d in node.body
                if isinstance(d, ast.FunctionDef)
            ]
        for name, d in defs:
            params = d.args.args + d.args.kwonlyargs
            if any(p.annotation and _array_params(ast.unparse(p.annotation)) for p in params):
                out.add(f"_core.{name}")
    return out


def python_array_callables() -> set[str]:
    """``pronet.X`` / ``pronet.X.method`` of ``pronet.__all__`` (Python-defined) with an
    ``ArrayLike`` parameter."""
    out = set()
    for name in pronet.__all__:
        obj = getattr(pronet, name)
        if not callable(obj) or getattr(obj, "__module__", "") == "pronet._core":
            continue
        if inspect.isclass(obj) and issubclass(obj, Warning):
            continue  # a warning category (PlausibilityWarning): no arguments of its own
        members = [(name, obj)]
        if inspect.isclass(obj):
            methods = vars(obj).items()
            members += [(f"{name}.{k}", v) for k, v in methods if inspect.isfunction(v)]
            members = [(q, v) for q, v in members if not q.endswith(".__init__")]
        for qual, fn in members:
            sig = inspect.signature(fn)
            if any("ArrayLike" in str(p.annotation) for p in sig.parameters.values()):
                out.add(f"pronet.{qual}")
    return out


def test_every_array_argument_is_walked() -> None:
    covered = {name for names, _ in CALLS.values() for name in names}
    wanted = stub_array_callables() | python_array_callables()
    assert "_core.SensorConfig" in wanted and "pronet.run_filter" in wanted  # the walk works
    assert wanted - covered == set(), "array arguments without a CALLS entry"
    assert covered - wanted == set(), "CALLS entries for callables without array arguments"


def _parts(x: Any) -> list[Any]:
    if isinstance(x, tuple | list) and not all(isinstance(v, str) for v in x):
        return [p for v in x for p in _parts(v)]
    return [x]


@pytest.mark.parametrize("entry", sorted(CALLS))
def test_lists_and_arrays_are_taken_alike(entry: str) -> None:
    _, call = CALLS[entry]
    want, got = _parts(call(as_is)), _parts(call(as_lists))
    assert len(want) == len(got)
    for a, b in zip(want, got, strict=True):
        if isinstance(a, str | list):
            assert a == b
        else:
            np.testing.assert_array_equal(np.asarray(b), np.asarray(a))


def test_sensor_outages_from_a_list() -> None:
    """The issue's example: a nested list of outages, as any other argument takes."""
    sensors = pronet.SensorConfig(dvl_outages=[[600, 700]])
    np.testing.assert_array_equal(sensors.dvl_outages, [[600.0, 700.0]])
    with pytest.raises(ValueError, match=r"^dvl_outages: expected real numbers"):
        pronet.SensorConfig(dvl_outages=[["600", "700"]])
