"""The regressors frozen in the core (``BaselineNet.frozen``, ``HCFEnsemble.frozen``):
the same function as the torch model and as the NumPy tree walk, on every shipped model
and on untrained nets, and what loops call."""

from __future__ import annotations

import copy
import json
import re
import subprocess
import sys

import numpy as np
import pytest
import torch

from pronet import _core
from pronet.learn import frozen, hybrid, modelfile, models
from pronet.learn.hcf import HCFEnsemble
from pronet.learn.models import BaselineNet, DetrendNet
from pronet.sim import scenarios

SHIPPED_NETS = [n for n in models.SHIPPED if not n.endswith("hcf")]
SHIPPED_HCF = [n for n in models.SHIPPED if n.endswith("hcf")]


def hard_windows(n: int = 600, seed: int = 0) -> np.ndarray:
    """Noise over nine decades of variance, on offsets (gravity) and ramps."""
    rng = np.random.default_rng(seed)
    sigma = 10.0 ** rng.uniform(-5, -0.5, (n, 1))
    offset = rng.choice([0.0, 9.81, -3.0], (n, 1))
    ramp = rng.normal(size=(n, 1)) * 1e-3 * np.arange(200)
    return (rng.standard_normal((n, 200)) * sigma + offset + ramp).astype(np.float32)


def torch_float64(net: BaselineNet, windows: np.ndarray) -> np.ndarray:
    """The torch model's own forward pass, evaluated in float64."""
    double = copy.deepcopy(net).double().eval()
    with torch.inference_mode():
        return double(torch.from_numpy(windows.astype(np.float64))).numpy()


@pytest.mark.parametrize("name", SHIPPED_NETS)
def test_the_frozen_pass_equals_the_torch_model_on_every_shipped_net(name) -> None:
    net = models.load(name)
    assert isinstance(net, BaselineNet)
    w = hard_windows()
    frozen = net.frozen().predict(w)
    exact = torch_float64(net, w)
    np.testing.assert_allclose(frozen, exact, rtol=1e-10)
    # torch's float32 pass approximates the same function (loosely on the quiet windows
    # around gravity, whose 9.81 mean it removes in float32)
    np.testing.assert_allclose(net.predict(w, native=False), exact, rtol=3e-2)
    # predict() runs the frozen pass by default, any batch shape
    np.testing.assert_array_equal(net.predict(w.reshape(100, 6, 200)), frozen.reshape(100, 6))


@pytest.mark.parametrize("cls", [BaselineNet, DetrendNet])
@pytest.mark.parametrize("scaling", ["fixed", "spread"])
def test_untrained_and_reshaped_nets_freeze_too(cls, scaling) -> None:
    torch.manual_seed(3)
    net = cls(
        window=64,
        channels=(8, 12, 20),
        kernels=(3, 5, 7),
        strides=(1, 3, 2),
        hidden=(10, 5, 3),
        scaling=scaling,
    )
    for p in net.head[-1].parameters():  # a spread net starts at z = 0: give it a head
        torch.nn.init.normal_(p, std=0.3)
    w = hard_windows(200, seed=1)[:, :64]
    np.testing.assert_allclose(net.frozen().predict(w), torch_float64(net, w), rtol=1e-10)
    # the same numbers whatever the batch and the thread count
    one_by_one = np.concatenate(
        [net.frozen(threads=1).predict(w[i : i + 3]) for i in range(0, 200, 3)]
    )
    np.testing.assert_array_equal(one_by_one, net.frozen().predict(w))


def test_a_frozen_net_is_a_copy_and_a_subclass_runs_torch() -> None:
    torch.manual_seed(0)
    net = DetrendNet(scaling="spread")
    w = hard_windows(50)
    frozen = net.frozen(threads=1)
    before = frozen.predict(w)
    with torch.no_grad():
        net.head[-1].bias.fill_(1.0)  # training after freezing does not reach the copy
    np.testing.assert_array_equal(frozen.predict(w), before)
    np.testing.assert_allclose(net.predict(w), before * np.e, rtol=1e-12)

    class Custom(DetrendNet):  # may override forward: pronet cannot know its function
        def forward(self, x: torch.Tensor) -> torch.Tensor:
            return super().forward(x) * 2.0

    custom = Custom(scaling="spread")
    custom.load_state_dict(net.state_dict())
    np.testing.assert_allclose(custom.predict(w), 2 * net.predict(w), rtol=1e-3)  # torch float32
    with pytest.raises(
        NotImplementedError, match="frozen: the core implements BaselineNet and DetrendNet"
    ):
        custom.frozen()
    assert hybrid.for_loop(custom) is custom


def test_frozen_nets_keep_the_nan_rules_and_name_bad_input() -> None:
    net = models.load("detrend")
    w = hard_windows(4)
    w[1, 5] = np.nan
    w[2, 7] = 3e15  # beyond MAX_SAMPLE: float32 LayerNorm would overflow in torch
    q = net.predict(w)
    assert np.isfinite(q[[0, 3]]).all() and np.isnan(q[[1, 2]]).all()
    with pytest.raises(ValueError, match="windows: this model reads windows of 200"):
        net.frozen().predict(np.zeros((3, 100), np.float32))
    core = net.frozen().core
    with pytest.raises(ValueError, match=r"windows: expected shape \(n, 200\)"):
        core.predict(np.zeros((3, 100), np.float32))
    with pytest.raises(ValueError, match="prepare: 'centre' or 'detrend'"):
        _core.ConvNet(window=200, prepare="linear", scaling="fixed", blocks=[], head=[])
    with pytest.raises(ValueError, match="blocks: need at least one block"):
        _core.ConvNet(window=200, prepare="centre", scaling="fixed", blocks=[], head=[])
    bad = (
        np.zeros((4, 2, 3), np.float32),
        np.zeros(4, np.float32),
        np.ones(4, np.float32),
        np.zeros(4, np.float32),
        1,
        1e-5,
    )
    with pytest.raises(
        ValueError, match="blocks\\[0\\]: takes 2 channels and gives 4; the previous layer gives 1"
    ):
        _core.ConvNet(window=200, prepare="centre", scaling="fixed", blocks=[bad], head=[])


@pytest.mark.slow
def test_the_hybrid_loop_runs_the_frozen_pass_with_the_torch_numbers() -> None:
    sc = scenarios.SCENARIOS["varying-matched"](0)
    traj = sc.trajectory
    net = models.load("detrend")

    class TorchOnly:  # the same net, forced through torch's float32 pass
        def predict(self, windows: np.ndarray) -> np.ndarray:
            return net.predict(windows, native=False)

    args = dict(prior_q=sc.q_nominal, sensors=sc.sensors, n_runs=4, seed=0)
    frozen = hybrid.run_hybrid(net, traj, **args).result
    torch_run = hybrid.run_hybrid(TorchOnly(), traj, **args).result
    np.testing.assert_allclose(frozen.srmse, torch_run.srmse, rtol=1e-5)
    np.testing.assert_allclose(
        frozen.final_horizontal_error, torch_run.final_horizontal_error, rtol=1e-5
    )


@pytest.mark.filterwarnings("ignore:overflow encountered in cast")  # NumPy, 1e60 windows
@pytest.mark.parametrize("name", SHIPPED_HCF)
def test_the_frozen_hcf_equals_the_numpy_walk_on_every_shipped_ensemble(name) -> None:
    model = models.load(name)
    assert isinstance(model, HCFEnsemble)
    w = hard_windows(3000, seed=4).astype(np.float64)
    w[:50] *= 1e-60  # tiny and huge windows: the power-of-two scaling keeps them exact
    w[50:100] *= 1e60
    w[100, 3] = np.nan
    w[101] = 2.5  # constant: d = 0
    numpy_q = model.predict(w, native=False)
    frozen_q = model.frozen(threads=1).predict(w)
    np.testing.assert_allclose(frozen_q, numpy_q, rtol=1e-12)
    assert np.array_equal(np.isnan(frozen_q), np.isnan(numpy_q)) and np.isnan(frozen_q[100])
    np.testing.assert_array_equal(model.predict(w.reshape(300, 10, 200)), frozen_q.reshape(300, 10))
    assert hybrid.for_loop(model) is not model


def test_a_frozen_hcf_names_bad_trees_and_windows() -> None:
    model = models.load("hcf")
    assert isinstance(model, HCFEnsemble)
    with pytest.raises(ValueError, match="windows: this model reads windows of 200"):
        model.frozen().predict(np.zeros((2, 50)))
    arrays = [
        model.gb.left.copy(),
        model.gb.right,
        model.gb.feature,
        model.gb.threshold,
        model.gb.value,
        model.gb.roots,
    ]
    arrays[0][0] = 0  # a cycle
    kwargs = dict(window=200, gb_init=0.0, gb_rate=0.1, rf=tuple(arrays), target="q")
    with pytest.raises(ValueError, match="gb: trees: node 0 is not a valid node"):
        _core.HcfEnsemble(gb=tuple(arrays), **{**kwargs, "rf": tuple(arrays)})
    with pytest.raises(ValueError, match="target: 'q' or 'log-ratio'"):
        _core.HcfEnsemble(gb=tuple(arrays), **{**kwargs, "target": "ratio"})


@pytest.mark.parametrize("name", models.SHIPPED)
def test_a_model_frozen_from_its_file_without_torch_equals_the_frozen_torch_model(name) -> None:
    w = hard_windows(300, seed=5)
    from_file = frozen.load_frozen(name).predict(w)
    np.testing.assert_array_equal(from_file, models.load(name).frozen().predict(w))


def test_the_detrend_ramp_is_the_torch_models_buffer() -> None:
    for window in (3, 4, 17, 64, 199, 200, 201, 300):
        net = DetrendNet(window=window, kernels=(3, 3, 3))
        np.testing.assert_array_equal(frozen.detrend_ramp(window), net._t.numpy())


def test_frozen_loading_needs_no_torch_and_names_bad_files(tmp_path) -> None:
    code = (
        "import sys, numpy as np; from pronet.learn import frozen;"
        "from pronet.recorded import real; from pronet.experiments import study, reproduce;"
        "q = frozen.load_frozen('detrend').predict(np.ones((2, 200), np.float32) * 0.1);"
        "print('torch' in sys.modules, q.shape)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "(2,)"]
    net = models.load("detrend")
    assert isinstance(net, BaselineNet)
    card = {**net.card, "architecture": {**net.architecture(), "channels": [16, 32, 8]}}
    models.save_net(net, tmp_path / "m", {})
    (tmp_path / "m.json").write_text(json.dumps(card))
    with pytest.raises(
        ValueError, match=r"m.safetensors: tensor 'features.2.conv.weight' has shape"
    ):
        frozen.load_frozen(tmp_path / "m")
    (tmp_path / "m.json").write_text(json.dumps({**card, "architecture": {"layers": 3}}))
    with pytest.raises(ValueError, match=r"m.json: bad architecture \(unknown \['layers'\]\)"):
        frozen.load_frozen(tmp_path / "m")
    with pytest.raises(ValueError, match="no_such"):
        frozen.load_frozen(tmp_path / "no_such")


@pytest.mark.parametrize("name", ["detrend", "hcf"])
def test_a_frozen_model_moves_to_the_loops_threads_with_the_same_numbers(name) -> None:
    w = hard_windows(100, seed=6)
    loaded = frozen.load_frozen(name)
    assert loaded.frozen() is loaded
    one = hybrid.for_loop(loaded, threads=1)
    assert one is not loaded and one.card == loaded.card
    if isinstance(loaded, frozen.FrozenNet):  # a CNN: in the loops' precision
        loaded = frozen.load_frozen(name, precision=hybrid.LOOP_PRECISION)
    np.testing.assert_array_equal(one.predict(w), loaded.predict(w))


def test_the_frozen_defaults_are_the_torch_constructors() -> None:
    import inspect

    params = inspect.signature(BaselineNet.__init__).parameters
    defaults = {k: p.default for k, p in params.items() if k != "self"}
    as_lists = {k: list(v) if isinstance(v, tuple) else v for k, v in defaults.items()}
    assert as_lists == frozen.NET_DEFAULTS
    assert set(frozen.NET_KINDS) == set(models.NETS)


@pytest.mark.parametrize("name", ["baseline", "hcf", "learned:detrend"])
def test_a_bad_thread_count_in_the_environment_is_named_not_blamed_on_the_model(name, monkeypatch):
    """``RAYON_NUM_THREADS=100000`` was "baseline.json: bad architecture (...)": a
    shipped model blamed for the environment. Now the variable and its bound, before
    the model is read."""
    from pronet.strategies import StrategySpec, strategy

    monkeypatch.setenv("RAYON_NUM_THREADS", "100000")
    with pytest.raises(ValueError) as caught:
        if name.startswith("learned:"):
            strategy(StrategySpec.parse(name), [1e-4] * 6)
        else:
            frozen.load_frozen(name)
    message = str(caught.value)
    assert not isinstance(caught.value, modelfile.ModelFileError), message
    assert re.fullmatch(r"RAYON_NUM_THREADS: must be 1 to \d+ \(.*\), got 100000", message)
