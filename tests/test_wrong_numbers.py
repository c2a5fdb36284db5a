"""Never a wrong number without a word: runs that leave the physically possible range fail,
the stability advice holds when followed, and every fixed-step run that is far off carries a
warning (the step-halving estimate with the command line's default tolerance)."""

import math

import numpy as np
import pytest

import torquesim as ts
from torquesim.cli import main

from .conftest import max_angle_error

CLI_TOLERANCE = math.radians(0.5)  # torquesim simulate's default --tolerance


def error_on_reference_grid(run, reference) -> float:
    """Max |θ − θ_ref| (rad) with θ interpolated onto the reference's 1 ms grid (any step)."""
    return float(np.max(np.abs(np.interp(reference.time, run.time, run.theta)
                               - reference.theta)))


def test_a_step_of_three_seconds_fails_instead_of_a_63000_degree_curl(tmp_path, capsys):
    out = tmp_path / "o.csv"
    code = main(["simulate", "--step", "3", "--out", str(out)])
    # One line of error; before it the compile notice when this process compiles the run
    # (which test ran first in this test process decides that).
    err = [line for line in capsys.readouterr().err.splitlines()
           if not line.startswith(("compiling ", "still compiling"))]
    assert code == 1 and len(err) == 1 and not out.exists()
    assert "physically possible range" in err[0] and "elbow_flexion" in err[0]
    assert "imex" in err[0]


def test_a_state_beyond_a_full_turn_past_the_end_stops_is_a_failure():
    model = ts.default_model().replace(duration=0.01,
                                       body=ts.BodyParameters(endstop_torque=0.0))
    y0 = model.to_chain().initial_state().state.copy()
    y0[0] = model.body.endstop_upper_angle + 2 * math.pi + 0.5  # far past the stops
    y0[2:] = y0[0]
    failed = ts.simulate(model, "monolithic", 1e-4, initial_state=y0, check=False)
    assert failed.status == "failed" and "more than a full turn" in failed.message
    with pytest.raises(ts.SimulationError):
        ts.simulate(model, "monolithic", 1e-4, initial_state=y0)


@pytest.mark.parametrize("step", [5e-3, 1e-3, 5e-4])
def test_the_advised_step_runs_without_warning_and_accurately(model, reference, step):
    bad = ts.simulate(model, "monolithic", step)
    assert bad.stability.exceeded
    advised = bad.stability.largest_safe_step
    assert f"{advised * 1e3:.4g} ms" in bad.message and "checked" in bad.message
    followed = ts.simulate(model, "monolithic", advised)
    assert not followed.stability.exceeded and followed.message == ""
    assert error_on_reference_grid(followed, reference) < 1e-3


def test_no_verified_step_says_so_and_points_to_the_implicit_methods(model):
    """From 3 s, eight halvings reach 11.7 ms: none is within RK4's stability limit."""
    failed = ts.simulate(model, "monolithic", 3.0, check=False)
    assert failed.status == "failed" and "imex" in failed.message
    assert failed.stability.largest_safe_step == 0.0


def test_error_estimate_tracks_the_true_error(model, reference):
    """Step halving with the technique's order: within a factor 2 of the true error for the
    first-order partitioned technique and the second-order IMEX."""
    for method, step, coupling in [("partitioned", 1e-4, None), ("imex", 5e-3, None),
                                   ("partitioned", 2e-4, ts.Coupling(predictor="linear"))]:
        run = ts.simulate(model, method, step, coupling=coupling, tolerance=1e-9)
        true = max_angle_error(run, reference) if step <= 1e-3 else \
            error_on_reference_grid(run, reference)
        estimate = run.settings["estimated_error_rad"]
        assert 0.5 * true < estimate < 2.0 * true, (method, step, true, estimate)
        assert "exceeds the tolerance" in run.message


def test_good_runs_stay_quiet_with_the_cli_tolerance(model):
    for method, step in [("monolithic", 1e-4), ("imex", 5e-3), ("imex", 1e-3)]:
        run = ts.simulate(model, method, step, tolerance=CLI_TOLERANCE)
        assert run.message == "" and run.settings["estimated_error_rad"] < CLI_TOLERANCE


COUPLINGS = {
    "monolithic": ("monolithic", None),
    "partitioned": ("partitioned", ts.Coupling()),
    "body-first": ("partitioned", ts.Coupling(order="body-first")),
    "muscles-first": ("partitioned", ts.Coupling(order="muscles-first")),
    "linear": ("partitioned", ts.Coupling(predictor="linear")),
    "iterated": ("partitioned", ts.Coupling(iterations=3)),
    "sub-cycled": ("partitioned", ts.Coupling(muscle_substeps=4)),
    "jacobi-sdirk2": ("partitioned", ts.Coupling(muscle_solver="sdirk2")),
    "body-first-sdirk2": ("partitioned", ts.Coupling(order="body-first",
                                                     muscle_solver="sdirk2")),
    "imex": ("imex", None),
}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(COUPLINGS))
@pytest.mark.parametrize("step", [5e-3, 1e-3, 5e-4, 1e-4])
def test_every_run_off_by_more_than_a_tenth_of_a_radian_carries_a_warning(model, reference,
                                                                           name, step):
    method, coupling = COUPLINGS[name]
    run = ts.simulate(model, method, step, coupling=coupling, check=False, advise=False,
                      tolerance=CLI_TOLERANCE)  # the advice is tested above
    if not run.success:
        assert run.message  # a failure always says why
        return
    error = error_on_reference_grid(run, reference)
    if error > 0.1:
        assert run.message, f"{name} at {step * 1e3:g} ms is {error:.3g} rad off, silently"


def test_a_scipy_run_far_off_carries_a_warning_and_a_close_one_none(model, reference):
    """SciPy's error control can pass a run that is far off: explicit RK45 at rtol 1e-3 on
    the curl (its stiff units) was 68° off the reference without a word. The check against
    the run at tolerances ten times tighter flags it and says what to change. Its estimate is
    a lower bound there (32°): the tighter explicit run is off too, the units' stiffness
    rather than the tolerance setting its error. Radau at 1e-6 stays quiet."""
    far = ts.simulate(model, "scipy:RK45", rtol=1e-3)
    true = error_on_reference_grid(far, reference)
    estimate = far.settings["estimated_error_rad"]
    assert true > 0.1 and 0.25 * true < estimate <= 1.1 * true, (true, estimate)
    assert "exceeds the tolerance" in far.message and "scipy:Radau" in far.message
    close = ts.simulate(model, "scipy:Radau", rtol=1e-6)
    assert close.message == "" and close.settings["estimated_error_rad"] < CLI_TOLERANCE
    assert error_on_reference_grid(close, reference) < 2.0 * close.settings[
        "estimated_error_rad"] + 1e-9


def test_a_scipy_solver_that_meets_a_non_finite_state_fails_saying_what_to_change():
    """Radau's Jacobian of a non-finite state made SciPy raise (a traceback); the run now
    ends failed, saying what to change, and `simulate` raises its own SimulationError. A
    state that overflows the contact force (the body far below the ground) makes it so."""
    model = ts.load_model("builtin:squat-jump").replace(duration=0.01)
    y0 = model.initial_state().state.copy()
    y0[1] = -1e200  # the base's height, m
    failed = ts.simulate(model, "scipy:Radau", rtol=1e-6, initial_state=y0, check=False)
    assert failed.status == "failed" and "non-finite" in failed.message
    assert "use smaller rtol and atol or method 'reference'" in failed.message
    with pytest.raises(ts.SimulationError, match="non-finite"):
        ts.simulate(model, "scipy:Radau", rtol=1e-6, initial_state=y0)
