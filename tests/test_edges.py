"""Issue 30's edges: names that would collide in the output table, help and docs that list
every preset, the preset notes that match the file."""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import torquesim as ts
from torquesim.cli import cli, main
from torquesim.io.model_file import model_to_toml
from torquesim.model.chain import RESERVED_COLUMNS
from torquesim.model.presets import PRESETS

ROOT = Path(__file__).parent.parent


def _error_line(capsys, argv):
    assert main(argv) == 2
    err = "\n".join(line for line in capsys.readouterr().err.strip().splitlines()
                    if not line.startswith(("compiling", "still compiling")))
    assert err.startswith("error: ") and "\n" not in err and "Traceback" not in err
    return err


@pytest.mark.parametrize("old, new, field", [
    ('name = "hip_joint"', 'name = "com"', "points[2].name"),
    ('name = "hip_joint"', 'name = "grf"', "points[2].name"),
    ('name = "hip_joint"', 'name = "base"', "points[2].name"),
    ('coordinate = "knee_angle"', 'coordinate = "grf_y"', "joints[2].coordinate"),
    ('coordinate = "knee_angle"', 'coordinate = "cop_x"', "joints[2].coordinate"),
    ('coordinate = "knee_angle"', 'coordinate = "toe_x"', "points[0].name"),
    ('name = "knee_flexors"', 'name = "net_knee"', "units[3].name"),
])
def test_a_name_whose_output_column_is_taken_is_refused(tmp_path, capsys, old, new, field):
    """A point named com, a coordinate named grf_y …: before, accepted and the column
    silently overwritten by the centre of mass or the ground force."""
    text = model_to_toml(ts.load_model("builtin:squat-jump"))
    assert old in text
    path = tmp_path / "m.toml"
    path.write_text(text.replace(old, new, 1))
    out = tmp_path / "run.csv"
    err = _error_line(capsys, ["simulate", "--model", str(path), "--out", str(out)])
    assert err.startswith("error: ") and "gives the output column" in err, err
    assert field in err and ("reserved" in err or "also named by" in err)
    assert not out.exists()


def test_reserved_columns_are_refused_on_a_model_without_them():
    """The model's own columns are reserved on every model (a coordinate named com_x on the
    elbow would collide as soon as a point is added)."""
    elbow = ts.load_model("builtin:elbow-curl")
    for name in RESERVED_COLUMNS:
        with pytest.raises(ts.ModelError) as info:
            elbow.replace_joint("elbow", coordinate=name)
        assert info.value.field in ("joints[0].coordinate", "coordinate")


def test_every_output_column_is_named_once_and_holds_its_quantity():
    """One name per column on every preset (none dropped by a collision), and the table's
    columns hold what their names say: the state, and for the jump its centre of mass and
    summed ground force computed apart."""
    for name in PRESETS:
        model = ts.load_model(f"builtin:{name}")
        pairs = model._output_column_pairs()
        assert len({column for column, _ in pairs}) == len(pairs)
        run = ts.simulate(model, "imex", step=2.5e-4, duration=0.01, check=False)
        columns = run.columns()
        assert list(columns) == [column for column, _ in pairs]
        np.testing.assert_array_equal(columns["time"], run.time)
        for k, state in enumerate(model.state_names()):
            np.testing.assert_array_equal(columns[state], run.states[:, k])
        if model.contacts:
            np.testing.assert_allclose(columns["com_y"], run.kinematics()["com"][:, 1])
            np.testing.assert_allclose(columns["grf_y"], sum(
                columns[f"grf_y_{c.point}"] for c in model.contacts))


@pytest.mark.parametrize("bad", ["toe tip", "toe-tip", "", "heel.1"])
def test_a_point_name_that_breaks_a_header_is_refused(bad):
    with pytest.raises(ts.ModelError) as info:
        ts.Point(bad, "foot", 0.1)
    assert info.value.field == "name"
    with pytest.raises(ts.ModelError) as info:
        ts.GroundContact(bad)
    assert info.value.field == "point"


@pytest.mark.parametrize("command", [["simulate"], ["fit"], ["optimise"], ["compare"],
                                     ["batch", "sweep"], ["batch", "fit"]])
def test_every_model_help_lists_every_preset(command):
    """The lists in the help come from the registry of presets (before, three commands'
    help left out builtin:squat-jump)."""
    text = " ".join(CliRunner().invoke(cli, [*command, "--help"], terminal_width=200)
                    .output.split())
    for name in PRESETS:  # (a name may wrap after a hyphen)
        assert f"builtin:{name}" in text.replace("- ", "-"), (command, name)
    assert "|" not in text.partition("--model")[2].partition("--")[0]


def test_the_docs_list_every_preset():
    for page in ("README.md", "docs/presets.md"):
        text = (ROOT / page).read_text()
        for name in PRESETS:
            assert f"builtin:{name}" in text or f"`{name}`" in text, (page, name)
    for page in ("README.md", "docs/index.md"):
        assert "(1 to 16)" in (ROOT / page).read_text()


def test_the_squat_jump_note_says_what_its_profiles_hold():
    """The note gave '150 ms at full level' where the file held 50 and 100 ms: every
    extensor's start and hold (ms) and every antagonist's level are in the note."""
    model = ts.load_model("builtin:squat-jump")
    notes = " ".join(model.notes)
    for unit in model.units:
        ramps = unit.activation.ramps
        if ramps[0].level == 1.0:
            start, held = round(ramps[0].delay * 1e3), round(ramps[1].delay * 1e3)
            assert f"at {start} ms" in notes and f" {held}" in notes, (unit.name, start, held)
        else:
            assert f"to {ramps[0].level:g}" in notes, unit.name
    assert math.isclose(model.duration, 0.55)


class _Reached(Exception):
    """Raised by a stub where a command's real work would start: every default was resolved
    and checked by then."""


def _stop_at(monkeypatch, module, name, check):
    def stub(*args, **kwargs):
        check(*args, **kwargs)
        raise _Reached

    monkeypatch.setattr(module, name, stub)


@pytest.mark.parametrize("preset", list(PRESETS))
def test_every_preset_is_a_start_fit_and_optimise_take_as_it_is(preset):
    """Every unit of every preset has at most the 3 ramps a fit and an optimisation vary, so
    both start from the preset's own activations (padding with held ramps changes none),
    and those ramps lie within the fit's default bounds (a 30 ms ramp was clipped to 50 ms:
    the drop landing's fit then started 9.8° off its own motion)."""
    from torquesim.fitting.parameters import ParameterSpace, own_vector
    from torquesim.optimisation.problem import three_ramps

    model = ts.load_model(f"builtin:{preset}")
    own = own_vector(model)
    space = ParameterSpace.for_model(model)
    assert np.array_equal(space.clip(own), own)
    padded = three_ramps(model)
    levels = model.initial_state().levels
    t = np.linspace(0.0, model.duration, 201)
    for unit, again, level in zip(model.units, padded.units, levels, strict=True):
        assert len(again.activation.ramps) == 3
        assert np.array_equal(unit.activation(t, level), again.activation(t, level))


@pytest.mark.parametrize("preset", list(PRESETS))
def test_every_command_runs_on_every_preset_with_its_defaults(preset, tmp_path, monkeypatch,
                                                              capsys):
    """simulate and model run for real; compare, fit, optimise and batch sweep run their
    defaults' resolution and checks (steps that divide the duration, the fit's step and target,
    the optimisation's start) up to where their search starts, which a stub stops (the searches
    themselves are tested elsewhere). Before, compare's default steps failed on the squat jump
    ("0.02 s does not divide the duration 0.55 s")."""
    import importlib

    sweep_module = importlib.import_module("torquesim.batch.sweep")
    import torquesim.fitting.outputs as fit_outputs
    import torquesim.optimisation as optimisation
    import torquesim.study.outputs as study_outputs
    from torquesim.fitting.problem import fit_step
    from torquesim.solvers.choice import choose_technique
    from torquesim.solvers.simulation import step_count

    model = ts.load_model(f"builtin:{preset}")
    spec = ["--model", f"builtin:{preset}"]
    capsys.readouterr()
    assert main(["simulate", *spec, "--out", str(tmp_path / "run.csv")]) == 0
    # No warning: where the default 0.1 ms breaks explicit RK4's limit (the jumps' stiff
    # units), the run is at a verified step, said in a note (before, it warned and went on).
    err = capsys.readouterr().err
    assert "warning" not in err, err
    plain = ts.simulate(model, "monolithic", 1e-4, advise=False, tolerance=None, check=False)
    assert ("note: the default step 0.1 ms" in err) == plain.stability.exceeded, err
    assert main(["model", preset, "--out", str(tmp_path / "m.toml")]) == 0

    def study_check(_directory, chain, *, steps, **_):
        assert len(steps) >= 6
        for h in steps:
            step_count(chain.duration, h)

    _stop_at(monkeypatch, study_outputs, "write_study", study_check)
    with pytest.raises(_Reached):
        main(["compare", *spec, "--quiet", "--out", str(tmp_path / "cmp")])

    def fit_check(problem, *_, **__):
        assert problem.step > 0 and problem.target.time.size > 10

    _stop_at(monkeypatch, fit_outputs, "fit_and_write", fit_check)
    with pytest.raises(_Reached):
        main(["fit", *spec, "--quiet", "--out", str(tmp_path / "fit")])

    def optimise_check(chain, goals, method, step, *_, accuracy, **__):
        # the optimisation's defaults, resolved as OptimiseProblem does (its compiled search
        # kernels are tested in test_optimise.py): a technique and step within the accuracy
        assert goals and method is None and step is None
        choice = choose_technique(chain, accuracy)
        assert choice is not None and choice.error <= accuracy
        fit_step(chain.duration, choice.step)

    goal = "jump_height" if model.contacts else f"peak_speed:{model.joints[-1].name}"
    _stop_at(monkeypatch, optimisation, "OptimiseProblem", optimise_check)
    with pytest.raises(_Reached):
        main(["optimise", *spec, "--maximise", goal, "--quiet", "--out",
              str(tmp_path / "opt")])

    def sweep_check(_engine, _claim, chain, _paths, _values, method, step, *_, **__):
        # the default step holds the model's own run within every stability limit (5 ms
        # made every sample of a jump diverge)
        run = ts.simulate(chain, method, step, tolerance=None, advise=False, check=False)
        assert run.success and not run.stability.exceeded, run.message

    _stop_at(monkeypatch, sweep_module, "_run_chunks", sweep_check)
    path = f"{model.units[0].name}.se_stiffness"
    stiffness = model.units[0].parameters.se_stiffness
    with pytest.raises(_Reached):
        main(["batch", "sweep", *spec, "--vary",
              f"{path}=uniform({0.9 * stiffness},{1.1 * stiffness})", "--quiet", "--out",
              str(tmp_path / "sweep")])


# ------------------------------------------------------------------ bad input, new surfaces

def test_two_outputs_to_one_file_are_refused_before_any_work(tmp_path, capsys):
    """--out x.mot --grf x.mot wrote both (the table then held the forces, and its manifest
    described the motion)."""
    same = tmp_path / "x.mot"
    err = _error_line(capsys, ["simulate", "--model", "builtin:squat-jump", "--out", str(same),
                               "--grf", str(same)])
    assert err.startswith("error: --grf:") and "also the file of --out" in err
    assert not any(tmp_path.iterdir())


def test_an_animation_name_that_cannot_be_written_is_refused_before_the_table(tmp_path,
                                                                              capsys):
    """Before, the table was written and the animation then failed naming a temporary file."""
    table = tmp_path / "run.csv"
    err = _error_line(capsys, ["simulate", "--out", str(table), "--animate",
                               str(tmp_path / ("a" * 240 + ".gif"))])
    assert err.startswith("error: --animate:") and "bytes" in err and ".tmp" not in err
    assert not table.exists()
    (tmp_path / "folder.gif").mkdir()
    err = _error_line(capsys, ["simulate", "--out", str(table), "--animate",
                               str(tmp_path / "folder.gif")])
    assert "is a directory" in err and not table.exists()


def test_a_long_run_is_animated_in_a_bounded_number_of_frames(tmp_path, monkeypatch):
    """A 60 s run took 217 s and 2 GB (1.3 MB a frame, 25 frames a second, unbounded)."""
    from PIL import Image

    import torquesim.plots as plots

    monkeypatch.setattr(plots, "MAX_FRAMES", 12)
    monkeypatch.setattr(plots, "MIN_PLAYING_TIME", 0.4)
    run = ts.simulate(ts.default_model(), "imex", 5e-3, duration=6.0)
    path = tmp_path / "long.gif"
    plots.animate_result(run, path)
    with Image.open(path) as gif:
        assert gif.n_frames == 12
    short = ts.simulate(ts.default_model(), "imex", 5e-3, duration=0.4)
    plots.animate_result(short, tmp_path / "short.gif")
    with Image.open(tmp_path / "short.gif") as gif:
        assert gif.n_frames == 11  # 25 a simulated second, real time


def _jump_target(**scale):
    from torquesim.fitting.target import jump_motion

    t = jump_motion()
    channels = {k: v * scale.get(k, 1.0) for k, v in t.channels.items()}
    return ts.fitting.Target(t.time * scale.get("time", 1.0), t.angles, t.joints, "x",
                             channels)


@pytest.mark.parametrize("scale, field, words", [
    ({"grf_y": 1e-3}, "target.grf_y", "kN or body weights"),
    ({"grf_y": 1 / 716.0}, "target.grf_y", "kN or body weights"),
    ({"grf_y": -1.0}, "target.grf_y", "the ground only pushes"),
    ({"com_y": 100.0}, "target.com_y", "cm or mm"),
    ({"com_x": 1000.0, "com_y": 1000.0}, "target.com_x", "cm or mm"),
    ({"time": 1000.0}, "target.time", "in ms"),
])
def test_a_target_in_other_units_is_named_before_any_simulation(scale, field, words):
    """A GRF target in kN, in body weights or negative ended blaming the step (after 100 s
    for a time in ms); a CoM in cm was fitted as metres ('com_y RMS 8896 cm')."""
    from torquesim.fitting import FitProblem

    model = ts.load_model("builtin:squat-jump")
    with pytest.raises(ts.ModelError) as info:
        FitProblem(_jump_target(**scale), base_model=model)
    assert info.value.field == field and words in str(info.value)
    FitProblem(_jump_target(), base_model=model)  # the same target in SI is taken


def test_a_grf_file_in_kilonewtons_is_one_line_and_no_output(tmp_path, capsys):
    target = _jump_target(grf_x=1e-3, grf_y=1e-3)
    lines = ["time,knee_angle,grf_x,grf_y"] + [
        f"{t},{math.degrees(q)},{fx},{fy}" for t, q, fx, fy in zip(
            target.time, target.angles[2], target.channels["grf_x"], target.channels["grf_y"],
            strict=True)]
    path = tmp_path / "trial.csv"
    path.write_text("\n".join(lines) + "\n")
    out = tmp_path / "fit"
    err = _error_line(capsys, ["fit", "--model", "builtin:squat-jump", "--target", str(path),
                               "--out", str(out), "--quiet"])
    assert err.startswith("error: target.grf_y:") and "kN" in err
    assert not out.exists()


def test_contacts_too_soft_to_stand_on_name_the_stiffness():
    """A stiffness of 1e-3 (inside its documented range) let the body sink 5 km; the advice
    then blamed the step."""
    model = ts.load_model("builtin:squat-jump")
    soft = tuple(replace(c, stiffness=1e-3) for c in model.contacts)
    with pytest.raises(ts.ModelError) as info:
        model.replace(contacts=soft)
    assert info.value.field == "contacts[0].stiffness" and "sink" in str(info.value)
    assert "allowed ≥" in str(info.value)


def test_a_missing_thigh_length_is_named_not_the_posture(tmp_path, capsys):
    text = model_to_toml(ts.load_model("builtin:squat-jump"))
    line = next(ln for ln in text.split("[[segments]]")[3].splitlines()
                if ln.startswith("length = "))
    path = tmp_path / "m.toml"
    path.write_text(text.replace(line, "", 1))
    err = _error_line(capsys, ["simulate", "--model", str(path)])
    assert err.startswith("error: segments[2].length: is missing"), err


@pytest.mark.parametrize("argv, option", [
    (["--bound", "nosuch=0,1"], "--bound"),
    (["--bound", "elbow_flexor.ramp7=0,1"], "--bound"),
    (["--freeze", "elbow_flexor.ramp0"], "--freeze"),
    (["--free", "nosuch"], "--free"),
    (["--timing-error", "5"], "--timing-error"),
    (["--window-delay", "-1"], "--window-delay"),
    (["--minimise", "time_to:elbow=10deg"], "--minimise"),
    (["--freeze", "elbow_flexor.ramp1.level=7"], "--freeze elbow_flexor.ramp1.level: 7 is "
                                                  "out of range; allowed [0, 1]"),
    (["--minimise", "time_to:elbow=400"], "--minimise time_to:elbow=400: 400 is out of "
                                          "range; allowed [-360, 360] deg"),
])
def test_optimise_options_are_named_in_their_errors(tmp_path, capsys, argv, option):
    goal = [] if "--minimise" in argv else ["--minimise", "time_to:elbow=90deg"]
    out = tmp_path / "opt"
    err = _error_line(capsys, ["optimise", *goal, *argv, "--out", str(out), "--quiet"])
    assert err.startswith(f"error: {option}"), err
    assert not out.exists()


@pytest.mark.parametrize("model", ["builtin:elbow-curl", "builtin:squat-jump"])
def test_a_column_map_on_a_built_in_motion_is_refused(tmp_path, capsys, model):
    """--column grf_y=nosuch on the squat jump's built-in motion was ignored and the fit ran."""
    out = tmp_path / "fit"
    err = _error_line(capsys, ["fit", "--model", model, "--column", "grf_y=nosuch", "--out",
                               str(out), "--quiet"])
    assert err.startswith("error: --column:") and "--target file" in err
    assert not out.exists()


def test_a_default_step_past_the_stability_limit_gives_way_to_a_verified_one():
    """simulate's step chosen from the model (step None): the curl keeps 0.1 ms; on the squat
    jump, whose units are stiff (§5 of docs/model.md), 0.1 ms breaks explicit RK4's limit
    and the run is at the largest step the advice search verifies: within the limit, within
    the tolerance, and the same motion as IMEX at 0.25 ms to 0.01°."""
    curl = ts.simulate(ts.default_model(), "monolithic", None)
    assert curl.step == 1e-4 and "step_note" not in curl.settings and curl.message == ""
    jump = ts.load_model("builtin:squat-jump")
    run = ts.simulate(jump, "monolithic", None)
    assert run.step < 1e-4 and run.message == "" and not run.stability.exceeded
    assert f"ran at {run.step * 1e3:.4g} ms" in run.settings["step_note"]
    assert run.settings["estimated_error_rad"] < math.radians(0.5)
    imex = ts.simulate(jump, "imex", 2.5e-4)
    stride = round(2.5e-4 / run.step)
    assert np.max(np.abs(run.q[::stride] - imex.q)) < math.radians(0.01)
    # a duration the default step does not divide: the largest step below it that does
    odd = ts.simulate(ts.default_model(), "monolithic", None, duration=0.33333)
    assert odd.step <= 1e-4 and round(0.33333 / odd.step) * odd.step == pytest.approx(0.33333)


def test_model_names_a_bad_preset_before_asking_what_to_write(capsys):
    assert main(["model", "nope"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "NAME" in err and "'nope'" in err and "squat-jump" in err


def test_an_error_estimate_that_cannot_be_made_is_said_in_words():
    """One 3 s IMEX step: the runs at half the step fail, so there is no estimate; the
    warning says so, not 'estimated max angle error inf°'."""
    run = ts.simulate(ts.default_model(), "imex", 3.0)
    assert math.isinf(run.settings["estimated_error_rad"])
    assert "no error estimate stands" in run.message and "inf" not in run.message


@pytest.mark.parametrize("method", ["reference", "imex-ros2-adaptive"])
def test_an_output_grid_made_to_divide_any_duration(method):
    """The adaptive methods' output grid: 1 ms, or where that does not divide the duration
    the largest step below it that does (as the fixed steps' default), down to one interval
    for a run shorter than 1 ms; given explicitly, one that does not divide is refused."""
    model = ts.default_model()
    for duration in (0.0123, 0.0004):
        run = ts.simulate(model, method, duration=duration, tolerance=None)
        h = run.settings["output_step"]
        intervals = round(duration / h)
        assert h <= 1e-3 and intervals * h == pytest.approx(duration)
        assert np.allclose(np.diff(run.time), h) and run.time[-1] == pytest.approx(duration)
        assert intervals == 1 or duration / (intervals - 1) > 1e-3  # the largest such grid
    with pytest.raises(ts.ModelError, match="output_step"):
        ts.simulate(model, method, duration=0.0123, output_step=1e-3)


def test_the_error_controlled_tolerance_is_bounded_on_the_command_line(capsys):
    """Below 1e-10 rad the round-off of the millions of steps approaches the tolerance and the
    accuracy check would take tens of millions more: refused in one line naming --atol's
    field and its range."""
    err = _error_line(capsys, ["simulate", "--model", "builtin:squat-jump", "--method",
                               "imex-ros2-adaptive", "--atol", "1e-11"])
    assert "atol" in err and "[1e-10, 1]" in err


def test_the_output_grid_is_an_option_of_the_methods_that_choose_their_steps(tmp_path, capsys):
    """`--output-step` writes an error-controlled run at its multiples (0.1 ms: ten times
    the rows of the default 1 ms); a fixed-step method, which writes every step, refuses it
    in one line."""
    out = tmp_path / "fine.csv"
    assert main(["simulate", "--model", "builtin:elbow-curl", "--method", "imex-ros2-adaptive",
                 "--output-step", "0.1ms", "--duration", "0.5", "--out", str(out)]) == 0
    time = np.loadtxt(out, delimiter=",", skiprows=1, usecols=0)
    assert time.size == 5001 and np.allclose(np.diff(time), 1e-4)
    capsys.readouterr()
    err = _error_line(capsys, ["simulate", "--method", "imex", "--output-step", "1ms",
                               "--out", str(tmp_path / "x.csv")])
    assert "--output-step" in err and "imex-ros2-adaptive" in err
    assert not (tmp_path / "x.csv").exists()


def test_a_failed_run_gives_its_advice_once():
    """The drop landing at a 10 ms imex-ros2 step leaves the possible range at the impact;
    the error names the verified step once (it said 'use a smaller step …' before the
    verified advice too), and a run at that step succeeds."""
    landing = ts.load_model("builtin:drop-landing")
    with pytest.raises(ts.SimulationError) as failed:
        ts.simulate(landing, "imex-ros2", 1e-2)
    message = str(failed.value)
    assert message.count("use ") == 1 and "a run at that step was checked" in message, message
    safe = float(message.split("step ≤ ")[1].split(" ms")[0]) * 1e-3
    assert 0.0 < safe < 1e-2 and ts.simulate(landing, "imex-ros2", safe).success


def test_a_body_that_passes_through_the_ground_is_warned_about():
    """Only the contact points meet the ground: the squat jump run for 3 s lands, falls over
    and sinks through the ground (its centre of mass ends 1 m below it). The run warns at the
    first time a joint or a centre of mass is 5 cm below the ground, with what to change; the
    jump as given (0.55 s, flight included) does not."""
    jump = ts.load_model("builtin:squat-jump")
    for method, step in (("imex-ros2-adaptive", None), ("imex", 2.5e-4)):
        run = ts.simulate(jump, method, step, duration=3.0, tolerance=None)
        assert "passes through the ground" in run.message and "duration ≤" in run.message
        said = next(part for part in run.message.split(" Also: ") if "passes through" in part)
        when = float(said.split("at t = ")[1].split(" s")[0])
        where = jump.kinematics(run.states[:, :jump.n_base + jump.n_joints])
        lowest = np.minimum(where["joints"][..., 1].min(axis=1),
                            where["centres"][..., 1].min(axis=1))
        first = run.time[np.flatnonzero(lowest < -0.05)[0]]
        assert when == pytest.approx(first, abs=1e-3) and 0.9 < when < 1.5
        assert lowest[run.time < first].min() > -0.05
    assert "ground" not in ts.simulate(jump, "imex-ros2-adaptive", tolerance=None).message


def test_a_long_step_search_says_each_step_it_tries(capsys, monkeypatch):
    """simulate's search for a step a run verifies (after a run that fails or breaks the
    stability limit) says each step it tries once it has run a while (here at once), down
    to the step it advises; the error stays the last line."""
    import torquesim.cli as cli

    monkeypatch.setattr(cli, "SEARCH_REPORT_AFTER", 0.0)
    code = main(["simulate", "--model", "builtin:drop-landing", "--method", "imex-ros2",
                 "--step", "10ms"])
    err = [line for line in capsys.readouterr().err.splitlines()
           if not line.startswith(("compiling ", "still compiling"))]
    tried = [float(line.split("trying ")[1].split(" ms")[0]) for line in err[:-1]]
    assert code == 1 and err[-1].startswith("error: ") and "step ≤ 0.3125 ms" in err[-1]
    assert all(line.startswith("note: the run at 10 ms failed") for line in err[:-1])
    assert tried[-1] == 0.3125 and tried == [10 / 2**k for k in range(2, len(tried) + 2)]
