"""The error-controlled technique ``imex-ros2-adaptive`` (issue 33, item 2): imex-ros2's step
at steps an embedded error estimate chooses, take-off and touchdown located as events, the
state written on a fixed grid by interpolation. Measured here: its order from the work
against the error, the global error following the tolerance, events against the analytic
free fall, flight under gravity, impulse and momentum, the energy of a dropped passive body,
and its own accuracy estimate."""

import math

import numpy as np
import pytest

import torquesim as ts
from torquesim.errors import ModelError
from torquesim.model.preset_names import PRESET_NAMES
from torquesim.solvers.error_control import EVENT_TIME_TOLERANCE
from torquesim.solvers.simulation import GROUND_OUTPUT_STEP
from torquesim.solvers.techniques import ERROR_CONTROL_ATOL, GROUND_CONTROL_ATOL

from .test_ground import G, dropped_bar, dropped_bar_energy

METHOD = "imex-ros2-adaptive"


@pytest.fixture(scope="module")
def jump():
    return ts.load_model("builtin:squat-jump")


@pytest.fixture(scope="module")
def jump_reference(jump):
    return ts.simulate(jump, "reference")


@pytest.fixture(scope="module")
def jump_runs(jump):
    """The jump at three angle tolerances, a decade apart."""
    return {atol: ts.simulate(jump, METHOD, atol=atol, tolerance=None)
            for atol in (1e-3, 1e-4, 1e-5)}


def _max_error(run, reference) -> float:
    return float(np.max(np.abs(run.q - reference.q)))


def test_order_two_from_work_and_error_following_the_tolerance(jump_runs, jump_reference):
    """Error against steps falls as N^−p with p ≈ 2 (the technique's declared order), and a
    decade of atol moves the global error by about a decade (3–50x: tolerance proportionality,
    which the accuracy estimate relies on)."""
    runs = [jump_runs[a] for a in (1e-3, 1e-4, 1e-5)]
    errors = [_max_error(r, jump_reference) for r in runs]
    steps = [r.cost.steps for r in runs]
    order = -np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert 1.6 < order < 2.6, (order, errors, steps)
    for coarse, fine in zip(errors, errors[1:], strict=False):
        assert 3.0 < coarse / fine < 50.0, errors
    assert math.degrees(errors[1]) < 0.05


def test_steps_adapt_to_the_motion_and_events_end_steps(jump_runs):
    """Small steps at the take-offs, large ones in flight: the step spans two decades, the
    largest is the ramps' bound (a tenth of the shortest ramp), and the heel's and the toe's
    take-offs are located, at atol 1e-4 and 1e-5 within 0.1 ms of each other (a tenth of the
    output grid: the heel lifts slowly, so its time moves with the height error)."""
    run = jump_runs[1e-4]
    s = run.settings
    assert s["largest_step"] == pytest.approx(s["max_step"])
    assert s["largest_step"] / s["smallest_step"] > 100.0
    assert s["events"] == 2
    assert np.allclose(jump_runs[1e-5].settings["event_times"], s["event_times"], atol=1e-4)
    take_off = run.ground_events().take_off
    assert s["event_times"][-1] == pytest.approx(take_off, abs=run.time[1])


def test_touchdown_of_a_falling_body_is_located_to_the_event_tolerance():
    """The dropped bar (`dropped_bar`): before touching the ground it falls freely, and its
    first contact point (on the base) touches down at √(2·h/g); the first event lies within
    `EVENT_TIME_TOLERANCE` of it. Its energy falls by what the contacts dissipate."""
    fine, contacts = dropped_bar()
    model, y0 = fine.model, fine.states[0]
    run = ts.simulate(model, METHOD, atol=1e-5, initial_state=y0, output_step=1e-5,
                      tolerance=None)
    heights = model.kinematics(y0[None, :3], y0[None, 3:6])["points"][0, :, 1]
    first = min(math.sqrt(2.0 * h / G) for h in heights)
    assert abs(run.settings["event_times"][0] - first) <= EVENT_TIME_TOLERANCE
    assert run.settings["events"] >= 4  # touchdowns and bounces
    energy, dissipated = dropped_bar_energy(run, contacts)
    assert dissipated[-1] > 0.1
    assert np.max(np.abs(energy + dissipated - energy[0])) < 1e-2 * energy[0]


def test_flight_follows_gravity_and_impulse_matches_momentum(jump):
    """In flight the centre of mass falls at g and over the jump the ground's impulse equals
    the momentum change, to within what the tolerance allows (both are nonlinear in the state,
    so no Runge-Kutta method keeps them exactly; their error follows atol). At the default
    atol on a body with ground contacts (5e-8) the impulse is the momentum change within
    1e-6 of the largest change, as issue 33 asks (measured 5.0e-7, on the default output grid
    of a body on the ground, 0.1 ms: 2.5e-5 on 1 ms, the trapezoid's), and the flight's speed
    change −g·t within 1e-6; at 1e-4 within 3e-3 and 5e-4
    (measured 1.5e-3 and 1.7e-4). The centre of mass stays on the take-off's parabola within
    1 mm."""
    mass = sum(s.total_mass for s in jump.segments)
    for atol, speed_bound, impulse_bound in ((None, 1e-6, 1e-6), (1e-4, 5e-4, 3e-3)):
        run = ts.simulate(jump, METHOD, atol=atol, tolerance=None)  # every default but atol
        assert run.settings["atol"] == (atol or GROUND_CONTROL_ATOL)
        assert run.time[1] == pytest.approx(GROUND_OUTPUT_STEP)
        c = run.columns()
        air = np.flatnonzero(c["grf_y"] == 0.0)
        first, last = air[0] + 1, air[-1]
        span = run.time[last] - run.time[first]
        change = c["com_speed_y"][last] - c["com_speed_y"][first]
        assert abs(change + G * span) < speed_bound * G * span, atol
        t = run.time[first:last + 1] - run.time[first]
        parabola = c["com_y"][first] + c["com_speed_y"][first] * t - 0.5 * G * t**2
        assert np.max(np.abs(c["com_y"][first:last + 1] - parabola)) < 1e-3
        for force, speed, weight in (("grf_y", "com_speed_y", mass * G),
                                     ("grf_x", "com_speed_x", 0.0)):
            net = c[force] - weight
            impulse = np.concatenate([[0.0], np.cumsum(0.5 * (net[1:] + net[:-1])
                                                       * np.diff(run.time))])
            momentum = mass * (c[speed] - c[speed][0])
            scale = np.abs(momentum).max() if force == "grf_y" else mass * 1.0
            assert np.max(np.abs(impulse - momentum)) < impulse_bound * scale, (atol, force)


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_every_preset_passes_the_default_check_at_the_default_tolerance(name):
    """The error-controlled technique's default atol (`ERROR_CONTROL_ATOL`; on a body with
    ground contacts `GROUND_CONTROL_ATOL`) passes simulate's default accuracy check (0.5°)
    on every built-in model, the check's estimate within 2x of the true error there. (At
    1e-4 the arm raise was 1.1° off, warned; the countermovement jump 0.74°.)"""
    model = ts.load_model(f"builtin:{name}")
    run = ts.simulate(model, METHOD)
    default = GROUND_CONTROL_ATOL if model.contacts else ERROR_CONTROL_ATOL
    assert run.settings["atol"] == default
    assert run.message == "", run.message
    true = _max_error(run, ts.simulate(model, "reference", output_step=run.time[1]))
    assert true < math.radians(0.5)
    if true > math.radians(0.001):
        assert 0.5 * true < run.settings["estimated_error_rad"] < 2.0 * true


def test_the_accuracy_estimate_holds_and_warns(jump, jump_reference):
    """simulate's check of an error-controlled run (against atol 4x tighter) is within 2x of
    the true error, and a tolerance below it is warned about with what to change."""
    run = ts.simulate(jump, METHOD, atol=1e-4, tolerance=math.radians(0.5))
    estimate = run.settings["estimated_error_rad"]
    true = _max_error(run, jump_reference)
    assert 0.5 * true < estimate < 2.0 * true
    warned = ts.simulate(jump, METHOD, atol=1e-3, tolerance=math.radians(0.01))
    assert "use a smaller atol" in warned.message


@pytest.mark.parametrize("name", ["arm-raise", "drop-landing"])
def test_no_silent_wrong_run_at_any_tolerance(name):
    """From atol 1 rad (every step the largest) down: the estimate is within 2x of the true
    error wherever that is above 0.01°, and a run beyond simulate's default tolerance (0.5°)
    is warned about. (At a loose atol every step is the largest, so a check at a tighter
    atol alone would repeat the run and see nothing: the arm raise ran 1.4° off with an
    estimate of 0 until the check halved the largest step too.)"""
    model = ts.load_model(f"builtin:{name}")
    reference = ts.simulate(model, "reference")
    for atol in (1.0, 1e-2, 1e-3, 1e-4):
        run = ts.simulate(model, METHOD, atol=atol, check=False)
        true = math.degrees(_max_error(run, reference))
        estimate = math.degrees(run.settings["estimated_error_rad"])
        if true > 0.01:
            assert 0.5 * true < estimate < 2.0 * true, (atol, true, estimate)
        if true > 0.5:
            assert "exceeds the tolerance" in run.message, (atol, true)


@pytest.mark.parametrize("atol", [0.0, 2.0, math.nan])
def test_bad_tolerances_name_the_field(atol):
    with pytest.raises(ModelError, match="atol"):
        ts.simulate(None, METHOD, atol=atol)


def test_the_curl_runs_error_controlled():
    """A body without contacts (one segment on a pivot): no events, and within 0.1° of the
    reference at the default tolerance."""
    model = ts.load_model("builtin:elbow-curl")
    run = ts.simulate(model, METHOD, tolerance=None)
    reference = ts.simulate(model, "reference")
    assert run.settings["events"] == 0
    assert math.degrees(_max_error(run, reference)) < 0.1
