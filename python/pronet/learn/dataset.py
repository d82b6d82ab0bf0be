"""The ProNet training set: labelled windows of noisy IMU samples.

Starting from the ideal IMU of the four built-in training trajectories (400 s at 100 Hz),
each of ``n_levels`` noise variances q, spaced linearly over ``[q_min, q_max]`` (the
paper's spacing; 15 values in [0.001, 0.05]), is added as zero-mean white Gaussian noise
to all six channels. Each channel is cut into non-overlapping windows of ``window``
samples (200 windows of 200 samples per 40,000-sample channel). One example is one
channel's window, labelled with its q: 4 × 15 × 6 × 200 = 72,000 examples. The split is
80:20 at random within each trajectory, so every trajectory is on both sides
(57,600 / 14,400).

With ``spacing="log-uniform"`` (:data:`GRADES`, the training set of the shipped
``baseline``, ``detrend`` and ``hcf``; the paper's ``paper-*`` models were trained on the
linear default) every window of every channel instead gets its own q, drawn log-uniformly from
its sensor's range: accelerometer ``[q_min, q_max]``, gyro ``[gyro_q_min, gyro_q_max]``
(nine and eight decades covering consumer to navigation grade); ``n_levels`` is then
the number of draws per trajectory, each a fresh noise realization.

The file is an uncompressed ``.npz`` written with fixed zip timestamps, so the same seed
and parameters give the same bytes; a JSON card beside it holds the seed, the parameters
and the file's SHA-256. Noise for (trajectory t, level l) comes from
``numpy.random.default_rng([seed, t, l])``; the split from ``default_rng([seed, 1000])``.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import os
import zipfile
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from pronet import _core
from pronet._util.files import json_bytes, previous_matching, replace_together
from pronet._util.validate import I64_MAX, count, scalar

#: Training trajectories, in the order of the ``trajectory`` index in the metadata.
TRAINING_TRAJECTORIES = ("train-straight", "train-turns", "train-zigzag", "train-helix")
#: IMU samples of each training trajectory (400 s at 100 Hz).
TRAJECTORY_SAMPLES = 40_000
#: The most memory [bytes] a dataset's windows may take (4 GiB; building it holds about
#: as much again): ``n_levels`` up to about 1,100.
MAX_DATASET_BYTES = 4 << 30
CHANNELS = ("f_x", "f_y", "f_z", "w_x", "w_y", "w_z")
FORMAT = "pronet-dataset"
VERSION = 1
#: The arrays of a dataset file and the dtype kinds each may have.
_KINDS = dict(windows="f", q="f", trajectory="iu", channel="iu", start="iu", train="b")


@dataclass(frozen=True)
class DatasetParams:
    """How a dataset is generated (all recorded in its card)."""

    seed: int = 0
    n_levels: int = 15
    q_min: float = 0.001
    q_max: float = 0.05
    window: int = 200
    train_fraction: float = 0.8
    #: ``"linear"``: the paper's levels, one q for all six channels; ``"log-uniform"``:
    #: one q per window and channel, drawn log-uniformly from its sensor's range.
    spacing: str = "linear"
    #: The gyro's range for ``"log-uniform"`` [(rad/s)²] (None: ``q_min``, ``q_max``).
    gyro_q_min: float | None = None
    gyro_q_max: float | None = None

    def validate(self) -> None:
        count(self.seed, "seed")
        if self.seed < 0:
            raise ValueError(f"seed: must be >= 0, got {self.seed}")
        if count(self.n_levels, "n_levels", I64_MAX) < 1:
            raise ValueError(f"n_levels: must be >= 1, got {self.n_levels}")
        size = len(TRAINING_TRAJECTORIES) * self.n_levels * 6 * TRAJECTORY_SAMPLES * 4
        if size > MAX_DATASET_BYTES:
            most = MAX_DATASET_BYTES // (len(TRAINING_TRAJECTORIES) * 6 * TRAJECTORY_SAMPLES * 4)
            raise ValueError(
                f"n_levels: {self.n_levels} levels make {size / 2**30:.1f} GiB of windows; at "
                f"most {MAX_DATASET_BYTES / 2**30:.0f} GiB ({most} levels)"
            )
        q_min, q_max = scalar(self.q_min, "q_min"), scalar(self.q_max, "q_max")
        if not (0 < q_min <= q_max and np.isfinite(q_max)):
            raise ValueError(f"q_min, q_max: need 0 < q_min <= q_max, got {q_min}, {q_max}")
        if count(self.window, "window") < 2:
            raise ValueError(f"window: must be >= 2 samples, got {self.window}")
        if not 0 < scalar(self.train_fraction, "train_fraction") < 1:
            raise ValueError(f"train_fraction: must be in (0, 1), got {self.train_fraction}")
        if self.spacing not in ("linear", "log-uniform"):
            raise ValueError(f"spacing: 'linear' or 'log-uniform', got {self.spacing!r}")
        lo, hi = self.gyro_range()
        if not (0 < scalar(lo, "gyro_q_min") <= scalar(hi, "gyro_q_max") < np.inf):
            raise ValueError(f"gyro_q_min, gyro_q_max: need 0 < min <= max, got {lo}, {hi}")

    def gyro_range(self) -> tuple[float, float]:
        """The gyro's variance range [(rad/s)²] of a log-uniform set."""
        lo = self.q_min if self.gyro_q_min is None else self.gyro_q_min
        hi = self.q_max if self.gyro_q_max is None else self.gyro_q_max
        return float(lo), float(hi)

    def channel_ranges(self) -> list[tuple[float, float]]:
        """Each channel's variance range ``(low, high)``, in :data:`CHANNELS` order."""
        return [(float(self.q_min), float(self.q_max))] * 3 + [self.gyro_range()] * 3

    def q_levels(self) -> NDArray[np.float64]:
        """The noise variances, linearly spaced [(m/s²)² or (rad/s)² per sample]."""
        return np.linspace(float(self.q_min), float(self.q_max), int(self.n_levels))


#: The training set of the shipped models (``baseline``, ``detrend``, ``hcf``): per-window
#: variances log-uniform over accelerometer 1e-7 … 1e-1 (m/s²)² and gyro 1e-10 … 1e-2
#: (rad/s)² (100 Hz samples: from a navigation-grade IMU in a quiet survey to a consumer
#: MEMS under heavy vibration).
GRADES = DatasetParams(
    spacing="log-uniform", q_min=1e-7, q_max=1e-1, gyro_q_min=1e-10, gyro_q_max=1e-2
)


@dataclass(frozen=True)
class Dataset:
    """Windows, labels, metadata and the split.

    Attributes:
        windows: ``(M, window)`` float32 raw noisy samples of one channel each.
        q: ``(M,)`` float64 label: the noise variance added to that window.
        trajectory: ``(M,)`` index into :data:`TRAINING_TRAJECTORIES`.
        channel: ``(M,)`` index into :data:`CHANNELS`.
        start: ``(M,)`` index of the window's first sample in its channel.
        train: ``(M,)`` bool, True for the training side of the split.
    """

    windows: NDArray[np.float32]
    q: NDArray[np.float64]
    trajectory: NDArray[np.int8]
    channel: NDArray[np.int8]
    start: NDArray[np.int32]
    train: NDArray[np.bool_]

    @property
    def n_train(self) -> int:
        return int(self.train.sum())

    @property
    def n_test(self) -> int:
        return int((~self.train).sum())


def build_dataset(params: DatasetParams | None = None) -> Dataset:
    """Generate the dataset (deterministic in ``params``)."""
    params = params or DatasetParams()
    params.validate()
    levels = params.q_levels()
    parts: list[tuple[np.ndarray, ...]] = []
    for t, name in enumerate(TRAINING_TRAJECTORIES):
        ideal = _core.builtin_trajectory(name, 0.01).imu
        n_win = ideal.shape[0] // params.window
        if n_win == 0:
            raise ValueError(f"window: longer than the {ideal.shape[0]} samples of {name}")
        starts = np.arange(n_win, dtype=np.int32) * params.window
        for lev, q_level in enumerate(levels):
            rng = np.random.default_rng([params.seed, t, lev])
            cut, q = _noisy_windows(params, ideal, q_level, n_win, rng)
            with np.errstate(over="ignore"):
                windows = cut.reshape(-1, params.window).astype(np.float32)
            if not np.isfinite(windows).all():
                raise ValueError(f"q_max: noise of variance {q.max()} overflows float32 windows")
            parts.append(
                (
                    windows,
                    q.reshape(-1),
                    np.full(6 * n_win, t, dtype=np.int8),
                    np.repeat(np.arange(6, dtype=np.int8), n_win),
                    np.tile(starts, 6),
                )
            )
    windows, q, traj, channel, start = (np.concatenate(c) for c in zip(*parts, strict=True))
    train = np.zeros(q.shape[0], dtype=bool)
    rng = np.random.default_rng([params.seed, 1000])
    for t in range(len(TRAINING_TRAJECTORIES)):
        idx = np.flatnonzero(traj == t)
        n_train = int(round(params.train_fraction * idx.size))
        train[rng.permutation(idx)[:n_train]] = True
    return Dataset(windows, q, traj, channel, start, train)


def _noisy_windows(
    params: DatasetParams,
    ideal: NDArray[np.float64],
    level: float,
    n_win: int,
    rng: np.random.Generator,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """One draw's noisy windows ``(6, n_win, window)`` of the ideal samples ``(n, 6)``
    and their variances ``(6, n_win)``: ``level`` everywhere (linear), or one log-uniform
    draw per channel and window from the channel's range."""
    n = n_win * params.window
    if params.spacing == "linear":
        noisy = ideal + rng.standard_normal(ideal.shape) * np.sqrt(level)
        # (samples, channel) -> (channel, window index, sample in window)
        return noisy[:n].T.reshape(6, n_win, params.window), np.full((6, n_win), level)
    lows, highs = _libm(math.log, np.array(params.channel_ranges())).T
    q = _libm(math.exp, rng.uniform(lows[:, None], highs[:, None], (6, n_win)))
    cut = ideal[:n].T.reshape(6, n_win, params.window)
    return cut + rng.standard_normal(cut.shape) * np.sqrt(q)[..., None], q


def _libm(f: Callable[[float], float], x: NDArray[np.float64]) -> NDArray[np.float64]:
    """``f`` (``math.exp`` or ``math.log``) of every element of ``x``, through the C
    library: NumPy's own ``exp`` and ``log`` take an AVX-512 path on CPUs that have it,
    whose last bits differ from the C library's (on ~5 % of values), and a dataset's
    bytes, hence its SHA-256 on the model cards, must not depend on the CPU."""
    return np.array([f(v) for v in x.ravel().tolist()], dtype=np.float64).reshape(x.shape)


def _npz_bytes(ds: Dataset) -> bytes:
    """Uncompressed npz with fixed timestamps: same arrays, same bytes."""
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_STORED) as zf:
        for name in ("windows", "q", "trajectory", "channel", "start", "train"):
            arr = io.BytesIO()
            np.lib.format.write_array(arr, getattr(ds, name), allow_pickle=False)
            zf.writestr(
                zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0)), arr.getvalue()
            )
    return buf.getvalue()


def dataset_sha256(ds: Dataset) -> str:
    """SHA-256 of the bytes :func:`save_dataset` writes for ``ds``."""
    return hashlib.sha256(_npz_bytes(ds)).hexdigest()


def card_path(path: Path) -> Path:
    return path.with_suffix(".json")


def save_dataset(ds: Dataset, path: str | os.PathLike[str], params: DatasetParams) -> Path:
    """Write ``path`` (.npz) and its card ``path.json``, replacing an earlier pair as
    one (both or neither: :func:`pronet._util.files.replace_together`, the card last)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    data = _npz_bytes(ds)
    card = {
        "format": FORMAT,
        "version": VERSION,
        "params": asdict(params),
        "q_levels": params.q_levels().tolist() if params.spacing == "linear" else None,
        "q_ranges": params.channel_ranges(),
        "spacing": params.spacing,
        "trajectories": list(TRAINING_TRAJECTORIES),
        "channels": list(CHANNELS),
        "n_examples": int(ds.q.shape[0]),
        "n_train": ds.n_train,
        "n_test": ds.n_test,
        "sha256": hashlib.sha256(data).hexdigest(),
    }
    replace_together([(path, data), (card_path(path), json_bytes(card))])
    return path


def _read_card(path: Path) -> dict:
    try:
        card = json.loads(card_path(path).read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise ValueError(f"path: cannot read the dataset card {card_path(path)}: {exc}") from None
    if not isinstance(card, dict) or card.get("format") != FORMAT or card.get("version") != VERSION:
        raise ValueError(f"path: {card_path(path)} is not a {FORMAT} v{VERSION} card")
    return card


def load_params(path: str | os.PathLike[str]) -> DatasetParams:
    """The parameters recorded in the card of the dataset at ``path``."""
    try:
        params = DatasetParams(**_read_card(Path(path))["params"])
        params.validate()
    except (KeyError, TypeError, ValueError) as exc:
        if str(exc).startswith("path:"):
            raise
        raise ValueError(f"path: {card_path(Path(path))} has no valid params ({exc})") from None
    return params


def load_dataset(path: str | os.PathLike[str]) -> Dataset:
    """Read a dataset written by :func:`save_dataset`, checking its card and hash first.

    Only plain numeric arrays are read (``allow_pickle=False``).
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"path: {path}: no such dataset file")
    card = _read_card(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"path: cannot read {path}: {exc}") from None
    if hashlib.sha256(data).hexdigest() != card.get("sha256"):
        # a write of a new pair killed between its renames: the old card's old data
        kept = previous_matching(path, card.get("sha256"))
        if kept is None:
            raise ValueError(
                f"path: {path} does not match the hash in its card (changed or truncated)"
            )
        data = kept
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            arrays = {k: z[k] for k in _KINDS}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
        raise ValueError(f"path: {path} is not a readable dataset ({exc})") from None
    m = arrays["q"].shape[:1]
    for name, kinds in _KINDS.items():
        a = arrays[name]
        ndim = 2 if name == "windows" else 1
        if a.dtype.kind not in kinds or a.ndim != ndim or a.shape[:1] != m:
            raise ValueError(f"path: {path} holds a malformed {name} ({a.dtype}, {a.shape})")
    return Dataset(**arrays)
