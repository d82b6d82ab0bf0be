"""Trained regressors frozen in pronet's core, loaded without torch.

A model file (safetensors weights and a JSON card, :mod:`pronet.learn.modelfile`) holds
everything the prediction needs. :func:`load_frozen` builds it directly in the core:
:class:`FrozenNet` for the CNNs (``_core.ConvNet``) and :class:`pronet.learn.hcf.FrozenHCF`
for the HCF ensemble. Loops (the hybrid loop, recorded data, the study) use these; torch
is needed only to train a net or to run one through torch
(:func:`pronet.learn.models.load`).

A CNN computes in one of two precisions (:data:`Precision`), both deterministic (the
same bits whatever the batch, thread count or CPU):

- ``"float64"``, the default of :class:`FrozenNet`, :func:`load_frozen`, :func:`conv_net`
  and ``BaselineNet.predict``: the torch model's function evaluated in float64, equal to
  its forward pass in float64 to ~1e-12 relative;
- ``"float32"``: the convolution blocks (convolution, LayerNorm, LeakyReLU, pooling) in
  float32, ~1.7× as fast, within :data:`FLOAT32_RTOL` of float64 (the window's
  mean or line, its RMS and the scaling are still taken in float64, then the Linear
  layers; an accelerometer window's ~9.8 m/s² mean would cancel catastrophically in
  float32). The loops run the shipped CNNs so
  (:data:`pronet.learn.hybrid.LOOP_PRECISION`): 1e-5 of q is far below what a
  regressor's error or the filter can tell apart.
"""

from __future__ import annotations

import hashlib
import os
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet import _core
from pronet._util.validate import count, scalar
from pronet._util.validate import threads as check_threads
from pronet.learn import modelfile
from pronet.learn.windowstats import as_windows

if TYPE_CHECKING:
    from pronet.learn.hcf import FrozenHCF

#: The three regressors trained scale-free over nine decades of q, for real sensor grades
#: (:data:`pronet.learn.dataset.GRADES`): what ``learned:baseline`` etc. run.
GRADE_MODELS = ("baseline", "detrend", "hcf")
#: The paper's three, trained on its range [0.001, 0.05] for every channel: the
#: reproduction of its table (``pronet reproduce``) runs them.
PAPER_MODELS = ("paper-baseline", "paper-detrend", "paper-hcf")
#: Models shipped inside the package, loadable by name.
SHIPPED = GRADE_MODELS + PAPER_MODELS

#: Largest |sample| the nets read [m/s² or rad/s]: beyond it the torch model's float32
#: LayerNorm overflows, so such windows get NaN (in the core too, for equal answers).
MAX_SAMPLE = 1e15
#: The element types a CNN's blocks compute in, in the core (see the module docs).
Precision = Literal["float64", "float32"]
PRECISIONS: tuple[Precision, ...] = ("float64", "float32")
#: How far the float32 predictions may be from the float64 ones (relative): the tests
#: hold both shipped nets to it over nine decades of q and on raw accelerometer windows.
FLOAT32_RTOL = 1e-5
#: The CNN architectures the core implements: the card's ``kind`` → how it prepares a
#: window.
NET_KINDS = {"baseline": "centre", "detrend": "detrend"}
#: The constructor defaults of :class:`pronet.learn.models.BaselineNet` (what an older card
#: may leave out).
NET_DEFAULTS: dict[str, Any] = {
    "window": 200,
    "channels": [16, 32, 32],
    "kernels": [7, 5, 5],
    "strides": [1, 2, 2],
    "hidden": [64, 32, 16],
    "input_scale": 0.1,
    "q_scale": 0.01,
    "scaling": "fixed",
}


def check_precision(value: object, name: str = "precision") -> Precision:
    """``value`` if it is one of :data:`PRECISIONS`, else ``ValueError`` naming ``name``."""
    for p in PRECISIONS:
        if isinstance(value, str) and value == p:
            return p
    raise ValueError(f"{name}: expected 'float64' or 'float32', got {value!r}")


class NetBuild(Protocol):
    """Builds the same net on ``threads`` worker threads in ``precision``."""

    def __call__(
        self, threads: int | None = None, *, precision: Precision = "float64"
    ) -> _core.ConvNet: ...


class FrozenNet:
    """A CNN regressor's forward pass in pronet's core: ``predict(windows (..., N)) ->
    q (...)`` [(unit)² per sample], as the net's; ``card``: its model card;
    ``precision``: the core's (:data:`Precision`, float64 unless built otherwise)."""

    def __init__(
        self,
        core: _core.ConvNet,
        card: dict[str, Any] | None = None,
        build: NetBuild | None = None,
    ) -> None:
        self.core = core
        self.window = core.window
        self.precision: Precision = check_precision(core.precision)
        self.card: dict[str, Any] = card or {}
        self._build = build  # the same net on other threads or in another precision

    def predict(self, windows: ArrayLike) -> NDArray[np.float64]:
        w = as_windows(windows, dtype=np.float32)
        if w.shape[-1] != self.window:
            raise ValueError(
                f"windows: this model reads windows of {self.window} samples, got shape {w.shape}"
            )
        flat = np.ascontiguousarray(w.reshape(-1, self.window))
        return mark_overflow(self.core.predict(flat), flat).reshape(w.shape[:-1])

    def frozen(self, threads: int | None = None, precision: Precision | None = None) -> FrozenNet:
        """This net on ``threads`` worker threads, in ``precision`` (None: as it is)."""
        precision = self.precision if precision is None else check_precision(precision)
        if (threads is None or self._build is None) and precision == self.precision:
            return self
        if self._build is None:
            raise ValueError(
                f"precision: this net was built from a core alone, in {self.precision}; "
                "build it with conv_net(..., precision=...)"
            )
        return FrozenNet(self._build(threads, precision=precision), self.card, self._build)


def mark_overflow(q: NDArray[np.float64], flat: NDArray[np.float32]) -> NDArray[np.float64]:
    """NaN where a window holds a sample beyond :data:`MAX_SAMPLE` (or a NaN)."""
    with np.errstate(invalid="ignore"):
        q[~(np.abs(flat).max(axis=-1, initial=0.0) <= MAX_SAMPLE)] = np.nan
    return q


def detrend_ramp(window: int) -> NDArray[np.float32]:
    """The unit-norm centred time ramp a detrend net projects out, computed in float32
    as the torch model computes its buffer (so that both detrend alike)."""
    t = np.arange(window, dtype=np.float32) - np.float32((window - 1) / 2.0)
    norm = np.sqrt(np.float32(np.dot(t, t)), dtype=np.float32)
    return (t / norm).astype(np.float32)


def net_shapes(arch: dict[str, Any]) -> dict[str, tuple[int, ...]]:
    """The tensor names and shapes of a net with architecture ``arch`` (the names of
    :class:`pronet.learn.models.BaselineNet`'s state dict)."""
    shapes: dict[str, tuple[int, ...]] = {}
    c_in = 1
    for i, (c_out, k) in enumerate(zip(arch["channels"], arch["kernels"], strict=True)):
        shapes |= {
            f"features.{i}.conv.weight": (c_out, c_in, k),
            f"features.{i}.conv.bias": (c_out,),
            f"features.{i}.norm.weight": (c_out,),
            f"features.{i}.norm.bias": (c_out,),
        }
        c_in = c_out
    for j, width in enumerate([*arch["hidden"], 1]):
        shapes |= {f"head.{2 * j}.weight": (width, c_in), f"head.{2 * j}.bias": (width,)}
        c_in = width
    return shapes


def conv_net(
    kind: str,
    arch: dict[str, Any],
    tensors: dict[str, NDArray[Any]],
    threads: int | None = None,
    norm_eps: float = 1e-5,
    *,
    precision: Precision = "float64",
) -> _core.ConvNet:
    """The core's forward pass of a ``kind`` net (:data:`NET_KINDS`) with architecture
    ``arch`` and weights ``tensors`` (state-dict names, as :func:`net_shapes`), on
    ``threads`` worker threads, computing in ``precision`` (:data:`Precision`)."""
    precision = check_precision(precision)

    def f32(name: str) -> NDArray[np.float32]:
        return np.ascontiguousarray(tensors[name], dtype=np.float32)

    blocks = [
        (
            f32(f"features.{i}.conv.weight"),
            f32(f"features.{i}.conv.bias"),
            f32(f"features.{i}.norm.weight"),
            f32(f"features.{i}.norm.bias"),
            int(stride),
            norm_eps,
        )
        for i, stride in enumerate(arch["strides"])
    ]
    head = [
        (f32(f"head.{2 * j}.weight"), f32(f"head.{2 * j}.bias"))
        for j in range(len(arch["hidden"]) + 1)
    ]
    window = int(arch["window"])
    return _core.ConvNet(
        window=window,
        prepare=NET_KINDS[kind],
        scaling=arch["scaling"],
        blocks=blocks,
        head=head,
        input_scale=float(arch["input_scale"]),
        q_scale=float(arch["q_scale"]),
        negative_slope=0.01,
        ramp=detrend_ramp(window) if kind == "detrend" else None,
        threads=threads,
        precision=precision,
    )


def shipped_sha256() -> str:
    """SHA-256 over the shipped models' weight and card files: what a cached result
    computed with them depends on."""
    h = hashlib.sha256()
    for path in sorted(modelfile.SHIPPED_DIR.iterdir()):
        if path.suffix in (".safetensors", ".json"):
            h.update(path.name.encode())
            h.update(path.read_bytes())
    return h.hexdigest()


def checked_architecture(
    card: dict[str, Any], tensors: dict[str, NDArray[Any]], weights: Path, card_file: Path
) -> dict[str, Any]:
    """The net architecture of a model card (its keys over :data:`NET_DEFAULTS`),
    checked against the tensors of the weights file before anything is built, so that
    a card claiming a huge net over small weights fails at once (``ModelFileError``),
    never after allocating the net it describes."""
    given = card.get("architecture", {})
    unknown = sorted(set(given) - set(NET_DEFAULTS)) if isinstance(given, dict) else ["?"]
    if unknown:
        raise modelfile.ModelFileError(f"{card_file}: bad architecture (unknown {unknown})")
    arch = {**NET_DEFAULTS, **given}
    for key, value in arch.items():
        _check_entry(key, value, card_file)
    try:
        modelfile.check_tensors(weights, tensors, net_shapes(arch))
    except (TypeError, KeyError) as exc:
        raise modelfile.ModelFileError(f"{card_file}: bad architecture ({exc})") from None
    return arch


def _check_entry(key: str, value: object, card_file: Path) -> None:
    """``ModelFileError`` naming the card and ``key`` unless ``value`` has the type of
    :data:`NET_DEFAULTS`'s entry: whole numbers are whole numbers (``"200"``, ``200.7``
    and ``true`` are not), scales real numbers, ``scaling`` text."""
    default = NET_DEFAULTS[key]
    try:
        if isinstance(default, str):
            if not isinstance(value, str):
                raise ValueError(f"{key}: expected text, got {value!r}")
        elif isinstance(default, list):
            if not isinstance(value, list):
                raise ValueError(f"{key}: expected a list of whole numbers, got {value!r}")
            for v in value:
                if count(v, key) < 1:
                    raise ValueError(f"{key}: expected whole numbers >= 1, got {v!r}")
        elif isinstance(default, int):
            count(value, key)
        elif not 0 < scalar(value, key) < np.inf:
            raise ValueError(f"{key}: must be finite and > 0, got {value!r}")
    except ValueError as exc:
        raise modelfile.ModelFileError(f"{card_file}: architecture {exc}") from None


def read_model(
    name_or_path: str | os.PathLike[str],
) -> tuple[dict[str, NDArray[Any]], dict[str, Any], Path, Path]:
    """``(tensors, card, weights file, card file)`` of a shipped model by name
    (:data:`SHIPPED`) or of a model file by path (either suffix, or none)."""
    if isinstance(name_or_path, str) and name_or_path in SHIPPED:
        path: str | os.PathLike[str] = modelfile.SHIPPED_DIR / name_or_path
    else:
        path = name_or_path
    tensors, card = modelfile.read(path)
    weights, card_file = modelfile.paths(path)
    return tensors, card, weights, card_file


def load_frozen(
    name_or_path: str | os.PathLike[str],
    threads: int | None = None,
    precision: Precision = "float64",
) -> FrozenNet | FrozenHCF:
    """A shipped model by name or a model file by path (as :func:`pronet.learn.models.load`),
    frozen in the core without torch; a CNN computes in ``precision`` (:data:`Precision`;
    the HCF ensemble ignores it). Raises ``ModelFileError`` (a ``ValueError``) naming the
    file if it is missing, corrupted, truncated or not what its card says; a bad
    ``threads`` (or ``RAYON_NUM_THREADS``) or ``precision`` is a ``ValueError`` naming
    it, before the model is read."""
    from pronet.learn.hcf import HCFEnsemble

    threads = check_threads(threads, "threads")
    precision = check_precision(precision)
    tensors, card, weights, card_file = read_model(name_or_path)
    kind = card.get("kind")
    if kind == "hcf":
        return HCFEnsemble.from_tensors(tensors, card, weights).frozen(threads)
    if kind not in NET_KINDS:
        raise modelfile.ModelFileError(f"{card_file}: unknown model kind {kind!r}")
    arch = checked_architecture(card, tensors, weights, card_file)
    try:
        core = conv_net(kind, arch, tensors, threads, precision=precision)
        build = partial(conv_net, kind, arch, tensors)
    except (TypeError, KeyError) as exc:
        raise modelfile.ModelFileError(f"{card_file}: bad architecture ({exc})") from None
    except ValueError as exc:
        if isinstance(exc, modelfile.ModelFileError):
            raise
        raise modelfile.ModelFileError(f"{card_file}: bad architecture ({exc})") from None
    return FrozenNet(core, card, build)
