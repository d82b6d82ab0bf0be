"""Learned noise regressors: a window of raw IMU samples in, its noise variance q out.

Every regressor has ``predict(windows) -> q``: ``windows`` is ``(..., N)`` raw samples of
one IMU channel each (specific force [m/s²] or angular rate [rad/s], N = 200 at 100 Hz),
``q`` is ``(...)`` float64, the per-sample noise variance [(m/s²)² or (rad/s)²]. The
hybrid loop hands ``(n_runs, 6, N)`` and gets ``(n_runs, 6)`` back. Non-finite samples
give non-finite predictions (the hybrid loop's guardrails deal with those); so do, for
the nets, samples beyond :data:`MAX_SAMPLE`, where their float32 arithmetic overflows.

The two CNNs (section III of the paper), 12,769 parameters each:

- :class:`BaselineNet`: the window is centred (its mean removed, so a channel's constant
  level, gravity on f_z included, carries no weight) and divided by ``input_scale``
  (0.1, a typical noise standard deviation); three blocks of Conv1d → LayerNorm (over
  the channels at each time step) → LeakyReLU(0.01) with 16/32/32 channels, kernels
  7/5/5 and strides 1/2/2; global average pooling; four Linear layers 32 → 64 → 32 →
  16 → 1 with LeakyReLU(0.01) between them. The output z gives ``q = q_scale·exp(z)``
  (q_scale = 0.01), positive by construction.
- :class:`DetrendNet`: the same network after each window's least-squares line is
  subtracted, inside ``forward``, so no caller can forget it.

With ``scaling="spread"`` (the shipped ``baseline`` and ``detrend``, trained over nine
decades of q; the paper's are ``paper-baseline`` and ``paper-detrend``) a net
is scale-free instead: the prepared window is divided by its own RMS s, and the head
gives ``ln q = ln s² + z``, so that multiplying a window by c multiplies q by c², and an
untrained net (z = 0, the last layer starts at zero) predicts the window's own
variance. Such nets are trained on ln q.

Also here: :class:`DetrendedVariance`, the statistical reference as a regressor, and
:func:`load`, which opens a shipped model by name or a user's model file by path.
"""

from __future__ import annotations

import os
from functools import partial
from typing import Any, Protocol, cast, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet._util.extras import missing

try:
    import torch
    from torch import nn
except ImportError as exc:  # one error that names the extra
    raise missing("torch", "training or evaluating the nets (pronet.learn.models)") from exc

from pronet.learn import modelfile
from pronet.learn.frozen import GRADE_MODELS as GRADE_MODELS  # the names, without torch too
from pronet.learn.frozen import MAX_SAMPLE as MAX_SAMPLE
from pronet.learn.frozen import PAPER_MODELS as PAPER_MODELS
from pronet.learn.frozen import SHIPPED as SHIPPED
from pronet.learn.frozen import (
    FrozenNet,
    Precision,
    check_precision,
    checked_architecture,
    conv_net,
    mark_overflow,
    read_model,
)
from pronet.learn.frozen import shipped_sha256 as shipped_sha256
from pronet.learn.windowstats import DetrendedVariance as DetrendedVariance  # re-exported
from pronet.learn.windowstats import as_windows


@runtime_checkable
class Regressor(Protocol):
    """Anything that maps raw windows ``(..., N)`` to noise variances ``(...)``.

    A regressor may also offer ``frozen(threads=None)``, returning a regressor with the
    same predictions that loops call instead (:func:`pronet.learn.hybrid.for_loop`), or
    raising ``NotImplementedError``; the shipped CNNs return their forward pass in
    pronet's core."""

    def predict(self, windows: ArrayLike) -> NDArray[np.float64]: ...


class _ConvBlock(nn.Module):
    """Conv1d → LayerNorm over the channels at each time step → LeakyReLU(0.01), on
    time-major activations ``(B, L, C)``.

    The convolution is one matrix product over the unfolded windows (im2col) with the
    ``nn.Conv1d``'s own weights (zero padding ``kernel // 2``, as Conv1d pads): in this
    layout the LayerNorm needs no transposes, and on CPU it runs about twice as fast as
    ``Conv1d`` in ``(B, C, L)`` with the transposes around the norm.
    """

    def __init__(self, c_in: int, c_out: int, kernel: int, stride: int) -> None:
        super().__init__()
        self.conv = nn.Conv1d(c_in, c_out, kernel, stride=stride, padding=kernel // 2)
        self.norm = nn.LayerNorm(c_out)
        self.act = nn.LeakyReLU(0.01)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        (kernel,), (stride,) = self.conv.kernel_size, self.conv.stride
        pad = int(self.conv.padding[0])  # an int padding: Conv1d keeps it as a 1-tuple
        # (B, L_out, C_in, kernel): the same (C_in, kernel) order as the weight's last axes
        cols = nn.functional.pad(x, (0, 0, pad, pad)).unfold(1, kernel, stride)
        weight = self.conv.weight.reshape(self.conv.out_channels, -1)
        batch, length = cols.shape[:2]
        assert self.conv.bias is not None  # made with bias=True
        y = torch.addmm(self.conv.bias, cols.reshape(batch * length, weight.shape[1]), weight.t())
        return self.act(self.norm(y.reshape(batch, length, self.conv.out_channels)))


class BaselineNet(nn.Module):
    """The paper's baseline CNN regressor on centred, scaled raw windows.

    Args:
        window: samples per window N.
        channels: the three convolution blocks' output channels.
        kernels: their kernel sizes.
        strides: their strides.
        hidden: widths of the three hidden Linear layers (the fourth gives z).
        input_scale: windows are divided by this [m/s² or rad/s] before the first layer.
        q_scale: ``q = q_scale·exp(z)`` [(unit)² per sample].
        scaling: ``"fixed"`` (the paper's: ``input_scale`` and ``q_scale``) or
            ``"spread"`` (scale-free: the window's own RMS; see the module docstring).
    """

    kind = "baseline"

    def __init__(
        self,
        window: int = 200,
        channels: tuple[int, int, int] = (16, 32, 32),
        kernels: tuple[int, int, int] = (7, 5, 5),
        strides: tuple[int, int, int] = (1, 2, 2),
        hidden: tuple[int, int, int] = (64, 32, 16),
        input_scale: float = 0.1,
        q_scale: float = 0.01,
        scaling: str = "fixed",
    ) -> None:
        super().__init__()
        if window < 3:
            raise ValueError(f"window: must be >= 3 samples, got {window}")
        if scaling not in ("fixed", "spread"):
            raise ValueError(f"scaling: 'fixed' or 'spread', got {scaling!r}")
        self.scaling = scaling
        self.window = int(window)
        self.channels, self.kernels, self.strides = tuple(channels), tuple(kernels), tuple(strides)
        self.hidden = tuple(hidden)
        self.input_scale, self.q_scale = float(input_scale), float(q_scale)
        blocks, c_in = [], 1
        for c_out, k, s in zip(self.channels, self.kernels, self.strides, strict=True):
            blocks.append(_ConvBlock(c_in, c_out, k, s))
            c_in = c_out
        self.features = nn.Sequential(*blocks)
        layers: list[nn.Module] = []
        for width in self.hidden:
            layers += [nn.Linear(c_in, width), nn.LeakyReLU(0.01)]
            c_in = width
        last = nn.Linear(c_in, 1)
        if scaling == "spread":  # start at the window's own variance
            nn.init.zeros_(last.weight)
            nn.init.zeros_(last.bias)
        self.head = nn.Sequential(*layers, last)
        t = torch.arange(self.window, dtype=torch.float32) - (self.window - 1) / 2.0
        self.register_buffer("_t", t / torch.sqrt((t * t).sum()), persistent=False)

    def architecture(self) -> dict[str, Any]:
        """The constructor arguments: what a model card records to rebuild the net."""
        return {
            "window": self.window,
            "channels": list(self.channels),
            "kernels": list(self.kernels),
            "strides": list(self.strides),
            "hidden": list(self.hidden),
            "input_scale": self.input_scale,
            "q_scale": self.q_scale,
            "scaling": self.scaling,
        }

    def prepare(self, x: torch.Tensor) -> torch.Tensor:
        """Remove each window's mean: ``(B, N)`` → ``(B, N)``."""
        return x - x.mean(dim=-1, keepdim=True)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        """Raw windows ``(B, N)`` → q ``(B,)``."""
        if self.scaling == "spread":
            return torch.exp(self.log_q(x))
        z = self.prepare(x) / self.input_scale
        h = self.features(z.unsqueeze(-1)).mean(dim=1)  # time-major (B, L, C)
        # exp of a clamped z: positive q, and no overflow from an untrained net
        return self.q_scale * torch.exp(self.head(h).squeeze(-1).clamp(-20.0, 20.0))

    def log_q(self, x: torch.Tensor) -> torch.Tensor:
        """Raw windows ``(B, N)`` → ln q ``(B,)`` (what a spread net is trained on)."""
        if self.scaling != "spread":
            return torch.log(self(x))
        p = self.prepare(x)
        # the RMS of a constant window is 0: floored, so its q is tiny rather than NaN
        s2 = (p * p).mean(dim=-1, keepdim=True).clamp_min(torch.finfo(p.dtype).tiny)
        h = self.features((p / torch.sqrt(s2)).unsqueeze(-1)).mean(dim=1)
        return torch.log(s2.squeeze(-1)) + self.head(h).squeeze(-1).clamp(-20.0, 20.0)

    def predict(
        self,
        windows: ArrayLike,
        *,
        native: bool | None = None,
        precision: Precision = "float64",
    ) -> NDArray[np.float64]:
        """q [(unit)² per sample] for raw windows ``(..., N)``.

        Args:
            windows: raw samples ``(..., N)`` of one channel each.
            native: run the forward pass in pronet's core (:meth:`frozen`, from this
                net's current weights) instead of torch. The default does so for
                :class:`BaselineNet` and :class:`DetrendNet` themselves, whose forward
                pass the core implements; a subclass, which may override ``forward``,
                runs torch (float32, under ``torch.inference_mode``).
            precision: the core's (:data:`pronet.learn.frozen.Precision`): float64,
                the torch model's function, or float32 blocks, ~1.7× as fast and
                within 1e-5 relative of it. Only the native pass reads it.
        """
        precision = check_precision(precision)
        if native is None:
            native = type(self) in NETS.values()
        if native:
            return self.frozen(precision=precision).predict(windows)
        flat, shape = self._flat(windows)
        return mark_overflow(self._torch_predict(flat), flat).reshape(shape)

    def _flat(self, windows: ArrayLike) -> tuple[NDArray[np.float32], tuple[int, ...]]:
        """``windows`` as a contiguous float32 ``(n, N)`` and the leading shape."""
        w = as_windows(windows, dtype=np.float32)
        if w.shape[-1] != self.window:
            raise ValueError(
                f"windows: this model reads windows of {self.window} samples, got shape {w.shape}"
            )
        return np.ascontiguousarray(w.reshape(-1, self.window)), w.shape[:-1]

    def _torch_predict(self, flat: NDArray[np.float32]) -> NDArray[np.float64]:
        was_training = self.training
        self.eval()
        try:
            with torch.inference_mode():
                return self(torch.from_numpy(flat)).numpy().astype(np.float64)
        finally:
            self.train(was_training)

    def frozen(self, threads: int | None = None, precision: Precision = "float64") -> FrozenNet:
        """This net's forward pass in pronet's core, from its current weights (a copy:
        later training does not reach it), for :class:`BaselineNet` and
        :class:`DetrendNet`. In ``precision`` ``"float64"`` it is the torch model's
        function evaluated in float64 (equal to ``net.double()``'s forward pass to
        ~1e-12 relative, whatever the batch or thread count), about twice as fast as
        torch's float32 pass on CPU and without torch's threads; torch's float32 pass
        departs from that function by ~1e-6 relative for the paper's nets, up to ~1e-2
        for the nets trained over nine decades of q. In ``"float32"`` (what the loops
        run) its blocks compute in float32, ~1.7× as fast again, within 1e-5
        relative of float64 (:mod:`pronet.learn.frozen`). ``threads``: its worker
        threads (default: all cores)."""
        precision = check_precision(precision)
        if type(self) not in NETS.values():
            raise NotImplementedError(
                f"frozen: the core implements BaselineNet and DetrendNet, not {type(self).__name__}"
            )
        if any(block.norm.eps != 1e-5 for block in self.features):  # type: ignore[union-attr]
            raise NotImplementedError("frozen: LayerNorm eps other than 1e-5")
        tensors = {k: v.detach().cpu().numpy() for k, v in self.state_dict().items()}
        build = partial(conv_net, self.kind, self.architecture(), tensors)
        core = build(threads, precision=precision)
        return FrozenNet(core, getattr(self, "card", None), build)

    def n_parameters(self) -> int:
        return sum(p.numel() for p in self.parameters())


class DetrendNet(BaselineNet):
    """:class:`BaselineNet` after subtracting each window's least-squares line."""

    kind = "detrend"

    def prepare(self, x: torch.Tensor) -> torch.Tensor:
        """Remove each window's least-squares line: ``(B, N)`` → ``(B, N)``, batched."""
        centred = x - x.mean(dim=-1, keepdim=True)
        t = cast(torch.Tensor, self._t)
        return centred - (centred @ t).unsqueeze(-1) * t


NETS: dict[str, type[BaselineNet]] = {"baseline": BaselineNet, "detrend": DetrendNet}


def save_net(net: BaselineNet, path: str | os.PathLike[str], card: dict[str, Any]) -> None:
    """Write ``net`` as safetensors plus a JSON card (``card`` adds training records)."""
    tensors = {k: v.detach().cpu().numpy() for k, v in net.state_dict().items()}
    modelfile.write(
        path,
        tensors,
        {
            "kind": net.kind,
            "architecture": net.architecture(),
            "n_parameters": net.n_parameters(),
            **card,
        },
    )


def load(name_or_path: str | os.PathLike[str]) -> Regressor:
    """A shipped model by name (:data:`SHIPPED`: ``"baseline"``, ``"detrend"``,
    ``"hcf"`` and the paper's ``"paper-baseline"`` …), or a model file by path (either
    suffix, or none). Raises ``ModelFileError`` (a ``ValueError``) naming the file if it
    is missing, corrupted, truncated or not what its card says."""
    tensors, card, weights, card_file = read_model(name_or_path)
    kind = card.get("kind")
    if kind == "hcf":
        from pronet.learn.hcf import HCFEnsemble

        return HCFEnsemble.from_tensors(tensors, card, weights)
    if kind not in NETS:
        raise modelfile.ModelFileError(f"{card_file}: unknown model kind {kind!r}")
    checked_architecture(card, tensors, weights, card_file)  # before the net is allocated
    try:
        net = NETS[kind](**card.get("architecture", {}))
    except (TypeError, ValueError, RuntimeError) as exc:
        raise modelfile.ModelFileError(f"{card_file}: bad architecture ({exc})") from None
    expected = {k: tuple(v.shape) for k, v in net.state_dict().items()}
    modelfile.check_tensors(weights, tensors, expected)
    net.load_state_dict({k: torch.from_numpy(np.array(v)) for k, v in tensors.items()})
    net.eval()
    net.card = card  # type: ignore[assignment]
    return net
