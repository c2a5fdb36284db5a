"""Result tables: CSV and OpenSim storage (.sto/.mot), plus a JSON manifest beside them."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

from ..errors import ModelError
from .atomic import write_atomic, write_text_atomic
from .provenance import provenance

TABLE_SUFFIXES = (".csv", ".sto", ".mot")


def table_kind(path, field: str = "out") -> str:
    """``"csv"`` or ``"sto"`` from the file name; anything else is an error."""
    suffix = Path(path).suffix.lower()
    if suffix not in TABLE_SUFFIXES:
        raise ModelError(field, f"{str(path)!r}: unknown extension; allowed "
                         f"{', '.join(TABLE_SUFFIXES)}")
    return "csv" if suffix == ".csv" else "sto"


def _write_csv(tmp: Path, columns: dict[str, np.ndarray]) -> None:
    data = np.column_stack(list(columns.values()))
    with tmp.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(columns.keys())
        writer.writerows([repr(float(x)) for x in row] for row in data)


def _write_sto(tmp: Path, columns: dict[str, np.ndarray], name: str,
               in_degrees: bool) -> None:
    data = np.column_stack(list(columns.values()))
    with tmp.open("w", encoding="utf-8") as fh:
        fh.write(f"{name}\nversion=1\nnRows={data.shape[0]}\nnColumns={data.shape[1]}\n")
        fh.write(f"inDegrees={'yes' if in_degrees else 'no'}\nendheader\n")
        fh.write("\t".join(columns.keys()) + "\n")
        for row in data:
            fh.write("\t".join(repr(float(x)) for x in row) + "\n")


def write_table(path, columns: dict[str, np.ndarray], *, name: str = "torquesim",
                in_degrees: bool = False, field: str = "out") -> Path:
    """Write columns (first one ``time``) as CSV or OpenSim storage, atomically."""
    kind = table_kind(path, field)
    if kind == "csv":
        return write_atomic(path, lambda tmp: _write_csv(tmp, columns), field)
    return write_atomic(path, lambda tmp: _write_sto(tmp, columns, name, in_degrees), field)


def save_ground_reactions(result, path, field: str = "--grf") -> Path:
    """Write a run's ground reaction forces as an OpenSim external-loads data file (.mot,
    forces in N, points in m, y up, z = 0 in the sagittal plane): the total as
    ``ground_force_v{x,y,z}`` at the centre of pressure ``ground_force_p{x,y,z}`` (0 in
    flight) with ``ground_torque_{x,y,z}`` = 0, and each contact as ``<point>_ground_force_*``
    at its point, so that an ExternalLoads file can reference either."""
    if not result.model.contacts:
        raise ModelError(field, f"{result.model.name} has no ground contacts; allowed: a "
                         "model with [[contacts]]")
    if table_kind(path, field) != "sto" or not str(path).endswith(".mot"):
        raise ModelError(field, f"{str(path)!r}: allowed a .mot file")
    c = result.columns()
    zero = np.zeros_like(result.time)
    columns = {"time": result.time}

    def force(prefix, fx, fy, px, py):
        columns.update({f"{prefix}ground_force_vx": fx, f"{prefix}ground_force_vy": fy,
                        f"{prefix}ground_force_vz": zero, f"{prefix}ground_force_px": px,
                        f"{prefix}ground_force_py": py, f"{prefix}ground_force_pz": zero})

    force("", c["grf_x"], c["grf_y"], np.nan_to_num(c["cop_x"]), zero)
    columns.update({"ground_torque_x": zero, "ground_torque_y": zero, "ground_torque_z": zero})
    for contact in result.model.contacts:
        name = contact.point
        force(f"{name}_", c[f"grf_x_{name}"], c[f"grf_y_{name}"], c[f"{name}_x"],
              c[f"{name}_y"])
    return write_table(path, columns, name=f"{result.model.name}_grf", field=field)


def csv_cell(value) -> str:
    """One CSV cell: empty for None, floats in full precision (``repr``), tuples joined by
    ``;``, anything else as ``str``."""
    if value is None:
        return ""
    if isinstance(value, float | np.floating):
        return repr(float(value))
    if isinstance(value, tuple):
        return ";".join(repr(v) for v in value)
    return str(value)


def write_rows(path, rows, columns, field: str = "out") -> Path:
    """Write rows (dicts, or sequences in ``columns`` order) as a CSV table with ``columns``
    as its header (cells by `csv_cell`), atomically: every table of records torquesim writes
    (study results and verdict, the sensitivity summary, batch tables, rank correlations)
    goes through here."""
    columns = list(columns)
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(columns)
    for r in rows:
        cells = [r.get(c) for c in columns] if isinstance(r, dict) else list(r)
        writer.writerow([csv_cell(v) for v in cells])
    return write_text_atomic(path, buf.getvalue(), field)


def manifest(result, **extra) -> dict:
    """What is needed to repeat a run: version, model, method, settings, machine."""
    from .model_file import model_to_toml

    stability = result.stability
    return {
        **provenance(),
        "units": {"time": "s", "angles": "rad", "angular_speeds": "rad/s",
                  "torques": "N·m", "forces": "N", "positions": "m"},
        "method": result.method,
        "step_s": result.step,
        "settings": result.settings,
        "status": result.status,
        "message": result.message,
        "cost": {"steps": result.cost.steps, "rhs_body": result.cost.rhs_body,
                 "rhs_muscle": result.cost.rhs_muscle, "wall_time_s": result.cost.wall_time},
        "stability": None if stability is None else {
            "max_step_over_tau": stability.max_step_ratio, "at_time_s": stability.time,
            "unit": stability.unit, "exceeded": stability.exceeded,
            "largest_safe_step_s": stability.largest_safe_step},
        "model_toml": model_to_toml(result.model),
        **extra,
    }


def save_result(result, path, field: str = "path") -> Path:
    """Write a result table (CSV or .sto by extension) and ``<path>.manifest.json``: both or
    neither (a manifest that cannot be written removes the table)."""
    if not all(hasattr(result, name) for name in ("columns", "method", "states", "model")):
        raise TypeError(f"result: expected a torquesim SimulationResult (from simulate), got "
                        f"{type(result).__name__}")
    if not isinstance(path, str | Path):
        raise TypeError(f"path: expected a file name, got {type(path).__name__}")
    path = Path(path)
    table_kind(path, field)
    info = manifest(result)
    existed = path.exists()
    write_table(path, result.columns(), name=f"torquesim {result.method}", field=field)
    try:
        write_text_atomic(path.with_name(path.name + ".manifest.json"),
                          json.dumps(info, indent=2, default=float) + "\n", field)
    except BaseException:
        if not existed:
            path.unlink(missing_ok=True)
        raise
    return path


def storage_header(lines: list[str], fail) -> tuple[int, bool | None, dict[str, int]]:
    """The header of an OpenSim storage file (``.sto``/``.mot``) given as ``lines``: (index of
    the first line after ``endheader``, ``inDegrees`` as True/False or None when absent, the
    declared ``nRows``/``nColumns``). ``fail(message)`` makes the exception raised for a bad
    header (no ``endheader``, an ``inDegrees`` other than yes/no, a count that is not a whole
    number)."""
    in_degrees = None
    declared: dict[str, int] = {}
    for i, line in enumerate(lines):
        key = line.strip().lower().replace(" ", "")
        if key.startswith("indegrees="):
            value = key.split("=", 1)[1]
            if value not in ("yes", "no"):
                raise fail(f"line {i + 1}: inDegrees={value!r}; allowed yes or no")
            in_degrees = value == "yes"
        for field in ("nrows", "ncolumns"):
            if key.startswith(field + "="):
                try:
                    declared[field] = int(key.split("=", 1)[1])
                except ValueError:
                    raise fail(f"line {i + 1}: {line.strip()!r} is not a whole "
                               "number") from None
        if key == "endheader":
            return i + 1, in_degrees, declared
    raise fail("no 'endheader' line; allowed: an OpenSim storage file")


def read_table(path) -> dict[str, np.ndarray]:
    """Read a CSV or OpenSim storage file written by torquesim (or any numeric table with a
    header row) into columns. For .sto/.mot, ``inDegrees`` is returned under ``"_in_degrees"``
    as a 0-d boolean array when present."""
    if not isinstance(path, str | Path):
        raise TypeError(f"path: expected a file name, got {type(path).__name__}")
    path = Path(path)
    kind = table_kind(path, "path")
    try:
        lines = path.read_text(encoding="utf-8-sig").splitlines()
    except OSError as exc:
        raise ModelError("path", f"cannot read {str(path)!r}: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise ModelError("path", f"{str(path)!r} is not UTF-8 text; allowed: a CSV or .sto "
                         "table") from None
    in_degrees = None
    if kind == "sto":
        start, in_degrees, _ = storage_header(
            lines, lambda message: ModelError("path", f"{str(path)!r}: {message}"))
        rows = [line.split() for line in lines[start:] if line.strip()]
    else:
        rows = list(csv.reader(lines))
    if not rows:
        raise ModelError("path", f"{str(path)!r} has no header row; allowed: a table with "
                         "named columns")
    header, body = rows[0], rows[1:]
    try:
        data = np.array(body, dtype=float).reshape(len(body), len(header))
    except ValueError:
        raise ModelError("path", f"{str(path)!r}: every row must hold {len(header)} numbers "
                         "(one per header name)") from None
    out = {name.strip(): data[:, j] for j, name in enumerate(header)}
    if in_degrees is not None:
        out["_in_degrees"] = np.array(in_degrees)
    return out
