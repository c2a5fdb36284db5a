"""The motion a fit must reproduce: measured joint angle histories (one per scored joint) and,
for a body on the ground, ground reaction force and centre-of-mass histories; or a built-in
motion for each preset."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..errors import ModelError
from ..io.target_file import read_angle_table
from ..model.body import GROUND_OUTPUTS
from .coordinate_map import OPTIONAL_COLUMNS, is_expression, parse_expression

#: Sample interval of the built-in targets, s (100 Hz, a usual motion-capture rate).
BUILTIN_SAMPLE_INTERVAL = 0.01
BUILTIN_CURL = "builtin:curl"
#: What a target may hold besides joint angles, as torquesim's results name them: the total
#: ground reaction force (N) and the centre of mass position (m), ground frame (x forwards,
#: y up). Only a body on the ground (base = "free") has them.
CHANNELS = GROUND_OUTPUTS


@dataclass(frozen=True)
class Target:
    """Target joint angle histories.

    Attributes
    ----------
    time : ndarray
        Sample times, s, strictly increasing. The simulation starts at ``time[0]``.
    angles : ndarray
        (joints, samples): the angle of each scored joint at those times, rad.
    joints : tuple of str
        The model joints scored, in the rows' order. Joints of the model not listed are
        simulated but not scored.
    source : str
        Where it came from (file name and columns, or ``builtin:NAME``).
    channels : dict
        Optional histories besides the angles, at the same times: `CHANNELS` name → samples
        (``grf_x``, ``grf_y`` in N; ``com_x``, ``com_y`` in m).
    """

    time: np.ndarray = field(repr=False)
    angles: np.ndarray = field(repr=False)
    joints: tuple[str, ...] = ("elbow",)
    source: str = ""
    channels: dict = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        angles = np.atleast_2d(np.asarray(self.angles, dtype=float))
        object.__setattr__(self, "angles", angles)
        if angles.shape != (len(self.joints), np.size(self.time)):
            raise ModelError("target", f"{angles.shape} angles for {len(self.joints)} joints "
                             f"and {np.size(self.time)} samples")
        channels = {}
        for name in sorted(self.channels, key=lambda c: CHANNELS.index(c)
                           if c in CHANNELS else len(CHANNELS)):
            if name not in CHANNELS:
                raise ModelError("target", f"channel {name!r}; allowed: {', '.join(CHANNELS)}")
            values = np.asarray(self.channels[name], dtype=float)
            if values.shape != (np.size(self.time),):
                raise ModelError("target", f"channel {name!r} has {values.size} samples, the "
                                 f"time {np.size(self.time)}; allowed: one per sample")
            if not np.all(np.isfinite(values)):
                raise ModelError("target", f"channel {name!r} is not finite everywhere; "
                                 "allowed: finite numbers")
            channels[name] = values
        object.__setattr__(self, "channels", channels)

    @property
    def angle(self) -> np.ndarray:
        """The first scored joint's angle, rad."""
        return self.angles[0]

    @property
    def duration(self) -> float:
        """Time span of the target, s."""
        return float(self.time[-1] - self.time[0])

    @property
    def elapsed(self) -> np.ndarray:
        """Sample times from the start of the target, s."""
        return self.time - self.time[0]

    def smoothed(self, row: int = 0, samples: int | None = None):
        """A smoothing spline q(t − t0) through row ``row``'s samples (the first ``samples``
        of them; default all; smoothing chosen by generalised cross-validation: exact data are
        nearly interpolated, noisy data are smoothed; natural: q̈ = 0 at both ends);
        ``.derivative(n)`` gives q̇ and q̈. SciPy's cross-validation fails on very many samples:
        on 10 001 exact samples of a smooth 3 s motion it picks a spline up to 0.7 rad off
        (3e-5 rad on 6 001), on 60 001 it stops ("ill-posed"; the arm raise's own 30 001 at
        0.1 ms: a traceback from `fit`). So the spline runs through at most
        `MAX_SPLINE_SAMPLES` of them, evenly picked (the ends kept), and through every other
        one of those while SciPy still finds it ill-posed."""
        from scipy.interpolate import make_smoothing_spline

        x, y = self.elapsed[:samples], self.angles[row, :samples]
        keep = _evenly_picked(x.size, MAX_SPLINE_SAMPLES)
        x, y = x[keep], y[keep]
        for _ in range(SPLINE_THINNINGS):
            try:
                return make_smoothing_spline(x, y)
            except ValueError:
                keep = _evenly_picked(x.size, (x.size + 1) // 2)
                x, y = x[keep], y[keep]
        raise ModelError("target", f"{self.joints[row]}: no smoothing spline fits its "
                         f"angles (cross-validation ill-posed down to {x.size} samples); "
                         "allowed: a motion a spline can follow (resample it, e.g. at 1 kHz)")

    def noisy(self) -> np.ndarray:
        """Which joints' first samples carry noise (a recording) rather than none (a simulated
        target): the median |third difference| of the first 12 samples / (0.6745·√20), the
        standard deviation of white noise (a smooth motion's third differences are h³ times
        its jerk, next to nothing), above `NOISE_FREE`. One flag per joint."""
        if self.time.size < 5:
            return np.zeros(len(self.joints), dtype=bool)
        first = self.angles[:, :12]
        noise = np.median(np.abs(np.diff(first, n=3, axis=1)), axis=1) / (0.6745
                                                                          * math.sqrt(20))
        return noise > NOISE_FREE

    def start_angles(self) -> np.ndarray:
        """Each joint's angle at the first sample, rad: for a recording with noise (`noisy`)
        the value at t0 of the smoothing spline of `smoothed` (a value the first frames agree
        on); for a noise-free one (a simulated target) the first sample itself. A standing
        body's equilibrium is sensitive to the start: 0.3° of noise in the first sample
        tipped the feet of examples/jump from 61.9° to 54.8°."""
        start = self.angles[:, 0].copy()
        for row in np.flatnonzero(self.noisy()):
            try:
                start[row] = float(self.smoothed(int(row))(0.0))
            except (ValueError, np.linalg.LinAlgError):
                pass  # no spline through these samples: the first sample as recorded
        return start

    def start_speeds(self) -> np.ndarray:
        """Each joint's angular velocity at the first sample, rad/s, from its first
        `START_WINDOW` samples: for a recording with noise (`noisy`) the derivative at t0 of
        a smoothing spline (as `smoothed`); for a noise-free one the derivative of the
        interpolating cubic spline (not-a-knot ends). The smoothing spline is natural
        (q̈ = 0 at t0), which a simulated motion that starts still with a large acceleration
        does not obey: on such a target it read 23°/s where the motion starts at rest. A
        second-order one-sided difference where no spline can be made. All zero when every
        joint moves slower than `STILL` there (a recording that starts still: the fit starts
        at rest, in static equilibrium)."""
        from scipy.interpolate import CubicSpline

        if self.time.size < 5:
            return np.zeros(len(self.joints))
        noisy = self.noisy()
        speeds = np.empty(len(self.joints))
        for row in range(len(self.joints)):
            try:
                spline = (self.smoothed(row, START_WINDOW) if noisy[row] else
                          CubicSpline(self.elapsed[:START_WINDOW],
                                      self.angles[row, :START_WINDOW]))
                speeds[row] = float(spline.derivative()(0.0))
            except (ValueError, np.linalg.LinAlgError):
                speeds[row] = float(np.gradient(self.angles[row, :3], self.elapsed[:3],
                                                edge_order=2)[0])
        return speeds if np.max(np.abs(speeds)) >= STILL else np.zeros_like(speeds)

    def angular_velocity(self) -> np.ndarray:
        """dq/dt at the samples, (joints, samples), rad/s (second-order differences)."""
        return np.gradient(self.angles, self.time, axis=1, edge_order=2)


def min_jerk(t, start: float, end: float, t0: float, t1: float) -> np.ndarray:
    """start → end between t0 and t1 by the minimum-jerk quintic 10s³ − 15s⁴ + 6s⁵."""
    s = np.clip((np.asarray(t) - t0) / (t1 - t0), 0.0, 1.0)
    return start + (end - start) * s**3 * (10 - 15 * s + 6 * s**2)


def min_jerk_curl(start_deg: float = 10.0, peak_deg: float = 135.0, half_time: float = 1.5,
                  sample_interval: float = BUILTIN_SAMPLE_INTERVAL) -> Target:
    """docs/model.md §6: start → peak → start, each half a minimum-jerk quintic lasting
    ``half_time`` s."""
    n = int(round(2 * half_time / sample_interval))
    t = np.linspace(0.0, 2 * half_time, n + 1)
    a, b = math.radians(start_deg), math.radians(peak_deg)
    angle = np.where(t <= half_time, min_jerk(t, a, b, 0.0, half_time),
                     min_jerk(t, b, a, half_time, 2 * half_time))
    return Target(t, angle[None, :], ("elbow",), BUILTIN_CURL)


def raise_hold_lower(joints: dict[str, tuple[float, float]], source: str) -> Target:
    """Each joint start → peak (degrees) by minimum jerk in 0.1–1.3 s, a hold, and back
    in 1.7–2.9 s; 3 s at 100 Hz (docs/presets.md: the motions the presets were made for)."""
    t = np.linspace(0.0, 3.0, 301)
    rows = []
    for start, peak in joints.values():
        a, b = math.radians(start), math.radians(peak)
        rows.append(np.where(t <= 1.5, min_jerk(t, a, b, 0.1, 1.3), min_jerk(t, b, a, 1.7, 2.9)))
    return Target(t, np.array(rows), tuple(joints), source)


@lru_cache(maxsize=2)
def jump_motion(name: str = "squat-jump", sample_interval: float = 0.005) -> Target:
    """The preset jump ``name`` simulated with the reference solver (SciPy Radau, rtol
    1e-10), sampled at 200 Hz: the four joint angles, the total ground reaction force and the
    centre of mass, as a force plate and motion capture would record them."""
    from ..model.presets import preset
    from ..solvers.simulation import simulate

    model = preset(f"builtin:{name}")
    run = simulate(model, "reference", output_step=sample_interval)
    columns = run.columns()
    joints = tuple(j.name for j in model.joints)
    return Target(run.time, run.q.T.copy(), joints, f"builtin:{name}",
                  {channel: columns[channel] for channel in CHANNELS})


#: ``builtin:NAME`` targets: the motion of each preset.
BUILTIN_TARGETS = {
    "squat-jump": jump_motion,
    "countermovement-jump": lambda: jump_motion("countermovement-jump"),
    "squat-jump-biarticular": lambda: jump_motion("squat-jump-biarticular"),
    "drop-landing": lambda: jump_motion("drop-landing"),
    "curl": min_jerk_curl,
    "elbow-curl": min_jerk_curl,
    "knee-extension": lambda: raise_hold_lower({"knee": (90.0, 15.0)},
                                               "builtin:knee-extension"),
    "arm-raise": lambda: raise_hold_lower({"shoulder": (5.0, 70.0), "elbow": (10.0, 70.0)},
                                          "builtin:arm-raise"),
}


def _auto_column(joint, names: list[str], one_joint: bool) -> str | None:
    """The column of ``joint`` by name: its coordinate, its name, the only column containing
    its name, or (one-joint model) the only angle column."""
    lower = {n.lower(): n for n in names}
    for key in (joint.coordinate.lower(), joint.name.lower()):
        if key in lower:
            return lower[key]
    containing = [n for n in names if joint.name.lower() in n.lower()]
    if len(containing) == 1:
        return containing[0]
    if one_joint and len(names) == 1:
        return names[0]
    return None


#: A target whose first samples show less noise than this (rad, 0.01°) is taken as
#: noise-free (simulated) and starts from its first sample.
NOISE_FREE = math.radians(0.01)
#: The most samples `Target.smoothed` passes to SciPy's smoothing spline, and how many times
#: it halves them when SciPy's cross-validation fails.
MAX_SPLINE_SAMPLES = 4000
SPLINE_THINNINGS = 6


def _evenly_picked(size: int, most: int) -> np.ndarray:
    """Indices of at most ``most`` (≥ 2) of ``size`` samples at an even stride, the last
    one kept."""
    stride = max(1, math.ceil((size - 1) / (most - 1)))
    return np.unique(np.r_[np.arange(0, size, stride), size - 1])


#: A recording whose joints all move slower than this at its first sample starts still, rad/s
#: (5°/s: 0.5° over the first 0.1 s, within the noise of a motion capture's angles).
STILL = math.radians(5.0)
#: The samples a start speed is judged on (at 100-200 Hz, 0.2-0.4 s).
START_WINDOW = 40
#: Largest median interval between a target's samples, s: a motion recorded in ms instead of
#: s shows its samples 1 to 10 "s" apart.
MAX_SAMPLE_INTERVAL = 0.5
#: The ground pushes: a vertical force below this many body weights is not a force in N.
MIN_GRF_Y_BODY_WEIGHTS = -0.05
#: The peak vertical ground reaction force of a movement on the ground, in body weights: below
#: or above it the channel is in other units (kN, body weights, mN).
GRF_Y_PEAK_BODY_WEIGHTS = (0.3, 15.0)
#: The largest |horizontal force| in body weights.
MAX_GRF_X_BODY_WEIGHTS = 5.0
#: The centre of mass lies within this many times the model's size (the sum of its segments'
#: extents) of the ground frame's origin, or within `MIN_COM_REACH` m, whichever is larger.
COM_REACH_SIZES, MIN_COM_REACH = 2.0, 5.0


def check_target(chain, target: Target) -> None:
    """A one-line `ModelError` unless ``target`` fits ``chain``: its time in seconds (samples at
    most `MAX_SAMPLE_INTERVAL` apart), and, for channels, a free base, ground contacts for a
    ground reaction force, forces in N within the body weight's scale and positions in m
    within the body's reach (a channel in kN, body weights, cm or mm is named with what it
    looks like)."""
    if target.time.size > 1:
        interval = float(np.median(np.diff(target.time)))
        if interval > MAX_SAMPLE_INTERVAL:
            raise ModelError("target.time", f"samples {interval:.4g} s apart, "
                             f"{target.duration:.4g} s in all: is the time in ms? allowed: "
                             f"seconds, samples at most {MAX_SAMPLE_INTERVAL:g} s apart")
    if not target.channels:
        return
    names = ", ".join(target.channels)
    if chain.base != "free":
        raise ModelError("target", f"holds {names}, which only a body on the ground has; "
                         f"{chain.name!r} hangs from a fixed base; allowed: joint angles only")
    if not chain.contacts and any(c.startswith("grf") for c in target.channels):
        raise ModelError("target", f"holds a ground reaction force but {chain.name!r} has no "
                         "ground contact; allowed: com_x, com_y and joint angles")
    weight = chain.weight
    if "grf_y" in target.channels:
        force = target.channels["grf_y"] / weight
        low, high = GRF_Y_PEAK_BODY_WEIGHTS
        if force.min() < MIN_GRF_Y_BODY_WEIGHTS:
            raise ModelError("target.grf_y", f"values down to {force.min() * weight:.4g} N "
                             f"({force.min():.3g} body weights of {weight:.0f} N): the ground "
                             "only pushes; allowed: N, upwards positive (≥ "
                             f"{MIN_GRF_Y_BODY_WEIGHTS:g} body weights)")
        if not low <= force.max() <= high:
            looks = "kN or body weights" if force.max() < low else "mN or another unit"
            raise ModelError("target.grf_y", f"peak {force.max() * weight:.4g} is "
                             f"{force.max():.3g} body weights of this model ({weight:.0f} N): "
                             f"is it in {looks}? allowed: N, a peak of {low:g} to {high:g} "
                             "body weights")
    if "grf_x" in target.channels:
        largest = float(np.max(np.abs(target.channels["grf_x"]))) / weight
        if largest > MAX_GRF_X_BODY_WEIGHTS:
            raise ModelError("target.grf_x", f"values up to {largest:.3g} body weights of this "
                             f"model ({weight:.0f} N); allowed: N, within "
                             f"±{MAX_GRF_X_BODY_WEIGHTS:g} body weights")
    size = sum(seg.extent for seg in chain.segments)
    reach = max(COM_REACH_SIZES * size, MIN_COM_REACH)
    for name in ("com_x", "com_y"):
        if name in target.channels:
            largest = float(np.max(np.abs(target.channels[name])))
            if largest > reach:
                raise ModelError(f"target.{name}", f"values up to {largest:.4g}: is it in cm or "
                                 f"mm? allowed: m, within ±{reach:.3g} m of the ground frame's "
                                 f"origin (this model's segments span {size:.3g} m)")


def load_target(spec: str, model=None, columns=None, units: str | None = None) -> Target:
    """A target for ``model`` (a chain; default the elbow curl).

    ``spec``: ``builtin:NAME`` (`BUILTIN_TARGETS`) or a CSV / OpenSim ``.mot``/``.sto``
    file (`torquesim.io.target_file.read_angle_table`). Model joints are matched to
    columns by name (the joint's coordinate, e.g. ``elbow_flexion``; its name; the only column
    containing its name) or by ``columns`` {joint: column}; on a one-joint model ``columns``
    may be a column name, and a joint's column may be an expression of several
    (`torquesim.fitting.coordinate_map`: ``"-knee_angle_r"``, ``"118 - ankle_angle_r"``, in
    degrees). Joints without a column are simulated but not scored; at least one
    joint must be matched. On a body on the ground, columns named after a `CHANNELS` entry
    (``grf_y`` …, as torquesim's results name them; or mapped by ``columns``, e.g.
    {"grf_y": "ground_force_vy"}) are read as they are (N, m) and scored too.
    """
    from ..model.chain import as_chain
    from ..model.presets import preset

    chain = as_chain(model) if model is not None else preset("builtin:elbow-curl")
    joint_names = [j.name for j in chain.joints]
    if spec.startswith("builtin:"):
        if columns:
            raise ModelError("column", f"{spec} is a built-in motion with the model's own "
                             "joints and channels; allowed: --column only with a --target file")
        name = spec.split(":", 1)[1]
        if name not in BUILTIN_TARGETS:
            raise ModelError("target", f"{spec!r}; allowed: "
                             f"{', '.join('builtin:' + k for k in BUILTIN_TARGETS)}")
        target = BUILTIN_TARGETS[name]()
        missing = [j for j in target.joints if j not in joint_names]
        if missing:
            raise ModelError("target", f"{spec} moves joint(s) {', '.join(missing)}, which the "
                             f"model {chain.name!r} does not have (joints: "
                             f"{', '.join(joint_names)})")
        check_target(chain, target)
        return target
    if isinstance(columns, str):
        if chain.n_joints != 1:
            raise ModelError("column", f"{columns!r}: this model has joints "
                             f"{', '.join(joint_names)}; allowed: JOINT=COLUMN per joint")
        columns = {joint_names[0]: columns}
    columns = dict(columns or {})
    for joint in columns:
        if joint not in joint_names and joint not in CHANNELS:
            raise ModelError("column", f"{joint!r} is not a joint of the model; allowed: "
                             f"{', '.join(joint_names + list(CHANNELS))}")
    mapping: dict[str, str] = {}
    channel_columns: dict[str, str] = {}
    expressions = {j: parse_expression(e, f"column.{j}") for j, e in columns.items()
                   if j in joint_names and is_expression(e)}
    absent: set[str] = set()

    def pick(names: list[str]) -> list[str]:
        for joint, (coefficients, _) in expressions.items():
            for name in coefficients:
                if name not in names and name in OPTIONAL_COLUMNS:
                    absent.add(name)
                elif name not in names:
                    raise ModelError("column", f"{joint}={columns[joint]}: {Path(spec).name} "
                                     f"has no column {name!r}; columns: {', '.join(names)}")
        for joint in chain.joints:
            if joint.name in expressions:
                mapping[joint.name] = columns[joint.name]
                continue
            column = columns.get(joint.name) or _auto_column(joint, names,
                                                             chain.n_joints == 1)
            if column is not None:
                mapping[joint.name] = column
        if not mapping:
            raise ModelError("target", f"{spec}: no column matches a joint of the model "
                             f"({', '.join(j.coordinate for j in chain.joints)}); columns: "
                             f"{', '.join(names)}; allowed: --column JOINT=COLUMN")
        if chain.base == "free":
            lower = {n.lower(): n for n in names}
            for channel in CHANNELS:
                column = columns.get(channel) or lower.get(channel)
                if column is not None:
                    channel_columns[channel] = column
        elif any(c in columns for c in CHANNELS):
            raise ModelError("column", f"{', '.join(c for c in columns if c in CHANNELS)}: "
                             f"only a body on the ground has them; {chain.name!r} hangs "
                             "from a fixed base; allowed: JOINT=COLUMN")
        else:
            held = [n for n in names if n.lower() in CHANNELS]
            if held:
                raise ModelError("target", f"{Path(spec).name} holds {', '.join(held)}, "
                                 f"which only a body on the ground has; {chain.name!r} "
                                 "hangs from a fixed base; allowed: joint angles only "
                                 "(remove or rename those columns)")
        read = [c for j, c in mapping.items() if j not in expressions]
        read += [n for coefficients, _ in expressions.values() for n in coefficients
                 if n not in absent]
        return list(dict.fromkeys([*read, *channel_columns.values()]))

    time, angles = read_angle_table(spec, units, columns=pick,
                                    raw=lambda: set(channel_columns.values()))
    for joint, (coefficients, offset) in expressions.items():
        angles[columns[joint]] = sum((c * angles[n] for n, c in coefficients.items()
                                      if n not in absent), np.full(time.size,
                                                                   math.radians(offset)))
    if time[-1] - time[0] > 600.0:
        raise ModelError("target.time", f"{spec}: spans {time[-1] - time[0]:g} s (is the "
                         "time in ms?); allowed: seconds, at most 600 s")
    joints = tuple(mapping)
    described = ", ".join(f"{j}={c}" for j, c in [*mapping.items(), *channel_columns.items()])
    if absent:
        described += f"; absent, read as 0: {', '.join(sorted(absent))}"
    target = Target(time, np.array([angles[mapping[j]] for j in joints]), joints,
                    f"{spec} [{described}]",
                    {c: angles[column] for c, column in channel_columns.items()})
    check_target(chain, target)
    return target


def with_forces(chain, target: Target, path, cutoff: float, rezero: bool = False,
                components: str = "xy", axes: str = "x,z") -> tuple[Target, list[str]]:
    """``target`` with ``grf_y`` (``components="y"``) or ``grf_x`` and ``grf_y`` ("xy") from a
    force-plate file (plates summed, zero-lag low-passed at ``cutoff`` Hz, interpolated at the
    target's times; a C3D file's platforms in the lab frame ``axes``; see
    `torquesim.io.force_plates`), and the lines to tell the user: the plates read, the filter,
    the body mass of the quiet standing against the model's, a re-zeroing."""
    from dataclasses import replace

    from ..io.force_plates import (
        check_zero_offset,
        grf_channels,
        read_plates,
        standing_body_mass,
    )

    if chain.base != "free" or not chain.contacts:
        raise ModelError("--forces", f"{chain.name!r} does not stand on the ground; allowed: "
                         "a model with a free base and ground contacts")
    totals = read_plates(path, axes=axes)
    lines = [f"forces        {totals.name}: {len(totals.plates)} plate(s) summed, "
             f"{totals.rate:.4g} Hz, zero-lag Butterworth low-pass at {cutoff:g} Hz"
             + (f"; {totals.note}" if totals.note else "")]
    weight = chain.weight
    mass = sum(seg.total_mass for seg in chain.segments)
    try:
        standing = standing_body_mass(totals)
    except ModelError:
        standing = None
    if standing is not None:
        lines.append(f"body mass     {standing:.1f} kg from the quiet standing; the model "
                     f"{mass:.1f} kg")
        if abs(standing - mass) > 0.05 * mass:
            lines.append("warning: the model's mass differs from the subject's by more than "
                         "5 %: make the model for the subject (torquesim model NAME "
                         f"--body-mass {standing:.1f} --height H)")
    totals, said = check_zero_offset(totals, weight, rezero)
    if said:
        lines.append(f"zero offset   {said}")
    if components not in ("y", "xy"):
        raise ModelError("--grf-components", f"{components!r}; allowed: y, xy")
    channels = {k: v for k, v in grf_channels(totals, target.time, cutoff).items()
                if k[-1] in components}
    out = replace(target, channels={**target.channels, **channels},
                  source=f"{target.source} + {totals.name} [{', '.join(channels)}]")
    check_target(chain, out)
    return out, lines
