"""Model files: round trips, and every kind of bad file refused with a clear error that
names it, before anything is used. Pickle is never executed."""

from __future__ import annotations

import json
import os
import pickle

import numpy as np
import pytest
import torch

from pronet.learn import modelfile, models
from pronet.learn.frozen import load_frozen
from pronet.learn.hcf import HCFEnsemble
from pronet.learn.modelfile import ModelFileError


@pytest.fixture()
def saved_net(tmp_path):
    torch.manual_seed(0)
    net = models.DetrendNet()
    models.save_net(net, tmp_path / "net", {"note": "test"})
    return net, tmp_path / "net"


def _windows() -> np.ndarray:
    return np.random.default_rng(0).standard_normal((4, 6, 200)) * 0.1


def _rehash(path) -> None:
    """Make the card's hash match the (altered) weights, so a later check must catch it."""
    weights, card_file = modelfile.paths(path)
    card = json.loads(card_file.read_text())
    import hashlib

    card["weights_sha256"] = hashlib.sha256(weights.read_bytes()).hexdigest()
    card_file.write_text(json.dumps(card))


def test_net_round_trip_by_any_suffix(saved_net) -> None:
    net, path = saved_net
    for p in (path, path.with_suffix(".safetensors"), path.with_suffix(".json"), str(path)):
        loaded = models.load(p)
        assert type(loaded) is models.DetrendNet
        np.testing.assert_array_equal(loaded.predict(_windows()), net.predict(_windows()))
    assert loaded.card["note"] == "test" and loaded.card["kind"] == "detrend"


def test_hcf_round_trip(tmp_path) -> None:
    rng = np.random.default_rng(1)
    q = rng.choice([0.001, 0.02, 0.05], 300)
    w = rng.standard_normal((300, 200)) * np.sqrt(q)[:, None]
    model = HCFEnsemble.fit(w, q, gb_trees=10, rf_trees=5, rf_depth=5)
    model.save(tmp_path / "hcf", {})
    loaded = models.load(tmp_path / "hcf")
    np.testing.assert_array_equal(loaded.predict(w), model.predict(w))


def test_missing_files(tmp_path, saved_net) -> None:
    with pytest.raises(ModelFileError, match="nothing.json: model card not found"):
        models.load(tmp_path / "nothing")
    _, path = saved_net
    os.remove(path.with_suffix(".safetensors"))
    with pytest.raises(ModelFileError, match=r"net\.safetensors: cannot read the weights"):
        models.load(path)


@pytest.mark.parametrize("damage", ["flip", "truncate"])
def test_corrupted_or_truncated_weights(saved_net, damage) -> None:
    _, path = saved_net
    weights = path.with_suffix(".safetensors")
    data = bytearray(weights.read_bytes())
    if damage == "flip":
        data[len(data) // 2] ^= 0xFF
    else:
        data = data[: len(data) // 2]
    weights.write_bytes(bytes(data))
    with pytest.raises(ModelFileError, match=r"net\.safetensors: .*corrupted or truncated"):
        models.load(path)
    # With a forged hash the truncation is still caught, by the safetensors parser.
    if damage == "truncate":
        _rehash(path)
        with pytest.raises(ModelFileError, match=r"net\.safetensors: not a safetensors file"):
            models.load(path)


def test_bad_cards(saved_net) -> None:
    _, path = saved_net
    card_file = path.with_suffix(".json")
    card = json.loads(card_file.read_text())
    for change, message in (
        ({"version": 99}, "card version 99; this pronet reads 1"),
        ({"format": "other"}, "not a pronet-model card"),
        ({"kind": "transformer"}, "unknown model kind 'transformer'"),
        ({"architecture": {"window": 1}}, "bad architecture"),
        ({"architecture": {"widths": 3}}, "bad architecture"),
        # one type rule: a whole number is a whole number, a scale a real number
        ({"architecture": {"window": "200"}}, "architecture window: expected a whole number"),
        ({"architecture": {"window": 200.7}}, "architecture window: expected a whole number"),
        ({"architecture": {"window": True}}, "architecture window: expected a whole number"),
        ({"architecture": {"channels": [16, "32", 32]}}, "architecture channels: expected a whole"),
        ({"architecture": {"input_scale": "0.1"}}, "architecture input_scale: expected a real"),
        ({"architecture": {"q_scale": False}}, "architecture q_scale: expected a real"),
        ({"architecture": {"scaling": 1}}, "architecture scaling: expected text"),
    ):
        card_file.write_text(json.dumps({**card, **change}))
        with pytest.raises(ModelFileError, match=rf"net\.json: .*{message}"):
            models.load(path)
    card_file.write_text("{not json")
    with pytest.raises(ModelFileError, match=r"net\.json: not a readable JSON model card"):
        models.load(path)


def test_wrong_shape_and_wrong_architecture(saved_net, tmp_path) -> None:
    _, path = saved_net
    card_file = path.with_suffix(".json")
    card = json.loads(card_file.read_text())
    # The card claims wider convolutions than the weights have.
    card_file.write_text(json.dumps({**card, "architecture": {"channels": [16, 32, 64]}}))
    with pytest.raises(ModelFileError, match=r"net\.safetensors: tensor .* has shape"):
        models.load(path)
    # A net's card over an HCF ensemble's weights.
    rng = np.random.default_rng(2)
    q = rng.choice([0.001, 0.05], 100)
    HCFEnsemble.fit(
        rng.standard_normal((100, 200)) * np.sqrt(q)[:, None], q, gb_trees=3, rf_trees=2
    ).save(tmp_path / "hcf", {})
    os.replace(tmp_path / "hcf.safetensors", path.with_suffix(".safetensors"))
    card_file.write_text(json.dumps(card))
    _rehash(path)
    with pytest.raises(ModelFileError, match=r"net\.safetensors: tensors do not fit"):
        models.load(path)
    # Non-finite weights.
    models.save_net(models.DetrendNet(), path, {})
    from safetensors.numpy import load, save

    tensors = load(path.with_suffix(".safetensors").read_bytes())
    tensors["head.0.bias"][0] = np.nan
    path.with_suffix(".safetensors").write_bytes(save(tensors))
    _rehash(path)
    with pytest.raises(ModelFileError, match="non-finite"):
        models.load(path)


def test_a_card_claiming_a_huge_net_fails_before_the_net_is_built(saved_net, monkeypatch) -> None:
    """Four million channels over small weights: the shapes are compared before torch
    allocates the net the card describes (that took 3 GB and 9 s)."""
    _, path = saved_net
    card_file = path.with_suffix(".json")
    card = json.loads(card_file.read_text())
    huge = {**card, "architecture": {"channels": [4_000_000, 32, 64]}}
    card_file.write_text(json.dumps(huge))

    def must_not_build(*args, **kwargs):
        raise AssertionError("the net was built")

    monkeypatch.setitem(models.NETS, "detrend", must_not_build)
    for load in (models.load, load_frozen):
        with pytest.raises(ModelFileError, match=r"net\.safetensors: tensor .* has shape"):
            load(path)


class _Payload:
    """Unpickling this would create a file: the proof that nothing was executed."""

    def __init__(self, target: str) -> None:
        self.target = target

    def __reduce__(self):
        return (open, (self.target, "w"))


def test_pickle_payload_is_refused_unexecuted(saved_net, tmp_path) -> None:
    _, path = saved_net
    target = tmp_path / "pwned"
    payload = pickle.dumps({"state_dict": _Payload(str(target))})
    path.with_suffix(".safetensors").write_bytes(payload)
    _rehash(path)  # the card vouches for the payload: only the parser stands in the way
    with pytest.raises(ModelFileError, match=r"net\.safetensors: not a safetensors file"):
        models.load(path)
    # Also as a torch checkpoint file handed over under a .pt name.
    pt = tmp_path / "model.pt"
    torch.save({"x": torch.zeros(1)}, pt)
    with pytest.raises(ModelFileError, match=r"model\.pt\.json: model card not found"):
        models.load(pt)
    assert not target.exists()
    # Sanity: the payload really does create the file when unpickled.
    pickle.loads(payload)
    assert target.exists()
