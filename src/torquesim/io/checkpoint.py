"""Checkpoint files of long searches (fits, optimisations): a ``.npz`` of the arrays and a
JSON record of everything else, written atomically, read without unpickling."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ..errors import ModelError
from .atomic import write_atomic


def save_checkpoint(path, state: dict) -> None:
    """Write ``state`` (arrays and JSON-able values) atomically as ``.npz``."""
    def write(tmp: Path) -> None:
        with tmp.open("wb") as fh:
            np.savez(fh, meta=json.dumps({k: v for k, v in state.items()
                                          if not isinstance(v, np.ndarray)}),
                     **{k: v for k, v in state.items() if isinstance(v, np.ndarray)})

    write_atomic(path, write)


def read_checkpoint(path, keys, allowed: str) -> dict:
    """The state `save_checkpoint` wrote to ``path``, which must hold ``keys``. Never
    unpickles; an unreadable, empty, truncated or foreign file is a one-line `ModelError` on
    ``resume`` saying which, ending in ``allowed`` (what the user may give instead)."""
    name = repr(str(path))
    try:
        with open(path, "rb") as fh:
            magic = fh.read(4)
    except OSError as exc:
        raise ModelError("resume", f"cannot read checkpoint {name}: {exc.strerror or exc}") \
            from None
    if magic != b"PK\x03\x04":  # every .npz is a zip archive
        raise ModelError("resume", f"{name} is {'empty' if not magic else 'not a zip file'}: "
                         f"not a torquesim checkpoint; allowed: {allowed}")
    try:
        with np.load(path, allow_pickle=False) as data:
            state = json.loads(str(data["meta"]))
            state.update({k: data[k] for k in data.files if k != "meta"})
    except Exception as exc:  # noqa: BLE001 - zip, npy and JSON damage all mean "corrupt"
        raise ModelError("resume", f"checkpoint {name} is corrupt or not a torquesim "
                         f"checkpoint ({type(exc).__name__}); allowed: {allowed}, or start "
                         "again without --resume") from None
    missing = [k for k in keys if k not in state]
    if missing:
        raise ModelError("resume", f"{name} is not a torquesim checkpoint (no "
                         f"{', '.join(missing[:3])}); allowed: {allowed}")
    return state
