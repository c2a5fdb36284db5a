"""Rotational Hill-type torque generator unit (docs/model.md §2).

A unit is a contractile element (CE) in series with a linear torsional series elastic element
(SE). The CE torque is

    T = a(t) · d(ω_cc) · T_ω(ω_cc) · T_θ(θ_cc)                    (abstract Eq. 3)

with the tetanic torque/angular-velocity curve T_ω of Yeadon, King & Wilson (2006), the
differential activation d of Yeadon et al. (2006) in the form of Forrester et al. (2011) and a
quadratic (King-type) torque/angle curve T_θ. ω_cc > 0 is concentric (shortening).

The compiled functions take a unit's parameters as a plain float array laid out by the index
constants below (see `TorqueGeneratorUnit.to_array`). Their last argument ``o`` (default
0) is the offset of the unit's row when ``p`` holds several units' rows one after another: the
solvers pass every unit of a chain in one flat array, so the step loop creates no array views.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

import numpy as np

from ..errors import ModelError
from .fields import Allowed, check_fields
from .jit import njit

# Layout of the packed unit parameter array.
T0, T_MAX, OMEGA_MAX, OMEGA_C, SLOPE_RATIO, A_MIN, OMEGA_R, OMEGA_1 = range(8)
THETA_OPT, K2, K_SE = 8, 9, 10
# Derived constants (Yeadon et al. 2006), filled by to_array.
T_C, C_CONC, OMEGA_E, E_ECC, H_ISOMETRIC, H_ECC_LIMIT = 11, 12, 13, 14, 15, 16
CE_DAMPING = 17
UNIT_ARRAY_SIZE = 18

#: The torque/angle curve never falls below this fraction of its peak (docs/model.md §2.3).
TORQUE_ANGLE_FLOOR = 0.01
#: Activation used in the CE equation is max(a, ACTIVATION_FLOOR) (docs/model.md §2.5).
ACTIVATION_FLOOR = 0.01


#: Every field of `TorqueGeneratorUnit` with its allowed values, in the order they are
#: checked (a field that bounds another comes first).
UNIT_FIELDS: dict[str, Allowed] = {
    "isometric_torque": Allowed("N·m", "T0", 0.0, 1e4, low_open=True),
    "eccentric_torque_max": Allowed("N·m", "T_max", (1.0, "isometric_torque"),
                                    (10.0, "isometric_torque"), low_open=True),
    "max_velocity": Allowed("rad/s", "omega_max", 0.0, 200.0, low_open=True),
    "velocity_constant": Allowed("rad/s", "omega_c of the Hill hyperbola", 0.0, 1e3,
                                 low_open=True),
    "eccentric_slope_ratio": Allowed("", "eccentric/concentric slope of T_omega at 0 (Yeadon "
                                     "2006: 4.3)", 0.0, 100.0, low_open=True),
    "min_differential_activation": Allowed("", "a_min of d(omega)", 0.0, 1.0),
    "differential_activation_rate": Allowed("rad/s", "omega_r of d(omega)", 0.0, 1e3,
                                            low_open=True),
    "differential_activation_midpoint": Allowed("rad/s", "omega_1 of d(omega)",
                                                (-1.0, "max_velocity"), (1.0, "max_velocity"),
                                                low_open=True, high_open=True),
    "optimal_angle": Allowed("rad", "theta_opt of the torque/angle curve", -math.pi,
                             2 * math.pi),
    "angle_curvature": Allowed("rad^-2", "k2 of the torque/angle curve", 0.0, 1e3),
    "se_stiffness": Allowed("N·m/rad", "series elastic element", 0.0, 1e6, low_open=True),
    "ce_damping": Allowed("N·m·s/rad", "CE parallel damping beta (Millard 2013; 0 = abstract)",
                          0.0, 1e4),
}


@dataclass(frozen=True)
class TorqueGeneratorUnit:
    """Parameters of one torque generator unit (flexor or extensor).

    Attributes
    ----------
    isometric_torque : float
        T0, tetanic torque at zero CE velocity. N·m. Bounds (0, 1e4].
    eccentric_torque_max : float
        T_max, eccentric plateau of T_ω. N·m. Bounds (isometric_torque, 10 × isometric_torque].
    max_velocity : float
        ω_max, CE velocity at which T_ω reaches zero. rad/s. Bounds (0, 200].
    velocity_constant : float
        ω_c, Hill hyperbola constant of the concentric branch. rad/s. Bounds (0, 1e3].
    eccentric_slope_ratio : float
        k, ratio of eccentric to concentric slope of T_ω at ω = 0. Default 4.3. Bounds (0, 100].
    min_differential_activation : float
        a_min, lower asymptote of d(ω). Bounds [0, 1].
    differential_activation_rate : float
        ω_r, width of the d(ω) sigmoid. rad/s. Bounds (0, 1e3].
    differential_activation_midpoint : float
        ω_1, centre of the d(ω) sigmoid. rad/s. Bounds (−max_velocity, max_velocity).
    optimal_angle : float
        θ_opt, CE angle (joint-equivalent) of peak torque. rad. Bounds [−π, 2π].
    angle_curvature : float
        k2, curvature of the quadratic torque/angle curve. rad⁻². Bounds [0, 1e3].
    se_stiffness : float
        k, torsional stiffness of the series elastic element. N·m/rad. Bounds (0, 1e6].
    ce_damping : float
        β, a damper in parallel with the CE (the remedy of Millard et al. 2013, rotational
        form): the CE torque becomes a·T_θ·h(ω_cc) − β·ω_cc, which makes the CE equation
        solvable for any state and bounds the time constant below by β/k. N·m·s/rad.
        Default 0 = the abstract's model. Bounds [0, 1e4].
    """

    isometric_torque: float
    eccentric_torque_max: float
    max_velocity: float
    velocity_constant: float
    min_differential_activation: float
    differential_activation_rate: float
    differential_activation_midpoint: float
    optimal_angle: float
    angle_curvature: float
    se_stiffness: float
    eccentric_slope_ratio: float = 4.3
    ce_damping: float = 0.0

    def __post_init__(self) -> None:
        check_fields(self, UNIT_FIELDS)
        _check_monotone(self.to_array())

    @classmethod
    def flexor_default(cls) -> TorqueGeneratorUnit:
        """Elbow flexor defaults of docs/model.md §2.4 (Yeadon et al. 2006 form; Kentel et al. 2011
        curves; T0 consistent with Lategan & Krüger 2003)."""
        return cls(isometric_torque=75.0, eccentric_torque_max=101.25, max_velocity=18.0,
                   velocity_constant=5.5, min_differential_activation=0.90,
                   differential_activation_rate=0.5, differential_activation_midpoint=0.0,
                   optimal_angle=1.66, angle_curvature=0.23, se_stiffness=600.0)

    @classmethod
    def extensor_default(cls) -> TorqueGeneratorUnit:
        """Elbow extensor defaults of docs/model.md §2.4."""
        return cls(isometric_torque=60.0, eccentric_torque_max=78.0, max_velocity=18.0,
                   velocity_constant=5.5, min_differential_activation=0.90,
                   differential_activation_rate=0.5, differential_activation_midpoint=0.0,
                   optimal_angle=1.57, angle_curvature=0.15, se_stiffness=300.0)

    def as_dict(self) -> dict[str, float]:
        return asdict(self)

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))

    def to_array(self) -> np.ndarray:
        """Pack into the float array read by the compiled functions (derived constants too)."""
        return pack_unit_parameters(
            np.array([getattr(self, name) for name in PACKED_FIELDS]))


#: The fields of `TorqueGeneratorUnit` in the order `pack_unit_parameters` reads them (the
#: order of the packed array's first slots).
PACKED_FIELDS = ("isometric_torque", "eccentric_torque_max", "max_velocity", "velocity_constant",
                 "eccentric_slope_ratio", "min_differential_activation",
                 "differential_activation_rate", "differential_activation_midpoint",
                 "optimal_angle", "angle_curvature", "se_stiffness", "ce_damping")
#: Where each of `PACKED_FIELDS` sits in the packed array.
PACKED_SLOTS = (T0, T_MAX, OMEGA_MAX, OMEGA_C, SLOPE_RATIO, A_MIN, OMEGA_R, OMEGA_1,
                 THETA_OPT, K2, K_SE, CE_DAMPING)


def pack_unit_parameters(values: np.ndarray) -> np.ndarray:
    """The packed parameter array of a unit from its 12 field values in `PACKED_FIELDS`
    order, with the derived constants of Yeadon et al. (2006) (docs/model.md §2.1):
    T_c = T0·ω_c/ω_max, C = T_c·(ω_max + ω_c), ω_e = (T_max − T0)/(k·T0)·ω_max·ω_c/(ω_max + ω_c),
    E = −(T_max − T0)·ω_e. No validation: `TorqueGeneratorUnit` checks the values; a fit
    packs trial values with this before it builds the checked unit."""
    p = np.zeros(UNIT_ARRAY_SIZE)
    p[list(PACKED_SLOTS)] = values
    t0, tmax, wmax, wc, k = p[T0], p[T_MAX], p[OMEGA_MAX], p[OMEGA_C], p[SLOPE_RATIO]
    p[T_C] = t0 * wc / wmax
    p[C_CONC] = p[T_C] * (wmax + wc)
    p[OMEGA_E] = (tmax - t0) / (k * t0) * wmax * wc / (wmax + wc)
    p[E_ECC] = -(tmax - t0) * p[OMEGA_E]
    p[H_ISOMETRIC] = ce_torque_velocity(0.0, p, 0)
    p[H_ECC_LIMIT] = ce_torque_velocity(-wmax, p, 0)
    return p


#: The T_ω and d parameter sets already found monotone (h depends on p[T0 : OMEGA_1 + 1]
#: only), so that sweeps over the other fields (SE stiffness, angle curve) do not repeat the
#: check.
_MONOTONE = set()


def _check_monotone(p: np.ndarray) -> None:
    """Reject a parameter set for which h = d·T_ω is not strictly decreasing on [-ω_max, ω_max].

    h is checked on a dense grid (4001 points per branch) together with the sign of its
    analytical derivative; the CE velocity is then the unique root of h(ω) = target.
    """
    key = p[T0: OMEGA_1 + 1].tobytes()
    if key in _MONOTONE:
        return
    wmax = p[OMEGA_MAX]
    grid = np.concatenate([np.linspace(-wmax, 0.0, 4001), np.linspace(0.0, wmax, 4001)[1:]])
    values, slopes = _h_on_grid(grid, p, 0)
    slopes = slopes[:-1]
    if not (np.all(np.diff(values) < 0.0) and np.all(slopes < 0.0)):
        bad = grid[:-1][(np.diff(values) >= 0.0) | (slopes >= 0.0)][0]
        culprit = ("min_differential_activation" if p[A_MIN] < 0.5
                   else "differential_activation_rate")
        raise ModelError(
            culprit,
            f"d(ω)·T_ω(ω) is not strictly decreasing near ω = {bad:.3f} rad/s, so the CE "
            "velocity is not unique; allowed: parameter sets with a decreasing h "
            "(raise min_differential_activation or differential_activation_rate)",
        )
    if len(_MONOTONE) > 4096:
        _MONOTONE.clear()
    _MONOTONE.add(key)


@njit(cache=True, error_model="numpy")
def _h_on_grid(grid, p, o):
    """h(ω) and h'(ω) at every ω of ``grid`` (one compiled call instead of one per point)."""
    values = np.empty(grid.size)
    slopes = np.empty(grid.size)
    for i in range(grid.size):
        values[i] = ce_torque_velocity(grid[i], p, o)
        slopes[i] = ce_torque_velocity_slope(grid[i], p, o)
    return values, slopes


@njit(cache=True, error_model="numpy")
def tetanic_torque_velocity(omega, p, o=0):
    """T_ω(ω): tetanic torque/angular-velocity curve, N·m (Yeadon, King & Wilson 2006).

    Concentric (0 ≤ ω < ω_max): C/(ω_c + ω) − T_c; zero for ω ≥ ω_max;
    eccentric (ω < 0): E/(ω_e − ω) + T_max. Continuous at 0 (value T0), with a slope jump of
    factor ``eccentric_slope_ratio`` there.
    """
    if omega >= p[o + OMEGA_MAX]:
        return 0.0
    if omega >= 0.0:
        return p[o + C_CONC] / (p[o + OMEGA_C] + omega) - p[o + T_C]
    return p[o + E_ECC] / (p[o + OMEGA_E] - omega) + p[o + T_MAX]


@njit(cache=True, error_model="numpy")
def tetanic_torque_velocity_slope(omega, p, o=0):
    """dT_ω/dω, N·m·s/rad; at the kink ω = 0 the concentric (right) slope."""
    if omega >= p[o + OMEGA_MAX]:
        return 0.0
    if omega >= 0.0:
        x = p[o + OMEGA_C] + omega
        return -p[o + C_CONC] / (x * x)
    x = p[o + OMEGA_E] - omega
    return p[o + E_ECC] / (x * x)


@njit(cache=True, error_model="numpy")
def differential_activation(omega, p, o=0):
    """d(ω) = a_min + (1 − a_min)/(1 + exp(−(ω − ω_1)/ω_r)), dimensionless.

    Yeadon et al. (2006), form of Forrester et al. (2011).
    """
    return p[o + A_MIN] + (1.0 - p[o + A_MIN]) / (1.0 + math.exp(-(omega - p[o + OMEGA_1])
                                                                   / p[o + OMEGA_R]))


@njit(cache=True, error_model="numpy")
def differential_activation_slope(omega, p, o=0):
    """dd/dω, s/rad."""
    s = 1.0 / (1.0 + math.exp(-(omega - p[o + OMEGA_1]) / p[o + OMEGA_R]))
    return (1.0 - p[o + A_MIN]) * s * (1.0 - s) / p[o + OMEGA_R]


@njit(cache=True, error_model="numpy")
def torque_angle(theta_cc, p, o=0):
    """T_θ(θ_cc) = max(1 − k2·(θ_cc − θ_opt)², 0.01), dimensionless (King-type quadratic)."""
    x = theta_cc - p[o + THETA_OPT]
    return max(1.0 - p[o + K2] * x * x, TORQUE_ANGLE_FLOOR)


@njit(cache=True, error_model="numpy")
def torque_angle_slope(theta_cc, p, o=0):
    """dT_θ/dθ_cc, rad⁻¹ (zero on the floor)."""
    x = theta_cc - p[o + THETA_OPT]
    if 1.0 - p[o + K2] * x * x > TORQUE_ANGLE_FLOOR:
        return -2.0 * p[o + K2] * x
    return 0.0


@njit(cache=True, error_model="numpy")
def ce_torque_velocity(omega, p, o=0):
    """h(ω) = d(ω)·T_ω(ω), N·m: the CE torque at full activation and optimal angle."""
    return differential_activation(omega, p, o) * tetanic_torque_velocity(omega, p, o)


@njit(cache=True, error_model="numpy")
def ce_torque_velocity_slope(omega, p, o=0):
    """h'(ω) = d'·T_ω + d·T_ω', N·m·s/rad (concentric slope at the kink ω = 0)."""
    return (differential_activation_slope(omega, p, o) * tetanic_torque_velocity(omega, p, o)
            + differential_activation(omega, p, o) * tetanic_torque_velocity_slope(omega, p, o))


@njit(cache=True, error_model="numpy")
def maximum_voluntary_torque(theta_cc, omega_cc, p):
    """T_mv(θ_cc, ω_cc) = d(ω_cc)·T_ω(ω_cc)·T_θ(θ_cc), N·m, at every pair of the arrays
    ``theta_cc`` (rad) and ``omega_cc`` (rad/s, positive concentric): the CE torque of abstract
    Eq. 3 at full activation, the maximum voluntary torque function fitted to dynamometer
    trials (King, Wilson & Yeadon 2006; Forrester et al. 2011)."""
    out = np.empty(theta_cc.size)
    for i in range(theta_cc.size):
        out[i] = ce_torque_velocity(omega_cc[i], p, 0) * torque_angle(theta_cc[i], p, 0)
    return out


#: ce_velocity accepts a Halley step shorter than this (rad/s): convergence is cubic, so the
#: root is then exact to about 1e-16 rad/s. A plain Newton step must be 100× shorter.
INVERSION_STEP_TOLERANCE = 1.0e-6


@njit(cache=True, error_model="numpy")
def ce_velocity(target, p, guess=np.nan, damping=0.0, o=0):
    """CE angular velocity ω_cc solving h(ω_cc) − c·ω_cc = target (docs/model.md §2.5), rad/s.

    See `ce_velocity_and_slope`, which this returns the first part of.
    """
    return ce_velocity_and_slope(target, p, guess, damping, o)[0]


@njit(cache=True, error_model="numpy", inline="always")
def ce_velocity_and_slope(target, p, guess, damping, o=0):
    """CE angular velocity ω_cc solving f(ω) = h(ω) − c·ω − target = 0 (docs/model.md §2.5), rad/s,
    and the slope f'(ω_cc) = h'(ω_cc) − c, N·m·s/rad (−inf where ω_cc is clamped and does not
    respond to the target; the concentric slope at ω_cc = 0).

    ``target = T / (max(a, 0.01)·T_θ(θ_cc))`` in N·m, ``damping`` c = β/(max(a, 0.01)·T_θ) in
    N·m·s/rad (0, the abstract's model, unless the unit has ``ce_damping`` β). Clamps: with
    c = 0 a target ≤ 0 (slack SE) gives +ω_max; a target ≥ h(−ω_max) + c·ω_max gives −ω_max.
    Otherwise the unique root, on the branch (concentric or eccentric) that holds it, so the
    kink of T_ω at ω = 0 is never crossed: f is smooth and decreasing on the branch.

    Halley's method (cubic convergence) starts from ``guess`` (rad/s; the solvers pass a
    prediction from their previous evaluations, usually within 1e-6 rad/s of the root, so one
    step suffices) when it lies on the root's branch, else from the closed-form inverse of T_ω
    with d frozen at d(0) and c ignored. Each step costs one exp and one division (f, f', f''
    are scaled by powers of q = 1 + exp(−(ω − ω_1)/ω_r)). It is safeguarded by bisection on the
    branch's bracket, and falls back to a Newton step where Halley's denominator is not
    positive. The root does not depend on the guess beyond rounding. The slope is the one of the
    last step, taken within 1e-6 rad/s of the root.
    """
    wmax = p[o + OMEGA_MAX]
    if target <= 0.0 and damping == 0.0:
        return wmax, -np.inf
    if target >= p[o + H_ECC_LIMIT] + damping * wmax:
        return -wmax, -np.inf
    if target == p[o + H_ISOMETRIC]:
        return 0.0, ce_torque_velocity_slope(0.0, p, o) - damping
    # On the branch, with v = shift + σ·ω and u = 1/v: T_ω = scale·u + offset,
    # dT_ω/dω = −σ·scale·u², d²T_ω/dω² = 2·scale·u³.
    if target < p[o + H_ISOMETRIC]:  # concentric: T_ω = C/(ω_c + ω) − T_c
        scale, offset, shift, sigma = p[o + C_CONC], -p[o + T_C], p[o + OMEGA_C], 1.0
        lo, hi = 0.0, wmax
    else:  # eccentric: T_ω = E/(ω_e − ω) + T_max
        scale, offset, shift, sigma = p[o + E_ECC], p[o + T_MAX], p[o + OMEGA_E], -1.0
        lo, hi = -wmax, 0.0
    if lo < guess < hi:  # False for NaN
        w = guess
    else:
        w = sigma * (scale / (target * p[o + T0] / p[o + H_ISOMETRIC] - offset) - shift)
    a_min = p[o + A_MIN]
    d_range = 1.0 - a_min
    inv_rate = 1.0 / p[o + OMEGA_R]
    for _ in range(100):
        if not (lo < w < hi):
            w = 0.5 * (lo + hi)
        u = 1.0 / (shift + sigma * w)
        tet = scale * u + offset
        tet1 = -sigma * scale * u * u
        tet2 = 2.0 * scale * u * u * u
        e = math.exp((p[o + OMEGA_1] - w) * inv_rate)
        q = 1.0 + e
        # d = D/q, d' = D1/q², d'' = D2/q³  (d = a_min + (1 − a_min)/q)
        big_d = a_min * q + d_range
        big_d1 = d_range * e * inv_rate
        big_d2 = big_d1 * (e - 1.0) * inv_rate
        # F = q·f, F1 = q²·f', F2 = q³·f''
        f = big_d * tet - q * (damping * w + target)
        f1 = big_d1 * tet + q * (big_d * tet1 - damping * q)
        f2 = big_d2 * tet + q * (2.0 * big_d1 * tet1 + q * big_d * tet2)
        if f == 0.0:
            return w, f1 / (q * q)
        if f > 0.0:
            lo = w
        else:
            hi = w
        denominator = 2.0 * f1 * f1 - f * f2
        if denominator > 0.0:  # Halley: 2·f·f'/(2·f'² − f·f'')
            step = 2.0 * f * f1 * q / denominator
            tolerance = INVERSION_STEP_TOLERANCE
        else:  # Newton: f/f'
            step = f * q / f1
            tolerance = 0.01 * INVERSION_STEP_TOLERANCE
        if abs(step) <= tolerance:  # the root is in the bracket, whatever rounding says
            return min(max(w - step, lo), hi), f1 / (q * q)
        if hi - lo <= 1e-15 * (1.0 + abs(w)):
            return w, f1 / (q * q)
        w -= step
    return w, f1 / (q * q)


@njit(cache=True, error_model="numpy")
def unit_torque(stretch, p, o=0):
    """SE torque k·max(s, 0), N·m: a slack SE cannot push."""
    return p[o + K_SE] * max(stretch, 0.0)


@njit(cache=True, error_model="numpy", inline="always")
def ce_capacity(theta_cc, activation, p, o=0):
    """max(a, 0.01)·T_θ(θ_cc), dimensionless: the fraction of h(ω) the CE can produce."""
    return max(activation, ACTIVATION_FLOOR) * torque_angle(theta_cc, p, o)


@njit(cache=True, error_model="numpy", inline="always")
def ce_equation(stretch, theta_cc, activation, p, o=0):
    """(capacity, target, c) of the CE equation h(ω) − c·ω = target (docs/model.md §2.5): capacity
    max(a, 0.01)·T_θ, target = k·max(s, 0)/capacity in N·m, c = β/capacity in N·m·s/rad."""
    capacity = ce_capacity(theta_cc, activation, p, o)
    return capacity, unit_torque(stretch, p, o) / capacity, p[o + CE_DAMPING] / capacity


@njit(cache=True, error_model="numpy", inline="always")
def unit_ce_velocity(stretch, theta_cc, activation, p, guess=np.nan, o=0):
    """CE velocity ω_cc (rad/s) of a unit with SE stretch ``stretch`` at CE angle ``theta_cc``.

    It solves max(a, 0.01)·T_θ·h(ω) − β·ω = k·max(s, 0), β = ``ce_damping`` (0 by default).
    ``guess`` (rad/s) only seeds the root finder."""
    _, target, damping = ce_equation(stretch, theta_cc, activation, p, o)
    return ce_velocity(target, p, guess, damping, o)


@njit(cache=True, error_model="numpy", inline="always")
def ce_time_constant(capacity, slope, p, o=0):
    """The unit's time constant τ (s, as `unit_time_constant`) from what its CE equation's
    root finder ends with: the capacity a·T_θ (`ce_equation`) and the slope
    f' = h'(ω_cc) − β/(a·T_θ) (`ce_velocity_and_slope`): τ = a·T_θ·|f'|/k =
    (a·T_θ·|h'| + β)/k, inf where ω_cc is clamped. No extra evaluation."""
    return capacity * abs(slope) / p[o + K_SE]


@njit(cache=True, error_model="numpy")
def unit_time_constant(omega_cc, theta_cc, activation, p, o=0):
    """Time constant τ = (a·T_θ·|h'(ω_cc)| + β)/k of the unit's CE equation, s (docs/model.md §5;
    β = ``ce_damping``, 0 by default).

    Returns +inf where the CE velocity is clamped (slack SE or ±ω_max), where it does not
    respond to the state. Explicit RK4 is stable for step/τ ≤ 2.785
    (torquesim.solvers.fixed_step.RK4_STABILITY_LIMIT).
    """
    wmax = p[o + OMEGA_MAX]
    if omega_cc >= wmax or omega_cc <= -wmax:
        return np.inf
    slope = abs(ce_torque_velocity_slope(omega_cc, p, o))
    return (ce_capacity(theta_cc, activation, p, o) * slope + p[o + CE_DAMPING]) / p[o + K_SE]
