"""Read measured joint angle histories: CSV, or OpenSim storage (.mot/.sto) from inverse
kinematics, one column per coordinate."""

from __future__ import annotations

import csv
import math
from collections.abc import Callable, Collection
from pathlib import Path

import numpy as np

from ..errors import ModelError
from .tables import storage_header

UNITS = ("deg", "rad")
#: Fewest samples a target may have.
MIN_SAMPLES = 5


def manifest_units(path) -> str | None:
    """The angle units of a table torquesim wrote (``save_result``): "rad", read off the
    ``<path>.manifest.json`` beside it (its ``units``; every torquesim table holds radians,
    those written before the key too); None when no torquesim manifest is there."""
    import json

    beside = Path(path).with_name(Path(path).name + ".manifest.json")
    try:
        info = json.loads(beside.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(info, dict) or "torquesim_version" not in info:
        return None
    units = info.get("units", {}).get("angles", "rad") if isinstance(info.get("units"), dict) \
        else "rad"
    return units if units in UNITS else None


def _fail(path: Path, message: str, field: str = "target") -> ModelError:
    return ModelError(field, f"{path.name}: {message}")


def _number(path: Path, text: str, line: int, column: str, field: str = "target") -> float:
    try:
        value = float(text)
    except ValueError:
        raise _fail(path, f"line {line}, column {column!r}: {text.strip()!r} is not a "
                          "number", field) from None
    if not math.isfinite(value):
        raise _fail(path, f"line {line}, column {column!r}: {text.strip()!r} is not finite "
                          "(NaN or inf); allowed: finite numbers", field)
    return value


def read_angle_table(
    path, units: str | None = None,
    columns: Callable[[list[str]], list[str]] | list[str] | None = None,
    raw: Callable[[], Collection[str]] | Collection[str] = (),
    field: str = "target",
) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Time (s) and every angle column (rad) of a CSV or OpenSim ``.mot``/``.sto`` file.

    CSV (comma, semicolon or tab separated; lines starting with ``#`` are comments): a header
    row with ``time`` and angle columns; ``units`` is ``"deg"`` (default) or ``"rad"``; a
    table torquesim wrote is read in the units its manifest gives (`manifest_units`: rad).
    Storage files (OpenSim inverse kinematics): header lines up to ``endheader``, then
    tab/space-separated columns named after the coordinates; ``inDegrees=yes|no`` in the
    header gives the units (an explicit ``units`` that contradicts it is an error; without the
    key ``units`` applies, default degrees). Time must increase strictly; every cell of the
    columns read must be a finite number, and no angle may exceed a full turn (the wrong
    units). ``columns`` limits the columns read (and checked) to those names; it may be a
    function of the angle column names that returns them. Columns named in ``raw`` (or by
    ``raw()``, called after ``columns``) are not angles: they are read as they are (forces in
    N, positions in m), with no unit conversion. Errors name the file, line and column (and
    ``field``, the option the file came from).
    Returns (time, {column name: angle in rad, or the raw column's values}).
    """
    path = Path(path)

    def fail(message: str) -> ModelError:
        return _fail(path, message, field)

    if units is not None and units not in UNITS:
        raise ModelError("units", f"{units!r}; allowed: {', '.join(UNITS)}")
    try:
        lines = path.read_text(encoding="utf-8-sig").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelError(field, f"cannot read {str(path)!r}: "
                         f"{getattr(exc, 'strerror', None) or exc}") from None
    suffix = path.suffix.lower()
    declared = {}
    if suffix in (".mot", ".sto"):
        first, in_degrees, declared = storage_header(lines, fail)
        if in_degrees is not None:
            stated = "deg" if in_degrees else "rad"
            if units is not None and units != stated:
                raise fail(f"header says inDegrees={'yes' if in_degrees else 'no'} "
                                  f"but --angle-units is {units}")
            units = stated
        rows = [(i + 1, line.split()) for i, line in enumerate(lines) if i >= first]
    elif suffix in (".csv", ".txt"):
        if units is None:
            units = manifest_units(path)
        try:
            sample = [line for line in lines if not line.lstrip().startswith("#")][:20]
            dialect = csv.Sniffer().sniff("\n".join(sample), delimiters=",;\t")
        except csv.Error:
            dialect = csv.excel
        rows = [(i + 1, r) for i, r in enumerate(csv.reader(lines, dialect))
                if not (r and r[0].lstrip().startswith("#"))]
    else:
        raise ModelError(field, f"{path.name}: unknown file type {suffix!r}; allowed: "
                         ".csv, .mot, .sto or builtin:curl")
    rows = [(n, r) for n, r in rows if r and any(c.strip() for c in r)]
    if not rows:
        raise fail("is empty")
    header_line, header = rows[0]
    names = [h.strip() for h in header]
    if "time" not in [n.lower() for n in names]:
        raise fail(f"line {header_line}: no 'time' column in the header")
    t_col = [n.lower() for n in names].index("time")
    others = [n for n in names if n.lower() != "time"]
    wanted = others if columns is None else list(columns(others) if callable(columns)
                                                 else columns)
    for name in wanted:
        allowed = ", ".join(n for n in names if n.lower() != "time")
        if name.lower() == "time":
            raise fail(f"column {name!r} is the time, not an angle; allowed: {allowed}")
        if name not in names:
            raise fail(f"no column {name!r}; allowed: {allowed}")
    if not wanted:
        raise fail(f"line {header_line}: no angle column beside 'time'")
    a_cols = [names.index(n) for n in wanted]
    time, angle = [], []
    for line_no, row in rows[1:]:
        if len(row) != len(names):
            raise fail(f"line {line_no}: {len(row)} cells, the header has {len(names)}")
        time.append(_number(path, row[t_col], line_no, names[t_col], field))
        angle.append([_number(path, row[c], line_no, names[c], field) for c in a_cols])
        if len(time) > 1 and time[-1] <= time[-2]:
            raise fail(f"line {line_no}, column {names[t_col]!r}: time "
                              f"{time[-1]!r} does not increase (previous {time[-2]!r})")
    if "nrows" in declared and declared["nrows"] != len(time):
        raise fail(f"header nRows={declared['nrows']} but the file has {len(time)} data "
                          "rows; allowed: a header that matches its data (a truncated file?)")
    if "ncolumns" in declared and declared["ncolumns"] != len(names):
        raise fail(f"header nColumns={declared['ncolumns']} but the data has "
                          f"{len(names)} columns; allowed: a header that matches its data")
    if len(time) < MIN_SAMPLES:
        raise fail(f"{len(time)} samples; allowed at least {MIN_SAMPLES}")
    table = np.array(angle).reshape(len(time), len(a_cols))
    as_is = set(raw() if callable(raw) else raw)
    out = {}
    for i, name in enumerate(wanted):
        if name in as_is:
            out[name] = np.ascontiguousarray(table[:, i])
            continue
        if (units or "deg") == "deg":
            table[:, i] = np.radians(table[:, i])
        worst = float(np.max(np.abs(table[:, i])))
        if worst > 2 * math.pi:
            raise fail(f"column {name!r}: {math.degrees(worst):.4g}° is more than a "
                              "full turn: not a joint angle in these units; allowed |angle| "
                              "≤ 360° (check --angle-units or the file's inDegrees)")
        out[name] = np.ascontiguousarray(table[:, i])
    return np.array(time), out


#: A sampling interval more than this many times the median is a gap in a recording.
MAX_STEP_RATIO = 1.5


def sampling_interval(time: np.ndarray, fail: Callable[[str], ModelError]) -> float:
    """The median interval of a recording's ``time`` (s); a gap (an interval above
    `MAX_STEP_RATIO` times it) raises ``fail(message)`` naming the row."""
    steps = np.diff(time)
    typical = float(np.median(steps))
    gap = int(np.argmax(steps))
    if steps[gap] > MAX_STEP_RATIO * typical:
        raise fail(f"row {gap + 2} (t = {time[gap + 1]:.6g} s), column 'time': a gap of "
                   f"{steps[gap]:.4g} s where the sampling interval is {typical:.4g} s; "
                   "allowed: uniform sampling (interpolate the gap or cut the recording)")
    return typical


def longest_run(mask: np.ndarray) -> tuple[int, int]:
    """(start, stop) of the longest run of True in ``mask`` (the first of equal ones; (0, 0)
    if none): a recording's constant-speed phase, a force file's flight."""
    edges = np.diff(np.concatenate([[0], np.asarray(mask, dtype=np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    if starts.size == 0:
        return 0, 0
    k = int(np.argmax(stops - starts))
    return int(starts[k]), int(stops[k])
