"""Model (c) of docs/how-to/learning-q.md: an A-KIT-like Q model that sees the raw IMU window
and the filter's own velocity estimate (after Cohen & Klein 2025, whose set
transformer reads IMU readings and the EKF's velocity; here a small MLP, named so).

At each tuning instant (every second once 200 samples exist, the hybrid loop's
instants) the net reads the last 200 samples of each channel and the filter's NED
velocity at that epoch: ``q_c = s²_c · exp(z_c)``, s²_c the detrended window's mean
square of channel c and ``z = MLP([ln s² / 10, |v_h|, v_d])`` (LeakyReLU, the last
layer starting at zero, so an untrained net is the detrended variance).

How it gets the filter's velocity:

- in training, from the torch filter itself (:mod:`pronet.learn.torchfilter`), which
  runs each window chunk by chunk between the instants with ``advance``, so the
  gradient reaches the net through both q and the velocity it fed back;
- in ``pronet real`` and the cross-validation, from a stepped core run
  (:func:`akit_schedule`): at each instant the core's pass up to that epoch with the
  schedule so far gives the velocity, then the net gives the next q. It is the filter
  users run (the torch filter equals it to 1e-9), causal, and O(k²) in instants, about
  20 s for a 400 s Snapir section against about 2 min for the torch filter's
  per-sample loop on one sequence.
"""

from __future__ import annotations

import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, cast

import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from pronet import _core
from pronet.filter import run_filter
from pronet.learn import modelfile
from pronet.learn.hybrid import (
    DEFAULT_TUNING_PERIOD,
    DEFAULT_WINDOW,
    Guardrails,
    QSchedule,
    guard_schedule,
)

F64 = NDArray[np.float64]
#: The card kind.
AKIT = "akit"


class AkitNet(nn.Module):
    """See the module. ``hidden``: the MLP's two hidden widths."""

    kind = AKIT

    def __init__(self, window: int = DEFAULT_WINDOW, hidden: tuple[int, int] = (32, 32)) -> None:
        super().__init__()
        if window < 3:
            raise ValueError(f"window: must be >= 3 samples, got {window}")
        self.window, self.hidden = int(window), tuple(int(h) for h in hidden)
        last = nn.Linear(self.hidden[1], 6)
        nn.init.zeros_(last.weight)
        nn.init.zeros_(last.bias)
        self.mlp = nn.Sequential(
            nn.Linear(8, self.hidden[0]),
            nn.LeakyReLU(0.01),
            nn.Linear(self.hidden[0], self.hidden[1]),
            nn.LeakyReLU(0.01),
            last,
        )
        t = torch.arange(self.window, dtype=torch.float64) - (self.window - 1) / 2.0
        self.register_buffer("_t", t / torch.sqrt((t * t).sum()), persistent=False)

    def architecture(self) -> dict[str, Any]:
        return {"window": self.window, "hidden": list(self.hidden)}

    def forward(self, windows: torch.Tensor, vel: torch.Tensor) -> torch.Tensor:
        """Raw windows ``(B, 6, N)`` and the filter's NED velocity ``(B, 3)`` [m/s] →
        q ``(B, 6)`` [(m/s²)², (rad/s)²]."""
        t = cast(torch.Tensor, self._t).to(windows.dtype)
        centred = windows - windows.mean(dim=-1, keepdim=True)
        detrended = centred - (centred @ t).unsqueeze(-1) * t
        s2 = (detrended**2).mean(dim=-1).clamp_min(torch.finfo(windows.dtype).tiny)
        ln = torch.log(s2)
        feats = torch.cat(
            [ln / 10.0, torch.hypot(vel[:, 0], vel[:, 1])[:, None], vel[:, 2:3]], dim=1
        )
        return torch.exp(ln + self.mlp(feats.to(ln.dtype)).clamp(-20.0, 20.0))

    def n_parameters(self) -> int:
        return sum(p.numel() for p in self.parameters())

    # -- as a model file run by learned:PATH on recorded data
    card: dict[str, Any] | None = None

    def recorded_schedule(self, rec: Any, prior_q: Sequence[float]) -> QSchedule:
        """The q schedule of a pass over recorded sensors (:func:`akit_schedule`)."""
        return akit_schedule(self, rec, prior_q)


def save_akit(net: AkitNet, path: str | os.PathLike[str], card: dict[str, Any]) -> Path:
    """Write ``net`` (float64 weights) and its card."""
    tensors = {k: v.detach().double().cpu().numpy() for k, v in net.state_dict().items()}
    full = {"kind": AKIT, "architecture": net.architecture(), **card}
    full["n_parameters"] = net.n_parameters()
    return modelfile.write(path, tensors, full)


def akit_from_tensors(tensors: dict[str, Any], card: dict[str, Any], weights: Path) -> AkitNet:
    """The net of a checked model file (``ModelFileError`` naming ``weights``)."""
    arch = card.get("architecture", {})
    try:
        net = AkitNet(int(arch.get("window", DEFAULT_WINDOW)), tuple(arch.get("hidden", (32, 32))))
    except (TypeError, ValueError) as exc:
        raise modelfile.ModelFileError(f"{weights}: bad architecture ({exc})") from None
    expected = {k: tuple(v.shape) for k, v in net.state_dict().items()}
    modelfile.check_tensors(weights, tensors, expected)
    net.load_state_dict({k: torch.from_numpy(np.array(v)) for k, v in tensors.items()})
    net.double().eval()
    net.card = card
    return net


def _windows_at(imu: F64, ends: NDArray[np.intp], window: int) -> torch.Tensor:
    strided = np.lib.stride_tricks.sliding_window_view(imu, window, 0)
    return torch.as_tensor(np.ascontiguousarray(strided[ends - window]))


def akit_schedule(net: AkitNet, rec: Any, prior_q: Sequence[float]) -> QSchedule:
    """The net's q over a recorded pass (``rec``: a :class:`pronet.run.Recorded`), each
    instant's velocity from a stepped core run (see the module); guarded as the hybrid
    loop guards a regressor's q."""
    start = time.perf_counter()
    n = len(rec.imu)
    dt = float(np.median(np.diff(rec.imu_time)))
    ends = _core.tuning_instants(n, dt, net.window, DEFAULT_TUNING_PERIOD)
    windows = _windows_at(rec.imu, ends, net.window)
    prior = np.asarray(prior_q, dtype=np.float64)
    times = rec.imu_time[ends - 1]
    rows: list[F64] = []
    for j, end in enumerate(ends):
        take = rec.dvl_time < rec.imu_time[end - 1] + 0.5 * dt
        result = run_filter(
            rec.imu[:end], rec.imu_time[:end], [_core.Dvl(rec.dvl_time[take], rec.dvl[take])],
            t0=rec.t0, lla0=rec.lla0, vel0=rec.vel0, rpy0=rec.rpy0, config=rec.config,
            strategy=_core.Strategy.external(tuple(prior)),
            q_time=times[:j] if j else None, q=np.array(rows) if j else None, epochs="last",
            warn=False,
        )  # fmt: skip
        with torch.no_grad():
            q = net(windows[j : j + 1].double(), torch.as_tensor(result.vel[-1:]))
        guarded, _, _ = guard_schedule(q.numpy(), prior if not rows else rows[-1], Guardrails())
        rows.append(guarded[0])
    q_all = np.array(rows).reshape(-1, 6)
    return QSchedule(times, q_all, 0, 0, time.perf_counter() - start)
