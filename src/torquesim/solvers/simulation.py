"""The friendly entry point: run a model with one of the solution techniques."""

from __future__ import annotations

import math
import time as _time
from dataclasses import replace

import numpy as np

from ..errors import ModelError, SimulationError, check_range
from ..model.body import body_kinds
from ..model.chain import ChainModel, as_chain
from ..model.elbow import default_model
from . import fixed_step as fs
from . import step_loop
from .coupling import Coupling
from .coupling_layout import ABSOLUTE_TOLERANCE, MAX_STEP, RELATIVE_TOLERANCE
from .error_control import MIN_STEP as MIN_CONTROLLED_STEP
from .rates import compiled_derivative
from .result import RunCost, SimulationResult, StabilityReport
from .techniques import (
    ERROR_CONTROL_ATOL,
    ERROR_CONTROLLED_METHODS,
    FIXED_STEP_METHODS,
    GROUND_CONTROL_ATOL,
    METHODS,
    MIN_CONTROL_ATOL,
    REFERENCE,
    SCIPY_METHODS,
    STIFF_SCIPY_METHODS,
    default_coupling,
    explicit_muscles,
    method_technique,
    nominal_order,
    runs_monolithic,
    scipy_solver,
)

# SciPy is imported only when a SciPy method is used (start-up time).
DEFAULT_STEP = 1.0e-4
REFERENCE_RTOL = 1.0e-10
REFERENCE_ATOL = 1.0e-12
#: The reference's default atol on a body on the ground. Standing still, every CE sits at the
#: kink of its force–velocity curve (ω = 0) and every speed near 0, where atol 1e-12 makes
#: Radau thrash: the squat jump's fitted model took 61 000 steps, 52 s, against 2 800 steps,
#: 1.1 s, at 1e-10, the two within 3e-10 rad of each other and of RK4 at 2.5 µs.
GROUND_REFERENCE_ATOL = 1.0e-10
DEFAULT_OUTPUT_STEP = 1.0e-3
#: Their default output grid on a body with ground contacts, s: the fixed-step runs' default
#: step. The ground force changes within milliseconds (push-off, impact), and on a 1 ms grid
#: the trapezoid of the written force misses the jump's momentum change by 2.5e-5 of it
#: (Radau at rtol 1e-10 as the error-controlled technique; 9e-7 and 5e-7 on this grid).
GROUND_OUTPUT_STEP = 1.0e-4
#: The error-controlled technique's largest step, s (`largest_step`).
MAX_CONTROLLED_STEP = 10e-3
#: Default accuracy check of fixed-step runs in `simulate`: warn when the estimated max
#: angle error exceeds this (rad; 0.5°).
DEFAULT_TOLERANCE = math.radians(0.5)


def step_count(duration: float, step: float, field: str = "step") -> int:
    """Number of fixed steps, round(duration/step); the step must divide the duration
    within 1e-9 s."""
    check_range(field, step, 0.0, duration, low_open=True, unit="s")
    n = round(duration / step)
    if n < 1 or abs(n * step - duration) > 1e-9:
        raise ModelError(field, f"{step!r} s does not divide the duration {duration!r} s "
                         "(allowed: duration/step a whole number, within 1e-9 s)")
    if n > 200_000_000:
        raise ModelError(field, f"{step!r} s needs {n} steps; allowed at most 2e8")
    return n


def simulate(
    model=None,
    method: str = "monolithic",
    step: float | None = None,
    *,
    duration: float | None = None,
    coupling: Coupling | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    output_step: float | None = None,
    initial_state=None,
    check: bool = True,
    advise: bool = True,
    tolerance: float | None = DEFAULT_TOLERANCE,
    progress=None,
) -> SimulationResult:
    """Simulate ``model`` (default: the built-in curl) with one solution technique.

    Parameters
    ----------
    model : ChainModel or ElbowModel, optional
        Any planar chain (`torquesim.load_model` of a file or ``"builtin:NAME"``); an
        ElbowModel is simulated as its one-segment chain.
    method : str
        One of `METHODS` or "scipy:NAME". ``monolithic``: classical RK4 on the whole state.
        ``partitioned``: each part with its own RK4, exchanging at step boundaries as
        ``coupling`` says (default zero-order hold). ``imex``: the body on explicit RK4, each
        unit's CE equation on implicit SDIRK2. ``imex-ros2``: the body on ROS2, linearly
        implicit in the end stops and contacts. ``imex-ros2-adaptive``: imex-ros2 at steps an
        error estimate chooses, at the angle tolerance ``atol`` (rad; default 1e-5,
        `ERROR_CONTROL_ATOL`; on a body with ground contacts 5e-8, `GROUND_CONTROL_ATOL`).
        ``reference``: SciPy Radau at ``rtol`` (default 1e-10, `REFERENCE_RTOL`) and ``atol``
        (default 1e-12; on a body with ground contacts 1e-10, `GROUND_REFERENCE_ATOL`).
        ``scipy:RK45`` etc.: that SciPy solver on the whole system, at ``rtol`` and ``atol``
        (the same defaults).
    step : float or None
        Fixed step for the RK4 methods, s. Must divide the duration. Default (None): chosen
        from the model (`default_step_run`): 0.1 ms (`default_fixed_step`), or, where a run
        at it breaks the stability limit of the technique's explicit part (stiff units or
        contacts), the largest step a run verifies (`verified_run`), said in
        ``result.settings["step_note"]``.
    duration : float, optional
        Overrides the model's duration, s.
    output_step : float, optional
        Output grid of the adaptive solvers (SciPy's, the reference and the error-controlled
        technique), s; it must divide the duration. Default 1 ms (0.1 ms on a body with
        ground contacts), or the largest step below it that divides the duration.
    initial_state : array, optional
        y(0) = (q, q̇, θ_cc of every unit) replacing the static-equilibrium start.
    check : bool
        Raise `SimulationError` if the state goes non-finite or leaves the physically
        possible range (default); otherwise return the failed result with
        ``status == "failed"``.
    advise : bool
        Fixed-step runs that fail or break the stability limit: find the step to recommend by
        running it (`verified_run`), so the advice holds when followed. Default True;
        studies that try many steps on purpose turn it off. (With ``step`` None the search
        runs regardless: it chooses the step.)
    tolerance : float or None
        SciPy solvers (``scipy:NAME``; not ``reference``): estimate the max angle error
        against a run at ``rtol`` and ``atol`` `TIGHTER` times tighter and warn as below
        (their error control can pass a run that is far off: the explicit ones at loose
        tolerances on stiff units, tests/test_wrong_numbers.py). Fixed-step runs: estimate
        the max angle error by Richardson extrapolation against a run at twice the step (half
        a run's work) and, when that exceeds the tolerance, against a run at half the step
        (error ≈ max|q_h − q_h/2|·2^p/(2^p − 1), p the technique's order, `nominal_order`),
        and warn (``result.message``) when it exceeds ``tolerance`` (rad). Default 0.5°; None
        turns the check off. The estimate is
        in ``result.settings["estimated_error_rad"]``.
    progress : callable, optional
        ``progress(text)`` hears, in one line each, the steps tried when a fixed-step run
        failed or broke the stability limit and the search for a step a run verifies runs
        (up to 16 more runs at ever smaller steps: seconds on a stiff model).
    """
    model = as_chain(default_model() if model is None else model)
    if not isinstance(method, str):
        raise TypeError(f"method: expected a string such as 'monolithic', got "
                        f"{type(method).__name__}")
    if coupling is not None and not isinstance(coupling, Coupling):
        raise TypeError(f"coupling: expected a torquesim.Coupling, got {type(coupling).__name__}")
    if duration is not None:
        model = model.replace(duration=check_range("duration", duration, 0.0, 600.0,
                                                   low_open=True, unit="s"))
    if output_step is None:
        output_step = default_output_step(model.duration, bool(model.contacts))
    start = model.initial_state()
    packed = model.pack(start.levels)
    y0 = start.state if initial_state is None else _check_state(initial_state, model)
    if method in FIXED_STEP_METHODS:
        coupling = coupling or default_coupling(method)
        if not explicit_muscles(method) and not coupling.implicit_muscles:
            raise ModelError("coupling.muscle_solver", f"method {method!r} needs an implicit "
                             "muscle solver; allowed: sdirk2")
        if tolerance is not None:
            check_range("tolerance", tolerance, 0.0, math.pi, low_open=True, unit="rad")
        if step is None:
            result = default_step_run(model, packed, y0, method, coupling, progress)
        else:
            result = _fixed_step(model, packed, y0, method, step, coupling)
            if advise and (not result.success or result.stability.exceeded):
                safe = verified_run(model, packed, y0, method, step, coupling,
                                    _search_progress(progress, result))
                result = _with_advice(result, None if safe is None else safe.step)
        if tolerance is not None and result.success:
            result = _with_error_estimate(result, model, packed, y0, method, coupling,
                                          tolerance)
    elif method in ERROR_CONTROLLED_METHODS:
        if atol is None:
            atol = GROUND_CONTROL_ATOL if model.contacts else ERROR_CONTROL_ATOL
        rtol = 0.0 if rtol is None else rtol
        check_range("atol", atol, MIN_CONTROL_ATOL, 1.0, unit="rad")
        check_range("rtol", rtol, 0.0, 1.0)
        result = _error_controlled(model, packed, y0, method, atol, rtol, output_step)
        if tolerance is not None and result.success:
            check_range("tolerance", tolerance, 0.0, math.pi, low_open=True, unit="rad")
            result = _with_controlled_estimate(result, model, packed, y0, method, tolerance)
    elif (name := scipy_solver(method)) is not None:
        if name not in SCIPY_METHODS:
            allowed = ", ".join(f"scipy:{m}" for m in SCIPY_METHODS)
            raise ModelError("method", f"{method!r}: allowed {allowed}")
        if atol is None:
            atol = GROUND_REFERENCE_ATOL if model.contacts else REFERENCE_ATOL
        rtol = REFERENCE_RTOL if rtol is None else rtol
        check_range("rtol", rtol, 1e-14, 1.0)
        check_range("atol", atol, 1e-16, 1.0)
        result = _adaptive(model, packed, y0, method, name, rtol, atol, output_step)
        if tolerance is not None and method != REFERENCE and result.success:
            check_range("tolerance", tolerance, 0.0, math.pi, low_open=True, unit="rad")
            result = _with_tighter_estimate(result, model, packed, y0, method, name, tolerance)
    else:
        raise ModelError("method", f"{method!r} is not one of {', '.join(METHODS)} or scipy:NAME")
    if model.contacts and result.states.shape[0] > 1:  # (a failed run: up to its failure)
        result = _with_ground_check(result, model)
    if check and not result.success:
        raise SimulationError(result.message)
    return result


#: A joint or a segment's centre of mass this far below the ground (y = 0), and below the
#: deepest contact point, has passed through it, m: only the contact points meet the ground
#: (they sink millimetres; a joint at a contact point sinks with it).
THROUGH_GROUND = 0.05


def _with_ground_check(result: SimulationResult, model: ChainModel) -> SimulationResult:
    """``result`` with a warning (``result.message``) when a joint or a segment's centre of mass
    goes more than `THROUGH_GROUND` below the ground and below the deepest contact point:
    only the contact points meet the ground, so the body passes through it and the motion
    from there on is not physical (the squat jump run for 3 s lands, falls and ends with its
    centre of mass 1 m underground)."""
    states = result.states if result.success else result.states[:-1]  # (not the failure)
    where = model.kinematics(states[:, :model.n_base + model.n_joints])
    heights = np.concatenate([where["joints"][..., 1], where["centres"][..., 1]], axis=1)
    index = {p.name: i for i, p in enumerate(model.points)}
    contacts = where["points"][:, [index[c.point] for c in model.contacts], 1]
    floor = np.minimum(contacts.min(axis=1), 0.0) - THROUGH_GROUND
    below = np.flatnonzero(np.any(heights < floor[:, None], axis=1))
    if below.size == 0:
        return result
    row = int(below[0])
    k = int(np.argmin(heights[row]))
    n = model.n_joints
    what = f"the {model.joints[k].name} joint" if k < n else \
        f"the {model.segments[k - n].name}'s centre of mass"
    points = ", ".join(c.point for c in model.contacts)
    warning = (f"at t = {result.time[row]:.4g} s {what} is {-heights[row, k] * 100:.0f} cm "
               f"below the ground: only the contact points ({points}) meet it, so the body "
               "passes through the ground and the motion from there on is not physical; end "
               f"the run before (duration ≤ {result.time[row]:.3g} s) or add contact points")
    said = result.message.rstrip(".")
    return replace(result, message=f"{said}. Also: {warning}" if said else warning)


def _check_state(initial_state, model: ChainModel) -> np.ndarray:
    try:
        y0 = np.asarray(initial_state, dtype=float)
    except (TypeError, ValueError):
        y0 = np.full(0, np.nan)
    if y0.shape != (model.state_size,) or not np.all(np.isfinite(y0)):
        raise ModelError("initial_state", f"must be {model.state_size} finite numbers "
                         f"({', '.join(model.state_names())})")
    return y0.copy()


def _fixed_step(model, packed, y0, method, step, coupling) -> SimulationResult:
    n = step_count(model.duration, step)
    out = np.empty((n + 1, model.state_size))
    stats = fs.new_stats()
    partitioned = not runs_monolithic(method)
    if partitioned:
        label, exchange = coupling.label(), coupling.to_array()
    else:
        label, exchange = method, np.zeros(fs.COUPLING_SIZE)  # unused
    kinds = step_loop.model_step_kinds(model, not partitioned, exchange)
    run = step_loop.run_step_loop  # (from Python: only the chosen loop is compiled)
    # A zero-step call compiles the loop (or loads it from the disk cache) outside the timing.
    run(kinds, tuple(packed), y0, float(step), 0, exchange, out, fs.new_stats())
    start = _time.perf_counter()
    run(kinds, tuple(packed), y0, float(step), n, exchange, out, stats)
    wall = _time.perf_counter() - start
    done = int(stats[fs.STEPS])
    times = np.arange(done + 1) * step
    implicit = partitioned and coupling.implicit_muscles
    # the step the units are integrated at (the partitioned loop's muscle sub-steps)
    muscle_step = step if kinds.monolithic else step / coupling.muscle_substeps
    stability = StabilityReport(float(stats[fs.WORST_RATIO]), float(stats[fs.WORST_TIME]),
                                model.units[int(stats[fs.WORST_UNIT])].name
                                if model.units else "", muscle_step,
                                math.inf if implicit else fs.RK4_STABILITY_LIMIT)
    contact_ratio = float(stats[fs.CONTACT_RATIO])
    # (the contacts bind explicit RK4 in the body part, not its implicit ROS2)
    if not (partitioned and coupling.implicit_body) and \
            contact_ratio / fs.RK4_STABILITY_LIMIT > stability.max_step_ratio / stability.limit:
        point = model.contacts[int(stats[fs.CONTACT_INDEX])].point
        stability = StabilityReport(contact_ratio, float(stats[fs.CONTACT_TIME]),
                                    f"ground contact at {point}", step)
    status, message = "success", ""
    if stats[fs.STATUS] != fs.OK:
        what = "went non-finite" if stats[fs.STATUS] == fs.NON_FINITE else \
            _out_of_range(model, out[done])
        status = "failed"
        message = (f"{label} with step {step * 1e3:g} ms: the state {what} at t = "
                   f"{times[-1]:.6g} s: the step is too large for this motion; "
                   + _advice_text(stability.largest_safe_step,
                                  implicit=implicit or stability.in_contact))
    elif stability.exceeded:
        message = stability.message()
    else:
        message = _resolution_warning(model, step)
    cost = RunCost(done, int(stats[fs.NFEV_BODY]), int(stats[fs.NFEV_MUSCLE]), wall,
                   newton_iterations=int(stats[fs.NEWTON_ITERATIONS]),
                   implicit_solves=int(stats[fs.IMPLICIT_SOLVES]),
                   jacobians=int(stats[fs.BODY_JACOBIANS]),
                   lu_decompositions=int(stats[fs.BODY_JACOBIANS]))
    settings = {"step": step, "steps": n}
    if model.contacts:  # which part is stiff: the smallest time constant of each, s
        settings["unit_time_constant_min_s"] = muscle_step / float(stats[fs.WORST_RATIO]) \
            if stats[fs.WORST_RATIO] > 0 else math.inf
        settings["contact_time_constant_min_s"] = step / contact_ratio \
            if contact_ratio > 0 else math.inf
    if partitioned:
        settings["coupling"] = coupling.__dict__.copy()
        # The exchange's jumps at the step ends (a diagnostic, not the accuracy check: see
        # docs/study.md, "No wrong run without a word").
        settings["coupling_jump"] = {
            "torque_jump_integral_nms": float(stats[fs.COUPLING_TORQUE]),
            "largest_torque_jump_nm": float(stats[fs.COUPLING_TORQUE_MAX]),
            "largest_at_s": float(stats[fs.COUPLING_TIME]),
            "angle_jump_sum_rad": float(stats[fs.COUPLING_ANGLE])}
    return SimulationResult(model, packed, times, out[: done + 1], label, float(step), cost,
                            stability, status, message, settings)


def _out_of_range(model: ChainModel, y) -> str:
    """Which joint left the physically possible range in state ``y``, in words."""
    limits = model.speed_limits()
    n, nb = model.n_coordinates, model.n_base
    for k, joint in enumerate(model.joints):
        i = nb + k
        angle = math.degrees(y[i])
        if abs(y[n + i]) > limits[i]:
            return (f"left the physically possible range ({joint.coordinate} speed "
                    f"{y[n + i]:.3g} rad/s, beyond the limit {limits[i]:g} rad/s)")
        if nb and k == 0:
            continue  # a free base's angle has no end stops
        if not (joint.endstop_lower_angle - 2 * math.pi <= y[i]
                <= joint.endstop_upper_angle + 2 * math.pi):
            return (f"left the physically possible range ({joint.coordinate} = {angle:.4g}°, "
                    "more than a full turn beyond its end stops)")
    return "left the physically possible range"


def _advice_text(safe_step: float, verified: bool = False, implicit: bool = False) -> str:
    """What to change after a failed run; ``implicit``: the run's muscles were already
    implicit (IMEX), or a ground contact limits the step, so the advice is a smaller step or
    the reference solver."""
    others = "method 'reference'" if implicit else \
        "method 'imex' (implicit muscles) or 'reference'"
    if not math.isfinite(safe_step) or safe_step <= 0.0:
        return f"use {others}" if not implicit else f"use a smaller step or {others}"
    how = " (a run at that step was checked)" if verified else ""
    return f"use a step ≤ {safe_step * 1e3:.4g} ms{how} or {others}"


#: The advised step must agree with a run at half of it to this (rad, max over the motion).
ADVICE_AGREEMENT = 1.0e-3
#: How many halvings of the step the advice search tries, and the most steps a trial run of
#: it may take (beyond that the advice is the implicit methods, given in seconds, not minutes).
ADVICE_HALVINGS = 8
ADVICE_MAX_STEPS = 1_000_000


def divisor_step(duration: float, step: float) -> float:
    """The largest step ≤ ``step`` that divides ``duration``, s."""
    return duration / math.ceil(duration / step - 1e-9)


def default_output_step(duration: float, contacts: bool = False) -> float:
    """The adaptive methods' default output grid for ``duration`` (s): `DEFAULT_OUTPUT_STEP`
    (`GROUND_OUTPUT_STEP` on a body with ground contacts), or the largest step below it that
    divides the duration."""
    return divisor_step(duration, GROUND_OUTPUT_STEP if contacts else DEFAULT_OUTPUT_STEP)


def _max_difference(coarse, fine) -> float:
    """Max |q_coarse − q_fine| (rad) on the coarse grid (the fine step divides it)."""
    k = int(round(coarse.step / fine.step))
    n = min(coarse.time.size, (fine.time.size - 1) // k + 1)
    return float(np.max(np.abs(coarse.q[:n] - fine.q[::k][:n])))


def _search_progress(progress, result: SimulationResult):
    """``progress`` (`simulate`'s, or None) as `verified_run`'s: each trial step in a line
    that says why the search runs (``result``, the run that failed or broke the limit)."""
    if progress is None:
        return None
    report = result.stability
    what = "failed" if not result.success else "broke the stability limit in " + (
        report.unit if report.in_contact else f"the {report.unit} unit")
    return lambda h: progress(f"the run at {result.step * 1e3:.4g} ms {what}; searching for "
                              f"the largest step a run verifies: trying {h * 1e3:.4g} ms")


def verified_run(model, packed, y0, method, step, coupling,
                 progress=None) -> SimulationResult | None:
    """The run at the step to recommend after a fixed-step run at ``step`` failed or broke the
    stability limit, found by running: the largest of step/2, step/4, … (made to divide the
    duration) whose run succeeds within the stability limit and agrees with a run at half
    that step to `ADVICE_AGREEMENT` rad. None if no step down to step/2^8 (and no run of at
    most `ADVICE_MAX_STEPS` steps) does. ``progress(h)`` hears of each step tried."""
    h = step
    for _ in range(ADVICE_HALVINGS):
        h = divisor_step(model.duration, h / 2)
        if 2 * model.duration / h > ADVICE_MAX_STEPS:  # the run at half of it included
            return None
        if progress is not None:
            progress(h)
        trial = _fixed_step(model, packed, y0, method, h, coupling)
        if not trial.success or trial.stability.exceeded:
            continue
        half = _fixed_step(model, packed, y0, method, h / 2, coupling)
        if half.success and _max_difference(trial, half) <= ADVICE_AGREEMENT:
            return trial
    return None


def default_fixed_step(duration: float) -> float:
    """The first choice of a fixed step on a run of ``duration`` s: `DEFAULT_STEP` where it
    divides the duration (within 1e-9 s, as `step_count` asks), else the largest step
    below it that does (`divisor_step`)."""
    n = round(duration / DEFAULT_STEP)
    if n >= 1 and abs(n * DEFAULT_STEP - duration) <= 1e-9:
        return DEFAULT_STEP
    return divisor_step(duration, DEFAULT_STEP)


def default_step_run(model, packed, y0, method, coupling, progress=None) -> SimulationResult:
    """A fixed-step run at the step chosen from the model: `default_fixed_step`; where that
    run fails or breaks the stability limit of the technique's explicit part (the muscle
    part of monolithic and partitioned RK4 on stiff units, the contacts of every technique),
    the run `verified_run` finds, with a note saying so in ``settings["step_note"]``. (Where
    none is found, the run at the first step, whose message then says what to change.)
    ``progress`` as `simulate`'s."""
    step = default_fixed_step(model.duration)
    result = _fixed_step(model, packed, y0, method, step, coupling)
    if result.success and not result.stability.exceeded:
        return result
    chosen = verified_run(model, packed, y0, method, step, coupling,
                          _search_progress(progress, result))
    if chosen is None:
        return _with_advice(result, None)
    report = result.stability
    where = report.unit if report.in_contact else f"the {report.unit} unit"
    others = "" if math.isinf(report.limit) or report.in_contact else \
        " (method 'imex', implicit muscles, is stable at larger steps)"
    note = (f"the default step {step * 1e3:.4g} ms is beyond explicit RK4's stability limit "
            f"in {where} of {model.name}; ran at {chosen.step * 1e3:.4g} ms, the largest step "
            f"a run verified{others}")
    return replace(chosen, settings={**chosen.settings, "step_note": note})


def _with_advice(result: SimulationResult, safe: float | None) -> SimulationResult:
    """``result`` with its stability report and message carrying the verified advice."""
    stability = replace(result.stability, verified_step=safe if safe is not None else 0.0)
    if result.success:
        message = stability.message()
    else:
        head = result.message.split("; use ")[0]
        advice = _advice_text(stability.largest_safe_step, safe is not None,
                              math.isinf(stability.limit) or stability.in_contact)
        message = f"{head}; {advice}"
    return replace(result, stability=stability, message=message)


def _doubling_estimate(result, model, packed, y0, method, coupling, p) -> float | None:
    """Max angle error of ``result`` estimated against a run at twice its step (Richardson:
    max|q_h − q_2h|/(2^p − 1)); half a run's worth of work. None when the step count is odd,
    the coarse run fails or breaks the stability limit (it then says nothing about this
    run)."""
    n = int(result.settings["steps"])
    if n % 2 or n < 4:
        return None
    coarse = _fixed_step(model, packed, y0, method, 2 * result.step, coupling)
    if not coarse.success or coarse.stability.exceeded:
        return None
    return _max_difference(coarse, result) / (2**p - 1)


def _with_error_estimate(result, model, packed, y0, method, coupling, tolerance):
    """``result`` with an estimate of its max angle error (rad) and a warning above
    ``tolerance``.

    First against a run at twice the step (half a run's work); when that estimate exceeds the
    tolerance or cannot be made, against a run at half the step (two runs' work):
    max|q_h − q_h/2|·2^p/(2^p − 1), which decides. p is the technique's order
    (`nominal_order`). A run within the tolerance thus costs 1.5 runs, a flagged one
    3.5."""
    p = nominal_order(method, coupling)
    estimate = _doubling_estimate(result, model, packed, y0, method, coupling, p)
    how = "step doubling"
    if estimate is None or estimate > tolerance:
        half = _fixed_step(model, packed, y0, method, result.step / 2, coupling)
        estimate = (_max_difference(result, half) * 2**p / (2**p - 1) if half.success
                    else math.inf)
        how = "step halving"
    if not estimate > tolerance:
        advice = ""
    elif result.stability.verified_step is not None:  # the stability advice stands
        advice = "follow the stability advice above"
    elif math.isfinite(estimate):
        shrink = (tolerance / estimate) ** (1.0 / p)
        advice = f"a step ≤ {result.step * shrink * 1e3:.3g} ms should meet it (order {p})"
    else:
        advice = "use a smaller step or method 'reference'"
    if advice and not runs_monolithic(method) and not coupling.implicit_muscles:
        advice += ", or method 'imex'"
    return _with_estimate(result, estimate, tolerance, how, advice,
                          "the run at half the step failed")


def _with_estimate(result, estimate, tolerance, how, advice, unavailable):
    """``result`` with its estimated max angle error ``estimate`` (rad; made by ``how``) in
    its settings and, above ``tolerance`` (rad), a warning ending in ``advice``;
    ``unavailable`` says why an infinite estimate is none (its run failed)."""
    settings = {**result.settings, "estimated_error_rad": estimate, "tolerance_rad": tolerance,
                "error_estimate": how}
    message = result.message
    if estimate > tolerance:
        warning = (f"estimated max angle error {math.degrees(estimate):.3g}° ({how}) "
                   f"exceeds the tolerance {math.degrees(tolerance):.3g}°: {advice}"
                   if math.isfinite(estimate) else
                   f"{unavailable}, so no error estimate stands for this run: {advice}")
        message = f"{message} Also: {warning}" if message else warning
    return replace(result, settings=settings, message=message)


#: A fixed step longer than this fraction of the shortest activation ramp does not resolve the
#: activation: the run is stable (IMEX) but inaccurate.
RAMP_RESOLUTION = 0.1


def _resolution_warning(model, step) -> str:
    """A warning when the step is too coarse for the activation ramps, else ""."""
    ramps = [r.duration for unit in model.units for r in unit.activation.ramps]
    if not ramps or step <= RAMP_RESOLUTION * min(ramps):
        return ""
    return (f"step {step * 1e3:g} ms is longer than a tenth of the shortest activation ramp "
            f"({min(ramps):.3g} s): the activation is not resolved and the motion is "
            f"inaccurate; use a step ≤ {RAMP_RESOLUTION * min(ramps) * 1e3:.3g} ms")


#: The accuracy check of a SciPy run at the caller's tolerances: the run again at tolerances
#: this many times tighter (`_with_tighter_estimate`).
TIGHTER = 10.0


def _with_tighter_estimate(result, model, packed, y0, method, name, tolerance):
    """``result`` (a SciPy run) with an estimate of its max angle error (rad) and a warning
    above ``tolerance``: max|q − q_tight| against the run at rtol and atol `TIGHTER` times
    tighter (the tighter run taken as right; it failing, the estimate is infinite)."""
    rtol, atol = result.settings["rtol"], result.settings["atol"]
    tight = _adaptive(model, packed, y0, method, name, max(rtol / TIGHTER, 1e-14),
                      max(atol / TIGHTER, 1e-16), result.settings["output_step"])
    n = min(tight.time.size, result.time.size)
    estimate = float(np.max(np.abs(result.q[:n] - tight.q[:n]))) \
        if tight.success else math.inf
    how = f"against rtol and atol {TIGHTER:g}x tighter"
    explicit = "" if name in STIFF_SCIPY_METHODS else \
        " (an explicit solver: on stiff units or contacts use scipy:Radau or scipy:BDF)"
    return _with_estimate(result, estimate, tolerance, how,
                          f"use smaller rtol and atol{explicit}, or method 'reference'",
                          f"the run {how} failed")


#: The accuracy check of an error-controlled run: the run again at an atol this many times
#: tighter (`_with_controlled_estimate`).
CONTROLLED_TIGHTER = 4.0


def _with_controlled_estimate(result, model, packed, y0, method, tolerance):
    """``result`` (an error-controlled run) with an estimate of its max angle error (rad) and
    a warning above ``tolerance``: max|q − q_tight|·c/(c − 1) against the run at atol
    c = `CONTROLLED_TIGHTER` times tighter and at half the largest step, the global error
    being proportional to atol where the control chooses the steps (tests/test_error_control.py
    measures it) and to h² where the largest step does (order 2: half the step, a quarter of
    the error); the tighter run failing, infinite. (At a loose atol every step is the
    largest, and a run at a tighter atol alone would repeat it: the estimate would be 0.)"""
    c = CONTROLLED_TIGHTER
    settings = result.settings
    tight = _error_controlled(model, packed, y0, method, settings["atol"] / c,
                              settings["rtol"] / c, settings["output_step"],
                              settings["max_step"] / math.sqrt(c))
    n = min(tight.time.size, result.time.size)  # (the same grid)
    estimate = float(np.max(np.abs(result.q[:n] - tight.q[:n]))) * c / (c - 1.0) \
        if tight.success else math.inf
    how = f"against atol {c:g}x tighter, largest step halved"
    return _with_estimate(result, estimate, tolerance, how,
                          "use a smaller atol, or method 'reference'", f"the run {how} failed")


def largest_step(model: ChainModel) -> float:
    """The error-controlled loop's largest step, s: `RAMP_RESOLUTION` of the shortest
    activation ramp (so that no ramp falls between a step's stage times), at most
    `MAX_CONTROLLED_STEP` and a tenth of the duration."""
    ramps = [r.duration for unit in model.units for r in unit.activation.ramps]
    return min([MAX_CONTROLLED_STEP, 0.1 * model.duration,
                *(RAMP_RESOLUTION * r for r in ramps if r > 0.0)])


def control_array(model: ChainModel, coupling: Coupling, atol: float, rtol: float = 0.0,
                  max_step: float | None = None) -> np.ndarray:
    """The packed ``coupling`` with the error-controlled loop's settings: the angle tolerance
    ``atol`` (rad), ``rtol`` and the largest step (default the model's `largest_step`)."""
    control = coupling.to_array()
    control[ABSOLUTE_TOLERANCE] = atol
    control[RELATIVE_TOLERANCE] = rtol
    control[MAX_STEP] = largest_step(model) if max_step is None else max_step
    return control


def _error_controlled(model, packed, y0, method, atol, rtol, output_step,
                      max_step=None) -> SimulationResult:
    """A run of the error-controlled ``method`` (`error_control`, its registered coupling)
    at the angle tolerance ``atol`` (rad) and ``rtol``, written on the grid of
    ``output_step``; ``max_step`` as in `control_array`."""
    n = step_count(model.duration, output_step, "output_step")
    out = np.empty((n + 1, model.state_size))
    stats = fs.new_stats()
    control = control_array(model, method_technique(method).coupling, atol, rtol, max_step)
    kinds = step_loop.model_step_kinds(model, False, control)
    run = step_loop.run_step_loop
    run(kinds, tuple(packed), y0, float(output_step), 0, control, out, fs.new_stats())
    start = _time.perf_counter()
    run(kinds, tuple(packed), y0, float(output_step), n, control, out, stats)
    wall = _time.perf_counter() - start
    rows = int(stats[fs.ROWS])
    times = np.arange(rows) * output_step
    status, message = "success", ""
    if stats[fs.STATUS] != fs.OK:
        at = float(stats[fs.WORST_TIME])
        what = {fs.NON_FINITE: "the state went non-finite",
                fs.STEP_TOO_SMALL: f"the error control's step fell below "
                                   f"{MIN_CONTROLLED_STEP:g} s"}.get(
            int(stats[fs.STATUS]), f"the state {_out_of_range(model, out[max(rows - 1, 0)])}")
        status = "failed"
        message = (f"{method} at atol {atol:g} rad failed at t = {at:.6g} s: {what}; use a "
                   "larger atol (the step then stays larger) or method 'reference'")
    cost = RunCost(int(stats[fs.STEPS]), int(stats[fs.NFEV_BODY]), int(stats[fs.NFEV_MUSCLE]),
                   wall, newton_iterations=int(stats[fs.NEWTON_ITERATIONS]),
                   implicit_solves=int(stats[fs.IMPLICIT_SOLVES]),
                   jacobians=int(stats[fs.BODY_JACOBIANS]),
                   lu_decompositions=int(stats[fs.BODY_JACOBIANS]))
    events = int(stats[fs.EVENTS])
    settings = {"rtol": rtol, "atol": atol, "output_step": output_step,
                "max_step": float(control[MAX_STEP]),
                "rejected_steps": int(stats[fs.REJECTED_STEPS]),
                "smallest_step": float(stats[fs.SMALLEST_STEP]),
                "largest_step": float(stats[fs.LARGEST_STEP]),
                "events": events,
                "event_times": [float(v) for v in
                                stats[fs.EVENT_TIMES:fs.EVENT_TIMES + min(events, fs.EVENT_SLOTS)]]}
    # (no stability report: both parts' stiff terms are implicit, and the step varies)
    return SimulationResult(model, packed, times, out[:rows], method, None, cost, None,
                            status, message, settings)


def _adaptive(model, packed, y0, label, name, rtol, atol, output_step) -> SimulationResult:
    """Drive a SciPy solver step by step (counting accepted steps and every right-hand-side
    call, Jacobian differences included) and sample its dense output on the output grid."""
    n_out = step_count(model.duration, output_step, "output_step")
    grid = np.arange(n_out + 1) * output_step
    grid[-1] = model.duration
    calls = [0]
    body = body_kinds(packed.segments, model.n_coordinates)

    def rhs(t, y):
        calls[0] += 1
        # contiguous: SciPy passes views, which would compile a second specialization
        return compiled_derivative(t, np.ascontiguousarray(y, dtype=float), tuple(packed), body)

    states = np.full((grid.size, model.state_size), np.nan)
    states[0] = y0
    filled, steps, message = 1, 0, ""
    rhs(0.0, y0)  # compile outside the timing
    calls[0] = 0
    start = _time.perf_counter()
    with np.errstate(all="ignore"):
        import scipy.integrate

        solver = getattr(scipy.integrate, name)(rhs, 0.0, y0, model.duration, rtol=rtol, atol=atol)
        while solver.status == "running":
            try:
                message = solver.step() or ""
            except (ValueError, ArithmeticError, np.linalg.LinAlgError) as error:
                # SciPy raises, not fails, on a Jacobian or an LU of a non-finite state (any
                # other ValueError is not the run's: it propagates)
                if type(error) is ValueError and "infs or nans" not in str(error).lower():
                    raise
                message = f"the state went non-finite ({error})"
                break
            if solver.status == "failed":
                break
            steps += 1
            upto = int(np.searchsorted(grid, solver.t, side="right"))
            if upto > filled:
                states[filled:upto] = solver.dense_output()(grid[filled:upto]).T
                filled = upto
            if not np.all(np.isfinite(solver.y)):
                message = "the state went non-finite"
                break
    wall = _time.perf_counter() - start
    ok = filled == grid.size and np.all(np.isfinite(states))
    if not ok:
        others = "" if label == REFERENCE else f" or method '{REFERENCE}'"
        advice = (f"use smaller rtol and atol{others}" if "spacing between numbers" not in
                  message else "the motion there needs steps below the time's resolution "
                  "(check it up to that time: a body falling through the ground or a unit "
                  "beyond its range), or use larger rtol and atol")
        message = (f"{label} (rtol {rtol:g}, atol {atol:g}) failed at t = {solver.t:.6g} s: "
                   f"{(message or 'stopped early').rstrip('.')}; {advice}")
    cost = RunCost(steps, calls[0], calls[0], wall,
                   jacobians=int(getattr(solver, "njev", 0) or 0),
                   lu_decompositions=int(getattr(solver, "nlu", 0) or 0))
    settings = {"rtol": rtol, "atol": atol, "solver": name, "output_step": output_step,
                "njev": int(getattr(solver, "njev", 0)), "nlu": int(getattr(solver, "nlu", 0))}
    return SimulationResult(model, packed, grid[:filled], states[:filled], label, None, cost,
                            None, "success" if ok else "failed", message, settings)
