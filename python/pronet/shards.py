"""Finished pieces of a long experiment, saved as each completes, so that an interrupted
run resumes without redoing them.

A :class:`ShardStore` is a folder beside the result folder (``<out>.partial``). Each
finished (scenario, strategy) Monte Carlo is one ``.npz`` file, written atomically
(temporary file, then rename), holding only numeric and string arrays: loading never
unpickles. The store records the settings it was made with (``settings.json``); resuming
with other settings is refused, since the pieces would not belong together.
"""

from __future__ import annotations

import hashlib
import io
import json
import re
import shutil
from pathlib import Path
from typing import Any

import numpy as np

from pronet._util.files import atomic_write, json_bytes
from pronet.learn.hybrid import Guardrails, HybridResult
from pronet.montecarlo import MonteCarloResult

_SETTINGS = "settings.json"


class ShardStore:
    """Finished shards of one experiment, in ``folder``.

    Args:
        folder: where the shards live (created when missing).
        settings: what the experiment was started with (JSON-serializable); a store
            that exists with different settings raises ``ValueError``.
    """

    def __init__(self, folder: str | Path, settings: dict[str, Any]) -> None:
        self.folder = Path(folder)
        want = json.loads(json_bytes(settings))  # as it reads back
        path = self.folder / _SETTINGS
        if path.exists():
            have = json.loads(path.read_text())
            if have != want:
                raise ValueError(
                    f"resume: {self.folder} holds shards of different settings "
                    f"({have}); rerun with those, or remove the folder"
                )
        else:
            self.folder.mkdir(parents=True, exist_ok=True)
            atomic_write(path, json_bytes(want))

    def _path(self, scenario: str, label: str) -> Path:
        key = f"{scenario}--{label}"
        slug = re.sub(r"[^A-Za-z0-9_.=-]+", "_", key)
        # the slug is for people; the hash keeps labels that differ only in punctuation apart
        digest = hashlib.sha256(key.encode()).hexdigest()[:10]
        return self.folder / f"{slug}-{digest}.npz"

    def __len__(self) -> int:
        # atomic_write's temporaries are hidden (".name.xyz"): not counted.
        return len([p for p in self.folder.glob("*.npz") if not p.name.startswith(".")])

    def load(
        self, scenario: str, label: str
    ) -> tuple[MonteCarloResult, HybridResult | None] | None:
        """The saved shard, or None if it was not finished. ``ValueError`` naming the file
        if it cannot be read back (truncated or altered since it was written)."""
        path = self._path(scenario, label)
        if not path.exists():
            return None
        try:
            with np.load(path, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
            meta = json.loads(str(arrays.pop("meta")))
            optional = {k: arrays.pop(k, None) for k in ("error", "sigma", "q")}
            result = MonteCarloResult(**arrays, failure=meta["failure"], **optional)
        except Exception as exc:  # a damaged zip, array or record: say which file
            raise ValueError(
                f"resume: {path} is damaged ({type(exc).__name__}: {exc}); remove it and "
                "--resume again to redo that shard"
            ) from None
        hybrid = None
        if meta["hybrid"] is not None:
            h = meta["hybrid"]
            hybrid = HybridResult(
                result=result,
                n_tunings=h["n_tunings"],
                clipped=np.asarray(h["clipped"], dtype=np.int64),
                non_finite=np.asarray(h["non_finite"], dtype=np.int64),
                rust_seconds=h["rust_seconds"],
                model_seconds=h["model_seconds"],
                guardrails=Guardrails(**h["guardrails"]),
            )
        return result, hybrid

    def save(
        self, scenario: str, label: str, result: MonteCarloResult, hybrid: HybridResult | None
    ) -> None:
        """Save one finished shard atomically."""
        arrays = {
            k: v for k, v in vars(result).items() if k != "failure" and isinstance(v, np.ndarray)
        }
        meta = {
            "failure": result.failure,
            "hybrid": None
            if hybrid is None
            else {
                "n_tunings": hybrid.n_tunings,
                "clipped": hybrid.clipped.tolist(),
                "non_finite": hybrid.non_finite.tolist(),
                "rust_seconds": hybrid.rust_seconds,
                "model_seconds": hybrid.model_seconds,
                "guardrails": vars(hybrid.guardrails),
            },
        }
        buf = io.BytesIO()
        np.savez(buf, meta=np.array(json.dumps(meta)), **arrays)  # type: ignore[arg-type]
        atomic_write(self._path(scenario, label), buf.getvalue())

    def remove(self) -> None:
        """Delete the store (once the experiment's results are written)."""
        shutil.rmtree(self.folder, ignore_errors=True)
