"""One writer per output folder: a lock file that holds across processes and machines."""

from __future__ import annotations

import os
import socket
from pathlib import Path

from ..errors import ModelError

LOCK_FILE = ".torquesim-fit.lock"


def take_lock(folder, field: str = "--out") -> Path:
    """Create ``folder/.torquesim-fit.lock`` holding this host and process id, or refuse when
    another running process holds it. A lock left by a process of this host that is gone is
    taken over; one held on another host (a Dask worker elsewhere) is respected."""
    lock = Path(folder) / LOCK_FILE
    me = f"{socket.gethostname()} {os.getpid()}"
    for _ in range(2):
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            holder = _read(lock)
            if holder is not None and holder != me:
                raise ModelError(field, f"another torquesim fit (process {holder}) is "
                                 f"writing to {str(folder)!r}; allowed: one fit per directory "
                                 f"at a time (if none is running, delete {str(lock)!r})") \
                    from None
            lock.unlink(missing_ok=True)  # stale: its process is gone
            continue
        with os.fdopen(fd, "w") as fh:
            fh.write(me)
        return lock
    raise ModelError(field, f"cannot take the lock {str(lock)!r}")


def _read(lock: Path) -> str | None:
    """The running holder of ``lock`` ("host pid"), or None when it is stale or unreadable."""
    try:
        text = lock.read_text().split()
    except OSError:
        return None
    if len(text) == 1:  # written by torquesim 0.2: a pid on this host
        text = [socket.gethostname(), text[0]]
    if len(text) != 2 or not text[1].isdigit():
        return None
    host, pid = text[0], int(text[1])
    if host != socket.gethostname():
        return f"{pid} on {host}"
    try:
        os.kill(pid, 0)  # raises if there is no such process
    except ProcessLookupError:
        return None
    except OSError:
        pass  # it exists but belongs to someone else
    return f"{host} {pid}"
