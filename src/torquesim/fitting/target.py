"""The motion a fit must reproduce: a measured elbow angle history, or the built-in curl."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..errors import ModelError
from ..io.target_file import read_angle_history

BUILTIN_CURL = "builtin:curl"
#: Sample interval of the built-in curl, s (100 Hz, a usual motion-capture rate).
BUILTIN_SAMPLE_INTERVAL = 0.01


@dataclass(frozen=True)
class Target:
    """A target elbow angle history.

    Attributes
    ----------
    time : ndarray
        Sample times, s, strictly increasing. The simulation starts at ``time[0]``.
    angle : ndarray
        Elbow flexion angle at those times, rad.
    source : str
        Where it came from (file name and column, or ``builtin:curl``).
    """

    time: np.ndarray = field(repr=False)
    angle: np.ndarray = field(repr=False)
    source: str = ""

    @property
    def duration(self) -> float:
        """Time span of the target, s."""
        return float(self.time[-1] - self.time[0])

    @property
    def elapsed(self) -> np.ndarray:
        """Sample times from the start of the target, s."""
        return self.time - self.time[0]

    def smoothed(self):
        """A smoothing spline θ(t − t0) through the samples (smoothing chosen by generalised
        cross-validation, so exact data are nearly interpolated and noisy data are smoothed);
        call ``.derivative(n)`` for ω and α."""
        from scipy.interpolate import make_smoothing_spline

        return make_smoothing_spline(self.elapsed, self.angle)

    def angular_velocity(self) -> np.ndarray:
        """dθ/dt at the samples, rad/s (second-order finite differences)."""
        return np.gradient(self.angle, self.time, edge_order=2)


def min_jerk_curl(start_deg: float = 10.0, peak_deg: float = 135.0, half_time: float = 1.5,
                  sample_interval: float = BUILTIN_SAMPLE_INTERVAL) -> Target:
    """docs/model.md §6: start → peak → start, each half a minimum-jerk quintic
    θ = θ_a + (θ_b − θ_a)(10s³ − 15s⁴ + 6s⁵) lasting ``half_time`` s."""
    n = int(round(2 * half_time / sample_interval))
    t = np.linspace(0.0, 2 * half_time, n + 1)
    s = np.where(t <= half_time, t / half_time, (2 * half_time - t) / half_time)
    blend = s**3 * (10 - 15 * s + 6 * s**2)
    a, b = math.radians(start_deg), math.radians(peak_deg)
    return Target(t, a + (b - a) * blend, BUILTIN_CURL)


def load_target(spec: str, column: str | None = None, units: str | None = None) -> Target:
    """``builtin:curl`` or a CSV / OpenSim ``.mot``/``.sto`` file (see
    :func:`torquesim.io.target_file.read_angle_history`)."""
    if spec == BUILTIN_CURL:
        return min_jerk_curl()
    if spec.startswith("builtin:"):
        raise ModelError("target", f"{spec!r}; allowed builtin: {BUILTIN_CURL}")
    time, angle, name = read_angle_history(spec, column, units)
    if time[-1] - time[0] > 600.0:
        raise ModelError("target", f"{spec}: spans {time[-1] - time[0]:g} s; allowed at most "
                         "600 s")
    return Target(time, angle, f"{spec} [{name}]")
