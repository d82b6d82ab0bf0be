"""Input conversion shared by the Python entry points: array-likes become contiguous
float64 arrays, and anything unusable raises ``ValueError`` naming the argument."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from pronet import _core

#: Largest values of signed (counts) and unsigned (seeds) 64-bit integer arguments.
I64_MAX = 2**63 - 1
U64_MAX = 2**64 - 1
#: Most worker threads the native core takes (``threads::MAX_THREADS`` in Rust).
MAX_THREADS = _core.MAX_THREADS


def real_array(value: ArrayLike, name: str) -> NDArray[Any]:
    """``value`` as a NumPy array of integers or floats (any shape, no copy when it
    already is one), or ``ValueError`` naming the argument. A nested list is refused if
    any element is a bool or text (NumPy would read ``[60, True]`` as ``[60, 1]``)."""
    if isinstance(value, list | tuple):
        wrong = _not_a_number(value)
        if wrong is not None:
            raise ValueError(f"{name}: expected real numbers, got {wrong!r}")
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: cannot be read as a numeric array ({exc})") from None
    if arr.dtype.kind not in "iuf":
        raise ValueError(f"{name}: expected real numbers, got an array of dtype {arr.dtype}")
    return arr


def _not_a_number(value: list[Any] | tuple[Any, ...]) -> object | None:
    """The first element of the nested lists ``value`` that NumPy would take as a
    number although it is none (a bool, text, bytes, a bool array), else None."""
    stack: list[Any] = [value]
    while stack:
        item = stack.pop()
        if isinstance(item, list | tuple):
            stack.extend(reversed(item))
        elif isinstance(item, bool | np.bool_ | str | bytes) or (
            isinstance(item, np.ndarray) and item.dtype.kind not in "iuf"
        ):
            return item
    return None


def float_array(value: ArrayLike, name: str, shape: tuple[int | None, ...]) -> NDArray[np.float64]:
    """``value`` as a C-contiguous float64 array of ``shape`` (``None``: any length).

    Integers and floats of any width are accepted; booleans, complex numbers, strings
    and objects are not. Finiteness is checked by the native core, which reports the
    offending row.
    """
    arr = real_array(value, name)
    if arr.ndim != len(shape) or any(
        want is not None and got != want for got, want in zip(arr.shape, shape, strict=True)
    ):
        want_text = "(" + ", ".join("n" if s is None else str(s) for s in shape)
        want_text += ",)" if len(shape) == 1 else ")"
        raise ValueError(f"{name}: expected shape {want_text}, got {arr.shape}")
    return np.ascontiguousarray(arr, dtype=np.float64)


def scalar(value: object, name: str) -> float:
    """``value`` as a Python float, or ``ValueError`` naming the argument."""
    if isinstance(value, bool | complex | str | bytes) or (
        isinstance(value, np.ndarray | np.generic) and value.dtype.kind not in "iuf"
    ):
        raise ValueError(f"{name}: expected a real number, got {type(value).__name__}")
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a real number, got {type(value).__name__}") from None
    except OverflowError:
        raise ValueError(f"{name}: too large for a float64") from None


def count(value: object, name: str, maximum: int | None = None) -> int:
    """``value`` as a Python int (a whole number, at most ``maximum`` if given), or
    ``ValueError`` naming the argument."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise ValueError(f"{name}: expected a whole number, got {value!r}")
    if maximum is not None and value > maximum:
        raise ValueError(f"{name}: must be at most {maximum}")
    return int(value)


def seconds(value: float, name: str) -> float:
    """``value`` as a duration [s]: a finite number > 0, else ``ValueError`` naming the
    argument."""
    if not 0 < value < math.inf:
        raise ValueError(f"{name}: must be a finite number of seconds > 0, got {value}")
    return float(value)


def threads(value: object, name: str, per_core: bool = True) -> int | None:
    """A thread count: None (the default: ``RAYON_NUM_THREADS`` if set, else one per
    core) or a whole number from 1 to :func:`pronet._core.max_threads` (at most
    :data:`pronet._core.THREADS_PER_CORE` per core this process may use, never more than
    :data:`MAX_THREADS`), else ``ValueError`` naming the argument (or the environment
    variable). The core's rule (:func:`pronet._core.check_threads`), checked before any
    work. ``per_core=False``: 1 to :data:`MAX_THREADS` only (a count for other machines,
    as a Ray sweep's CPUs per shard)."""
    if value is None:
        _core.check_threads(None)  # a bad RAYON_NUM_THREADS is named now, not mid-run
        return None
    n = count(value, name)
    most = _core.max_threads() if per_core else MAX_THREADS
    if not 1 <= n <= most:
        cap = f" ({_core.THREADS_PER_CORE} per core this process may use)" if per_core else ""
        raise ValueError(f"{name}: expected 1 to {most}{cap}, got {n}")
    return n


def flag(value: object, name: str) -> bool:
    """``value`` as a Python bool (``True``/``False``, NumPy's included), or ``ValueError``
    naming the argument: a string such as ``"no"`` is not silently true."""
    if not isinstance(value, bool | np.bool_):
        raise ValueError(f"{name}: expected True or False, got {value!r}")
    return bool(value)


def check_type(value: object, kind: type, name: str) -> None:
    """``ValueError`` naming the argument unless ``value`` is a ``kind``."""
    if not isinstance(value, kind):
        raise ValueError(f"{name}: expected a {kind.__name__}, got {type(value).__name__}")
