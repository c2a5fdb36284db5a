"""The friendly entry point: run a model with one of the solution techniques."""

from __future__ import annotations

import math
import time as _time

import numpy as np
from scipy.integrate import solve_ivp

from ..errors import ModelError, SimulationError, check_range
from ..model.elbow import ElbowModel, default_model
from . import fixed_step as fs
from .coupling import Coupling
from .rates import elbow_rates
from .result import UNIT_NAMES, RunCost, SimulationResult, StabilityReport

FIXED_STEP_METHODS = ("monolithic", "partitioned")
#: SciPy solvers usable on the whole system (``scipy:NAME``); ``reference`` is Radau.
SCIPY_METHODS = ("RK45", "DOP853", "Radau", "BDF", "LSODA")
METHODS = (*FIXED_STEP_METHODS, "reference")
DEFAULT_STEP = 1.0e-4
REFERENCE_RTOL = 1.0e-10
REFERENCE_ATOL = 1.0e-12
DEFAULT_OUTPUT_STEP = 1.0e-3


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
    model: ElbowModel | None = None,
    method: str = "monolithic",
    step: float = DEFAULT_STEP,
    *,
    duration: float | None = None,
    coupling: Coupling | None = None,
    rtol: float = REFERENCE_RTOL,
    atol: float = REFERENCE_ATOL,
    output_step: float = DEFAULT_OUTPUT_STEP,
    initial_state=None,
    check: bool = True,
) -> SimulationResult:
    """Simulate ``model`` (default: the built-in curl) with one solution technique.

    Parameters
    ----------
    method : {"monolithic", "partitioned", "reference"} or "scipy:NAME"
        ``monolithic``: classical RK4 on the whole state. ``partitioned``: each part with its
        own RK4, exchanging at step boundaries as ``coupling`` says (default zero-order hold).
        ``reference``: SciPy Radau at ``rtol`` (default 1e-10). ``scipy:RK45`` etc.: that SciPy
        solver on the whole system.
    step : float
        Fixed step for the RK4 methods, s. Must divide the duration. Default 0.1 ms.
    duration : float, optional
        Overrides the model's duration, s.
    output_step : float
        Output grid of the adaptive solvers, s. Default 1 ms.
    initial_state : array of 4, optional
        (θ, ω, θ_cc,F, θ_cc,E) replacing the static-equilibrium start.
    check : bool
        Raise :class:`SimulationError` if the state goes non-finite or diverges (default);
        otherwise return the failed result with ``status == "failed"``.
    """
    model = default_model() if model is None else model
    if duration is not None:
        model = model.replace(duration=check_range("duration", duration, 0.0, 600.0,
                                                   low_open=True, unit="s"))
    packed = model.pack()
    y0 = model.initial_state().state if initial_state is None else _check_state(initial_state)
    if method in FIXED_STEP_METHODS:
        result = _fixed_step(model, packed, y0, method, step, coupling or Coupling())
    elif method == "reference" or method.startswith("scipy:"):
        name = "Radau" if method == "reference" else method.split(":", 1)[1]
        if name not in SCIPY_METHODS:
            raise ModelError("method", f"{method!r}: allowed scipy:{', scipy:'.join(SCIPY_METHODS)}")
        check_range("rtol", rtol, 1e-14, 1.0)
        check_range("atol", atol, 1e-16, 1.0)
        result = _adaptive(model, packed, y0, method, name, rtol, atol, output_step)
    else:
        raise ModelError("method", f"{method!r} is not one of {', '.join(METHODS)} or scipy:NAME")
    if check and not result.success:
        raise SimulationError(result.message)
    return result


def _check_state(initial_state) -> np.ndarray:
    y0 = np.asarray(initial_state, dtype=float)
    if y0.shape != (4,) or not np.all(np.isfinite(y0)):
        raise ModelError("initial_state", "must be 4 finite numbers (θ, ω, θ_cc,F, θ_cc,E)")
    return y0.copy()


def _fixed_step(model, packed, y0, method, step, coupling) -> SimulationResult:
    n = step_count(model.duration, step)
    out = np.empty((n + 1, 4))
    stats = fs.new_stats()
    args = (y0, float(step), n, *packed)
    start = _time.perf_counter()
    if method == "monolithic":
        fs.rk4_monolithic(*args, out, stats)
        label = "monolithic"
    else:
        fs.rk4_partitioned(*args, coupling.to_array(), out, stats)
        label = coupling.label()
    wall = _time.perf_counter() - start
    done = int(stats[fs.STEPS])
    times = np.arange(done + 1) * step
    stability = StabilityReport(float(stats[fs.WORST_RATIO]), float(stats[fs.WORST_TIME]),
                                UNIT_NAMES[int(stats[fs.WORST_UNIT])],
                                step / (coupling.muscle_substeps if method == "partitioned"
                                        else 1))
    status, message = "success", ""
    if stats[fs.STATUS] != fs.OK:
        what = "went non-finite" if stats[fs.STATUS] == fs.NON_FINITE else \
            f"diverged (|ω| > {fs.DIVERGENCE_OMEGA:g} rad/s)"
        status = "failed"
        message = (f"{label} with step {step * 1e3:g} ms: the state {what} at t = "
                   f"{times[-1]:.6g} s; use a smaller step (largest stable step ≈ "
                   f"{stability.largest_safe_step * 1e3:.3g} ms) or method 'reference'")
    elif stability.exceeded:
        message = stability.message()
    cost = RunCost(done, int(stats[fs.NFEV_BODY]), int(stats[fs.NFEV_MUSCLE]), wall)
    settings = {"step": step, "steps": n}
    if method == "partitioned":
        settings["coupling"] = coupling.__dict__.copy()
    return SimulationResult(model, packed, times, out[: done + 1], label, float(step), cost,
                            stability, status, message, settings)


def _adaptive(model, packed, y0, label, name, rtol, atol, output_step) -> SimulationResult:
    n_out = step_count(model.duration, output_step, "output_step")
    grid = np.arange(n_out + 1) * output_step
    grid[-1] = model.duration
    calls = [0]

    def rhs(t, y):
        calls[0] += 1
        return np.array(elbow_rates(t, y[0], y[1], y[2], y[3], *packed))

    start = _time.perf_counter()
    with np.errstate(all="ignore"):
        sol = solve_ivp(rhs, (0.0, model.duration), y0, method=name, t_eval=grid, rtol=rtol,
                        atol=atol)
    wall = _time.perf_counter() - start
    states = sol.y.T.copy()
    ok = sol.success and np.all(np.isfinite(states)) and states.shape[0] == grid.size
    message = "" if ok else (f"{label} (rtol {rtol:g}) failed at t = "
                             f"{(sol.t[-1] if sol.t.size else 0.0):.6g} s: {sol.message}")
    cost = RunCost(int(sol.t.size and len(sol.t)), calls[0], calls[0], wall)
    if hasattr(sol, "nfev"):
        cost = RunCost(_steps_taken(sol), calls[0], calls[0], wall)
    settings = {"rtol": rtol, "atol": atol, "solver": name, "output_step": output_step,
                "njev": int(getattr(sol, "njev", 0)), "nlu": int(getattr(sol, "nlu", 0))}
    return SimulationResult(model, packed, sol.t.copy(), states, label, None, cost, None,
                            "success" if ok else "failed", message, settings)


def _steps_taken(sol) -> int:
    """SciPy does not report accepted steps when t_eval is given; -1 marks 'not known'."""
    return -1 if sol.t is None else int(getattr(sol, "nsteps", -1))


def largest_safe_step(result: SimulationResult) -> float:
    """Largest RK4 step (s) the stability guard allows for the motion in ``result``."""
    tau_f, tau_e = result.time_constants()
    tau = min(float(np.min(tau_f)), float(np.min(tau_e)))
    return math.inf if not math.isfinite(tau) else 2.785293563405282 * tau
