"""Hostile parameters, cards and files for the training data (:mod:`pronet.learn.dataset`)."""

from __future__ import annotations

import hashlib
import io
import json
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from pronet.learn import dataset

from .contract import (
    INF,
    any_scalar,
    attempt,
    finite,
    fuzz,
)


@fuzz(60)
@given(
    fields=st.fixed_dictionaries(
        {},
        optional={
            "seed": st.one_of(st.integers(-3, 2**70), any_scalar),
            "n_levels": st.one_of(st.integers(-2, 20), any_scalar),
            "q_min": st.one_of(st.floats(1e-6, 1.0), any_scalar),
            "q_max": st.one_of(st.floats(1e-6, 1.0), any_scalar),
            "window": st.one_of(st.integers(-2, 500), any_scalar),
            "train_fraction": st.one_of(st.floats(0.0, 1.0), any_scalar),
        },
    ),
    as_card=st.booleans(),
)
def test_dataset_params_and_cards(fields, as_card) -> None:
    names = ("seed", "n_levels", "q_min", "q_max", "window", "train_fraction")
    params = dataset.DatasetParams(**fields)
    if as_card:
        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "d.npz"
            card = {"format": dataset.FORMAT, "version": dataset.VERSION, "params": fields}
            try:
                text = json.dumps(card)
            except (TypeError, ValueError):  # not JSON: never in a card
                return
            dataset.card_path(path).write_text(text)
            loaded = attempt(lambda: dataset.load_params(path), "path")
            if loaded is None:
                return
            params = loaded
    if attempt(lambda: params.validate() or True, *names):
        assert isinstance(params.seed, int | np.integer) and params.seed >= 0
        assert isinstance(params.window, int | np.integer) and params.window >= 2
        assert 0 < params.q_min <= params.q_max < INF and 0 < params.train_fraction < 1
        assert params.n_levels >= 1
        if params.n_levels <= 10**4:  # more levels: a legitimately huge request
            assert finite(params.q_levels()) and len(params.q_levels()) == params.n_levels


def _dataset_arrays(m: int = 4, n: int = 5) -> dict[str, np.ndarray]:
    return {
        "windows": np.zeros((m, n), np.float32),
        "q": np.full(m, 1e-3),
        "trajectory": np.zeros(m, np.int8),
        "channel": np.arange(m, dtype=np.int8) % 6,
        "start": np.arange(m, dtype=np.int32) * n,
        "train": np.arange(m) % 2 == 0,
    }


@fuzz(40)
@given(
    mutation=st.sampled_from(
        ["none", "drop", "complex", "object", "ndim", "length", "text", "empty", "bool"]
    ),
    key=st.sampled_from(list(_dataset_arrays())),
)
def test_load_dataset_refuses_malformed_files_even_with_matching_hash(mutation, key) -> None:
    arrays = _dataset_arrays()
    a = arrays[key]
    arrays[key] = {
        "none": a,
        "complex": a.astype(complex),
        "object": a.astype(object),
        "ndim": a[..., None],
        "length": a[:-1],
        "bool": a != 0,
    }.get(mutation, a)
    if mutation == "drop":
        del arrays[key]
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    data = {"text": b"not a dataset", "empty": b""}.get(mutation, buf.getvalue())
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "d.npz"
        path.write_bytes(data)
        card = {
            "format": dataset.FORMAT,
            "version": dataset.VERSION,
            "sha256": hashlib.sha256(data).hexdigest(),
        }
        dataset.card_path(path).write_text(json.dumps(card))
        ds = attempt(lambda: dataset.load_dataset(path), "path")
    if ds is not None:
        m = len(ds.q)
        assert ds.windows.ndim == 2 and len(ds.windows) == m
        for name in ("trajectory", "channel", "start", "train"):
            assert getattr(ds, name).shape == (m,)
        assert ds.windows.dtype.kind == "f" and ds.train.dtype == bool


@pytest.mark.parametrize(
    ("params", "arg"),
    [
        ({"n_levels": 1, "window": 40_001}, "window"),
        ({"n_levels": 1, "window": 10_000, "q_min": 1e300, "q_max": 1e300}, "q_max"),
    ],
)
def test_build_dataset_refuses_params_that_give_no_or_non_finite_windows(params, arg) -> None:
    with pytest.raises(ValueError, match=rf"^{arg}\b"):
        dataset.build_dataset(dataset.DatasetParams(**params))
