"""Training and scoring the noise regressors on the ProNet dataset.

Nets: MSE on q (scaled by ``q_scale``², the same minimiser) for the paper's nets, MSE
on ln q for scale-free ones (trained on a log-uniform dataset, :data:`pronet.learn.dataset.GRADES`;
``scaling="spread"``, and the HCF ensemble's ``target="log-ratio"``), Adam, the learning rate
cut by 3 when the validation loss stalls for an epoch, early stopping after ``patience``
epochs without a 0.1 % improvement (the weights of the best epoch are kept). The validation part is
``val_fraction`` of the training split, drawn with the seed; the test split is never
seen. Fixed seeds and ``torch.use_deterministic_algorithms`` make a run repeat on CPU.

Scores: RMSE, MAE and R² on the test split, beside the detrended-variance reference and
the Cramér–Rao floor (:mod:`pronet.learn.windowstats`); and the RMSE of log10 q, overall and
per decade of q, beside the reference's (what matters over many decades).
"""

from __future__ import annotations

import math
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pronet._util.validate import count, scalar
from pronet.learn.dataset import Dataset, DatasetParams, dataset_sha256
from pronet.learn.models import NETS, DetrendedVariance, Regressor, save_net
from pronet.learn.windowstats import cramer_rao_rmse
from pronet.stats import format_number

MODEL_KINDS = ("baseline", "detrend", "hcf")


@dataclass(frozen=True)
class NetTraining:
    """Hyperparameters of :func:`train_net` (recorded in the model card)."""

    max_epochs: int = 20
    batch_size: int = 256
    learning_rate: float = 3e-3
    patience: int = 4
    #: an epoch counts as an improvement when it lowers the best validation loss by
    #: more than this fraction
    min_improvement: float = 1e-3
    val_fraction: float = 0.1
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("max_epochs", "batch_size", "patience"):
            if count(getattr(self, name), name) < 1:
                raise ValueError(f"{name}: must be at least 1, got {getattr(self, name)}")
        if count(self.seed, "seed") < 0:
            raise ValueError(f"seed: must be >= 0, got {self.seed}")
        if not 0 < scalar(self.learning_rate, "learning_rate") < np.inf:
            raise ValueError(f"learning_rate: must be finite and > 0, got {self.learning_rate}")
        if not 0 <= scalar(self.min_improvement, "min_improvement") < 1:
            raise ValueError(f"min_improvement: must be in [0, 1), got {self.min_improvement}")
        if not 0 < scalar(self.val_fraction, "val_fraction") < 1:
            raise ValueError(f"val_fraction: must be in (0, 1), got {self.val_fraction}")


def scores(pred: NDArray[np.float64], q: NDArray[np.float64]) -> dict[str, float]:
    """RMSE and MAE [(unit)² per sample] and R² of predictions against labels; R² is
    NaN (undefined, printed so) when every label is the same: there is no variance to
    explain, and the rounding of their mean would make it any number (−3e29 once)."""
    err = pred - q
    constant = q.size == 0 or bool(np.all(q == q.flat[0]))
    return {
        "rmse": float(np.sqrt(np.mean(err**2))),
        "mae": float(np.mean(np.abs(err))),
        "r2": math.nan if constant else float(1.0 - np.sum(err**2) / np.sum((q - q.mean()) ** 2)),
    }


def log_scores(pred: NDArray[np.float64], q: NDArray[np.float64]) -> dict[str, Any]:
    """RMSE of log10 q overall (``log10_rmse``) and per decade of the label
    (``log10_rmse_by_decade``: ``{"-7": ...}`` for q in [1e-7, 1e-6)); a non-positive or
    non-finite prediction counts as a miss of 10 decades."""
    with np.errstate(divide="ignore", invalid="ignore"):
        err = np.log10(pred) - np.log10(q)
    err = np.where(np.isfinite(err), err, 10.0)
    decade = np.floor(np.log10(q)).astype(int)
    return {
        "log10_rmse": float(np.sqrt(np.mean(err**2))),
        "log10_rmse_by_decade": {
            str(d): float(np.sqrt(np.mean(err[decade == d] ** 2))) for d in np.unique(decade)
        },
    }


def test_report(model: Regressor, ds: Dataset) -> dict[str, Any]:
    """``model``'s scores on the test split, beside the reference and the floor."""
    test = ~ds.train
    w, q = ds.windows[test], ds.q[test]
    pred, ref = model.predict(w), DetrendedVariance().predict(w)
    return {
        "n_test": int(q.size),
        "model": {**scores(pred, q), **log_scores(pred, q)},
        "detrended_variance": {**scores(ref, q), **log_scores(ref, q)},
        "cramer_rao_rmse": cramer_rao_rmse(q, w.shape[-1]),
    }


def _split_validation(ds: Dataset, fraction: float, seed: int) -> tuple[NDArray, NDArray]:
    idx = np.flatnonzero(ds.train)
    perm = np.random.default_rng([seed, 2000]).permutation(idx)
    n_val = max(1, int(round(fraction * idx.size)))
    return np.sort(perm[n_val:]), np.sort(perm[:n_val])


def train_net(
    kind: str,
    ds: Dataset,
    hp: NetTraining | None = None,
    *,
    progress: bool = True,
    scaling: str = "fixed",
) -> tuple[Any, list[dict[str, float]]]:
    """Train a ``"baseline"`` or ``"detrend"`` net with ``scaling`` (see
    :class:`pronet.learn.models.BaselineNet`) on ``ds``'s training split.

    Returns the net (best validation epoch) and the per-epoch history
    (``train_loss``, ``val_loss``, ``lr``); losses are MSE of q / q_scale (fixed) or
    of ln q (spread).
    """
    import torch

    if kind not in NETS:
        raise ValueError(f"kind: expected one of {sorted(NETS)}, got {kind!r}")
    hp = hp or NetTraining()  # NetTraining checks its fields when it is made
    was_deterministic = torch.are_deterministic_algorithms_enabled()
    torch.use_deterministic_algorithms(True)
    try:
        return _train_net(kind, ds, hp, progress, scaling)
    finally:
        torch.use_deterministic_algorithms(was_deterministic)


def _train_net(
    kind: str, ds: Dataset, hp: NetTraining, progress: bool, scaling: str
) -> tuple[Any, list[dict[str, float]]]:
    import torch
    from tqdm.auto import tqdm

    torch.manual_seed(hp.seed)
    fit_idx, val_idx = _split_validation(ds, hp.val_fraction, hp.seed)
    net = NETS[kind](window=ds.windows.shape[1], scaling=scaling)
    if scaling == "spread":  # MSE of ln q

        def label_of(q: NDArray[np.float64]) -> Any:
            return torch.from_numpy(np.log(q).astype(np.float32))

        output = net.log_q
    else:  # MSE of q / q_scale

        def label_of(q: NDArray[np.float64]) -> Any:
            return torch.from_numpy((q / net.q_scale).astype(np.float32))

        def output(x: Any) -> Any:
            return net(x) / net.q_scale

    x, y = torch.from_numpy(ds.windows[fit_idx]), label_of(ds.q[fit_idx])
    xv, yv = torch.from_numpy(ds.windows[val_idx]), label_of(ds.q[val_idx])
    opt = torch.optim.Adam(net.parameters(), lr=hp.learning_rate)
    sched = torch.optim.lr_scheduler.ReduceLROnPlateau(opt, factor=1 / 3, patience=0)
    gen = torch.Generator().manual_seed(hp.seed)
    best = target = np.inf  # best validation loss; the one the next epoch must beat
    best_state, stale, history = None, 0, []
    bar = tqdm(range(hp.max_epochs), desc=f"train {kind}", unit="epoch", disable=not progress)
    for epoch in bar:
        net.train()
        total = 0.0
        for batch in torch.randperm(y.numel(), generator=gen).split(hp.batch_size):
            loss = (output(x[batch]) - y[batch]).pow(2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += loss.item() * batch.numel()
        net.eval()
        with torch.inference_mode():
            val = float((output(xv) - yv).pow(2).mean())
        lr = opt.param_groups[0]["lr"]
        history.append({"epoch": epoch, "train_loss": total / y.numel(), "val_loss": val, "lr": lr})
        bar.set_postfix(train=f"{total / y.numel():.4f}", val=f"{val:.4f}", lr=f"{lr:.1e}")
        sched.step(val)
        if val < best:
            best = val
            best_state = {k: v.detach().clone() for k, v in net.state_dict().items()}
        if val < target:
            target, stale = val * (1.0 - hp.min_improvement), 0
        else:
            stale += 1
            if stale >= hp.patience:
                break
    if best_state is not None:
        net.load_state_dict(best_state)
    net.eval()
    return net, history


def train_and_save(
    kind: str,
    ds: Dataset,
    params: DatasetParams,
    out: str | os.PathLike[str],
    *,
    hp: NetTraining | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Train ``kind`` on ``ds`` (generated with ``params``), score it on the test split
    and write ``out/<kind>.safetensors`` with its card. Returns the card's test report."""
    if kind not in MODEL_KINDS:
        raise ValueError(f"model: expected one of {', '.join(MODEL_KINDS)}, got {kind!r}")
    start = time.perf_counter()
    dataset_card = {"params": asdict(params), "sha256": dataset_sha256(ds)}
    path = Path(out) / kind
    # over many decades, a model must be scale-free and learn ln q (the module docstring)
    log_uniform = params.spacing == "log-uniform"
    if kind == "hcf":
        from pronet.learn.hcf import HCFEnsemble

        seed = (hp or NetTraining()).seed
        target = "log-ratio" if log_uniform else "q"
        model: Any = HCFEnsemble.fit(ds.windows[ds.train], ds.q[ds.train], seed=seed, target=target)
        seconds = time.perf_counter() - start
        report = test_report(model, ds)
        model.save(
            path,
            {
                "hyperparameters": model.hyperparameters,
                "dataset": dataset_card,
                "test": report,
                "training_seconds": seconds,
            },
        )
        return report
    hp = hp or NetTraining()
    scaling = "spread" if log_uniform else "fixed"
    net, history = train_net(kind, ds, hp, progress=progress, scaling=scaling)
    seconds = time.perf_counter() - start
    report = test_report(net, ds)
    save_net(
        net,
        path,
        {
            "hyperparameters": asdict(hp),
            "loss": "MSE of ln q" if log_uniform else "MSE of q / q_scale",
            "dataset": dataset_card,
            "history": history,
            "test": report,
            "training_seconds": seconds,
        },
    )
    return report


def scores_table(reports: dict[str, dict[str, Any]]) -> str:
    """Markdown table of test scores per model, then the reference and the floor (from
    the first report; all share the test split). q in (unit)² per sample."""
    lines = [
        "| regressor | RMSE | MAE | R² | RMSE / reference |",
        "|---|---:|---:|---:|---:|",
    ]
    first = next(iter(reports.values()))
    ref = first["detrended_variance"]
    for name, rep in reports.items():
        s = rep["model"]
        lines.append(
            f"| {name} | {s['rmse']:.3e} | {s['mae']:.3e} | {format_number(s['r2'])} | "
            f"{s['rmse'] / ref['rmse']:.3f} |"
        )
    lines.append(
        f"| detrended variance (reference, N − 2 dof) | {ref['rmse']:.3e} | {ref['mae']:.3e} "
        f"| {format_number(ref['r2'])} | 1.000 |"
    )
    lines.append(
        f"| Cramér–Rao floor √(mean 2q²/N) | {first['cramer_rao_rmse']:.3e} | | | "
        f"{first['cramer_rao_rmse'] / ref['rmse']:.3f} |"
    )
    return "\n".join(lines)
