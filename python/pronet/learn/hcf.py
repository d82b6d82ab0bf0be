"""The handcrafted-feature (HCF) ensemble regressor, stored as plain arrays.

The 14 statistics of :func:`pronet.learn.windowstats.features` (raw and detrended: variance,
std, range, mean absolute deviation, RMS of first differences, skewness, kurtosis) feed
two scikit-learn ensembles whose predictions are averaged: gradient boosting (squared
error) and a random forest. Only training needs scikit-learn. The fitted trees are
exported as explicit arrays (children, split feature, threshold, leaf value) into a
safetensors file; :meth:`HCFEnsemble.predict` computes the features and walks the
trees in pronet's core (:meth:`HCFEnsemble.frozen`; ``native=False``: in NumPy, the
reference), so loading a model never unpickles anything.

Split rule, as in scikit-learn: features are rounded to float32, and a sample goes left
when ``feature <= threshold``.

``target="log-ratio"`` (the shipped ``hcf``, trained over nine decades of q; the paper's
``paper-hcf`` regresses q) makes
the ensemble scale-free: the scale features are divided by the window's detrended
variance ``d`` (or its square root), ``var_detrended`` itself becomes ``log10 d`` (the
level, so that the trees can correct differently per decade), and the trees regress
``ln(q / d)``: ``q = d·exp(½ gb + ½ rf)``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet import _core
from pronet._util.extras import missing
from pronet.learn import modelfile
from pronet.learn.windowstats import FEATURE_NAMES, as_windows, detrended_variance, features

#: Targets an ensemble can regress: q itself (the paper's) or ``ln(q / d)``.
TARGETS = ("q", "log-ratio")
#: Columns of :data:`FEATURE_NAMES` in units of the window (std, range, MAD, RMS of
#: differences) and in its units squared (the variances).
_LINEAR = [
    i for i, n in enumerate(FEATURE_NAMES) if n.split("_")[0] in ("std", "range", "mad", "rms")
]
_SQUARED = [i for i, n in enumerate(FEATURE_NAMES) if n.startswith("var_")]
_LEVEL = FEATURE_NAMES.index("var_detrended")


def scale_free_features(w: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``(x, d)``: the features of windows ``(n, N)`` made scale-free as the module
    docstring says, and each window's detrended variance ``d``."""
    x, d = features(w), detrended_variance(w)
    with np.errstate(divide="ignore", invalid="ignore"):
        x[:, _LINEAR] /= np.sqrt(d)[:, None]
        x[:, _SQUARED] /= d[:, None]
        x[:, _LEVEL] = np.log10(d)
    return x, d


_ARRAYS = ("left", "right", "feature", "threshold", "value", "roots")


@dataclass(frozen=True)
class TreeSet:
    """Many binary regression trees in flat arrays; tree i starts at ``roots[i]``.

    ``left``/``right`` are absolute node indices (-1 at leaves), ``feature`` the split
    column, ``threshold`` the split value, ``value`` the leaf output.
    """

    left: NDArray[np.int32]
    right: NDArray[np.int32]
    feature: NDArray[np.int32]
    threshold: NDArray[np.float64]
    value: NDArray[np.float64]
    roots: NDArray[np.int32]

    @classmethod
    def from_sklearn(cls, trees: list[Any]) -> TreeSet:
        """Flatten fitted ``sklearn.tree`` estimators (single-output regression)."""
        parts: dict[str, list[NDArray[Any]]] = {k: [] for k in _ARRAYS[:-1]}
        roots, offset = [], 0
        for est in trees:
            t = est.tree_
            leaf = t.children_left < 0
            roots.append(offset)
            parts["left"].append(np.where(leaf, -1, t.children_left + offset))
            parts["right"].append(np.where(leaf, -1, t.children_right + offset))
            parts["feature"].append(np.where(leaf, 0, t.feature))
            parts["threshold"].append(t.threshold)
            parts["value"].append(t.value[:, 0, 0])
            offset += t.node_count
        return cls(
            left=np.concatenate(parts["left"]).astype(np.int32),
            right=np.concatenate(parts["right"]).astype(np.int32),
            feature=np.concatenate(parts["feature"]).astype(np.int32),
            threshold=np.concatenate(parts["threshold"]).astype(np.float64),
            value=np.concatenate(parts["value"]).astype(np.float64),
            roots=np.asarray(roots, dtype=np.int32),
        )

    def leaf_values(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Each tree's output for each row of ``x`` ``(n, n_features)``: ``(n, n_trees)``."""
        x32 = x.astype(np.float32).astype(np.float64)
        node = np.broadcast_to(self.roots, (x.shape[0], self.roots.size)).copy()
        rows = np.arange(x.shape[0])[:, None]
        while True:
            inner = self.left[node] >= 0
            if not inner.any():
                return self.value[node]
            go_left = x32[rows, self.feature[node]] <= self.threshold[node]
            node = np.where(inner, np.where(go_left, self.left[node], self.right[node]), node)

    def check(self, n_features: int, weights: Path) -> None:
        """``ModelFileError`` unless the arrays form valid trees over ``n_features``."""
        n = self.value.size
        sizes = {self.left.size, self.right.size, self.feature.size, self.threshold.size}
        if sizes != {n} or self.roots.size == 0:
            raise modelfile.ModelFileError(f"{weights}: tree arrays of unequal length")
        ok = (
            np.all((self.roots >= 0) & (self.roots < n))
            and np.all((self.left == -1) == (self.right == -1))
            and np.all((self.left >= -1) & (self.left < n) & (self.right < n))
            # children come after their parent, so every walk ends at a leaf
            and np.all((self.left < 0) | (self.left > np.arange(n)))
            and np.all((self.right < 0) | (self.right > np.arange(n)))
            and np.all((self.feature >= 0) & (self.feature < n_features))
        )
        if not ok:
            raise modelfile.ModelFileError(f"{weights}: tree arrays are not valid trees")


class HCFEnsemble:
    """Gradient boosting and a random forest on handcrafted window features, averaged.

    ``q = ½·(gb_init + gb_rate·Σ gb trees) + ½·mean(rf trees)``.
    """

    kind = "hcf"

    def __init__(
        self,
        window: int,
        gb: TreeSet,
        gb_init: float,
        gb_rate: float,
        rf: TreeSet,
        target: str = "q",
    ) -> None:
        if target not in TARGETS:
            raise ValueError(f"target: one of {TARGETS}, got {target!r}")
        self.window, self.gb, self.rf = int(window), gb, rf
        self.gb_init, self.gb_rate = float(gb_init), float(gb_rate)
        self.target = target
        self.card: dict[str, Any] = {}

    @classmethod
    def fit(
        cls,
        windows: ArrayLike,
        q: ArrayLike,
        *,
        seed: int = 0,
        gb_trees: int = 200,
        gb_depth: int = 3,
        gb_rate: float = 0.1,
        rf_trees: int = 50,
        rf_depth: int = 8,
        rf_min_leaf: int = 10,
        target: str = "q",
    ) -> HCFEnsemble:
        """Fit both ensembles on windows ``(n, N)`` with labels ``q`` ``(n,)``, regressing
        ``target`` (see :data:`TARGETS`)."""
        try:
            from sklearn.ensemble import GradientBoostingRegressor, RandomForestRegressor
        except ImportError as exc:
            raise missing("sklearn", "training the HCF ensemble") from exc

        if target not in TARGETS:
            raise ValueError(f"target: one of {TARGETS}, got {target!r}")
        w = as_windows(windows)
        if target == "q":
            x, y = features(w), np.asarray(q, dtype=np.float64)
        else:
            x, d = scale_free_features(w)
            y = np.log(np.asarray(q, dtype=np.float64) / d)
        gb = GradientBoostingRegressor(
            n_estimators=gb_trees, max_depth=gb_depth, learning_rate=gb_rate, random_state=seed
        ).fit(x, y)
        rf = RandomForestRegressor(
            n_estimators=rf_trees,
            max_depth=rf_depth,
            min_samples_leaf=rf_min_leaf,
            random_state=seed,
            n_jobs=1,  # one thread: the same trees on every machine
        ).fit(x, y)
        model = cls(
            w.shape[-1],
            TreeSet.from_sklearn(list(gb.estimators_[:, 0])),
            float(gb.init_.constant_.ravel()[0]),
            gb_rate,
            TreeSet.from_sklearn(list(rf.estimators_)),
            target,
        )
        model.hyperparameters = {  # type: ignore[attr-defined]
            "gb_trees": gb_trees,
            "gb_depth": gb_depth,
            "gb_rate": gb_rate,
            "rf_trees": rf_trees,
            "rf_depth": rf_depth,
            "rf_min_leaf": rf_min_leaf,
            "seed": seed,
            "target": target,
        }
        return model

    def predict(self, windows: ArrayLike, *, native: bool = True) -> NDArray[np.float64]:
        """q for raw windows ``(..., N)``; ``native``: in pronet's core (:meth:`frozen`),
        else in NumPy (the reference the core is tested against)."""
        w = as_windows(windows)
        if w.shape[-1] != self.window:
            raise ValueError(
                f"windows: this model reads windows of {self.window} samples, got shape {w.shape}"
            )
        flat = np.ascontiguousarray(w.reshape(-1, self.window))
        if native:
            return self.frozen().core.predict(flat).reshape(w.shape[:-1])
        if self.target == "q":
            x, d = features(flat), np.ones(flat.shape[0])
        else:
            x, d = scale_free_features(flat)
        q = np.full(x.shape[0], np.nan)
        ok = np.all(np.isfinite(x), axis=1)  # non-finite windows give NaN, as the nets do
        # A finite window that is a straight line has no noise: q = d·exp(out) → 0.
        q[(d == 0) & np.isfinite(flat).all(axis=1)] = 0.0
        if ok.any():
            gb = self.gb_init + self.gb_rate * self.gb.leaf_values(x[ok]).sum(axis=1)
            out = 0.5 * gb + 0.5 * self.rf.leaf_values(x[ok]).mean(axis=1)
            q[ok] = out if self.target == "q" else d[ok] * np.exp(np.minimum(out, 700.0))
        return q.reshape(w.shape[:-1])

    def frozen(self, threads: int | None = None) -> FrozenHCF:
        """This ensemble's prediction in pronet's core: the same features (to rounding,
        ~1e-15), the same float32 split rule, ~10× faster than the NumPy walk.
        ``threads``: its worker threads (default: all cores)."""
        core = _core.HcfEnsemble(
            window=self.window,
            gb=tuple(getattr(self.gb, k) for k in _ARRAYS),
            gb_init=self.gb_init,
            gb_rate=self.gb_rate,
            rf=tuple(getattr(self.rf, k) for k in _ARRAYS),
            target=self.target,
            threads=threads,
        )
        return FrozenHCF(core, self)

    def tensors(self) -> dict[str, NDArray[Any]]:
        out: dict[str, NDArray[Any]] = {}
        for prefix, trees in (("gb", self.gb), ("rf", self.rf)):
            for k in _ARRAYS:
                out[f"{prefix}.{k}"] = getattr(trees, k)
        out["gb.init_rate"] = np.array([self.gb_init, self.gb_rate])
        return out

    def save(self, path: str | os.PathLike[str], card: dict[str, Any]) -> None:
        """Write the trees as safetensors plus a JSON card."""
        modelfile.write(
            path,
            self.tensors(),
            {
                "kind": self.kind,
                "architecture": {
                    "window": self.window,
                    "features": list(FEATURE_NAMES),
                    "gb_trees": int(self.gb.roots.size),
                    "rf_trees": int(self.rf.roots.size),
                    "target": self.target,
                },
                **card,
            },
        )

    @classmethod
    def from_tensors(
        cls, tensors: dict[str, NDArray[Any]], card: dict[str, Any], weights: Path
    ) -> HCFEnsemble:
        """Rebuild from :meth:`tensors` output, checking every array first."""
        arch = card.get("architecture", {})
        window = arch.get("window") if isinstance(arch, dict) else None
        if isinstance(window, bool) or not isinstance(window, int) or window < 3:
            raise modelfile.ModelFileError(
                f"{weights}: card architecture window: expected a whole number >= 3, got {window!r}"
            )
        if arch.get("features") != list(FEATURE_NAMES):
            raise modelfile.ModelFileError(f"{weights}: card lists other features than pronet's")
        names = [f"{p}.{k}" for p in ("gb", "rf") for k in _ARRAYS] + ["gb.init_rate"]
        missing = sorted(set(names) - set(tensors))
        extra = sorted(set(tensors) - set(names))
        if missing or extra:
            raise modelfile.ModelFileError(
                f"{weights}: not an HCF ensemble (missing {missing}, unexpected {extra})"
            )
        sets = []
        for p in ("gb", "rf"):
            arrays = {k: np.asarray(tensors[f"{p}.{k}"]).ravel() for k in _ARRAYS}
            for k, a in arrays.items():
                if a.dtype.kind != ("f" if k in ("threshold", "value") else "i"):
                    raise modelfile.ModelFileError(f"{weights}: {p}.{k} has dtype {a.dtype}")
                if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
                    raise modelfile.ModelFileError(f"{weights}: {p}.{k} holds non-finite values")
            trees = TreeSet(**arrays)
            trees.check(len(FEATURE_NAMES), weights)
            sets.append(trees)
        init_rate = np.asarray(tensors["gb.init_rate"], dtype=np.float64)
        if init_rate.shape != (2,) or not np.all(np.isfinite(init_rate)):
            raise modelfile.ModelFileError(f"{weights}: bad gb.init_rate")
        target = arch.get("target", "q")  # files from before targets existed regress q
        if target not in TARGETS:
            raise modelfile.ModelFileError(f"{weights}: unknown target {target!r}")
        model = cls(window, sets[0], init_rate[0], init_rate[1], sets[1], target)
        model.card = card
        return model


class FrozenHCF:
    """An HCF ensemble's prediction in pronet's core (:meth:`HCFEnsemble.frozen`):
    ``predict(windows (..., N)) -> q (...)`` as the ensemble's."""

    def __init__(self, core: _core.HcfEnsemble, model: HCFEnsemble) -> None:
        self.core = core
        self.card: dict[str, Any] = model.card
        self._model = model  # to rebuild on other threads

    def predict(self, windows: ArrayLike) -> NDArray[np.float64]:
        w = as_windows(windows)
        if w.shape[-1] != self.core.window:
            raise ValueError(
                f"windows: this model reads windows of {self.core.window} samples, "
                f"got shape {w.shape}"
            )
        flat = np.ascontiguousarray(w.reshape(-1, self.core.window))
        return self.core.predict(flat).reshape(w.shape[:-1])

    def frozen(self, threads: int | None = None) -> FrozenHCF:
        """This ensemble on ``threads`` worker threads (None: as it is)."""
        return self if threads is None else self._model.frozen(threads)
