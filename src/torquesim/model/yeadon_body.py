"""A built-in model's segments from a subject's own measurements: Yeadon's inertia model.

Yeadon MR (1990) The simulation of aerial movement — II. A mathematical inertia model of the
human body. J Biomech 23:67–74. The `yeadon` package (Dembia, Moore & Hubbard 2014, J Open
Res Softw 2:e4) implements it: 95 lengths, perimeters, widths and depths give 40 solids of
uniform density (Dempster's by default), whose masses, centres of mass and inertias it sums.
torquesim reads a measurement file with it and lumps its solids into the model's segments;
the geometry is not rewritten here.

The lumping, in the package's frame (x lateral, y forwards, z up from the hip joint centres;
arms hanging, feet pointing down along the leg; left and right made alike by default):

- thigh: solids j0–j2, from the hip (length Lj3L, hip to knee);
- shank: j3–j4, from the knee (length Lj5L − Lj3L, knee to ankle);
- foot: j5–j8, from the ankle (length Lj9L, ankle to toe tip);
- upper arm: a0–a1, from the shoulder (La2L); forearm: a2–a3, from the elbow (La4L − La2L);
  hand: a4–a6, from the wrist (La7L);
- head-arms-trunk: segments P, T, C, A1, A2, B1 and B2, from the hip joint centres.

Each part's sagittal inertia is about the lateral axis (x) through its centre of mass; about a
joint it adds m·(d² + e²), d the distance along the segment and e the forward offset.
"""

from __future__ import annotations

import contextlib
import copy
import io
import math
import warnings
from dataclasses import dataclass
from pathlib import Path

from ..errors import ModelError

#: The solids of one side (the left; the package makes the sides alike) lumped into each part.
PART_SOLIDS = {
    "thigh": ("j0", "j1", "j2"),
    "shank": ("j3", "j4"),
    "foot": ("j5", "j6", "j7", "j8"),
    "upper_arm": ("a0", "a1"),
    "forearm": ("a2", "a3"),
    "hand": ("a4", "a5", "a6"),
}
#: Yeadon's segments that make head, arms and trunk.
HEAD_ARMS_TRUNK = ("P", "T", "C", "A1", "A2", "B1", "B2")
#: Lengths measured from one level, in the order they must grow (per side).
ORDERED_LENGTHS = (("Ls1L", "Ls2L", "Ls3L", "Ls4L", "Ls5L"), ("Ls6L", "Ls7L", "Ls8L"),
                   ("La2L", "La3L", "La4L"), ("La5L", "La6L", "La7L"),
                   ("Lb2L", "Lb3L", "Lb4L"), ("Lb5L", "Lb6L", "Lb7L"),
                   ("Lj1L", "Lj3L", "Lj4L", "Lj5L"), ("Lj6L", "Lj8L", "Lj9L"),
                   ("Lk1L", "Lk3L", "Lk4L", "Lk5L"), ("Lk6L", "Lk8L", "Lk9L"))
#: Density sets the package offers.
DENSITY_SETS = ("Dempster", "Chandler", "Clauser")
#: Height of the ankle joint centre above the floor, m, for a standing height estimated from
#: the measurements (they stop at the ankle): est.
ANKLE_HEIGHT = 0.08


@dataclass(frozen=True)
class Part:
    """One lumped part of a measured body (one side for paired parts).

    Attributes
    ----------
    mass : float
        kg.
    length : float
        Between its joint centres (the foot: ankle to toe tip; head-arms-trunk: hip joint
        centres to the top of the head), m.
    com : float
        Centre of mass from its proximal joint along the segment, m.
    offset : float
        Forward offset of the centre of mass from the segment's axis, m.
    inertia : float
        Sagittal moment of inertia about its centre of mass, kg·m².
    """

    mass: float
    length: float
    com: float
    offset: float
    inertia: float

    def inertia_about(self, distance: float) -> float:
        """Sagittal inertia about a point on the axis ``distance`` m from the centre of mass,
        kg·m² (parallel axes, the forward offset included)."""
        return self.inertia + self.mass * (distance ** 2 + self.offset ** 2)


@dataclass(frozen=True)
class MeasuredBody:
    """A subject's body from Yeadon measurements (`read_measurements`).

    Attributes
    ----------
    parts : dict[str, Part]
        ``thigh``, ``shank``, ``foot``, ``upper_arm``, ``forearm``, ``hand`` (one side) and
        ``head_arms_trunk``.
    mass : float
        Whole body, kg.
    height : float
        Standing height estimated as ankle height (`ANKLE_HEIGHT`) + hip to ankle (Lj5L) +
        hip to acromion (Ls5L) + acromion to the top of the head (Ls8L), m.
    source : str
        The file and density set, for the model's notes.
    warnings : tuple[str, ...]
        What the package said of the measurements (e.g. a stadium whose perimeter and width
        do not make one, which it then builds as it can).
    """

    parts: dict
    mass: float
    height: float
    source: str
    warnings: tuple = ()


def read_measurements(path, body_mass: float | None = None,
                      densities: str = "Dempster") -> MeasuredBody:
    """The parts of the body measured in ``path`` (a Yeadon measurement file: ``Ls1L=4.9``
    lines, ``measurementconversionfactor`` into metres; the `yeadon` package's format), its
    densities scaled so the body weighs ``body_mass`` kg when given. A file the package
    refuses is one line naming the file."""
    import numpy as np
    import yeadon

    path = Path(path)
    if not path.is_file():
        raise ModelError("--measurements", f"{path}: no such file; allowed: a Yeadon "
                         "measurement file (95 measurements, yeadon's meastemplate.txt)")
    if densities not in DENSITY_SETS:
        raise ModelError("--densities", f"{densities!r}; allowed: {', '.join(DENSITY_SETS)}")
    _check_file(path, yeadon.Human.measnames)
    try:
        with contextlib.redirect_stdout(io.StringIO()), \
                warnings.catch_warnings(record=True) as said:  # the package prints and warns
            warnings.simplefilter("always")
            human = yeadon.Human(str(path), density_set=densities)
            if body_mass is not None:
                # the package scales its class-wide density table in place: scale a copy
                human.segmental_densities = copy.deepcopy(human.segmental_densities)
                human.scale_human_by_mass(body_mass)
    except Exception as exc:  # noqa: BLE001 (the package raises plain Exceptions)
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ModelError("--measurements", f"{path}: {reason}") from None
    meas = human.meas

    def lumped(names, proximal_z: float, length: float, downwards: bool) -> Part:
        mass, centre, inertia = human.combine_inertia(tuple(names))
        centre = np.asarray(centre, dtype=float).ravel()
        along = proximal_z - centre[2] if downwards else centre[2] - proximal_z
        return Part(float(mass), float(length), float(along), float(centre[1]),
                    float(np.asarray(inertia)[0, 0]))

    knee, ankle = -meas["Lj3L"], -meas["Lj5L"]
    shoulder = meas["Ls4L"]
    elbow, wrist = shoulder - meas["La2L"], shoulder - meas["La4L"]
    parts = {
        "thigh": lumped(PART_SOLIDS["thigh"], 0.0, meas["Lj3L"], True),
        "shank": lumped(PART_SOLIDS["shank"], knee, meas["Lj5L"] - meas["Lj3L"], True),
        "foot": lumped(PART_SOLIDS["foot"], ankle, meas["Lj9L"], True),
        "upper_arm": lumped(PART_SOLIDS["upper_arm"], shoulder, meas["La2L"], True),
        "forearm": lumped(PART_SOLIDS["forearm"], elbow, meas["La4L"] - meas["La2L"], True),
        "hand": lumped(PART_SOLIDS["hand"], wrist, meas["La7L"], True),
        "head_arms_trunk": lumped(HEAD_ARMS_TRUNK, 0.0, meas["Ls5L"] + meas["Ls8L"], False),
    }
    for name, part in parts.items():
        if not (part.mass > 0 and part.length > 0 and math.isfinite(part.inertia)):
            raise ModelError("--measurements", f"{path}: the {name} comes out with mass "
                             f"{part.mass:.3g} kg and length {part.length:.3g} m; allowed: "
                             "positive (check the lengths and their conversion factor)")
    height = ANKLE_HEIGHT + meas["Lj5L"] + meas["Ls5L"] + meas["Ls8L"]
    if not 20.0 <= human.mass <= 250.0 or not 1.0 <= height <= 2.5:
        raise ModelError("--measurements", f"{path}: they make a body of {human.mass:.4g} kg "
                         f"and {height:.4g} m; allowed: 20-250 kg and 1.0-2.5 m (is "
                         "measurementconversionfactor the one into metres: 0.01 for cm?)")
    told = tuple(dict.fromkeys(str(w.message).split(".")[0].strip() for w in said))
    return MeasuredBody(parts, float(human.mass), float(height),
                        f"{path.name} ({densities} densities)", told)


def _check_file(path: Path, names) -> None:
    """One line for a measurement file the package would fail on obscurely: not ``key: value``
    lines, a measurement missing, not a number or not positive."""
    import yaml

    try:
        table = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as exc:
        raise ModelError("--measurements", f"{path}: cannot be read ({type(exc).__name__}); "
                         "allowed: 'Ls1L: 4.9' lines as yeadon's meastemplate.txt") from None
    if not isinstance(table, dict):
        raise ModelError("--measurements", f"{path}: no 'name: value' lines; allowed: "
                         "yeadon's meastemplate.txt format")
    for name in ("measurementconversionfactor", *names):
        value = table.get(name)
        if value is None:
            if name == "measurementconversionfactor":
                continue
            raise ModelError("--measurements", f"{path}: {name} is missing; allowed: all 95 "
                             "measurements of yeadon's meastemplate.txt")
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or not math.isfinite(value) or value <= 0:
            raise ModelError("--measurements", f"{path}: {name} = {value!r}; allowed: a "
                             "positive number")
    for levels in ORDERED_LENGTHS:
        for near, far in zip(levels, levels[1:], strict=False):
            if table[near] >= table[far]:
                raise ModelError("--measurements", f"{path}: {far} = {table[far]!r} is not "
                                 f"beyond {near} = {table[near]!r}; allowed: lengths that grow "
                                 "from the joint they are measured from")
