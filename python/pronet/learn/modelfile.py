"""Model files: safetensors weights beside a JSON card, and nothing else is ever read.

A model ``name`` is two files, ``name.safetensors`` (named float arrays, no code) and
``name.json`` (the card: format, version, kind, architecture, the weights' SHA-256 and
whatever the trainer recorded: dataset hash, hyperparameters, test metrics, time).
Reading checks, before any tensor is used: the card parses and has this format and
version, the weights hash matches the card (so a truncated or altered file is caught),
the safetensors header parses, and the caller then checks names and shapes against the
architecture. Pickle is never involved: a pickle payload fails the safetensors parse and
is never executed. A new pair replaces an old one as one (:func:`write`); where a write
was killed between its two renames, the old card's weights are read from where the
write kept them (``.NAME.safetensors.previous``, found by the card's hash).
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from pronet._util.files import json_bytes, previous_matching, replace_together

FORMAT = "pronet-model"
VERSION = 1
#: Where the shipped models live, inside the installed package.
SHIPPED_DIR = Path(__file__).with_name("weights")


class ModelFileError(ValueError):
    """A model file is missing, corrupted, truncated, or not what its card says."""


def paths(path: str | os.PathLike[str]) -> tuple[Path, Path]:
    """``(weights, card)`` for a path given with either suffix, or none."""
    p = Path(path)
    if p.suffix in (".safetensors", ".json"):
        p = p.with_suffix("")
    return p.with_name(p.name + ".safetensors"), p.with_name(p.name + ".json")


def write(path: str | os.PathLike[str], tensors: dict[str, NDArray[Any]], card: dict) -> Path:
    """Write the weights and their card, replacing an earlier pair as one (both or
    neither, :func:`pronet._util.files.replace_together`: the card last); returns the
    card's path."""
    from safetensors.numpy import save

    weights, card_file = paths(path)
    weights.parent.mkdir(parents=True, exist_ok=True)
    data = save({k: np.ascontiguousarray(v) for k, v in tensors.items()})
    full = {
        "format": FORMAT,
        "version": VERSION,
        **card,
        "weights_file": weights.name,
        "weights_sha256": hashlib.sha256(data).hexdigest(),
    }
    # an undefined score (R² of equal labels): null
    replace_together([(weights, data), (card_file, json_bytes(full))])
    return card_file


def read(path: str | os.PathLike[str]) -> tuple[dict[str, NDArray[Any]], dict]:
    """The tensors and card of a model file, checked as the module docstring says."""
    from safetensors import SafetensorError
    from safetensors.numpy import load

    weights, card_file = paths(path)
    try:
        card = json.loads(card_file.read_text())
    except FileNotFoundError:
        raise ModelFileError(
            f"{card_file}: model card not found (a pronet model is NAME.safetensors + NAME.json)"
        ) from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ModelFileError(f"{card_file}: not a readable JSON model card ({exc})") from None
    if not isinstance(card, dict) or card.get("format") != FORMAT:
        raise ModelFileError(f"{card_file}: not a {FORMAT} card")
    if card.get("version") != VERSION:
        raise ModelFileError(
            f"{card_file}: card version {card.get('version')!r}; this pronet reads {VERSION}"
        )
    try:
        data = weights.read_bytes()
    except OSError as exc:
        raise ModelFileError(f"{weights}: cannot read the weights ({exc})") from None
    if hashlib.sha256(data).hexdigest() != card.get("weights_sha256"):
        # a write of a new pair killed between its renames: the old card's old weights
        kept = previous_matching(weights, card.get("weights_sha256"))
        if kept is None:
            raise ModelFileError(
                f"{weights}: does not match the hash in {card_file.name} (corrupted or truncated)"
            )
        data = kept
    try:
        tensors = load(data)
    except (SafetensorError, ValueError, OSError) as exc:
        raise ModelFileError(f"{weights}: not a safetensors file ({exc})") from None
    return tensors, card


def check_tensors(
    weights: Path, tensors: dict[str, NDArray[Any]], expected: dict[str, tuple[int, ...]]
) -> None:
    """``ModelFileError`` naming ``weights`` unless ``tensors`` has exactly the expected
    names and shapes, all finite."""
    missing = sorted(set(expected) - set(tensors))
    extra = sorted(set(tensors) - set(expected))
    if missing or extra:
        raise ModelFileError(
            f"{weights}: tensors do not fit the architecture in its card "
            f"(missing {missing}, unexpected {extra})"
        )
    for name, shape in expected.items():
        if tuple(tensors[name].shape) != tuple(shape):
            raise ModelFileError(
                f"{weights}: tensor {name!r} has shape {tuple(tensors[name].shape)}, "
                f"the architecture needs {tuple(shape)}"
            )
        if tensors[name].dtype.kind == "f" and not np.all(np.isfinite(tensors[name])):
            raise ModelFileError(f"{weights}: tensor {name!r} holds non-finite values")
