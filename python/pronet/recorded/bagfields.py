"""A bag's topics read in one pass, and a topic's messages as columns of numbers, for
:mod:`pronet.recorded.bags`.

:func:`read_topics` reads every topic asked for in one pass over the bag
(:func:`read_raw`: the raw messages, in the order a pass over each topic alone gives
them), then each topic's messages deserialized, or with :func:`topic_fields` each
message's ``header.stamp`` and the named fields (``"linear_acceleration.x"``,
``"orientation_covariance[8]"``) as one float64 array, no message object kept.

A message type whose fields are a ``std_msgs/Header`` followed by float64 numbers only
(``sensor_msgs/Imu``, the ``…Stamped`` twists, poses and quaternions,
``FluidPressure``) has one layout but for its ``frame_id``'s length: such messages are
decoded from their raw bytes with NumPy, grouped by their length and the frame_id's,
the layout taken from the bag's own message definition (:func:`layout`). A message is
decoded so only where the deserializer would read it without complaint and give the
same numbers: little-endian CDR (ROS 2, the connection's serialization ``cdr``) or
ROS 1, a frame_id that ends where its length says (with CDR's terminating NUL) and
decodes as UTF-8, the float64 block 8-aligned after it (CDR) and the message ending
there (ROS 1: exactly; CDR: within the 3 bytes of padding the deserializer allows).
Every other message (a big-endian CDR message, a malformed one, a type of another
layout) goes through the bag reader's own deserializer, which raises where a message is
corrupt, as before. Both give the same bits: the same float64 numbers, the stamp ``sec
+ nanosec·1e-9`` in the same IEEE arithmetic (``tests/recorded/test_bag_fields.py``
compares them on ROS 1 and ROS 2 bags whose frame_ids vary in length).

Before, the reader read each topic in its own pass and kept every deserialized message
(a tree of Python objects per message, walked again and again by the garbage
collector), then built Python lists from them: a 25-minute 200 Hz bag took 2.0–3.6× a
plain ``rosbags`` loop over its topics, now 0.24–0.64× (``benches/run.py --only
bag-read``; docs/results/performance.md).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from operator import attrgetter
from typing import Any

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

#: The stamp's two fields, as the fast path finds them in the header.
_STAMP = ("header.stamp.sec", "header.stamp.nanosec")


@dataclass(frozen=True)
class Layout:
    """A message type of fixed layout but for one string: ``ints`` 4-byte integers
    (``(path, signed)``, the header's ``seq`` and stamp), the string (the frame_id),
    then ``floats`` float64 numbers, ``columns`` naming each (an array's ``path[i]``)."""

    ints: tuple[tuple[str, bool], ...]
    floats: int
    columns: dict[str, int]


def _leaves(typestore: Any, msgtype: str, prefix: str = "") -> list[tuple[str, str, int]] | None:
    """The message's fields flattened in wire order as ``(path, base type, count)``, or
    None where one is a sequence or an array of messages (variable or nested layouts)."""
    from rosbags.interfaces import Nodetype

    out: list[tuple[str, str, int]] = []
    for name, desc in typestore.fielddefs[msgtype][1]:
        path = prefix + name
        if desc[0] == Nodetype.NAME:
            inner = _leaves(typestore, desc[1], path + ".")
            if inner is None:
                return None
            out += inner
        elif desc[0] == Nodetype.BASE:
            out.append((path, desc[1][0], 1))
        elif desc[0] == Nodetype.ARRAY and desc[1][0][0] == Nodetype.BASE and desc[1][1] > 0:
            out.append((path, desc[1][0][1][0], int(desc[1][1])))
        else:
            return None
    return out


def layout(typestore: Any, msgtype: str) -> Layout | None:
    """The :class:`Layout` of ``msgtype`` as ``typestore`` (the bag's) defines it, or
    None where it is not one: 4-byte integers holding ``header.stamp``, one string,
    then float64 numbers only."""
    leaves = _leaves(typestore, msgtype)
    strings = [i for i, leaf in enumerate(leaves or []) if leaf[1] == "string"]
    if leaves is None or len(strings) != 1 or leaves[strings[0]][2] != 1:
        return None
    head, tail = leaves[: strings[0]], leaves[strings[0] + 1 :]
    if any(kind not in ("int32", "uint32") or n != 1 for _, kind, n in head):
        return None
    if not tail or any(kind != "float64" for _, kind, _ in tail):
        return None
    ints = tuple((path, kind == "int32") for path, kind, _ in head)
    if not set(_STAMP) <= {path for path, _ in ints}:
        return None
    columns: dict[str, int] = {}
    for path, _, n in tail:
        for i in range(n):
            columns[path if n == 1 else f"{path}[{i}]"] = len(columns)
    return Layout(ints, len(columns), columns)


def _ascii_or_utf8(text: NDArray[np.uint8]) -> NDArray[np.bool_]:
    """Which rows of bytes decode as UTF-8 (as the deserializer's ``bytes.decode()``)."""
    good: NDArray[np.bool_] = np.asarray((text < 0x80).all(axis=1))
    for i in np.flatnonzero(~good):
        try:
            bytes(text[i]).decode()
            good[i] = True
        except UnicodeDecodeError:
            pass
    return good


def _decode_group(
    block: NDArray[np.uint8], lay: Layout, cdr: bool, columns: list[int]
) -> tuple[NDArray[np.bool_], I64, F64]:
    """Messages of one length (rows of ``block``): which follow ``lay``, their integers
    and their float64 numbers of index ``columns`` (rows that do not: zeros)."""
    m, size = block.shape
    head = 4 if cdr else 0  # CDR's encapsulation header
    p, k = len(lay.ints), lay.floats
    ints, values = np.zeros((m, p), np.int64), np.zeros((m, len(columns)))
    ok = np.zeros(m, bool)
    at = head + 4 * p  # the string's length
    if size < at + 4:
        return ok, ints, values
    good = (block[:, 0] == 0) & (block[:, 1] == 1) if cdr else np.ones(m, bool)
    strlen = np.ascontiguousarray(block[:, at : at + 4]).view("<u4")[:, 0].astype(np.int64)
    byte = (8 * np.asarray(columns)[:, None] + np.arange(8)).ravel()
    for length in np.unique(strlen[good]):
        rows = np.flatnonzero(good & (strlen == length))
        start = at + 4
        if cdr:  # NUL-terminated; the float64 block 8-aligned after the encapsulation header
            text_end, end = start + length - 1, head + ((4 * p + 4 + length + 7) & -8)
            fits = length >= 1 and end + 8 * k <= size <= end + 8 * k + 3
        else:
            text_end = end = start + length
            fits = end + 8 * k == size
        if not fits:
            continue
        if cdr:
            rows = rows[block[rows, text_end] == 0]
        rows = rows[_ascii_or_utf8(block[rows, start:text_end])]
        take: Any = slice(None) if len(rows) == m else rows  # all (as usual): no gathering
        words = np.ascontiguousarray(block[take, head:at]).view("<u4")
        for j, (_, signed) in enumerate(lay.ints):
            ints[take, j] = words[:, j].view("<i4") if signed else words[:, j]
        values[take] = np.ascontiguousarray(block[take][:, end + byte]).view("<f8")
        ok[take] = True
    return ok, ints, values


def _decode(
    raws: Sequence[bytes], lay: Layout, cdr: bool, columns: list[int]
) -> tuple[NDArray[np.bool_], I64, F64]:
    """:func:`_decode_group` over messages of any lengths, in their order."""
    n = len(raws)
    sizes = np.fromiter(map(len, raws), np.int64, n)
    ok = np.zeros(n, bool)
    ints = np.zeros((n, len(lay.ints)), np.int64)
    values = np.zeros((n, len(columns)))
    for size in np.unique(sizes):
        rows = np.flatnonzero(sizes == size)
        joined = b"".join(raws if len(rows) == n else [raws[i] for i in rows.tolist()])
        block = np.frombuffer(joined, np.uint8).reshape(len(rows), int(size))
        ok[rows], ints[rows], values[rows] = _decode_group(block, lay, cdr, columns)
    return ok, ints, values


def _getter(path: str) -> Callable[[Any], Any]:
    """A field of a deserialized message by its path (``a.b``, ``a.b[3]``)."""
    name, _, index = path.partition("[")
    get = attrgetter(name)
    if not index:
        return get
    i = int(index[:-1])
    return lambda msg: get(msg)[i]


def topic_fields(
    reader: Any,
    msgtype: str,
    raws: Sequence[bytes],
    fields: Sequence[str],
    fast: bool = True,
) -> F64:
    """``(n, 1 + len(fields))``: each message's ``header.stamp`` [s] (``sec +
    nanosec·1e-9``) and the float value of each of ``fields``, in the order of ``raws``
    (the raw messages of ``msgtype`` from the rosbags ``AnyReader`` ``reader``); decoded
    with NumPy where the message allows it (module docstring), else deserialized with
    ``reader.deserialize`` (always with ``fast`` False: the reference)."""
    n = len(raws)
    stamps = np.zeros((n, 2), np.int64)
    out = np.zeros((n, 1 + len(fields)))
    done = np.zeros(n, bool)
    lay = layout(reader.typestore, msgtype) if fast else None
    if lay is not None and all(f in lay.columns for f in fields):
        ok, ints, values = _decode(raws, lay, bool(reader.is2), [lay.columns[f] for f in fields])
        names = [path for path, _ in lay.ints]
        stamps[ok] = ints[ok][:, [names.index(s) for s in _STAMP]]
        out[ok, 1:] = values[ok]
        done = ok
    getters = [_getter(f) for f in fields]
    for i in np.flatnonzero(~done):
        msg = reader.deserialize(raws[int(i)], msgtype)
        stamps[i] = (int(msg.header.stamp.sec), int(msg.header.stamp.nanosec))
        out[i, 1:] = [float(get(msg)) for get in getters]
    out[:, 0] = stamps[:, 0].astype(np.float64) + stamps[:, 1].astype(np.float64) * 1e-9
    return out


def read_raw(reader: Any, connections: Sequence[Any]) -> dict[str, tuple[list[bytes], list[str]]]:
    """The raw messages of ``connections`` read in one pass over the bag, by topic, with
    each one's type: in the order a pass over that topic alone gives them (rosbags merges
    its sources by timestamp, keeping each source's order)."""
    out: dict[str, tuple[list[bytes], list[str]]] = {c.topic: ([], []) for c in connections}
    unique = list({id(c): c for c in connections}.values())
    for connection, _, raw in reader.messages(connections=unique):
        raws, types = out[connection.topic]
        raws.append(raw)
        types.append(connection.msgtype)
    return out


def fast_path_applies(reader: Any, connections: Sequence[Any]) -> bool:
    """Whether the raw messages of ``connections`` may be decoded with NumPy at all:
    ROS 1, or ROS 2 connections serialized as ``cdr`` (the deserializer's own choice:
    CDR for every ROS 2 bag), all of one type."""
    if len({c.msgtype for c in connections}) != 1:
        return False
    return not reader.is2 or all(
        getattr(c.ext, "serialization_format", None) == "cdr" for c in connections
    )


def read_topics(
    reader: Any, requests: Sequence[tuple[str, Sequence[Any], Sequence[str] | None]]
) -> Iterator[F64 | list[Any]]:
    """Each request ``(topic, its connections, fields)`` read in one pass over the bag
    (:func:`read_raw`), then, one after the other: with ``fields`` its
    :func:`topic_fields` (the connections of one type), without its messages
    deserialized (``reader.deserialize``), in order."""
    raws = read_raw(reader, [c for _, conns, _ in requests for c in conns])
    for topic, conns, fields in requests:
        msgs, types = raws[topic]
        if fields is None:
            yield [reader.deserialize(raw, t) for raw, t in zip(msgs, types, strict=True)]
        else:
            fast = fast_path_applies(reader, conns)
            yield topic_fields(reader, conns[0].msgtype, msgs, fields, fast)
