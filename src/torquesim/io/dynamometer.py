"""Read isovelocity dynamometer trials: one file per trial (CSV or OpenSim ``.sto``/``.mot``)
with time, crank angle, angular velocity (optional) and torque.

The angle is the model's joint angle (its zero and sign, e.g. ``knee_angle`` of
``builtin:knee-extension``: 0 = straight, positive = flexed), in degrees unless the file says
otherwise (``inDegrees=no``, or ``--angle-units rad``); the velocity is in the same unit per
second. The torque is in N·m, positive towards increasing joint angle (``torque_sign="joint"``)
or positive in the unit's own direction (``"unit"``, as many dynamometers export a magnitude).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ModelError
from .target_file import read_angle_table, sampling_interval

#: Column names a trial file uses (any case); ``velocity`` may be left out.
TRIAL_COLUMNS = ("angle", "velocity", "torque")
TORQUE_SIGNS = ("joint", "unit")
#: Fewest samples of a trial, and its shortest duration (s).
MIN_TRIAL_SAMPLES = 10
MIN_TRIAL_DURATION = 0.1
#: Largest joint angular speed accepted, rad/s (≈ 2300 °/s, beyond any human joint and any
#: dynamometer: a larger one is a unit mistake).
MAX_SPEED = 40.0
#: Largest torque accepted, N·m (a larger one is a unit mistake, e.g. N·cm).
MAX_TORQUE = 5000.0


@dataclass(frozen=True)
class DynamometerTrial:
    """One dynamometer trial as read.

    Attributes
    ----------
    name : str
        The file's name (errors and tables name the trial by it).
    time : ndarray
        s, strictly increasing, uniformly sampled.
    angle : ndarray
        Joint angle, rad (the model's convention).
    velocity : ndarray
        Joint angular velocity, rad/s: the file's column, or the derivative of the angle when
        the file has none (``velocity_measured`` False).
    torque : ndarray
        Measured crank torque, N·m, positive towards increasing joint angle.
    velocity_measured : bool
    """

    name: str
    time: np.ndarray
    angle: np.ndarray
    velocity: np.ndarray
    torque: np.ndarray
    velocity_measured: bool

    def row(self, index: int) -> str:
        """``row N (t = … s)``: where sample ``index`` is (data rows counted from 1)."""
        return f"row {index + 1} (t = {self.time[index]:.4g} s)"


def _storage_units(path: Path, units: str | None, field: str) -> str:
    """The angle units in force for ``path``: a storage file's ``inDegrees``, else ``units``,
    else degrees (read_angle_table has already refused a contradiction)."""
    if path.suffix.lower() in (".sto", ".mot"):
        for line in path.read_text(encoding="utf-8-sig").splitlines():
            key = line.strip().lower().replace(" ", "")
            if key.startswith("indegrees="):
                return "deg" if key.endswith("yes") else "rad"
            if key == "endheader":
                break
    return units or "deg"


def read_trial(path, units: str | None = None, torque_sign: str = "joint", direction: int = 1,
               field: str = "trials") -> DynamometerTrial:
    """Read one trial file (see the module's docstring for its columns and conventions).

    ``direction`` is the unit's (+1 pulls towards increasing angle, −1 towards decreasing);
    with ``torque_sign="unit"`` the torque column is multiplied by it. Errors name ``field``,
    the file, and the row and column at fault: a missing column, a cell that is not a finite
    number, time that does not increase, a gap in the sampling, too few samples, an angle
    beyond a full turn, a speed above 40 rad/s or a torque above 5000 N·m in magnitude.
    """
    path = Path(path)
    if torque_sign not in TORQUE_SIGNS:
        raise ModelError("torque_sign", f"{torque_sign!r}; allowed: {', '.join(TORQUE_SIGNS)}")

    def fail(message: str) -> ModelError:
        return ModelError(field, f"{path.name}: {message}")

    found: dict[str, str] = {}

    def pick(names: list[str]) -> list[str]:
        lower = {n.lower(): n for n in names}
        for wanted in TRIAL_COLUMNS:
            if wanted in lower:
                found[wanted] = lower[wanted]
            elif wanted != "velocity":
                raise fail(f"no {wanted!r} column; allowed: a header naming time, angle, "
                           f"torque and optionally velocity (found {', '.join(names)})")
        return list(found.values())

    time, columns = read_angle_table(path, units, columns=pick, raw=lambda: found.values(),
                                     field=field)
    units = _storage_units(path, units, field)
    to_rad = math.pi / 180.0 if units == "deg" else 1.0
    angle = columns[found["angle"]] * to_rad
    torque = columns[found["torque"]] * (direction if torque_sign == "unit" else 1.0)
    if time.size < MIN_TRIAL_SAMPLES or time[-1] - time[0] < MIN_TRIAL_DURATION:
        raise fail(f"{time.size} samples over {time[-1] - time[0]:.4g} s; allowed: at least "
                   f"{MIN_TRIAL_SAMPLES} samples over at least {MIN_TRIAL_DURATION} s")
    sampling_interval(time, fail)
    trial_rows = DynamometerTrial(path.name, time, angle, angle, torque, False)
    worst = int(np.argmax(np.abs(angle)))
    if abs(angle[worst]) > 2.0 * math.pi:
        raise fail(f"{trial_rows.row(worst)}, column {found['angle']!r}: "
                   f"{math.degrees(angle[worst]):.4g}° is more than a full turn; allowed "
                   "|angle| ≤ 360° (check --angle-units or the file's inDegrees)")
    worst = int(np.argmax(np.abs(torque)))
    if abs(torque[worst]) > MAX_TORQUE:
        raise fail(f"{trial_rows.row(worst)}, column {found['torque']!r}: {torque[worst]:.6g} "
                   f"N·m; allowed |torque| ≤ {MAX_TORQUE:g} N·m (the column must be in N·m)")
    if "velocity" in found:
        velocity = columns[found["velocity"]] * to_rad
        measured = True
    else:
        velocity = np.gradient(angle, time)
        measured = False
    worst = int(np.argmax(np.abs(velocity)))
    if abs(velocity[worst]) > MAX_SPEED:
        where = f"column {found['velocity']!r}" if measured else "the angle's derivative"
        raise fail(f"{trial_rows.row(worst)}, {where}: {math.degrees(velocity[worst]):.6g} °/s; "
                   f"allowed |velocity| ≤ {math.degrees(MAX_SPEED):.0f} °/s "
                   f"({MAX_SPEED:g} rad/s)")
    return DynamometerTrial(path.name, time, angle, velocity, torque, measured)


def write_trial(trial: DynamometerTrial, path, field: str = "out") -> Path:
    """Write ``trial`` as a lab would export it (CSV, or OpenSim storage with
    ``inDegrees=yes``): time (s, 5 decimals), angle (°) and velocity (°/s) to 3 decimals,
    torque (N·m, positive towards increasing joint angle) to 3 decimals, atomically."""
    from .tables import write_table

    return write_table(path, {"time": np.round(trial.time, 5),
                              "angle": np.round(np.degrees(trial.angle), 3),
                              "velocity": np.round(np.degrees(trial.velocity), 3),
                              "torque": np.round(trial.torque, 3)},
                       name=trial.name, in_degrees=True, field=field)
