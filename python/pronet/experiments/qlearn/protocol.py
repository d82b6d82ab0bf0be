"""Honest evaluation of Q models learned from recorded missions: leave-one-section-out
cross-validation (:func:`cross_validate`), a held-out split (:func:`held_out`) and
the ledger that keeps a held-out set from being scored twice (:class:`Ledger`).

The protocol (docs/how-to/learning-q.md, "The protocol"): each section is scored by a model
trained without it; the rows beside it are the constant row (``pronet real``'s
default constant q), the per-section best constant (a 2-D search of the group scales
on the scored section itself: a ceiling known only after the fact, never a
prediction) and, in simulation, the oracle (the true q schedule). Differences are
paired over sections with a 95 % CI (:func:`pronet.experiments.qlearn.scoring.paired_rows`).
Before anything is scored, the (model, test set) pair is claimed in the ledger, and
recorded scored once its scores came out; a pair scored is refused, so a held-out set
is scored once per model setup (a claim whose scoring stopped early is released).
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import math
import os
import socket
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import AbstractContextManager as ContextManager
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pronet.experiments.qlearn.scoring import (
    ScaleGrid,
    constant_metrics,
    oracle_metrics,
    scale_grid,
)
from pronet.experiments.qlearn.sections import TrainingSection
from pronet.learn.qmodels import SectionScale
from pronet.recorded.metrics import SectionMetrics

#: Row labels of the comparison tables.
CONSTANT = "constant"
BEST_CONSTANT = "best constant (per section, ceiling)"
ORACLE = "oracle (true q)"
SCALE_ROW = "(a) section scale"


def section_key(sections: Sequence[TrainingSection]) -> str:
    """A short hash of the sections' names and sensor data: what "the same test set" means."""
    h = hashlib.sha256()
    for ts in sections:
        h.update(ts.name.encode())
        h.update(np.ascontiguousarray(ts.section.imu).tobytes())
        h.update(np.ascontiguousarray(ts.section.truth_vel).tobytes())
    return h.hexdigest()[:16]


class Ledger:
    """A JSON-lines file of the (model setup, test set) pairs already scored.

    :meth:`scoring` claims pairs before they are scored and records them scored when
    their scores came out; a pair already scored is refused (``ValueError`` naming the
    file and the earlier entry): a held-out set scored once is never scored again by the
    same model setup, whatever came out. A scoring that stops before its scores come
    out (Ctrl-C, an error) releases its claims: nothing was shown. A claim never
    settled is in progress while its process runs (refused, naming it), and stale once
    that process is gone (killed): the next claim takes it over. :meth:`claim` records
    a pair as scored at once (entries without a ``state`` are read so).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def entries(self) -> list[dict[str, Any]]:
        if not self.path.exists():
            return []
        return self._parse(self.path.read_text())

    def _parse(self, text: str) -> list[dict[str, Any]]:
        out = []
        for i, line in enumerate(text.splitlines(), 1):
            if line.strip():
                try:
                    out.append(json.loads(line))
                except json.JSONDecodeError:
                    raise ValueError(f"{self.path}: line {i} is not JSON") from None
        return out

    def claim(self, model: str, test_set: str, note: str = "") -> None:
        """Record that ``model`` (a description of the model setup: kind, training
        options, training sections) is scored on ``test_set`` (its
        :func:`section_key` with names), refused if it was."""
        self._append([(model, test_set)], {"note": note})

    @contextmanager
    def scoring(self, pairs: Sequence[tuple[str, str]], note: str = "") -> Iterator[None]:
        """Claim every ``(model, test_set)`` of ``pairs`` (none if one is refused), run
        the block that scores them, then record them scored; if the block raises,
        release the claims and re-raise."""
        notes = self._append(pairs, {"state": "claimed", "note": note})
        try:
            yield
        except BaseException:
            self._append(pairs, {"state": "released"}, check=False)
            raise
        self._append(pairs, {"state": "scored", "note": notes}, check=False)

    def _append(
        self, pairs: Sequence[tuple[str, str]], fields: dict[str, Any], check: bool = True
    ) -> str:
        """Check every pair (``check``), then write one entry for each, under a lock
        on the file; returns what the check noted (a stale claim taken over)."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        noted: list[str] = []
        with self.path.open("a+") as f:
            fcntl.flock(f, fcntl.LOCK_EX)  # released when the file closes
            f.seek(0)
            entries = self._parse(f.read())
            if check:
                noted = [n for m, t in pairs if (n := self._check(entries, m, t))]
            stamp = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
            for model, test_set in pairs:
                entry = {"model": model, "test_set": test_set, **fields, "time": stamp}
                if fields.get("state") == "claimed":
                    entry.update(pid=os.getpid(), host=socket.gethostname())
                    entry["note"] = "; ".join(x for x in (fields.get("note"), *noted) if x)
                f.write(json.dumps(entry) + "\n")
        return "; ".join(noted)

    def _check(self, entries: list[dict[str, Any]], model: str, test_set: str) -> str:
        """``ValueError`` if the pair was scored or is being scored; what to note of
        a stale claim taken over, else ''."""
        pending: dict[str, Any] | None = None
        for e in entries:
            if e.get("model") != model or e.get("test_set") != test_set:
                continue
            state = e.get("state", "scored")
            if state == "scored":
                raise ValueError(
                    f"{self.path}: {model!r} was already scored on {test_set!r} "
                    f"({e.get('time')}); a held-out set is scored once"
                )
            pending = e if state == "claimed" else None
        if pending is None:
            return ""
        pid, host = pending.get("pid"), pending.get("host")
        here = host == socket.gethostname()
        if not here or _running(pid):
            raise ValueError(
                f"{self.path}: {model!r} is being scored on {test_set!r} by process {pid} "
                f"on {host} (claimed {pending.get('time')}); a held-out set is scored once"
                + ("" if here else "; if that run is gone, remove its line")
            )
        return f"took over the stale claim of process {pid} ({pending.get('time')})"


def _running(pid: object) -> bool:
    """Whether process ``pid`` of this host runs."""
    if not isinstance(pid, int) or pid <= 0:
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # another user's
        return True
    return True


def fit_section_scale(grids: Sequence[ScaleGrid]) -> SectionScale:
    """Model (a) on training sections: the grid's group scales with the lowest mean
    squared SRMSE over ``grids`` (the Kalman-informed loss, the mean squared velocity
    error at the truth rows, averaged over sections), each grid from the core
    (:func:`pronet.experiments.qlearn.scoring.scale_grid`). Two parameters: the search is the
    loss's exact minimum on the grid, with no gradient needed."""
    if not grids:
        raise ValueError("grids: needs at least one training section")
    loss = np.nanmean(np.stack([g.srmse**2 for g in grids]), axis=0)
    i, j = np.unravel_index(int(np.nanargmin(loss)), loss.shape)
    log10 = grids[0].log10
    return SectionScale((float(10 ** log10[i]), float(10 ** log10[j])))


#: A trainer: training sections (and their constant grids) → a model whose row on a
#: held-out section is ``score(model, section)``.
Trainer = Callable[[Sequence[TrainingSection], Sequence[ScaleGrid]], Any]
Scorer = Callable[[Any, TrainingSection], SectionMetrics]


def scale_trainer(_: Sequence[TrainingSection], grids: Sequence[ScaleGrid]) -> SectionScale:
    return fit_section_scale(grids)


def scale_scorer(model: SectionScale, ts: TrainingSection) -> SectionMetrics:
    return constant_metrics(ts, model.scales)


@dataclass(frozen=True)
class Evaluation:
    """Rows (label → section → metrics) over the scored sections, and the models
    (label → section → the model that scored it)."""

    rows: dict[str, dict[str, SectionMetrics]]
    models: dict[str, dict[str, Any]]


def _base_rows(
    sections: Sequence[TrainingSection], grids: dict[str, ScaleGrid]
) -> dict[str, dict[str, SectionMetrics]]:
    rows: dict[str, dict[str, SectionMetrics]] = {CONSTANT: {}, BEST_CONSTANT: {}}
    for ts in sections:
        rows[CONSTANT][ts.name] = constant_metrics(ts)
        s_a, s_g, _, _ = grids[ts.name].best()
        rows[BEST_CONSTANT][ts.name] = constant_metrics(ts, (s_a, s_g))
        if ts.oracle_q is not None:
            rows.setdefault(ORACLE, {})[ts.name] = oracle_metrics(ts)
    return rows


def cross_validate(
    sections: Sequence[TrainingSection],
    trainers: dict[str, tuple[Trainer, Scorer]],
    *,
    ledger: Ledger | None = None,
    setup: str = "",
    on_done: Callable[[str], None] | None = None,
) -> Evaluation:
    """Leave-one-section-out: for each section, every trainer fits on the others and
    its model scores the section. ``ledger`` claims ``(label + setup, sections)`` for
    each trainer first (:meth:`Ledger.scoring`: released if this stops early)."""
    if len(sections) < 2:
        raise ValueError(f"sections: leave-one-out needs at least 2, got {len(sections)}")
    names = [ts.name for ts in sections]
    if len(set(names)) != len(names):
        raise ValueError(f"sections: names must differ, got {names}")
    key = f"LOSO {','.join(names)} {section_key(sections)}"
    pairs = [(f"{label} {setup}".strip(), key) for label in trainers]
    with _claimed(ledger, pairs):
        grids = {ts.name: scale_grid(ts) for ts in sections}
        if on_done is not None:
            on_done("constant grids")
        rows = _base_rows(sections, grids)
        models: dict[str, dict[str, Any]] = {label: {} for label in trainers}
        for k, ts in enumerate(sections):
            train = [s for i, s in enumerate(sections) if i != k]
            train_grids = [grids[s.name] for s in train]
            for label, (fit, scorer) in trainers.items():
                model = fit(train, train_grids)
                models[label][ts.name] = model
                rows.setdefault(label, {})[ts.name] = scorer(model, ts)
                if on_done is not None:
                    on_done(f"{ts.name}: {label}")
    return Evaluation(rows, models)


def _claimed(ledger: Ledger | None, pairs: list[tuple[str, str]]) -> ContextManager[None]:
    """:meth:`Ledger.scoring` of ``pairs``, or nothing without a ledger."""
    return nullcontext() if ledger is None else ledger.scoring(pairs)


def held_out(
    train: Sequence[TrainingSection],
    test: Sequence[TrainingSection],
    trainers: dict[str, tuple[Trainer, Scorer]],
    *,
    ledger: Ledger | None = None,
    setup: str = "",
) -> Evaluation:
    """Every trainer fits once on ``train`` and scores each of ``test`` (claimed in
    ``ledger`` first)."""
    overlap = {t.name for t in train} & {t.name for t in test}
    if overlap:
        raise ValueError(f"test: sections also in train: {sorted(overlap)}")
    key = f"held-out {','.join(t.name for t in test)} {section_key(test)}"
    setup = f"{setup} trained on {section_key(train)}"
    pairs = [(f"{label} {setup}".strip(), key) for label in trainers]
    with _claimed(ledger, pairs):
        train_grids = [scale_grid(ts) for ts in train]
        grids = {ts.name: scale_grid(ts) for ts in test}
        rows = _base_rows(test, grids)
        models: dict[str, dict[str, Any]] = {}
        for label, (fit, scorer) in trainers.items():
            model = fit(train, train_grids)
            models[label] = {ts.name: model for ts in test}
            rows[label] = {ts.name: scorer(model, ts) for ts in test}
    return Evaluation(rows, models)


def gain_share(rows: dict[str, dict[str, SectionMetrics]], label: str) -> float:
    """The share of the oracle's gain ``label`` recovers: its mean SRMSE reduction
    against the constant row over the oracle's, over the sections of both (NaN where
    the oracle has no gain: a schedule that never leaves its first piece)."""
    names = list(rows[ORACLE])
    const = np.array([rows[CONSTANT][n].srmse for n in names])
    oracle = np.array([rows[ORACLE][n].srmse for n in names])
    model = np.array([rows[label][n].srmse for n in names])
    gain = float(np.mean(const - oracle))
    return float(np.mean(const - model)) / gain if gain != 0 else math.nan
