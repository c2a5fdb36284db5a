"""One fingerprint for "is this saved work still valid": a fit checkpoint, a finished sweep
chunk, a finished fit of a batch."""

from __future__ import annotations

import hashlib

import numpy as np


def fingerprint(*parts) -> str:
    """16 hex digits of SHA-256 over ``parts`` in order: bytes as they are, text as UTF-8,
    NumPy arrays by dtype, shape and contents, anything else by its ``repr`` (frozen
    dataclasses, tuples, numbers)."""
    h = hashlib.sha256()
    for part in parts:
        if isinstance(part, bytes):
            data = part
        elif isinstance(part, str):
            data = part.encode()
        elif isinstance(part, np.ndarray):
            data = (f"{part.dtype}{part.shape}".encode()
                    + np.ascontiguousarray(part).tobytes())
        else:
            data = repr(part).encode()
        h.update(len(data).to_bytes(8, "little"))  # parts cannot run into each other
        h.update(data)
    return h.hexdigest()[:16]
