"""Fit a unit's maximum voluntary torque function to isovelocity dynamometer trials
(``torquesim strength``).

The function fitted is the CE torque of docs/model.md §2 at full activation,

    T_mv(θ_cc, ω_cc) = d(ω_cc) · T_ω(ω_cc) · T_θ(θ_cc)

(`torquesim.model.torque_generator.maximum_voluntary_torque`), the nine-parameter function of
King, Wilson & Yeadon (2006) and Forrester et al. (2011), with the lab's steps:

1. **Gravity and passive torque** of limb and crank are removed: T_u = δ·(T_crank − T_p(θ)),
   with T_p(θ) = A·cos θ + B·sin θ + C fitted to a passive trial (relaxed limb moved slowly
   through the range) or given as M·cos(θ − φ) (δ = +1 for a unit pulling towards increasing
   joint angle, −1 otherwise).
2. **The constant-velocity phase** of each isovelocity trial: the longest run of samples whose
   joint velocity is within ± max(5 %, 2 °/s) of the set speed (the median velocity of the
   samples above 80 % of the trial's peak speed), less its first 0.1 s while the torque
   settles to the new speed; a trial whose speed stays below 5 °/s is
   isometric, and its plateau (torque ≥ 95 % of its peak) is used, with the CE at rest
   (ω_cc = 0: a held maximal effort).
3. **The series elastic element**: under load the CE angle is not the crank angle. With SE
   stiffness k (held, from the model), θ_cc = θ + δ·T_u/k and ω_cc = δ·ω + (dT_u/dt)/k (the
   torque's rate from a cubic fitted to the phase, `_phase_rate`).
4. **The score**: the weighted RMS difference of Forrester et al. (2011), in which a sample
   above the function counts ``above_weight`` times one below, so that sub-maximal efforts
   (one-sided noise) do not pull the function down. ``above_weight="auto"`` weighs 1 (plain
   RMS) unless the plain fit's residuals are one-sided (skewness below −0.5), then 4.
5. **Bounds**: each parameter in a stated range (`PARAMETER_RANGES`); T_max/T0 in [1.1, 2.0]
   and h = d·T_ω strictly decreasing, as the model requires.
6. **Confidence intervals**, simultaneous at 95 % (Bonferroni: each at 1 − 0.05/p for p fitted
   parameters, so that all of them hold together), from the Jacobian at the optimum,
   s²·(JᵀJ)⁻¹, inflated by (1 + ρ)/(1 − ρ) for the lag-1 autocorrelation ρ of the residuals
   (samples of a trial are not independent), with Student's t. A parameter at a bound, or
   held, has none. They are local (linearised): the differential activation's ω_r and ω_1
   trade off against T_max and a_min, so wide intervals there are the data's answer.

Parameters the trials cannot determine are held at the starting unit's values and said so:
without eccentric trials, T_max/T0 and the differential activation (a_min, ω_r, ω_1); without
concentric trials, ω_max and ω_c. ``hold`` holds any other (e.g. ω_max from an independent
estimate, as Forrester et al. recommend).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np
from scipy import optimize, stats

from ..errors import ModelError, check_range
from ..io.dynamometer import DynamometerTrial
from ..io.target_file import longest_run
from ..model.torque_generator import (
    PACKED_FIELDS,
    PACKED_SLOTS,
    TorqueGeneratorUnit,
    _h_on_grid,
    maximum_voluntary_torque,
    pack_unit_parameters,
)

#: The nine parameters of the maximum voluntary torque function, in fit order.
FITTED_FIELDS = ("isometric_torque", "eccentric_torque_max", "max_velocity", "velocity_constant",
                 "min_differential_activation", "differential_activation_rate",
                 "differential_activation_midpoint", "optimal_angle", "angle_curvature")
ECCENTRIC_FIELDS = ("eccentric_torque_max", "min_differential_activation",
                    "differential_activation_rate", "differential_activation_midpoint")
CONCENTRIC_FIELDS = ("max_velocity", "velocity_constant")
ANGLE_FIELDS = ("optimal_angle", "angle_curvature")
#: The torque–angle parabola (T0, θ_opt, k2) needs torques at 3 or more CE angles at least
#: this far apart (rad, 5°), or a constant-velocity phase sweeping twice that: a single
#: isometric trial fitted θ_opt and k2 to its plateau's 1° of CE angle.
ANGLE_SEPARATION = math.radians(5.0)
#: The range each fitted parameter is searched in (SI units). The torque ranges are set from
#: the data (see `_bounds`); the others: ω_max 6–40 rad/s and ω_c 0.5–20 rad/s cover the
#: published single-joint fits (elbow ≈ 18, knee 17–30 rad/s; King et al. 2006, Forrester
#: et al. 2011), a_min 0.5–1, ω_r 0.05–10 rad/s, ω_1 ±5 rad/s, k2 0–5 rad⁻².
PARAMETER_RANGES = {
    "max_velocity": (6.0, 40.0),
    "velocity_constant": (0.5, 20.0),
    "min_differential_activation": (0.5, 1.0),
    "differential_activation_rate": (0.05, 10.0),
    "differential_activation_midpoint": (-5.0, 5.0),
    "angle_curvature": (0.0, 5.0),
}
#: T_max/T0 range (King et al. 2006 give 1.1–1.5 for maximal voluntary eccentric torque).
ECCENTRIC_RATIO = (1.1, 2.0)
#: Shortest constant-velocity phase, s.
MIN_PHASE = 0.05
#: Weight of a sample above the function when the data show one-sided noise.
ONE_SIDED_WEIGHT = 4.0
#: Residual skewness below which the noise counts as one-sided.
ONE_SIDED_SKEWNESS = -0.5


@dataclass(frozen=True)
class StrengthSettings:
    """How trials are read into data and the function fitted.

    Attributes
    ----------
    velocity_tolerance : float
        Constant-velocity phase: |ω − ω_set| ≤ max(velocity_tolerance·|ω_set|,
        min_velocity_tolerance). Default 0.05. Bounds (0, 0.5].
    min_velocity_tolerance : float
        rad/s. Default 2 °/s. Bounds (0, 0.5].
    isometric_speed : float
        A trial whose speed stays below this is isometric, rad/s. Default 5 °/s.
        Bounds (0, 1].
    plateau : float
        Isometric trials: the samples at or above this fraction of the trial's peak torque are
        used. Default 0.95. Bounds (0, 1].
    settling_time : float
        Isovelocity trials: the first part of the constant-velocity phase left out while the
        torque settles to the new speed (at least a third of the phase is kept), s.
        Default 0.1. Bounds [0, 1].
    above_weight : float or "auto"
        Weight of a sample above the function (Forrester et al. 2011). Default "auto" (see the
        module's docstring). Bounds [1, 100].
    se_stiffness : float or None
        SE stiffness k, N·m/rad; None (default): the unit's.
    hold : dict
        Field name → value (SI units) held instead of fitted.
    starts : int
        Local searches, from the unit, from the data, and from Latin-hypercube points.
        Default 8. Bounds [1, 200].
    seed : int
        Seed of the Latin hypercube. Default 1.
    """

    velocity_tolerance: float = 0.05
    min_velocity_tolerance: float = math.radians(2.0)
    isometric_speed: float = math.radians(5.0)
    plateau: float = 0.95
    settling_time: float = 0.1
    above_weight: float | str = "auto"
    se_stiffness: float | None = None
    hold: dict = field(default_factory=dict)
    starts: int = 8
    seed: int = 1

    def __post_init__(self) -> None:
        check_range("velocity_tolerance", self.velocity_tolerance, 0.0, 0.5, low_open=True)
        check_range("min_velocity_tolerance", self.min_velocity_tolerance, 0.0, 0.5,
                    low_open=True, unit="rad/s")
        check_range("isometric_speed", self.isometric_speed, 0.0, 1.0, low_open=True,
                    unit="rad/s")
        check_range("plateau", self.plateau, 0.0, 1.0, low_open=True)
        check_range("settling_time", self.settling_time, 0.0, 1.0, unit="s")
        if self.above_weight != "auto":
            check_range("above_weight", self.above_weight, 1.0, 100.0)
        if self.se_stiffness is not None:
            check_range("se_stiffness", self.se_stiffness, 0.0, 1e6, low_open=True,
                        unit="N·m/rad")
        for name in self.hold:
            if name not in FITTED_FIELDS:
                raise ModelError("hold", f"{name!r} is not a fitted parameter; allowed: "
                                 + ", ".join(FITTED_FIELDS))
        if isinstance(self.starts, bool) or not isinstance(self.starts, int) \
                or not 1 <= self.starts <= 200:
            raise ModelError("starts", f"{self.starts!r}; allowed a whole number in [1, 200]")


@dataclass(frozen=True)
class PassiveTorque:
    """Gravity and passive torque of limb and crank about the joint,
    T_p(θ) = A·cos θ + B·sin θ + C, N·m (positive towards increasing joint angle)."""

    cosine: float = 0.0
    sine: float = 0.0
    offset: float = 0.0
    source: str = "none (the trials' torque is the muscles')"

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        return self.cosine * np.cos(theta) + self.sine * np.sin(theta) + self.offset

    @classmethod
    def from_trial(cls, trial: DynamometerTrial) -> PassiveTorque:
        """Least-squares fit to a passive trial (relaxed limb moved through the range)."""
        span = float(np.ptp(trial.angle))
        if span < math.radians(10.0):
            raise ModelError("--passive", f"{trial.name}: the angle spans "
                             f"{math.degrees(span):.3g}°; allowed: a passive trial through at "
                             "least 10° of the range")
        design = np.column_stack([np.cos(trial.angle), np.sin(trial.angle),
                                  np.ones_like(trial.angle)])
        (a, b, c), *_ = np.linalg.lstsq(design, trial.torque, rcond=None)
        rms = float(np.sqrt(np.mean((design @ [a, b, c] - trial.torque) ** 2)))
        return cls(float(a), float(b), float(c),
                   f"fitted to the passive trial {trial.name} (A cos θ + B sin θ + C, RMS "
                   f"{rms:.3g} N·m)")

    @classmethod
    def given(cls, moment: float, angle: float) -> PassiveTorque:
        """M·cos(θ − φ): ``moment`` M in N·m (its largest value, the limb horizontal),
        ``angle`` φ in rad (the joint angle where it is largest)."""
        return cls(moment * math.cos(angle), moment * math.sin(angle), 0.0,
                   f"given: {moment:.6g}·cos(θ − {math.degrees(angle):.6g}°) N·m")


#: No gravity or passive torque to remove (the trials' torque is the muscles').
NO_PASSIVE_TORQUE = PassiveTorque()


@dataclass(frozen=True)
class Phase:
    """The samples of one trial that enter the fit.

    ``kind`` is "isometric", "concentric" or "eccentric" (of the unit); ``speed`` the set joint
    speed, rad/s (signed, the model's convention); ``rows`` the trial's sample indices;
    ``theta``, ``omega`` the joint's angle and velocity; ``torque`` the unit's torque T_u
    (N·m, gravity and passive removed, positive = the unit pulling); ``theta_cc``,
    ``omega_cc`` the CE's angle and velocity."""

    trial: str
    kind: str
    speed: float
    rows: np.ndarray
    theta: np.ndarray
    omega: np.ndarray
    torque: np.ndarray
    theta_cc: np.ndarray
    omega_cc: np.ndarray


def _phase_rate(time: np.ndarray, torque: np.ndarray) -> np.ndarray:
    """dT/dt (N·m/s) along a constant-velocity phase: the derivative of a cubic in time fitted
    to the phase's torque by least squares (at constant speed the torque follows the
    torque/angle curve, a quadratic in the angle and so in time; the cubic leaves room for
    the settling after the speed-up). Differentiating the noisy samples themselves would put
    the noise, amplified, into the CE velocity."""
    centre = time - time.mean()
    coefficients = np.polynomial.polynomial.polyfit(centre, torque, min(3, time.size - 1))
    return np.polynomial.polynomial.polyval(centre, np.polynomial.polynomial.polyder(
        coefficients))


def trial_phases(trial: DynamometerTrial, direction: int, stiffness: float,
                 passive: PassiveTorque, settings: StrengthSettings,
                 notes: list[str]) -> list[Phase]:
    """The phases of ``trial`` that enter the fit (at most one per direction of motion), for a
    unit pulling in ``direction`` with SE ``stiffness``. A relaxed phase (median torque below
    10 % of the trial's peak) is left out with a line in ``notes``; a trial with no phase, or
    whose torque has the wrong sign for the unit, is an error naming the file and rows."""

    def fail(message: str) -> ModelError:
        return ModelError("trials", f"{trial.name}: {message}")

    unit_torque = direction * (trial.torque - passive(trial.angle))
    peak_speed = float(np.max(np.abs(trial.velocity)))
    chosen: list[tuple[str, float, np.ndarray]] = []
    if peak_speed < settings.isometric_speed:
        chosen.append(("isometric", 0.0, np.arange(trial.time.size)))
    else:
        for sign in (1.0, -1.0):
            signed = sign * trial.velocity
            if signed.max() < max(settings.isometric_speed, 0.5 * peak_speed):
                continue
            speed = sign * float(np.median(signed[signed >= 0.8 * signed.max()]))
            tolerance = max(settings.velocity_tolerance * abs(speed),
                            settings.min_velocity_tolerance)
            start, stop = longest_run(np.abs(trial.velocity - speed) <= tolerance)
            dt = float(np.median(np.diff(trial.time)))
            if stop - start < max(5, int(math.ceil(MIN_PHASE / dt))):
                raise fail(f"no constant-velocity phase: the velocity stays within "
                           f"±{math.degrees(tolerance):.3g} °/s of the set speed "
                           f"{math.degrees(speed):.4g} °/s for {stop - start} samples; "
                           f"allowed: at least {MIN_PHASE * 1e3:g} ms and 5 samples (or raise "
                           "--velocity-tolerance)")
            chosen.append(("concentric" if direction * speed > 0 else "eccentric", speed,
                           np.arange(start, stop)))
    peak = float(np.max(np.abs(unit_torque)))
    phases = []
    for kind, speed, rows in chosen:
        median = float(np.median(unit_torque[rows]))
        if median < -0.05 * peak:
            raise fail(f"{trial.row(int(rows[0]))} to {trial.row(int(rows[-1]))}, column "
                       f"'torque': the unit's torque is negative (median {median:.4g} N·m "
                       "after gravity removal): the wrong sign for this unit, which pulls "
                       f"towards {'in' if direction > 0 else 'de'}creasing joint angle; "
                       "allowed: torque of the unit's sign (check the unit, the column's sign "
                       "or --torque-sign)")
        if median < 0.1 * peak:
            notes.append(f"{trial.name}: the {kind} phase at {math.degrees(speed):.4g} °/s is "
                         "relaxed (median torque below 10 % of the peak) and left out")
            continue
        if kind == "isometric":
            rows = rows[unit_torque[rows] >= settings.plateau * unit_torque[rows].max()]
        else:
            settled = rows[trial.time[rows] >= trial.time[rows[0]] + settings.settling_time]
            rows = settled if settled.size >= max(5, rows.size // 3) else rows
        torque = unit_torque[rows]
        stretch = np.maximum(torque, 0.0) / stiffness
        omega_cc = (np.zeros(rows.size) if kind == "isometric"
                    else direction * trial.velocity[rows]
                    + _phase_rate(trial.time[rows], torque) / stiffness)
        phases.append(Phase(trial.name, kind, speed, rows, trial.angle[rows],
                            trial.velocity[rows], torque, trial.angle[rows] + direction * stretch,
                            omega_cc))
    if not phases and chosen:
        raise fail("every phase is relaxed (torque below 10 % of its peak); allowed: a "
                   "maximal effort")
    return phases


@dataclass(frozen=True)
class StrengthFit:
    """A fitted maximum voluntary torque function.

    Attributes
    ----------
    parameters : TorqueGeneratorUnit
        The unit with its nine fitted (or held) values; SE stiffness, eccentric slope ratio and
        CE damping as the starting unit's (SE stiffness as ``se_stiffness`` when given).
    status : dict
        Field → "fitted", "at bound", or "held (why)".
    intervals : dict
        Field → (low, high), simultaneous 95 % confidence intervals (fitted fields not at a
        bound).
    rms, weighted_rms : float
        Plain and weighted RMS difference, N·m.
    above_weight : float
    skewness : float
        Of the plain fit's residuals.
    fraction_beneath : float
        Share of the samples at or beneath the fitted function.
    autocorrelation : float
        Lag-1 autocorrelation of the residuals within phases.
    phases : list of Phase
    fitted : ndarray
        T_mv at every sample, phases concatenated, N·m.
    notes : list of str
    evaluations : int
        Residual evaluations, all searches.
    """

    parameters: TorqueGeneratorUnit
    status: dict
    intervals: dict
    rms: float
    weighted_rms: float
    above_weight: float
    skewness: float
    fraction_beneath: float
    autocorrelation: float
    phases: list
    fitted: np.ndarray
    notes: list
    evaluations: int


def _bounds(data_torque: np.ndarray, theta_cc: np.ndarray) -> dict[str, tuple[float, float]]:
    peak = float(np.max(data_torque))
    low = max(float(theta_cc.min()) - math.pi / 2, -math.pi)
    high = min(float(theta_cc.max()) + math.pi / 2, 2 * math.pi)
    return {"isometric_torque": (0.5 * peak, 3.0 * peak),
            "eccentric_torque_max": (0.5 * peak * ECCENTRIC_RATIO[0], 3.0 * peak
                                     * ECCENTRIC_RATIO[1]),
            **PARAMETER_RANGES, "optimal_angle": (low, high)}


def _held_by_data(phases: list[Phase]) -> dict[str, str]:
    kinds = {p.kind for p in phases}
    held = {}
    if "eccentric" not in kinds:
        held.update(dict.fromkeys(ECCENTRIC_FIELDS, "held (no eccentric trial)"))
    if "concentric" not in kinds:
        held.update(dict.fromkeys(CONCENTRIC_FIELDS, "held (no concentric trial)"))
    sweeps = any(p.kind != "isometric" and np.ptp(p.theta_cc) >= 2 * ANGLE_SEPARATION
                 for p in phases if p.theta_cc.size)
    angles = np.sort([float(np.mean(p.theta_cc)) for p in phases
                      if p.kind == "isometric" and p.theta_cc.size])
    distinct = 1 + int(np.sum(np.diff(angles) >= ANGLE_SEPARATION)) if angles.size else 0
    if not sweeps and distinct < 3:
        held.update(dict.fromkeys(ANGLE_FIELDS, "held (torques at fewer than 3 angles)"))
    return held


#: ω values (fractions of ω_max) where h = d·T_ω must decrease, for the penalty (coarser than
#: the check of `TorqueGeneratorUnit`; `_monotone_unit` settles what slips between).
_MONOTONE_GRID = np.concatenate([-np.linspace(1.0, 0.0, 201), np.linspace(0.0, 1.0, 201)[1:]])
#: The penalty asks h' ≤ −MONOTONE_MARGIN·T0 (per rad/s), so that the optimum, which may lie
#: on the constraint, passes the check.
MONOTONE_MARGIN = 1e-6


def fit_strength(trials: list[DynamometerTrial], unit: TorqueGeneratorUnit, direction: int,
                 settings: StrengthSettings = StrengthSettings(),
                 passive: PassiveTorque = NO_PASSIVE_TORQUE, progress=None) -> StrengthFit:
    """Fit the maximum voluntary torque function of a unit pulling in ``direction`` (+1
    towards increasing joint angle) to ``trials``, starting from ``unit`` (see the module's
    docstring for every step). ``progress(message)`` hears each search's end."""
    if not trials:
        raise ModelError("trials", "none given; allowed: one or more trial files")
    stiffness = settings.se_stiffness or unit.se_stiffness
    notes: list[str] = []
    phases = [p for t in trials
              for p in trial_phases(t, direction, stiffness, passive, settings, notes)]
    torque = np.concatenate([p.torque for p in phases])
    if not torque.size or torque.max() <= 0.0:
        largest = torque.max() + 0.0 if torque.size else 0.0  # + 0.0: no "-0"
        raise ModelError("trials", f"no torque in the unit's direction (largest {largest:.3g} "
                         "N·m); allowed: trials in which the unit pulls (check --torque-sign "
                         "and --unit)")
    theta_cc = np.concatenate([p.theta_cc for p in phases])
    omega_cc = np.concatenate([p.omega_cc for p in phases])
    start_values = {**{f: getattr(unit, f) for f in PACKED_FIELDS}, "se_stiffness": stiffness}
    bounds = _bounds(torque, theta_cc)
    status = dict(_held_by_data(phases))
    for name, value in settings.hold.items():
        check_range(f"hold.{name}", value, -math.inf, math.inf)
        try:  # the held value in its field's range (the unit's own check)
            replace(unit, **{name: float(value)})
        except ModelError as exc:
            if exc.field == name:
                raise ModelError("hold", f"{name}={value:g}: {exc.reason}") from None
        status[name] = "held (given)"
        start_values[name] = float(value)
    free = [f for f in FITTED_FIELDS if f not in status]
    if len(free) == 0:
        raise ModelError("hold", "every parameter is held; allowed: at least one to fit")
    if torque.size <= len(free):
        raise ModelError("trials", f"{torque.size} samples for {len(free)} parameters; allowed: "
                         "more samples than parameters (more or longer trials)")
    lower = np.array([bounds[f][0] for f in free])
    upper = np.array([bounds[f][1] for f in free])
    order = list(PACKED_FIELDS)
    slots = [order.index(f) for f in free]
    base = np.array([start_values[f] for f in PACKED_FIELDS])
    evaluations = [0]

    keep_ratio = "eccentric_torque_max" in status and "eccentric_torque_max" not in settings.hold
    ratio = unit.eccentric_torque_max / unit.isometric_torque

    def packed(x: np.ndarray) -> np.ndarray:
        values = base.copy()
        values[slots] = x
        if keep_ratio:  # held without eccentric data: T_max/T0 as the starting unit's
            values[1] = ratio * values[0]
        return pack_unit_parameters(values)

    def penalties(p: np.ndarray) -> np.ndarray:
        """Zero inside the constraints (T_max/T0 in its range, h decreasing on the grid),
        growing linearly outside."""
        ratio = p[1] / p[0]
        _, slopes = _h_on_grid(_MONOTONE_GRID * p[2], p, 0)
        rising = np.maximum(slopes[:-1] + MONOTONE_MARGIN * p[0], 0.0) / p[0]
        return np.concatenate([[max(0.0, ECCENTRIC_RATIO[0] - ratio),
                                max(0.0, ratio - ECCENTRIC_RATIO[1])],
                               rising]) * 1e3 * math.sqrt(torque.size)

    def residuals(x: np.ndarray, weight: float) -> np.ndarray:
        evaluations[0] += 1
        p = packed(x)
        difference = torque - maximum_voluntary_torque(theta_cc, omega_cc, p)
        scale = np.where(difference > 0.0, math.sqrt(weight), 1.0)
        return np.concatenate([scale * difference, penalties(p)])

    starts = _starts(free, base, lower, upper, torque, theta_cc, settings)

    def search(weight: float, from_points) -> optimize.OptimizeResult:
        best = None
        for i, x0 in enumerate(from_points):
            result = optimize.least_squares(residuals, x0, bounds=(lower, upper), args=(weight,),
                                            x_scale=np.maximum(upper - lower, 1e-3) / 10,
                                            method="trf", max_nfev=400 * len(free))
            if best is None or result.cost < best.cost:
                best = result
            if progress is not None:
                progress(f"search {i + 1}/{len(from_points)} (weight {weight:g}): weighted "
                         f"RMS {math.sqrt(2 * result.cost / torque.size):.4g} N·m")
        return best

    plain = search(1.0, starts)
    plain_residual = torque - maximum_voluntary_torque(theta_cc, omega_cc, packed(plain.x))
    skewness = float(stats.skew(plain_residual))
    weight = settings.above_weight
    if weight == "auto":
        weight = ONE_SIDED_WEIGHT if skewness < ONE_SIDED_SKEWNESS else 1.0
    best = plain if weight == 1.0 else search(float(weight), [plain.x, *starts[:2]])
    p = packed(best.x)
    fitted = maximum_voluntary_torque(theta_cc, omega_cc, p)
    difference = torque - fitted
    weights = np.where(difference > 0.0, weight, 1.0)
    values = dict(zip(PACKED_FIELDS, packed(best.x)[list(PACKED_SLOTS)].tolist(), strict=True))
    parameters = _monotone_unit(values, notes)
    rho = _autocorrelation(difference, phases)
    intervals, at_bound = _intervals(best, free, lower, upper, difference, weights, rho)
    for name in free:
        status[name] = "at bound" if name in at_bound else "fitted"
    return StrengthFit(
        parameters=parameters, status={f: status[f] for f in FITTED_FIELDS},
        intervals=intervals, rms=float(np.sqrt(np.mean(difference ** 2))),
        weighted_rms=float(np.sqrt(np.sum(weights * difference ** 2) / np.sum(weights))),
        above_weight=float(weight), skewness=skewness,
        fraction_beneath=float(np.mean(difference <= 0.0)), autocorrelation=rho,
        phases=phases, fitted=fitted, notes=notes, evaluations=evaluations[0])


def _monotone_unit(values: dict, notes: list[str]) -> TorqueGeneratorUnit:
    """The unit of ``values``; if its h = d·T_ω is not strictly decreasing between the
    penalty's grid points (the optimum can sit on that constraint), a_min raised by bisection
    to the least value that makes it so (a_min = 1 always does), with a line in ``notes``."""
    try:
        return TorqueGeneratorUnit(**values)
    except ModelError as exc:
        if "strictly decreasing" not in str(exc):
            raise ModelError("trials", f"the fitted function is not a valid unit ({exc}); "
                             "allowed: trials that determine it (add trials, or --hold the "
                             "parameter named)") from None
    low, high = values["min_differential_activation"], 1.0
    for _ in range(30):
        middle = 0.5 * (low + high)
        try:
            TorqueGeneratorUnit(**{**values, "min_differential_activation": middle})
            high = middle
        except ModelError:
            low = middle
    notes.append(f"min_differential_activation raised from "
                 f"{values['min_differential_activation']:.6g} to {high:.6g} so that d·T_ω "
                 "decreases strictly (docs/model.md §2.5)")
    return TorqueGeneratorUnit(**{**values, "min_differential_activation": high})


def _starts(free, base, lower, upper, torque, theta_cc, settings) -> list[np.ndarray]:
    """Starting points: the unit's values, the data's (T0 = the largest torque of the trials,
    θ_opt the CE angle where it is reached), then Latin-hypercube points in the bounds."""
    order = list(PACKED_FIELDS)
    own = np.clip([base[order.index(f)] for f in free], lower, upper)
    guess = own.copy()
    at_peak = int(np.argmax(torque))
    for i, name in enumerate(free):
        if name == "isometric_torque":
            guess[i] = torque[at_peak]
        elif name == "eccentric_torque_max":
            guess[i] = 1.4 * torque[at_peak]
        elif name == "optimal_angle":
            guess[i] = theta_cc[at_peak]
    points = [own, np.clip(guess, lower, upper)]
    if settings.starts > 2:
        sampler = stats.qmc.LatinHypercube(d=len(free), rng=np.random.default_rng(settings.seed))
        points += list(stats.qmc.scale(sampler.random(settings.starts - 2), lower, upper))
    return points[:settings.starts]


def _autocorrelation(difference: np.ndarray, phases: list[Phase]) -> float:
    """Lag-1 autocorrelation of the residuals, pairs taken within each phase, clipped to
    [0, 0.99]."""
    pairs, start = [], 0
    for phase in phases:
        part = difference[start:start + phase.rows.size]
        start += phase.rows.size
        if part.size > 1:
            pairs.append(np.column_stack([part[:-1], part[1:]]))
    if not pairs:
        return 0.0
    both = np.concatenate(pairs)
    centred = both - difference.mean()
    denominator = float(np.sum(centred[:, 0] ** 2))
    rho = float(np.sum(centred[:, 0] * centred[:, 1]) / denominator) if denominator > 0 else 0.0
    return min(max(rho, 0.0), 0.99)


def _intervals(result, free, lower, upper, difference, weights, rho):
    """95 % confidence intervals of the free parameters not at a bound (see the module's
    docstring), and the names at a bound."""
    span = upper - lower
    at_bound = {name for name, x, lo, hi, s in zip(free, result.x, lower, upper, span,
                                                     strict=True)
                if x - lo <= 1e-6 * s or hi - x <= 1e-6 * s}
    keep = [i for i, name in enumerate(free) if name not in at_bound]
    n = difference.size
    if not keep or n <= len(keep):
        return {}, at_bound
    jacobian = result.jac[:n][:, keep]
    dof = n - len(keep)
    variance = float(np.sum(weights * difference ** 2)) / dof
    covariance = np.linalg.pinv(jacobian.T @ jacobian) * variance * (1 + rho) / (1 - rho)
    effective = max(n * (1 - rho) / (1 + rho) - len(keep), 1.0)
    level = 1.0 - 0.05 / (2 * len(keep))  # Bonferroni: all intervals hold together at 95 %
    half = stats.t.ppf(level, effective) * np.sqrt(np.maximum(np.diag(covariance), 0.0))
    return ({free[i]: (float(result.x[i] - h), float(result.x[i] + h))
             for i, h in zip(keep, half, strict=True)}, at_bound)


def for_limbs(fit: StrengthFit, limbs: int) -> StrengthFit:
    """``fit`` (of one limb's trials) for a unit that stands for ``limbs`` limbs: T0 and T_max
    times ``limbs``, the SE stiffness the one-limb fit used times ``limbs`` (the other
    parameters, angles and speeds, are the limb's)."""
    p = fit.parameters
    unit = replace(p, isometric_torque=limbs * p.isometric_torque,
                   eccentric_torque_max=limbs * p.eccentric_torque_max,
                   se_stiffness=limbs * p.se_stiffness)
    intervals = {k: (tuple(limbs * v for v in i) if k in ("isometric_torque",
                                                          "eccentric_torque_max") else i)
                 for k, i in fit.intervals.items()}
    return replace(fit, parameters=unit, intervals=intervals,
                   notes=[*fit.notes, f"the unit stands for {limbs} limbs: T0 and T_max are "
                          f"{limbs} times the trials' limb's"])
