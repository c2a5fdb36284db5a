"""Ground reaction forces from a lab's force-plate file, made into a fit's target channels.

A file (OpenSim external-loads ``.mot``/``.sto``, or CSV) holds one or more plates, each as
columns ``<prefix>ground_force_vx|vy|vz`` (N) and optionally ``<prefix>ground_force_px|py|pz``
(centre of pressure, m): ``ground_force_vy``, ``1_ground_force_vy``, ``r_ground_force_vy`` …
(OpenSim's names; y up, x forwards). A C3D file's force platforms are read through ``ezc3d``
(`read_c3d_plates`: its forces and centres of pressure in the lab's frame, whose forward and up
axes the user states). `plate_totals` sums the plates per component and combines
their centres of pressure (weighted by each plate's vertical force); `low_pass` filters with a
zero-lag Butterworth filter; `grf_channels` puts it all onto a target's times.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import signal

from ..errors import ModelError, check_range
from .target_file import longest_run, read_angle_table, sampling_interval

_FORCE = re.compile(r"^(.*?)ground_force_([vp])([xyz])$", re.IGNORECASE)
#: Default cut-off of the low-pass filter, Hz (jump GRF is commonly filtered at 50–100 Hz).
DEFAULT_CUTOFF = 50.0
#: Quiet standing: the first `STANDING_WINDOW` s, if the vertical force's standard deviation
#: there is below `STANDING_STEADINESS` of its mean.
STANDING_WINDOW = 0.2
STANDING_STEADINESS = 0.02
#: Flight: the vertical force below this fraction of body weight for at least `FLIGHT_MIN` s;
#: there a zeroed plate reads 0 within `ZERO_TOLERANCE` of body weight.
FLIGHT_LEVEL = 0.05
FLIGHT_MIN = 0.05
ZERO_TOLERANCE = 0.01
GRAVITY = 9.81


@dataclass(frozen=True)
class PlateTotals:
    """The plates of a force file summed: time (s), force components (N), centre of pressure
    along x (m, NaN where the vertical force is below 20 N), sampling rate (Hz), plates'
    prefixes, and what was done to read it (``note``, "" if nothing)."""

    name: str
    time: np.ndarray
    force_x: np.ndarray
    force_y: np.ndarray
    cop_x: np.ndarray
    rate: float
    plates: tuple[str, ...]
    note: str = ""


def read_plates(path, field: str = "--forces", axes: str = "x,z") -> PlateTotals:
    """Read a force file and sum its plates (see the module's docstring). Errors name
    ``field``, the file, and the row and column at fault: no force columns, a cell that is not
    a finite number, time that does not increase (a duplicated time too), a gap in the
    sampling. A ``.c3d`` file goes to `read_c3d_plates` with ``axes``."""
    path = Path(path)
    if path.suffix.lower() == ".c3d":
        return read_c3d_plates(path, axes, field)
    plates: dict[str, dict[str, str]] = {}

    def pick(names: list[str]) -> list[str]:
        for name in names:
            m = _FORCE.match(name)
            if m:
                plates.setdefault(m.group(1), {})[m.group(2).lower() + m.group(3).lower()] = name
        complete = {p: c for p, c in plates.items() if "vy" in c and "vx" in c}
        if not complete:
            raise ModelError(field, f"{path.name}: no force columns; allowed: "
                             "<plate>ground_force_vx and _vy (N) per plate, OpenSim's names "
                             "(e.g. ground_force_vy, 1_ground_force_vy)")
        plates.clear()
        plates.update(complete)
        return [c for p in complete.values() for c in p.values()]

    time, columns = read_angle_table(path, None, columns=pick,
                                     raw=lambda: [c for p in plates.values() for c in p.values()],
                                     field=field)
    typical = sampling_interval(time, lambda message: ModelError(field,
                                                                f"{path.name}: {message}"))
    note = ""
    total = _total_plate(plates, columns)
    if total is not None:  # a total beside its parts (torquesim's own --grf file): not summed
        parts = [p for p in plates if p != total]
        note = (f"its {total or 'unprefixed '}ground_force columns are the sum of the others' "
                f"({', '.join(parts)}): read alone")
        plates = {total: plates[total]}
    fx = sum(columns[c["vx"]] for c in plates.values())
    fy = sum(columns[c["vy"]] for c in plates.values())
    moment = np.zeros_like(time)
    for c in plates.values():
        if "px" in c:
            moment += columns[c["vy"]] * columns[c["px"]]
    with np.errstate(invalid="ignore", divide="ignore"):
        cop = np.where(fy > 20.0, moment / np.where(fy > 20.0, fy, 1.0), np.nan)
    return PlateTotals(path.name, time, fx, fy, cop, 1.0 / typical, tuple(plates), note)


def _total_plate(plates: dict[str, dict[str, str]], columns) -> str | None:
    """The prefix of a plate whose horizontal and vertical forces are, at every row, the sum
    of all the other plates' (to 1e-6 of the largest force): a total written beside its parts,
    as torquesim's ``simulate --grf`` writes the contacts' (summing all would count every
    force twice). None if there is none, and with fewer than three plates (two plates that
    read alike are two plates, not a total and its only part)."""
    if len(plates) < 3:
        return None
    scale = max(float(np.max(np.abs(columns[c["vy"]]))) for c in plates.values())
    for prefix, own in plates.items():
        others = [c for p, c in plates.items() if p != prefix]
        if all(np.allclose(columns[own[k]], sum(columns[c[k]] for c in others), rtol=0.0,
                           atol=1e-6 * scale + 1e-9) for k in ("vx", "vy")):
            return prefix
    return None


#: Length units a C3D file may give its positions in, in metres.
_LENGTH_UNITS = {"mm": 1e-3, "cm": 1e-2, "m": 1.0}


def lab_axes(text: str, field: str = "--lab-axes") -> tuple[tuple[int, float], tuple[int, float]]:
    """The lab frame's forward and up axes as given, e.g. ``x,z`` or ``-y,z``: ((axis index,
    sign) forward, (axis index, sign) up)."""
    parts = [p.strip().lower() for p in str(text).split(",")]
    out = []
    for part in parts:
        sign = -1.0 if part.startswith("-") else 1.0
        axis = part.lstrip("+-")
        if axis not in ("x", "y", "z"):
            out = []
            break
        out.append(("xyz".index(axis), sign))
    if len(parts) != 2 or len(out) != 2 or out[0][0] == out[1][0]:
        raise ModelError(field, f"{text!r}; allowed: the lab's forward and up axes, two of "
                         "x, y, z with an optional minus, e.g. x,z or -y,z")
    return out[0], out[1]


def read_c3d_plates(path, axes: str = "x,z", field: str = "--forces") -> PlateTotals:
    """The force platforms of a C3D file (through ``ezc3d``, which applies each platform's
    calibration, corners and origin), summed in the lab's frame: ``axes`` says which lab axis
    points forwards and which up (`lab_axes`). Times from the first frame at the analog rate;
    centres of pressure in the file's POINT units. A file whose vertical force is mostly
    negative gives the force on the plates, not on the body: it is turned (said in
    ``plates``). No platform, no ``ezc3d``, or an unreadable file: one line."""
    path = Path(path)
    (forward, f_sign), (up, u_sign) = lab_axes(axes)
    try:
        import ezc3d
    except ImportError:
        raise ModelError(field, f"{path.name}: reading C3D needs the ezc3d package; allowed: "
                         "pip install ezc3d (or torquesim[c3d]), or an OpenSim .mot") from None
    if not path.is_file():
        raise ModelError(field, f"{path}: no such file")
    try:
        c3d = ezc3d.c3d(str(path), extract_forceplat_data=True)
    except Exception as exc:  # noqa: BLE001 (ezc3d raises RuntimeError/ValueError alike)
        raise ModelError(field, f"{path.name}: not a readable C3D file with force platforms "
                         f"({str(exc).strip().splitlines()[0] if str(exc).strip() else exc})"
                         ) from None
    platforms = list(c3d["data"]["platform"])
    if not platforms:
        raise ModelError(field, f"{path.name}: no force platform (FORCE_PLATFORM:USED is 0); "
                         "allowed: a C3D file with force platforms")
    header = c3d["header"]
    rate = float(header["analogs"]["frame_rate"])
    start = float(header["points"]["first_frame"]) / float(header["points"]["frame_rate"])
    frames = platforms[0]["force"].shape[1]
    time = start + np.arange(frames) / rate
    fx = np.zeros(frames)
    fy = np.zeros(frames)
    moment = np.zeros(frames)
    for k, plate in enumerate(platforms):
        if plate["force"].shape[1] != frames:
            raise ModelError(field, f"{path.name}: platform {k + 1} has "
                             f"{plate['force'].shape[1]} frames, platform 1 {frames}")
        scale = _LENGTH_UNITS.get(str(plate["unit_position"]).strip().lower())
        if scale is None:
            raise ModelError(field, f"{path.name}: platform {k + 1}'s positions are in "
                             f"{plate['unit_position']!r}; allowed: mm, cm, m")
        force = np.asarray(plate["force"], dtype=float)
        if str(plate["unit_force"]).strip().lower() == "kn":
            force = force * 1e3
        vertical = u_sign * force[up]
        fx += f_sign * force[forward]
        fy += vertical
        moment += vertical * f_sign * scale * np.asarray(plate["center_of_pressure"][forward],
                                                         dtype=float)
    bad = np.flatnonzero(~np.isfinite(fx + fy))
    if bad.size:
        raise ModelError(field, f"{path.name}: frame {int(bad[0]) + 1} holds a force that is "
                         "not a finite number")
    names = tuple(f"platform {k + 1}" for k in range(len(platforms)))
    note = f"lab axes {axes} (forwards, up)"
    if np.median(fy[np.abs(fy) > 0.05 * np.abs(fy).max()]) < 0:
        fx, fy, moment = -fx, -fy, -moment  # the plates' reading: the force on them
        note += "; the file gives the force on the plates, turned into the force on the body"
    with np.errstate(invalid="ignore", divide="ignore"):
        cop = np.where(fy > 20.0, moment / np.where(fy > 20.0, fy, 1.0), np.nan)
    return PlateTotals(path.name, time, fx, fy, cop, rate, names, note)


def low_pass(values: np.ndarray, rate: float, cutoff: float) -> np.ndarray:
    """Zero-lag low-pass: a 2nd-order Butterworth run forwards and backwards
    (`scipy.signal.filtfilt`, 4th order in effect, no phase shift), cut-off ``cutoff`` Hz at a
    sampling ``rate`` Hz (the cut-off of the single pass). Its gain at 0 Hz is 1, so the
    impulse of a record whose ends are steady is kept (tests/test_force_plates.py measures
    it)."""
    check_range("--grf-cutoff", cutoff, 0.0, 0.5 * rate, low_open=True, high_open=True,
                unit=f"Hz (below half the force file's {rate:.4g} Hz sampling rate)")
    b, a = signal.butter(2, cutoff / (0.5 * rate))
    return signal.filtfilt(b, a, values)


def standing_body_mass(totals: PlateTotals) -> float:
    """Body mass (kg) from the quiet standing at the file's start: the mean vertical force
    over its first `STANDING_WINDOW` s over g. An error if the force there is not steady."""
    window = totals.force_y[totals.time <= totals.time[0] + STANDING_WINDOW]
    mean = float(np.mean(window))
    if mean <= 0.0 or float(np.std(window)) > STANDING_STEADINESS * mean:
        raise ModelError("--forces", f"{totals.name}: the first {STANDING_WINDOW:g} s are not "
                         f"quiet standing (vertical force {mean:.4g} ± {np.std(window):.3g} N); "
                         "allowed: a recording that starts standing still, or the model's "
                         "body mass given (torquesim model --body-mass)")
    return mean / GRAVITY


def check_zero_offset(totals: PlateTotals, weight: float, rezero: bool) -> tuple[PlateTotals,
                                                                                  str | None]:
    """Check that the plates read zero in flight (the vertical force below 5 % of body weight
    for at least 50 ms). A flight mean beyond 1 % of body weight is a drifting zero offset: an
    error naming the rows, or with ``rezero`` the flight mean subtracted from the whole
    recording, and said (the returned message)."""
    start, stop = longest_run(totals.force_y < FLIGHT_LEVEL * weight)
    if stop == start or totals.time[stop - 1] - totals.time[start] < FLIGHT_MIN:
        return totals, None
    offset = float(np.mean(totals.force_y[start:stop]))
    if abs(offset) <= ZERO_TOLERANCE * weight:
        return totals, None
    rows = f"rows {start + 1}-{stop} (t = {totals.time[start]:.4g}-{totals.time[stop - 1]:.4g} s)"
    if not rezero:
        raise ModelError("--forces", f"{totals.name}: {rows}, vertical force: in flight the "
                         f"plates read {offset:.4g} N, not 0 (a drifting zero offset); "
                         "allowed: plates zeroed before the trial, or --rezero to subtract "
                         "the flight's mean")
    fixed = PlateTotals(totals.name, totals.time, totals.force_x
                        - float(np.mean(totals.force_x[start:stop])), totals.force_y - offset,
                        totals.cop_x, totals.rate, totals.plates)
    return fixed, (f"{totals.name}: zero offset of {offset:.4g} N (the flight's mean, {rows}) "
                   "subtracted (--rezero)")


def grf_channels(totals: PlateTotals, times: np.ndarray, cutoff: float = DEFAULT_CUTOFF,
                 ) -> dict[str, np.ndarray]:
    """``grf_x`` and ``grf_y`` (N) low-passed at ``cutoff`` Hz and interpolated at ``times``
    (s, the target's clock: the force file's own time values are used, so files that start
    at other times or sample at other rates line up). Times outside the force recording are
    an error."""
    if times[0] < totals.time[0] - 1e-9 or times[-1] > totals.time[-1] + 1e-9:
        raise ModelError("--forces", f"{totals.name}: covers {totals.time[0]:.6g}-"
                         f"{totals.time[-1]:.6g} s, the target {times[0]:.6g}-"
                         f"{times[-1]:.6g} s; allowed: a force recording spanning the target")
    return {"grf_x": np.interp(times, totals.time, low_pass(totals.force_x, totals.rate,
                                                              cutoff)),
            "grf_y": np.interp(times, totals.time, low_pass(totals.force_y, totals.rate,
                                                              cutoff))}
