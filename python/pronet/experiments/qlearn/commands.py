"""What ``pronet train --recorded`` and ``--simulated`` do: train one Q model on
sections and write it (:func:`train_model`), or score models honestly
(:func:`evaluate`: leave-one-section-out, or a held-out split) into a result folder.

Models: ``a`` (:class:`pronet.learn.qmodels.SectionScale`, fitted by a 2-D search of
the Kalman-informed loss on the core, :func:`pronet.experiments.qlearn.protocol.fit_section_scale`)
and ``cnn`` (:func:`pronet.experiments.qlearn.gradient.train_cnn`, the gradient through the
torch filter).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from pronet._util.files import atomic_folder, atomic_write, json_bytes
from pronet.experiments.qlearn.protocol import (
    CONSTANT,
    ORACLE,
    SCALE_ROW,
    Evaluation,
    Ledger,
    Scorer,
    Trainer,
    cross_validate,
    gain_share,
    held_out,
    scale_scorer,
    scale_trainer,
)
from pronet.experiments.qlearn.scoring import comparison_table, paired_rows, scale_grid, score
from pronet.experiments.qlearn.sections import TrainingSection

#: The models ``--model`` names.
RECORDED_MODELS = ("a", "cnn", "akit")
CNN_ROW = "(b) windowed CNN"
AKIT_ROW = "(c) A-KIT-like (IMU + filter velocity)"

Say = Callable[[str], None]


def _cnn_trainer(hp: Any, say: Say | None) -> Trainer:
    def fit(train: Sequence[TrainingSection], _: Any) -> Any:
        from pronet.experiments.qlearn.gradient import train_cnn

        net, record = train_cnn(train, hp, say)
        if say is not None:
            say(f"cnn: trained on {len(train)} sections in {record['seconds']:.0f} s")
        return net

    return fit


def _cnn_scorer(net: Any, ts: TrainingSection) -> Any:
    from pronet.learn.hybrid import q_schedule
    from pronet.recorded.passes import section_recorded

    rec = section_recorded(ts.section, ts.config)
    sched = q_schedule(net, rec.imu, rec.imu_time, prior_q=ts.q_nominal)
    return score(ts, sched.time, sched.q)


def _akit_trainer(hp: Any, say: Say | None) -> Trainer:
    def fit(train: Sequence[TrainingSection], _: Any) -> Any:
        from pronet.experiments.qlearn.akit_training import train_akit

        net, record = train_akit(train, hp, say)
        if say is not None:
            say(f"akit: trained on {len(train)} sections in {record['seconds']:.0f} s")
        return net

    return fit


def _akit_scorer(net: Any, ts: TrainingSection) -> Any:
    from pronet.learn.akit import akit_schedule
    from pronet.recorded.passes import section_recorded

    sched = akit_schedule(net, section_recorded(ts.section, ts.config), ts.q_nominal)
    return score(ts, sched.time, sched.q)


def trainers(
    models: Sequence[str], hp: Any = None, say: Say | None = None
) -> dict[str, tuple[Trainer, Scorer]]:
    """The (trainer, scorer) of each named model."""
    out: dict[str, tuple[Trainer, Scorer]] = {}
    for m in models:
        if m == "a":
            out[SCALE_ROW] = (scale_trainer, scale_scorer)
        elif m == "cnn":
            out[CNN_ROW] = (_cnn_trainer(hp, say), _cnn_scorer)
        elif m == "akit":
            out[AKIT_ROW] = (_akit_trainer(hp, say), _akit_scorer)
        else:
            raise ValueError(f"--model: one of {', '.join(RECORDED_MODELS)}, got {m!r}")
    return out


def train_model(
    sections: Sequence[TrainingSection],
    model: str,
    out: str | Path,
    *,
    hp: Any = None,
    say: Say | None = None,
) -> tuple[Path, dict[str, Any]]:
    """Train ``model`` on all ``sections`` and write it to ``out`` (weights + card,
    each atomically); returns the card's path and the training record."""
    start = time.perf_counter()
    names = [ts.name for ts in sections]
    if model == "a":
        grids = [scale_grid(ts) for ts in sections]
        fitted = scale_trainer(sections, grids)
        record: dict[str, Any] = {"sections": names, "scales": list(fitted.scales)}
        record["seconds"] = time.perf_counter() - start
        card = fitted.save(out, {"training": record, "method": "2-D grid search on the core"})
        return card, record
    if model == "cnn":
        from pronet.experiments.qlearn.gradient import cnn_card, train_cnn
        from pronet.learn.models import save_net

        net, record = train_cnn(sections, hp, say)
        save_net(net, out, cnn_card(record))
        from pronet.learn.modelfile import paths

        return paths(out)[1], record
    if model == "akit":
        from pronet.experiments.qlearn.akit_training import train_akit
        from pronet.learn.akit import save_akit

        akit, record = train_akit(sections, hp, say)
        card = save_akit(akit, out, {"training": record, "trained_on": "recorded sections"})
        return card, record
    raise ValueError(f"--model: one of {', '.join(RECORDED_MODELS)}, got {model!r}")


def evaluate(
    sections: Sequence[TrainingSection],
    models: Sequence[str],
    out: Path,
    *,
    test: Sequence[TrainingSection] = (),
    ledger: Ledger | None = None,
    hp: Any = None,
    say: Say | None = None,
    title: str = "",
) -> tuple[str, dict[str, Any]]:
    """Leave-one-section-out over ``sections`` (or, with ``test``, train on
    ``sections`` and score ``test`` once), written to the new folder ``out``
    (``table.md``, ``metrics.json``); returns the table and the record."""
    chosen = trainers(models, hp, say)
    setup = f"hp={hp!r}" if hp is not None else ""
    if test:
        ev = held_out(sections, test, chosen, ledger=ledger, setup=setup)
        how = f"trained on {len(sections)} sections, scored on {len(test)} held out"
    else:
        ev = cross_validate(sections, chosen, ledger=ledger, setup=setup, on_done=say)
        how = f"leave-one-section-out over {len(sections)} sections"
    table = comparison_table(ev.rows, CONSTANT, f"{title} ({how})".strip())
    record = _record(ev, how)
    if ORACLE in ev.rows:
        shares = {label: gain_share(ev.rows, label) for label in ev.rows if label != CONSTANT}
        record["oracle_gain_share"] = shares
        table += (
            "\nShare of the oracle's SRMSE gain over the constant row: "
            + ", ".join(f"{k} {v:.2f}" for k, v in shares.items())
            + "\n"
        )
    with atomic_folder(out) as tmp:
        atomic_write(tmp / "table.md", table.encode())
        atomic_write(tmp / "metrics.json", json_bytes(record))
    return table, record


def _record(ev: Evaluation, how: str) -> dict[str, Any]:
    rows = {
        label: {
            name: {"srmse": m.srmse, "final_horizontal": m.final_horizontal}
            for name, m in by.items()
        }
        for label, by in ev.rows.items()
    }
    paired = {
        p.label: {
            "srmse": p.srmse.mean,
            "d_srmse": [p.d_srmse.mean, p.d_srmse.low, p.d_srmse.high],
            "final": p.final.mean,
            "d_final": [p.d_final.mean, p.d_final.low, p.d_final.high],
            "relative_srmse_percent": p.relative_srmse,
        }
        for p in paired_rows(ev.rows, CONSTANT)
    }
    scales = {
        label: {n: list(getattr(m, "scales", ())) for n, m in by.items()}
        for label, by in ev.models.items()
        if label == SCALE_ROW
    }
    return {"protocol": how, "rows": rows, "paired": paired, "scales": scales}
