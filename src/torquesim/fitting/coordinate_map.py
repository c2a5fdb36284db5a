"""From a 3D inverse-kinematics file to a planar model's joint angles: a coordinate map.

Each planar joint's angle is a linear combination of the file's coordinates plus an offset,
written as an expression in degrees, e.g. ``"-knee_angle_r"``, ``"118.1 - ankle_angle_r"``,
``"pelvis_tilt + hip_flexion_r + knee_angle_r + ankle_angle_r + 61.9"`` (a term is
``[number*]column`` or a number; the columns are read in degrees, the numbers are degrees).
A map comes from ``--column JOINT=EXPRESSION``, from a TOML file's ``[targets.map]`` table, or
by name for the common OpenSim full-body models (`DEFAULT_MAPS`).

The default maps (docs/opensim.md draws the conventions) are for the squat jump's joints
(root ``foot_ground``, then ``ankle``, ``knee``, ``hip``; each the counterclockwise angle of a
segment from its parent's, facing +x) and the right leg of an OpenSim model (rotations about
+z, counterclockwise facing +x): the absolute angle of the shank (ankle → knee) is
180° + pelvis_tilt + hip_flexion_r + knee_z, of the thigh (knee → hip) 180° + pelvis_tilt
+ hip_flexion_r, of the trunk 180° + pelvis_tilt + lumbar_extension, of the foot axis
(ankle → toe) pelvis_tilt + hip_flexion_r + knee_z + ankle_angle_r + φ_foot, where knee_z is
``knee_angle_r`` in gait2392 (flexion negative) and ``−knee_angle_r`` in Rajagopal et al.
(2016) (flexion positive), and φ_foot the foot axis's angle from hanging down with the ankle
at 0° (the model's standing foot: 61.9° for the squat jump).
"""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path

from ..errors import ModelError

_NUMBER = r"(?:\d+(?:\.\d*)?|\.\d+)"
_TERM = rf"(?:{_NUMBER}\s*\*\s*)?[A-Za-z_]\w*|{_NUMBER}"
_EXPRESSION = re.compile(rf"\s*[+-]?\s*(?:{_TERM})(?:\s*[+-]\s*(?:{_TERM}))*\s*")
_SIGNED_TERM = re.compile(rf"([+-]?)\s*(?:({_NUMBER})\s*\*\s*)?([A-Za-z_]\w*)|([+-]?)\s*"
                          rf"({_NUMBER})")


def parse_expression(text: str, field: str) -> tuple[dict[str, float], float]:
    """``({column: coefficient}, offset in degrees)`` of a map expression: terms
    ``[NUMBER*]COLUMN`` or ``NUMBER`` joined by ``+`` and ``-``; an error naming ``field`` for
    anything else."""
    if not _EXPRESSION.fullmatch(text):
        raise ModelError(field, f"{text!r}: allowed [NUMBER*]COLUMN or NUMBER terms joined by "
                         "+ and -, e.g. -knee_angle_r or 118 - ankle_angle_r")
    coefficients: dict[str, float] = {}
    offset = 0.0
    for m in _SIGNED_TERM.finditer(text):
        if m.group(3):
            factor = (-1.0 if m.group(1) == "-" else 1.0) * float(m.group(2) or 1)
            coefficients[m.group(3)] = coefficients.get(m.group(3), 0.0) + factor
        else:
            offset += (-1.0 if m.group(4) == "-" else 1.0) * float(m.group(5))
    return coefficients, offset


def is_expression(text: str) -> bool:
    """Whether a ``--column`` value is an expression rather than a plain column name."""
    return bool(re.search(r"[+*]|^\s*-|\s-\s|\d\s*$", text)) and not re.fullmatch(r"\w+", text)


def _squat_jump_map(knee_sign: float, foot_deg: float) -> dict[str, str]:
    knee = "+ knee_angle_r" if knee_sign > 0 else "- knee_angle_r"
    return {
        "foot_ground": f"pelvis_tilt + hip_flexion_r {knee} + ankle_angle_r + {foot_deg:.10g}",
        "ankle": f"{180.0 - foot_deg:.10g} - ankle_angle_r",
        "knee": f"{'-' if knee_sign > 0 else ''}knee_angle_r",
        "hip": "lumbar_extension - hip_flexion_r",
    }


#: Columns a default map reads as 0 when the file has none (a model without a lumbar joint).
OPTIONAL_COLUMNS = ("lumbar_extension",)
#: The OpenSim models a default map exists for, and the sign of their knee coordinate as a
#: rotation about +z (gait2392: flexion negative; Rajagopal et al. 2016: flexion positive).
DEFAULT_MAPS = {"gait2392": 1.0, "rajagopal2016": -1.0}


def default_map(name: str, chain) -> dict[str, str]:
    """The map ``name`` (`DEFAULT_MAPS`) for ``chain``: a model with the squat jump's joints
    (foot_ground, ankle, knee, hip), its φ_foot the root joint's initial angle (the standing
    foot)."""
    if name not in DEFAULT_MAPS:
        raise ModelError("--map", f"{name!r}; allowed: {', '.join(DEFAULT_MAPS)} or a .toml "
                         "file with a [targets.map] table")
    joints = [j.name for j in chain.joints]
    if joints[:4] != ["foot_ground", "ankle", "knee", "hip"]:
        raise ModelError("--map", f"the {name} map is for the squat jump's joints "
                         f"(foot_ground, ankle, knee, hip); {chain.name!r} has "
                         f"{', '.join(joints)}; allowed: --column JOINT=EXPRESSION per joint")
    foot = math.degrees(chain.joints[0].initial_angle)
    return _squat_jump_map(DEFAULT_MAPS[name], foot)


def map_file(path) -> dict[str, str]:
    """The ``[targets.map]`` table of a TOML file: joint = "expression"."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise ModelError("--map", f"{path.name}: {exc}") from None
    table = data.get("targets", {}).get("map") if isinstance(data.get("targets"), dict) \
        else None
    if not isinstance(table, dict) or not table or not all(
            isinstance(v, str) for v in table.values()):
        raise ModelError("--map", f"{path.name}: no [targets.map] table of joint = "
                         "\"expression\" strings")
    return dict(table)
