"""Crash-safe file writing shared by every module that saves something: atomic files
and folders, strict JSON, and the checks and reservation of a result folder before a
run computes anything into it."""

from __future__ import annotations

import atexit
import fcntl
import glob
import hashlib
import json
import math
import os
import re
import shutil
import tempfile
from collections.abc import Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from pathlib import Path

import numpy as np

#: The longest file name (bytes of UTF-8) most file systems allow (ext4, XFS, APFS,
#: NTFS in characters): the hidden names pronet makes beside a file fit in it.
NAME_MAX = 255
#: What :func:`tempfile.mkstemp` and :func:`tempfile.mkdtemp` add to a prefix.
_TEMP_CHARS = 8


def sibling(path: Path, suffix: str, hidden: bool = False, room: int = 0) -> Path:
    """The file beside ``path`` named ``<name><suffix>`` (``.<name><suffix>`` if
    ``hidden``), for a lock, a temporary or a ``.partial`` folder. When that name, with
    ``room`` bytes more, would exceed :data:`NAME_MAX`, ``<name>`` is cut and ended by a
    hash of the whole name: any name the file system allows for ``path`` gets its
    siblings (a 250-character ``--out`` once failed on its own lock)."""
    path = Path(path)
    dot = "." if hidden else ""
    name = f"{dot}{path.name}{suffix}"
    if len(name.encode()) + room <= NAME_MAX:
        return path.with_name(name)
    digest = "~" + hashlib.sha256(path.name.encode()).hexdigest()[:12]
    keep = NAME_MAX - room - len(f"{dot}{digest}{suffix}".encode())
    cut = path.name.encode()[:keep].decode(errors="ignore")
    return path.with_name(f"{dot}{cut}{digest}{suffix}")


def check_new_files(paths: list[Path], option: str, force: bool = False) -> None:
    """``ValueError`` naming ``option`` if any of ``paths`` (every file one output
    writes: a dataset and its card, a model's weights and card) exists and ``force`` is
    not set, or if one cannot be written (:func:`check_writable`). Checked before any
    work: without ``--force`` nothing existing is overwritten, whichever file of the set
    it is."""
    for path in paths:
        if path.is_dir():
            raise ValueError(f"{option}: {path} is a folder; name the file to write")
        if (path.exists() or path.is_symlink()) and not force:
            raise ValueError(f"{option}: {path} exists; use --force to replace it")
        check_writable(path, option)


def atomic_write(path: Path, data: bytes | Iterable[bytes]) -> None:
    """Write ``data`` (bytes, or pieces of them written one after the other: a large
    file need not be held whole) to ``path`` via a temporary sibling and a rename, so
    ``path`` is either the old file or the complete new one, never a partial write."""
    replace_together([(path, data)])


def replace_together(files: Sequence[tuple[Path, bytes | Iterable[bytes]]]) -> None:
    """Write files that belong together (a model's weights and card, a dataset and its
    card, a navigated recording's files), each ``(path, data)`` as :func:`atomic_write`
    takes it, so that they are replaced as one: all old or all new.

    Each is written whole to a temporary sibling first (a full disk, a file-size limit
    or Ctrl-C there leave every old file as it was); then they are renamed into place
    in order, the last one the commit (a card, which names its data by hash). Until it
    is in place, the old version of each earlier file is kept as :func:`previous`, and
    any error or Ctrl-C between the renames puts the old files back. A process killed
    between the renames leaves the earlier files new and the last one old: a reader
    whose old card does not match the new data finds the old data by its hash in
    :func:`previous` (:func:`previous_matching`); the next write removes it."""
    written: list[tuple[Path, Path]] = []
    if not files:
        return
    try:
        for path, data in files:
            written.append((Path(path), _temporary(Path(path), data)))
        _rename_all(written)
    finally:
        for _, tmp in written:  # those renamed are gone already
            tmp.unlink(missing_ok=True)


def _temporary(path: Path, data: bytes | Iterable[bytes]) -> Path:
    """``data`` written whole to a new temporary sibling of ``path``; the sibling. An
    ``OSError`` is raised naming ``path``."""
    prefix = sibling(path, ".", hidden=True, room=_TEMP_CHARS).name
    fd, tmp = tempfile.mkstemp(prefix=prefix, dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            for piece in [data] if isinstance(data, bytes | bytearray | memoryview) else data:
                fh.write(piece)
        os.chmod(tmp, 0o644)  # mkstemp makes it private; a saved file is an ordinary one
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise _naming(exc, path) from exc
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return Path(tmp)


def previous(path: Path) -> Path:
    """Where :func:`replace_together` keeps ``path``'s old version while the files after
    it are renamed into place: ``.<name>.previous`` beside it."""
    return sibling(Path(path), ".previous", hidden=True)


def previous_matching(path: Path, sha256: object) -> bytes | None:
    """The bytes of ``path``'s :func:`previous` version if their SHA-256 is ``sha256``
    (a write of ``path`` and its card killed between the renames: the old card's data),
    else None."""
    try:
        data = previous(path).read_bytes()
    except OSError:
        return None
    return data if hashlib.sha256(data).hexdigest() == sha256 else None


def _rename_all(written: list[tuple[Path, Path]]) -> None:
    """Rename each temporary of ``written`` ``(path, temporary)`` onto its path, in
    order; the old version of each but the last kept as :func:`previous` until the
    last is in place, and put back on any error (:func:`replace_together`)."""
    kept: list[tuple[Path, Path | None]] = []  # each path, and its old version (None: none)
    try:
        for path, tmp in written[:-1]:
            old = previous(path)
            old.unlink(missing_ok=True)  # left by a write killed between its renames
            kept.append((path, old if _keep(path, old) else None))
            os.replace(tmp, path)
        path, tmp = written[-1]
        os.replace(tmp, path)
    except OSError as exc:
        _put_back(kept)
        raise _naming(exc, path) from exc
    except BaseException:
        _put_back(kept)
        raise
    for _, kept_old in kept:
        if kept_old is not None:
            kept_old.unlink(missing_ok=True)


def _keep(path: Path, old: Path) -> bool:
    """Keep ``path``'s current file as ``old`` (a hard link, else a copy); False when
    there is none."""
    if not path.is_file():
        return False
    try:
        os.link(path, old)
    except OSError:  # a file system without hard links
        try:
            shutil.copyfile(path, old)
        except BaseException:
            old.unlink(missing_ok=True)
            raise
    return True


def _put_back(kept: list[tuple[Path, Path | None]]) -> None:
    """Undo :func:`_rename_all`'s renames: each path's old version back, or none."""
    for path, old in reversed(kept):
        if old is None:
            path.unlink(missing_ok=True)
        else:
            os.replace(old, path)


def _naming(exc: OSError, path: Path) -> OSError:
    """``exc`` itself if it names a file, else the same error naming ``path`` (a failed
    ``write`` on a full disk names no file)."""
    if exc.filename is not None or exc.errno is None:
        return exc
    return type(exc)(exc.errno, exc.strerror or str(exc), str(path))


@contextmanager
def atomic_folder(folder: Path) -> Iterator[Path]:
    """Yield a temporary sibling of ``folder`` to fill; on success it is renamed to
    ``folder``, on any error (or Ctrl-C) it is removed. An existing ``folder`` is
    refused, never overwritten. An ``OSError`` that names no file (a write on a full
    disk) is raised naming ``folder``."""
    folder = Path(folder)
    if folder.exists():
        raise FileExistsError(f"out: {folder} exists; choose a new folder")
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=_temp_prefix(folder), dir=folder.parent))
    try:
        yield tmp
        os.chmod(tmp, 0o755)  # mkdtemp makes it private; a result folder is an ordinary one
        os.replace(tmp, folder)
    except OSError as exc:  # named after the folder asked for, not the removed sibling
        shutil.rmtree(tmp, ignore_errors=True)
        raise _naming(exc, folder) from exc
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    finally:
        release_folder(folder)


def _temp_prefix(folder: Path) -> str:
    """The name prefix of :func:`atomic_folder`'s temporary sibling of ``folder``."""
    return sibling(folder, ".", hidden=True, room=_TEMP_CHARS).name


def _lock(folder: Path) -> Path:
    """The lock file of :func:`reserve_folder`'s reservation of ``folder``."""
    return sibling(folder, ".lock", hidden=True)


def json_bytes(data: object) -> bytes:
    """``data`` as strict JSON (indented, newline-terminated UTF-8), the one way pronet
    writes JSON: NaN and infinities become ``null``, NumPy arrays and scalars lists and
    numbers, paths strings. Anything else is a ``TypeError``: an object's ``repr`` can
    hold its address, and two identical runs must write identical files."""
    return (json.dumps(_plain(data), indent=2, allow_nan=False) + "\n").encode()


def _plain(value: object) -> object:
    if value is None or isinstance(value, bool | int | str):
        return value
    if isinstance(value, float | np.floating):
        number = float(value)
        return number if math.isfinite(number) else None
    if isinstance(value, np.integer | np.bool_):
        return value.item()
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    raise TypeError(f"JSON output: a {type(value).__name__} is not a plain value")


#: What ``tempfile.mkdtemp`` appends to a prefix.
_MKDTEMP_SUFFIX = re.compile(r"[a-z0-9_]{8}")

#: Lock files of the result folders this process has reserved, by folder.
_RESERVED: dict[Path, int] = {}


def check_writable(path: Path, option: str) -> None:
    """``ValueError`` naming ``option`` unless ``path`` can be written: its nearest
    existing ancestor (``path`` itself if it is a folder) is a writable folder, not a
    file."""
    path = Path(path)
    ancestor = path.absolute() if path.is_dir() else path.absolute().parent
    while not ancestor.exists():
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        raise ValueError(f"{option}: {path}: {ancestor} is a file, not a folder")
    if not os.access(ancestor, os.W_OK | os.X_OK):
        raise ValueError(f"{option}: {path}: {ancestor} is not writable")


def check_out_folder(folder: Path, option: str = "--out") -> None:
    """``ValueError`` naming ``option`` unless a new result folder can be made at
    ``folder``: it does not exist and :func:`check_writable` holds. Checked before a
    run computes anything."""
    folder = Path(folder)
    if folder.exists() or folder.is_symlink():
        raise ValueError(f"{option}: {folder} exists; choose another {option}")
    check_writable(folder, option)


def reserve_folder(folder: Path, option: str = "--out") -> None:
    """Reserve ``folder`` for this process's run until :func:`atomic_folder` has written
    it (or the process ends): an exclusive lock on ``.<name>.lock`` beside it. A second
    run into the same folder is refused (``ValueError`` naming ``option``) before it
    computes anything. Temporary folders that an earlier, killed run left beside it
    (``.<name>.XXXX``) are removed: nobody else can be writing them."""
    folder = Path(folder)
    key = folder.absolute()
    if key in _RESERVED:
        return
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(_lock(folder), os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as exc:
        raise ValueError(f"{option}: {folder}: {exc.strerror or exc}") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.read(fd, 32).decode(errors="replace").strip() or "?"
        os.close(fd)
        raise ValueError(
            f"{option}: {folder} is being written by another run (process {holder})"
        ) from None
    os.ftruncate(fd, 0)
    os.write(fd, str(os.getpid()).encode())
    _RESERVED[key] = fd
    prefix = _temp_prefix(folder)
    for left in folder.parent.glob(f"{glob.escape(prefix)}*"):
        # Exactly mkdtemp's eight characters after the prefix: ".res.v2.XXXXXXXX", the
        # temporary folder of a run into "res.v2", is not this folder's.
        if _MKDTEMP_SUFFIX.fullmatch(left.name[len(prefix) :]) and left.is_dir():
            if not left.is_symlink():
                shutil.rmtree(left, ignore_errors=True)


def release_folder(folder: Path) -> None:
    """End :func:`reserve_folder`'s reservation of ``folder`` (nothing if it has none)."""
    folder = Path(folder)
    fd = _RESERVED.pop(folder.absolute(), None)
    if fd is not None:
        _lock(folder).unlink(missing_ok=True)
        os.close(fd)


@atexit.register
def _release_all() -> None:
    """At exit, the lock files of reservations no run finished (a run that failed)."""
    for key in list(_RESERVED):
        release_folder(key)
