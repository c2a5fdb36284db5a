"""What every file torquesim writes about how it was made (``manifest.json``, the
``.manifest.json`` beside a table, ``fit_summary.json``): one place for the version, the
time and the machine."""

from __future__ import annotations

import os
import platform
from datetime import UTC, datetime


def load_average() -> float | None:
    """The 1-minute load average, or None where the system has none."""
    try:
        return os.getloadavg()[0]
    except (AttributeError, OSError):  # pragma: no cover - not on every platform
        return None


def provenance() -> dict:
    """``torquesim_version``, ``created`` (UTC, ISO 8601) and ``machine`` (Python, platform,
    processor, CPUs and the load average when the file was written)."""
    from .. import __version__

    return {"torquesim_version": __version__,
            "created": datetime.now(UTC).isoformat(timespec="seconds"),
            "machine": {"python": platform.python_version(), "platform": platform.platform(),
                        "processor": platform.machine(), "cpus": os.cpu_count(),
                        "load_average_1min": load_average()}}
