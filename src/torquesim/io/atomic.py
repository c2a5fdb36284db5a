"""Atomic file writes: a reader never sees a partial file, and a failed write keeps the old."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable
from pathlib import Path


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_atomic(path, write: Callable[[Path], None], field: str = "out") -> Path:
    """Call ``write(tmp_path)`` then move the finished file onto ``path``, with the permissions
    a new file gets under the current umask.

    If anything fails, ``path`` is left untouched (the previous file is kept) and the temporary
    file removed; an OS error (no such directory, no permission, no space, a path under /proc)
    becomes a `ModelError` naming the path, under ``field`` (the
    option or argument that gave it).
    """
    from ..errors import ModelError

    path = Path(path)
    directory = path.parent if str(path.parent) else Path(".")
    if not directory.is_dir():
        raise ModelError(field, f"directory {str(directory)!r} does not exist")
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=directory)
    except OSError as exc:
        raise ModelError(field, f"cannot write {str(path)!r}: {exc.strerror or exc}") from None
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        write(tmp_path)
        os.chmod(tmp_path, 0o666 & ~_umask())
        os.replace(tmp_path, path)
    except OSError as exc:
        tmp_path.unlink(missing_ok=True)
        raise ModelError(field, f"cannot write {str(path)!r}: {exc.strerror or exc}") from None
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise
    return path


def write_text_atomic(path, text: str, field: str = "out") -> Path:
    return write_atomic(path, lambda p: p.write_text(text, encoding="utf-8"), field)
