"""The CNNs frozen in the core in float32 (``precision="float32"``): within
``FLOAT32_RTOL`` of float64 on every shipped net, over nine decades of q and on raw
accelerometer windows, as deterministic as float64, and what the loops run."""

from __future__ import annotations

import numpy as np
import pytest

from pronet import _core
from pronet.learn import frozen, hybrid, models

SHIPPED_NETS = [n for n in models.SHIPPED if not n.endswith("hcf")]


def decade_windows(n: int, mean: float, ramp: float = 0.0, seed: int = 0) -> np.ndarray:
    """White noise of per-sample variance 1e-10 to 1e-1 (log-uniform), around ``mean``
    (9.8: an accelerometer's gravity) plus a random line of slope ~``ramp`` per sample."""
    rng = np.random.default_rng(seed)
    var = 10.0 ** np.linspace(-10.0, -1.0, n)[:, None]
    line = rng.normal(size=(n, 1)) * ramp * np.arange(200)
    return (mean + line + rng.standard_normal((n, 200)) * np.sqrt(var)).astype(np.float32)


@pytest.mark.parametrize("name", SHIPPED_NETS)
def test_float32_stays_within_its_tolerance_of_float64_on_every_shipped_net(name) -> None:
    f64 = frozen.load_frozen(name)
    f32 = frozen.load_frozen(name, precision="float32")
    assert isinstance(f64, frozen.FrozenNet) and isinstance(f32, frozen.FrozenNet)
    assert (f64.precision, f32.precision) == ("float64", "float32")
    assert f32.core.precision == "float32"
    worst = 0.0
    for mean, ramp in [(0.0, 0.0), (9.8, 0.0), (9.8, 1e-3), (1e-4, 0.0)]:
        w = decade_windows(2000, mean, ramp, seed=int(mean * 10))
        q64, q32 = f64.predict(w), f32.predict(w)
        assert np.isfinite(q64).all()
        rel = np.abs(q32 / q64 - 1.0)
        worst = max(worst, float(rel.max()))
    # measured: at most 3e-6 (2e-7 on the grade nets' noise windows, 2e-6 on a ramp
    # the baseline net does not remove, and on the paper's nets)
    assert worst <= frozen.FLOAT32_RTOL, worst
    assert worst > 0.0  # the blocks really ran in float32


def test_float32_bits_do_not_depend_on_the_batch_or_the_threads() -> None:
    w = decade_windows(300, 9.8, 1e-4, seed=3)
    whole = frozen.load_frozen("detrend", precision="float32").predict(w)
    net = models.load("detrend")
    one = net.frozen(threads=1, precision="float32")
    one_by_one = np.concatenate([one.predict(w[i : i + 7]) for i in range(0, 300, 7)])
    np.testing.assert_array_equal(one_by_one, whole)
    np.testing.assert_array_equal(net.predict(w, precision="float32"), whole)
    np.testing.assert_array_equal(one.frozen(threads=2).predict(w), whole)


def test_a_non_finite_or_huge_sample_gives_nan_in_float32_too() -> None:
    w = decade_windows(5, 9.8)
    w[1, 5] = np.nan
    w[2, 7] = np.inf
    w[3, 9] = 3e15  # beyond MAX_SAMPLE, as for float64
    q = frozen.load_frozen("baseline", precision="float32").predict(w)
    assert np.isfinite(q[[0, 4]]).all() and np.isnan(q[[1, 2, 3]]).all()


def test_the_loops_run_float32_and_the_rest_float64() -> None:
    w = decade_windows(60, 9.8, seed=5)
    loaded = frozen.load_frozen("detrend")
    net = models.load("detrend")
    assert loaded.precision == "float64" and net.frozen().precision == "float64"
    assert hybrid.LOOP_PRECISION == "float32"
    for regressor in (loaded, net):
        loop = hybrid.for_loop(regressor, threads=1)
        assert isinstance(loop, frozen.FrozenNet) and loop.precision == "float32"
        np.testing.assert_array_equal(loop.predict(w), net.predict(w, precision="float32"))
    same = hybrid.for_loop(loaded, precision="float64")
    assert same is loaded  # nothing to change
    np.testing.assert_array_equal(net.predict(w), loaded.predict(w))  # float64 by default


def test_a_bad_precision_is_named() -> None:
    message = r"precision: expected 'float64' or 'float32', got 'float16'"
    net = models.load("baseline")
    assert isinstance(net, models.BaselineNet)
    loaded = frozen.load_frozen("baseline")
    assert isinstance(loaded, frozen.FrozenNet)
    for call in (
        lambda: frozen.load_frozen("baseline", precision="float16"),  # type: ignore[arg-type]
        lambda: loaded.frozen(precision="float16"),  # type: ignore[arg-type]
        lambda: net.frozen(precision="float16"),  # type: ignore[arg-type]
        lambda: net.predict(np.zeros((1, 200)), precision="float16"),  # type: ignore[arg-type]
    ):
        with pytest.raises(ValueError, match=f"^{message}$"):
            call()
    with pytest.raises(ValueError, match="precision: 'float64' or 'float32', got \"f32\""):
        _core.ConvNet(
            window=200, prepare="centre", scaling="fixed", blocks=[], head=[], precision="f32"
        )
    with pytest.raises(ValueError, match="precision: expected a string, got"):
        _core.ConvNet(
            window=200, prepare="centre", scaling="fixed", blocks=[], head=[], precision=32
        )
    alone = frozen.FrozenNet(loaded.core)  # no way to rebuild it
    assert alone.frozen(threads=1) is alone
    with pytest.raises(ValueError, match="precision: this net was built from a core alone"):
        alone.frozen(precision="float32")
