"""Optimising a performance: goals, the searched space, robust copies, resume, the command."""

import json
import math

import numpy as np
import pytest

import torquesim as ts
from torquesim.cli import main
from torquesim.errors import ModelError
from torquesim.model.presets import preset
from torquesim.optimisation import (
    OptimiseProblem,
    OptimiseSettings,
    Trial,
    Window,
    goals_of,
    parse_goal,
)
from torquesim.optimisation.outputs import parameter_effects
from torquesim.optimisation.problem import (
    FAILED_COST,
    INFEASIBLE_COST,
    apply_timing_errors,
    three_ramps,
)
from torquesim.optimisation.search import load_checkpoint, optimise_population

G = 9.81


@pytest.fixture(scope="module")
def curl():
    """The default curl, cut to 1.2 s (every goal below happens before)."""
    return preset("builtin:elbow-curl").replace(duration=1.2)


def _trial(time, q, qd=None, **ground):
    q = np.asarray(q, dtype=float)
    qd = np.gradient(q, time) if qd is None else np.asarray(qd, dtype=float)
    return Trial(time, q[:, None], qd[:, None], np.zeros((time.size, 1)), gravity=G, **ground)


# ---- goals on known motions ------------------------------------------------------------

def test_goals_of_a_known_motion(curl):
    """q = 2t rad: 90° is reached at t = π/4 s with speed 2 rad/s; peak |q̇| and the final
    angle are read off; the effort of a = 0.5 on 1 unit is 0.25."""
    t = np.linspace(0.0, 1.0, 101)
    trial = Trial(t, (2 * t)[:, None], np.full((t.size, 1), 2.0),
                  np.full((t.size, 2), 0.5), gravity=G)
    joints = ("elbow",)
    value = {text: parse_goal(text, curl, maximise=True).value(trial, joints)[0]
             for text in ("time_to:elbow=90deg", "speed_at:elbow=1.0rad", "peak_speed:elbow",
                          "final_angle:elbow", "effort")}
    assert value["time_to:elbow=90deg"] == pytest.approx(math.pi / 4, abs=1e-12)
    assert value["speed_at:elbow=1.0rad"] == pytest.approx(2.0)
    assert value["peak_speed:elbow"] == pytest.approx(2.0)
    assert value["final_angle:elbow"] == pytest.approx(2.0)
    assert value["effort"] == pytest.approx(0.5)  # 2 units × 0.25


def test_a_goal_never_reached_is_undefined_with_its_reason(curl):
    t = np.linspace(0.0, 1.0, 11)
    trial = _trial(t, 0.1 * t)
    value, why = parse_goal("time_to:elbow=90deg", curl, maximise=False).value(trial, ("elbow",))
    assert math.isnan(value) and why == "elbow never reaches 90 deg"


def test_jump_height_of_a_ballistic_flight():
    """The CoM leaves the ground at t = 0.3 s at 1.2 m with 2.5 m/s upward: its apex is
    1.2 + 2.5²/(2g) whether or not the run lasts until it; without take-off, the highest
    point."""
    jump = preset("builtin:squat-jump")
    t = np.linspace(0.0, 0.4, 401)
    off = t >= 0.3
    vy = np.where(off, 2.5 - G * (t - 0.3), 2.5 * t / 0.3)
    y = np.where(off, 1.2 + 2.5 * (t - 0.3) - 0.5 * G * (t - 0.3) ** 2,
                 1.0 + 0.2 * (t / 0.3) ** 2)
    grf = np.where(off, 0.0, 700.0)
    trial = _trial(t, np.zeros_like(t), com_y=y, com_speed_x=np.zeros_like(t),
                   com_speed_y=vy, grf_y=grf)
    height = parse_goal("jump_height", jump, maximise=True)
    assert height.value(trial, ("ankle",))[0] == pytest.approx(1.2 + 2.5**2 / (2 * G) - 1.0,
                                                               rel=1e-12)
    speed = parse_goal("com_speed_at_takeoff", jump, maximise=True)
    assert speed.value(trial, ("ankle",))[0] == pytest.approx(2.5, rel=1e-12)
    grounded = _trial(t, np.zeros_like(t), com_y=y, com_speed_x=np.zeros_like(t),
                      com_speed_y=vy, grf_y=np.full_like(t, 700.0))
    assert height.value(grounded, ("ankle",))[0] == pytest.approx(y.max() - y[0])
    assert speed.value(grounded, ("ankle",)) [1] == "no take-off"


@pytest.mark.parametrize("text, message", [
    ("jump", "is not a goal; allowed: jump_height"),
    ("time_to:elbow", "allowed time_to:JOINT=ANGLE"),
    ("peak_speed:knee", "no joint 'knee'; allowed: elbow"),
    ("jump_height", "needs a body on the ground"),
    ("-2*effort", "allowed a number > 0"),
    ("time_to:elbow=abc", "is not a goal"),
])
def test_bad_goals_are_one_line_errors(curl, text, message):
    with pytest.raises(ModelError, match=message.replace("(", r"\(")) as err:
        parse_goal(text, curl, maximise=True)
    assert "\n" not in str(err.value)


# ---- the searched space ------------------------------------------------------------------

def test_three_ramps_keep_the_activation():
    """The squat jump's units have 2 or 0 ramps: padded to 3, every unit's activation is the
    same at every time."""
    jump = preset("builtin:squat-jump")
    padded = three_ramps(jump)
    assert all(len(u.activation.ramps) == 3 for u in padded.units)
    levels = jump.initial_state().levels
    t = np.linspace(0.0, jump.duration, 300)
    for u, (a, b) in enumerate(zip(jump.units, padded.units, strict=True)):
        np.testing.assert_array_equal(a.activation(t, levels[u]), b.activation(t, levels[u]))


def test_timing_errors_move_each_onset_by_its_error():
    x = np.array([0.1, 0.2, 0.5, 0.05, 0.1, 0.3, 0.2, 0.1, 0.4])  # 1 unit, 3 ramps
    errors = np.array([[0.01, -0.02, 0.015]])

    def onsets(v):
        t, out = 0.0, []
        for i in range(3):
            out.append(t + v[3 * i])
            t = out[-1] + v[3 * i + 1]
        return np.array(out)

    np.testing.assert_allclose(onsets(apply_timing_errors(x, errors)) - onsets(x), errors[0],
                               atol=1e-15)


def test_the_window_bounds_every_parameter(curl):
    problem = OptimiseProblem(curl, goals_of(curl, minimise="time_to:elbow=90deg"),
                              window=Window(delay=0.02, duration=0.1, level=0.2))
    space = problem.space
    for i, name in enumerate(space.names):
        if i not in space.free:
            continue
        x0, low, high = problem.x0[i], space.lower[i], space.upper[i]
        kind = name.rsplit(".", 1)[1]
        expected = {"delay": (max(x0 - 0.02, 0), x0 + 0.02),
                    "duration": (0.9 * x0, 1.1 * x0),
                    "level": (max(x0 - max(0.2 * x0, 0.05), 0), min(x0 + max(0.2 * x0, 0.05), 1))}
        assert (low, high) == pytest.approx(expected[kind], abs=1e-12), name


def test_free_and_freeze_choose_what_moves(curl):
    goals = goals_of(curl, minimise="time_to:elbow=90deg")
    only = OptimiseProblem(curl, goals, free=("elbow.flexor.ramp1",))
    assert [only.space.names[i] for i in only.space.free] == [
        "elbow_flexor.ramp1.delay", "elbow_flexor.ramp1.duration", "elbow_flexor.ramp1.level"]
    held = OptimiseProblem(curl, goals, frozen={"elbow_extensor": None,
                                                "elbow_flexor.ramp1.level": 0.6})
    assert held.space.frozen["elbow_flexor.ramp1.level"] == 0.6
    assert all(not held.space.names[i].startswith("elbow_extensor") for i in held.space.free)
    with pytest.raises(ModelError, match="excludes the starting model's"):
        OptimiseProblem(curl, goals, bounds={"elbow_flexor.ramp1.level": (0.8, 1.0)})
    with pytest.raises(ModelError, match="is not a parameter"):
        OptimiseProblem(curl, goals, free=("elbow_flexor.ramp7.level",))


def test_a_run_beyond_the_end_stops_is_infeasible_by_how_far(curl):
    """Every flexor ramp at full activation swings the elbow past its 150° end stop: by default
    (an optimum may not lean on the passive stop torque) that candidate is infeasible, costing
    INFEASIBLE_COST plus the end-stop scales it went past, so the search ranks it below every
    feasible one and a nearer one first; allowed that depth (--endstop-depth), it is scored
    by its goal."""
    problem = OptimiseProblem(curl, goals_of(curl, maximise="peak_speed:elbow"),
                              bounds={f"elbow_flexor.ramp{k}.level": (0.0, 1.0)
                                      for k in (1, 2, 3)})
    strong = problem.x0.copy()
    strong[[2, 5, 8]] = 1.0
    milder = problem.x0.copy()
    milder[[2, 5, 8]] = 0.9
    cost, nominal, _ = problem.score(np.array([problem.x0, strong, milder]))
    run = problem.run(strong)
    past = (run.q[:, 0].max() - math.radians(150.0)) / 0.05  # end-stop scales s_p
    assert past > 2
    assert cost[0] < 0 and cost[1] == pytest.approx(INFEASIBLE_COST + past, rel=1e-3)
    assert INFEASIBLE_COST < cost[2] < cost[1] and np.isfinite(nominal[1, 0])
    assert not problem.failures
    lenient = OptimiseProblem(curl, goals_of(curl, maximise="peak_speed:elbow"),
                              bounds={f"elbow_flexor.ramp{k}.level": (0.0, 1.0)
                                      for k in (1, 2, 3)}, endstop_depth=past + 0.5)
    cost, nominal, _ = lenient.score(np.array([strong]))
    assert cost[0] == pytest.approx(-nominal[0, 0] / lenient.scales[0])


def test_goals_combine_in_units_of_the_start(curl):
    """C = Σ w·σ·v/|v_start|: at the start every goal contributes ∓w; a candidate's cost is
    the weighted sum of its goal values over the start's."""
    problem = OptimiseProblem(curl, goals_of(curl, maximise="peak_speed:elbow",
                                             minimise=("2*effort", "time_to:elbow=90deg")))
    start = problem.start_values
    assert problem.cost_of_values(start[None, :])[0] == pytest.approx(-1 + 2 + 1)
    other = start * np.array([1.1, 0.5, 0.9])
    assert problem.cost_of_values(other[None, :])[0] == pytest.approx(-1.1 + 2 * 0.5 + 0.9)


# ---- the search ----------------------------------------------------------------------------

def test_a_known_optimum_is_found(curl):
    """Peak flexion speed within the first 0.25 s, only ramp 1 of the flexor free: the
    strongest activation, reached as early and as fast as allowed, is best (more activation
    means more torque at every state). The search ends at that corner, and its value is not
    beaten by random points of the box."""
    short = curl.replace(duration=0.25)
    problem = OptimiseProblem(short, goals_of(short, maximise="peak_speed:elbow"),
                              free=("elbow_flexor.ramp1",),
                              bounds={"elbow_flexor.ramp1.delay": (0.0, 0.1),
                                      "elbow_flexor.ramp1.duration": (0.05, 0.4),
                                      "elbow_flexor.ramp1.level": (0.2, 1.0)})
    outcome = optimise_population(problem, OptimiseSettings(generations=80, seed=3))
    best = problem.space.table(outcome.x)
    assert best["elbow_flexor.ramp1.level"] > 0.995
    assert best["elbow_flexor.ramp1.delay"] < 1e-4
    assert best["elbow_flexor.ramp1.duration"] < 0.0501
    corner = problem.x0.copy()
    corner[[0, 1, 2]] = 0.0, 0.05, 1.0
    corner_value = problem.goal_values(corner)[0][0, 0]
    assert outcome.values[0] == pytest.approx(corner_value, rel=1e-3)
    rng = np.random.default_rng(0)
    box = np.tile(problem.x0, (40, 1))
    box[:, 0] = rng.uniform(0.0, 0.1, 40)
    box[:, 1] = rng.uniform(0.05, 0.4, 40)
    box[:, 2] = rng.uniform(0.2, 1.0, 40)
    assert np.all(problem.goal_values(box)[0][:, 0] <= corner_value)
    # each of the three carries part of the gain: reverting it alone loses some
    effects = parameter_effects(problem, outcome)
    assert {e["parameter"] for e in effects} == {f"elbow_flexor.ramp1.{f}" for f in
                                                 ("delay", "duration", "level")}
    assert all(e["gain_lost_if_reverted_percent"] > 0 for e in effects)


def test_a_model_field_is_searched_from_its_own_start(curl):
    """A model field given bounds is searched: the flexor's strength T0 in [60, 80] N·m
    (the model's 75) for the peak flexion speed of the first 0.25 s. Each candidate runs its
    own model: a value's goal is exactly that of the same start on a model made with it
    (its flexor's level from its own static equilibrium), it grows with the strength, and
    the search ends at the upper bound. A value that makes the model invalid (T0 = 88 above
    a T_max of 101.25: the CE velocity no longer unique) fails with that reason."""
    from torquesim.model.paths import set_parameter

    path = "elbow_flexor.isometric_torque"
    short = curl.replace(duration=0.25)
    goals = goals_of(short, maximise="peak_speed:elbow")
    problem = OptimiseProblem(short, goals, free=(path,), bounds={path: (60.0, 80.0)},
                              step=1e-3)
    assert problem.space.names[-1] == path and problem.space.free.tolist() == [
        problem.space.size - 1]
    rows = np.tile(problem.x0, (4, 1))
    rows[:, -1] = 60.0, 75.0, 80.0, 88.0
    values, reasons, _ = problem.goal_values(rows)
    for value, strength in zip(values[:3, 0], (60.0, 75.0, 80.0), strict=True):
        made = OptimiseProblem(set_parameter(short, path, strength), goals, step=1e-3)
        assert value == made.goal_values(made.x0)[0][0, 0]
    assert values[0, 0] < values[1, 0] < values[2, 0]
    assert values[1, 0] == problem.start_values[0]
    assert math.isnan(values[3, 0]) and "no valid model" in reasons[3]
    outcome = optimise_population(problem, OptimiseSettings(generations=20, seed=1))
    assert problem.space.table(outcome.x)[path] > 79.5
    assert problem.model_for(outcome.x).units[0].parameters.isometric_torque > 79.5
    with pytest.raises(ModelError, match="without a range"):
        OptimiseProblem(short, goals, free=(path,))
    with pytest.raises(ModelError, match="excludes the starting model's"):
        OptimiseProblem(short, goals, bounds={path: (76.0, 80.0)})


def test_a_held_model_field_sets_the_start_and_an_infeasible_start_is_said():
    """``frozen`` at a value for a model field with no range sets it in the start (not
    searched). A flexor held at 80 N·m (the model's 75) takes the curl's first 1.5 s past
    its end stop: that start is infeasible, the optimum is the best feasible candidate, and
    the summary says why its goal may be worse than the start's."""
    from torquesim.model.paths import set_parameter

    curl = preset("builtin:elbow-curl").replace(duration=1.5)
    fixed = {"method": "imex", "step": 2.5e-3}  # no search for a technique
    held = OptimiseProblem(curl, goals_of(curl, minimise="time_to:elbow=90deg"),
                           frozen={"elbow_flexor.isometric_torque": 80.0}, **fixed)
    assert held.start_model == set_parameter(curl, "elbow_flexor.isometric_torque", 80.0)
    assert not held.space.fields and held.start_model.units[0].parameters \
        .isometric_torque == 80.0
    best = ts.optimise(curl, minimise="time_to:elbow=90deg",
                       frozen={"elbow_flexor.isometric_torque": 80.0},
                       settings=OptimiseSettings(generations=3, seed=1), **fixed)
    assert best.summary["cost"]["start"] >= INFEASIBLE_COST > best.summary["cost"]["optimum"]
    assert any(w.startswith("the start is infeasible") for w in best.summary["warnings"])
    with pytest.raises(ModelError, match="frozen.elbow_flexor.isometric_torque"):
        OptimiseProblem(curl, goals_of(curl, minimise="time_to:elbow=90deg"),
                        frozen={"elbow_flexor.isometric_torque": 90.0}, **fixed)


def test_the_robust_score_is_never_above_the_plain_one(curl):
    goals = goals_of(curl, maximise="peak_speed:elbow")
    robust = OptimiseProblem(curl, goals, robust=6, timing_error=0.02)
    rng = np.random.default_rng(1)
    low, high = np.array(robust.space.lower), np.array(robust.space.upper)
    population = np.array([robust.space.full(rng.uniform(low, high)[robust.space.free],
                                             robust.x0) for _ in range(12)])
    cost, nominal, worst = robust.score(population)
    usable = cost < FAILED_COST
    assert usable.sum() >= 6
    assert np.all(worst[usable] <= nominal[usable])
    plain_cost, plain_nominal, _ = OptimiseProblem(curl, goals).score(population)
    np.testing.assert_array_equal(plain_nominal[usable], nominal[usable])
    assert np.all(cost[usable] >= plain_cost[usable])


def test_resume_ends_where_the_uninterrupted_search_does(curl, tmp_path):
    goals = goals_of(curl, minimise="time_to:elbow=90deg")
    settings = OptimiseSettings(generations=8, seed=5)
    whole = optimise_population(OptimiseProblem(curl, goals), settings)
    problem = OptimiseProblem(curl, goals)
    polls = iter(range(100))
    cut = optimise_population(problem, settings, checkpoint=tmp_path / "c.npz",
                              should_stop=lambda: next(polls) >= 3)
    assert cut.interrupted and cut.generations_done == 3
    again = OptimiseProblem(curl, goals)
    state = load_checkpoint(tmp_path / "c.npz", again, settings)
    resumed = optimise_population(again, settings, resume=state)
    assert resumed.generations_done == 8 and not resumed.interrupted
    np.testing.assert_array_equal(resumed.x, whole.x)
    assert resumed.cost == whole.cost
    assert resumed.simulations == whole.simulations
    with pytest.raises(ModelError, match="seed = 5, not 6"):
        load_checkpoint(tmp_path / "c.npz", again, OptimiseSettings(generations=8, seed=6))
    other = OptimiseProblem(curl, goals_of(curl, maximise="peak_speed:elbow"))
    with pytest.raises(ModelError, match="belongs to another optimisation"):
        load_checkpoint(tmp_path / "c.npz", other, settings)


def test_a_faster_curl_holds_with_the_reference(curl):
    """The curl reaches 90° sooner after the search, and the reference re-simulation of the
    start and optimum agrees with the search's own (IMEX 5 ms) gain to 1 % of it."""
    best = ts.optimise(curl, minimise="time_to:elbow=90deg",
                       settings=OptimiseSettings(generations=15))
    goal = best.summary["goals"][0]
    assert goal["gain"] > 0.05  # s
    assert goal["reference_gain"] == pytest.approx(goal["gain"], rel=0.01)
    assert best.summary["warnings"] == []
    rerun = ts.simulate(best.model, "reference", output_step=0.005)
    value = parse_goal("time_to:elbow=90deg", curl, maximise=False).value(
        Trial.of(rerun), ("elbow",))[0]
    assert value == pytest.approx(goal["reference_optimum"], abs=1e-6)


def test_a_custom_goal_is_any_function_of_the_result(curl):
    def final_speed(result):
        return abs(result.qd[-1, 0])

    problem = OptimiseProblem(curl, goals_of(curl, maximise=final_speed),
                              free=("elbow_flexor.ramp1.level",))
    assert problem.goals[0].label == "final_speed"
    assert problem.start_values[0] == pytest.approx(abs(problem.run(problem.x0).qd[-1, 0]))


# ---- the command ---------------------------------------------------------------------------

def test_the_command_writes_an_optimised_model(tmp_path, capsys):
    out = tmp_path / "o"
    code = main(["optimise", "--minimise", "time_to:elbow=90deg", "--duration", "1.2",
                 "--generations", "6", "--out", str(out), "--quiet"])
    printed = capsys.readouterr().out
    assert code == 0
    assert "minimise time_to:elbow=90deg: start 874.3 ms → optimum" in printed
    summary = json.loads((out / "optimise_summary.json").read_text())
    goal = summary["goals"][0]
    assert goal["reference_optimum"] < goal["reference_start"]
    model = ts.load_model(out / "optimised_model.toml")
    assert "minimise time_to:elbow=90deg" in model.notes[0]
    assert (out / "optimise.png").read_bytes()[:4] == b"\x89PNG"
    assert "<img" in (out / "optimise.html").read_text()
    table = ts.read_table(out / "optimum_motion.csv")
    assert table["time"][-1] == pytest.approx(1.2)
    # an earlier optimisation is not silently replaced
    assert main(["optimise", "--minimise", "effort", "--out", str(out)]) == 2
    assert "holds an earlier optimisation" in capsys.readouterr().err


def test_searches_run_numpy_s_linear_algebra_on_one_thread():
    """Inside a fit's or an optimisation's search, BLAS runs on one thread (its spinning
    threads took a core from the population's), and as before after it."""
    from threadpoolctl import threadpool_info

    from torquesim.fitting.fit import run_fit
    from torquesim.fitting.objective import blas_on_one_thread
    from torquesim.optimisation.search import optimise_population

    def blas_threads():
        return [lib["num_threads"] for lib in threadpool_info() if lib["user_api"] == "blas"]

    before = blas_threads()
    if not before:
        pytest.skip("NumPy's BLAS has no thread pool threadpoolctl knows")
    assert blas_on_one_thread(blas_threads)() == [1] * len(before)
    assert blas_threads() == before
    for search in (run_fit, optimise_population):
        assert search.__wrapped__.__name__ == search.__name__


def test_a_stop_request_writes_the_best_so_far_and_resume_finishes(tmp_path, capsys,
                                                                    monkeypatch):
    """SIGTERM during the search (sent after its second generation, not timed): the
    generation finishes, the best so far is written with a checkpoint, the command exits 130
    and says how to continue, the previous handler is back; --resume finishes the search."""
    import os
    import signal

    import torquesim.cli as cli

    generations = []
    real_step = cli.Progress.step

    def step_then_signal(self, done, total, label):
        real_step(self, done, total, label)
        if label == "generations" and done > 0:
            generations.append(done)
            if len(generations) == 2:
                os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(cli.Progress, "step", step_then_signal)
    before = signal.getsignal(signal.SIGTERM)
    out = tmp_path / "o"
    args = ["optimise", "--minimise", "time_to:elbow=90deg", "--duration", "1.2",
            "--generations", "6", "--out", str(out)]
    assert main(args) == 130
    err = capsys.readouterr().err
    assert "stopping: finishing the current generation" in err
    assert f"continue with --resume --out {out}" in err
    assert signal.getsignal(signal.SIGTERM) is before
    summary = json.loads((out / "optimise_summary.json").read_text())
    assert ts.load_model(out / "optimised_model.toml").notes
    assert (out / "optimise_checkpoint.npz").stat().st_size > 0
    assert generations[-1] < 6
    monkeypatch.setattr(cli.Progress, "step", real_step)
    assert main([*args, "--resume", "--quiet"]) == 0
    resumed = json.loads((out / "optimise_summary.json").read_text())
    assert resumed["goals"][0]["optimum"] <= summary["goals"][0]["optimum"]


@pytest.mark.parametrize("argv, message", [
    (["--maximise", "jump_height"], "needs a body on the ground"),
    ([], "no goal given"),
    (["--minimise", "effort", "--bound", "elbow_flexor.ramp1.level=0.9,1"],
     "excludes the starting model's"),
    (["--minimise", "effort", "--freeze", "knee_flexor"], "is not a parameter"),
    (["--minimise", "effort", "--generations", "0"], "0 is not in the range"),
    (["--minimise", "effort", "--free", "gravity"], "--free: 'gravity' is a model field "
                                                    "without a range"),
    (["--minimise", "effort", "--bound", "gravity=0,9"], "excludes the starting model's"),
])
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, capsys, argv, message):
    out = tmp_path / "o"
    assert main(["optimise", *argv, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and err.startswith("error:")
    assert not out.exists()


def test_the_same_optimum_on_dask_workers(curl):
    """Each generation scored by 2 worker processes (one task per chunk) gives the search
    that this process's threads give: the same candidates, costs and optimum; with a
    searched model field too (each candidate's own start made on the worker)."""
    distributed = pytest.importorskip("distributed")
    settings = OptimiseSettings(generations=4, seed=2)
    field = {"bounds": {"elbow_flexor.se_stiffness": (300.0, 900.0)}}
    here = [ts.optimise(curl, minimise="time_to:elbow=90deg", settings=settings, **kwargs)
            for kwargs in ({}, field)]
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as client:
        there = [ts.optimise(curl, minimise="time_to:elbow=90deg", settings=settings,
                             client=client, **kwargs) for kwargs in ({}, field)]
    for a, b in zip(there, here, strict=True):
        np.testing.assert_array_equal(a.outcome.x, b.outcome.x)
        assert a.outcome.history == b.outcome.history
        assert a.outcome.failures == b.outcome.failures
    assert here[1].outcome.x.size == here[0].outcome.x.size + 1


def test_a_goal_the_free_parameters_cannot_move_is_told(curl):
    """Flexor ramp 3 starts after 1.9 s; the curl passes 30° long before: no candidate can
    beat the start, and the summary says so instead of reporting a gain of 0 silently."""
    best = ts.optimise(curl, minimise="time_to:elbow=30deg", free=["elbow_flexor.ramp3.delay"],
                       settings=OptimiseSettings(generations=3))
    assert best.summary["goals"][0]["gain"] == 0.0
    assert best.summary["warnings"][0].startswith("no candidate beat the start in 3 generations")


def _flight(take_off=10, land=None, n=60, g=9.81, dt=0.01, v0=2.0):
    """A synthetic trial: on the ground until ``take_off``, ballistic after, down again at
    sample ``land`` (None: not in the run)."""
    from torquesim.optimisation.goals import Trial

    t = np.arange(n) * dt
    flying = np.clip(t - take_off * dt, 0.0, None)
    y = 1.0 + v0 * flying - 0.5 * g * flying**2
    vy = np.where(t >= take_off * dt, v0 - g * flying, 0.0)
    grf = np.where(np.arange(n) < take_off, 700.0, 0.0)
    if land is not None:
        grf[land:] = 700.0
    zeros = np.zeros((n, 1))
    return Trial(t, zeros, zeros, zeros, com_y=y, com_speed_x=np.full(n, -0.3),
                 com_speed_y=vy, grf_y=grf, gravity=g)


def test_jump_height_is_the_apex_in_flight_and_no_jump_lands_before_it():
    """The real apex when the run holds it (v²/2g from take-off before); a run that touches
    down again before its apex made no jump (before: scored by its take-off speed)."""
    from torquesim.optimisation.goals import Goal

    height = Goal("jump_height", True)
    apex = 2.0**2 / (2 * 9.81)
    value, why = height.value(_flight(), ())
    assert why == "" and value == pytest.approx(apex, abs=2e-3)   # the highest sample
    value, why = height.value(_flight(n=25), ())  # ends rising: ballistic from take-off
    assert why == "" and value == pytest.approx(apex, rel=1e-12)
    value, why = height.value(_flight(land=20), ())  # down again at 0.1 s, apex at 0.2 s
    assert math.isnan(value) and "before its apex" in why
    drift = Goal("com_speed_x_at_takeoff", False)
    assert drift.value(_flight(), ()) == (-0.3, "")


def test_the_jump_apex_agrees_with_the_ballistic_flight_of_its_take_off():
    jump = ts.load_model("builtin:squat-jump")
    from torquesim.optimisation.goals import Goal, Trial, take_off_index

    run = ts.simulate(jump, "reference", output_step=1e-3)
    trial = Trial.of(run)
    i = take_off_index(trial.grf_y)
    ballistic = trial.com_y[i] + trial.com_speed_y[i] ** 2 / (2 * jump.gravity) - trial.com_y[0]
    value, why = Goal("jump_height", True).value(trial, ())
    assert why == "" and value == pytest.approx(ballistic, abs=2e-5)


def test_constraints_parse_in_their_units_and_rank_infeasible_candidates():
    from torquesim.optimisation import parse_constraint

    jump = ts.load_model("builtin:squat-jump")
    drift = parse_constraint("com_speed_x_at_takeoff=-0.1..0.1", jump)
    assert (drift.low, drift.high) == (-0.1, 0.1)
    assert drift.violation(0.05) == 0.0 and drift.violation(-0.48) == pytest.approx(1.9)
    curl = ts.load_model("builtin:elbow-curl")
    stop = parse_constraint("final_angle:elbow=..20", curl)
    assert stop.low == -math.inf and stop.high == pytest.approx(math.radians(20))
    for bad in ("final_angle:elbow=20", "final_angle:elbow=30..20", "jump_height=a..1",
                "nothing=0..1"):
        with pytest.raises(ModelError) as info:
            parse_constraint(bad, jump if "jump" in bad else curl)
        assert info.value.field == "constrain"
    forwards = parse_constraint("com_speed_x_at_takeoff=0.3..0.4", jump)
    problem = OptimiseProblem(jump, goals_of(jump, maximise="jump_height"), "imex", 2.5e-4,
                              constraints=(forwards,))  # a technique other tests compile
    values, reasons, violation = problem.goal_values(problem.x0[None, :])
    start_drift = Trial.of(problem.run(problem.x0)).com_speed_x
    assert reasons == [""] and violation[0] > 1.0  # the preset takes off nearly vertically
    cost, _, _ = problem.score(problem.x0[None, :])
    assert cost[0] == pytest.approx(INFEASIBLE_COST + violation[0])
    assert start_drift is not None


def test_a_goal_both_maximised_and_minimised_is_refused():
    """--minimise effort --maximise effort ran 60 generations to "no candidate beat the
    start"; the same goal at another angle, or another goal, is fine."""
    model = ts.default_model().to_chain()
    with pytest.raises(ModelError, match="'effort' is maximised too") as info:
        goals_of(model, maximise=("0.5*effort",), minimise=("effort",))
    assert info.value.field == "minimise"
    assert len(goals_of(model, maximise=("speed_at:elbow=60deg",),
                        minimise=("speed_at:elbow=90deg", "effort"))) == 3
