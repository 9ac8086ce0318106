"""Outputs that never cost a result: paths checked before the work, files written to a
temporary file in the same folder and renamed into place (a reader sees the old file or the
new one, never half of one, and a failure leaves the old one as it was), and strict JSON
(no NaN or Infinity: a non-finite number is written as null, with the reason beside it)."""
from __future__ import annotations

import contextlib
import json
import math
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any


class OutputPathError(ValueError):
    """An output or input path that cannot be used; the message names the path and why."""


def _nearest_existing(path: Path) -> Path:
    p = path
    while not p.exists() and not p.is_symlink():
        if p.parent == p:
            break
        p = p.parent
    return p


def _probe_writable(folder: Path) -> str | None:
    """Why no file can be created in `folder`, or None. A real probe (create and remove a
    temporary file): permission bits say nothing to root, or on a read-only file system."""
    try:
        fd, probe = tempfile.mkstemp(dir=folder, prefix=".lorascout-probe-")
    except OSError as exc:
        return exc.strerror or str(exc)
    os.close(fd)
    os.unlink(probe)
    return None


def _check_creatable(path: Path, what: str) -> None:
    """`path`'s missing folders can be made, and a file can be created in the last existing
    folder on the way."""
    base = _nearest_existing(path.parent)
    if not base.is_dir():
        raise OutputPathError(f"{path}: cannot create the {what}: {base} is not a folder")
    why = _probe_writable(base)
    if why is not None:
        raise OutputPathError(f"{path}: cannot create the {what}: folder {base} is not writable ({why})")


def check_out_dir(path: str | os.PathLike) -> Path:
    """An output folder: an existing writable folder, or one that can be created."""
    p = Path(path)
    if not str(path).strip():
        raise OutputPathError("an empty path names no folder")
    if p.exists():
        if not p.is_dir():
            raise OutputPathError(f"{p}: exists and is not a folder")
        why = _probe_writable(p)
        if why is not None:
            raise OutputPathError(f"{p}: folder is not writable ({why})")
        return p
    base = _nearest_existing(p)
    if not base.is_dir():
        raise OutputPathError(f"{p}: cannot create the output folder: {base} is not a folder")
    why = _probe_writable(base)
    if why is not None:
        raise OutputPathError(f"{p}: cannot create the output folder: folder {base} is not writable ({why})")
    return p


def check_out_file(path: str | os.PathLike) -> Path:
    """An output file: a regular file to be replaced (once the new one is complete) or a new
    file in a folder that exists or can be made. Devices, pipes and folders are refused: the
    rename would replace the device node itself."""
    p = Path(path)
    if not str(path).strip():
        raise OutputPathError("an empty path names no file")
    if p.is_dir():
        raise OutputPathError(f"{p}: is a folder, not a file")
    if p.exists() and not p.is_file():
        raise OutputPathError(f"{p}: exists and is not a regular file")
    _check_creatable(p, "output file")
    return p


def check_in_file(path: str | os.PathLike) -> Path:
    """An input file that exists, is not a folder and can be opened for reading."""
    p = Path(path)
    if not str(path).strip():
        raise OutputPathError("an empty path names no file")
    if p.is_dir():
        raise OutputPathError(f"{p}: is a folder, not a file")
    try:
        with open(p, "rb"):
            pass
    except OSError as exc:
        raise OutputPathError(f"{p}: cannot read it: {exc.strerror or exc}") from None
    return p


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """A temporary path in `path`'s folder (same suffix, so libraries that read the format off
    the name still work) that becomes `path` when the block ends without an exception; on an
    exception it is removed and `path` stays as it was. Missing folders are made."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=f".tmp{target.suffix}")
    os.close(fd)
    try:
        yield Path(tmp)
        mode = (os.stat(target).st_mode & 0o7777) if target.exists() else (0o666 & ~_umask())
        os.chmod(tmp, mode)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "w", **kwargs: Any) -> Iterator[IO]:
    """open() for writing, atomically (see atomic_path)."""
    with atomic_path(path) as tmp:
        with open(tmp, mode, **kwargs) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())


def write_text(path: str | os.PathLike, text: str) -> None:
    with atomic_open(path, "w", encoding="utf-8") as f:
        f.write(text)


def write_bytes(path: str | os.PathLike, data: bytes) -> None:
    with atomic_open(path, "wb") as f:
        f.write(data)


NULL_REASONS_KEY = "null_reasons"


def finite(obj: Any) -> tuple[Any, dict[str, str]]:
    """`obj` with every NaN or infinite float replaced by None, and {path: reason} for each."""
    reasons: dict[str, str] = {}

    def walk(x: Any, where: str) -> Any:
        if isinstance(x, float) and not math.isfinite(x):
            reasons[where or "."] = f"{x!r} is not a number JSON can hold"
            return None
        if isinstance(x, dict):
            return {k: walk(v, f"{where}.{k}" if where else str(k)) for k, v in x.items()}
        if isinstance(x, (list, tuple)):
            return [walk(v, f"{where}[{i}]") for i, v in enumerate(x)]
        return x

    return walk(obj, ""), reasons


def strict_dumps(obj: Any, **kwargs: Any) -> str:
    """json.dumps that writes no NaN or Infinity: such values become null, and a top-level
    object gets `null_reasons` naming each one and why."""
    clean, reasons = finite(obj)
    if reasons and isinstance(clean, dict):
        clean[NULL_REASONS_KEY] = reasons
    return json.dumps(clean, allow_nan=False, **kwargs)


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a number JSON can hold")


def strict_loads(text: str | bytes) -> Any:
    """json.loads that refuses NaN, Infinity and -Infinity (Python's reader accepts them)."""
    return json.loads(text, parse_constant=_reject_constant)
