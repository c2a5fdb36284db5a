"""Fitting: target readers, the objective, recovery of known profiles, freezing, resume,
the stability guard inside the fit, and the CLI."""

import json
import math

import numpy as np
import pytest

import torquesim as ts
from torquesim.cli import main
from torquesim.fitting import (
    FitProblem,
    ParameterSpace,
    SearchSettings,
    Target,
    fit_to_accuracy,
    load_target,
    min_jerk_curl,
    run_fit,
)
from torquesim.fitting.fit import _Run, load_checkpoint
from torquesim.fitting.objective import FAILED_SCORE, sample_joint
from torquesim.fitting.parameters import vector, with_ramps
from torquesim.model.paths import set_parameter

# A known activation pattern: flexor burst and release, mild extensor co-contraction.
TRUE_X = np.array([0.05, 0.3, 0.5, 0.3, 0.4, 0.25, 0.1, 0.2, 0.3,
                   0.2, 0.3, 0.15, 0.2, 0.3, 0.1, 0.1, 0.2, 0.1])
QUICK = SearchSettings(starts=2, iterations=40)
GLOBAL = SearchSettings(search="global", generations=30, population_per_parameter=8,
                        polish_simulations=1000)


def _elbow_with(x, duration, start_deg):
    chain = ts.load_model("builtin:elbow-curl")
    chain = with_ramps(chain, x, [None, 0.1]).replace(duration=duration)
    joint = chain.joints[0]
    from dataclasses import replace

    return chain.replace(joints=(replace(joint, initial_angle=math.radians(start_deg)),))


@pytest.fixture(scope="module")
def synthetic_target():
    """1.5 s motion (20° → ~70°) simulated with the reference solver from TRUE_X."""
    ref = ts.simulate(_elbow_with(TRUE_X, 1.5, 20.0), "reference", output_step=0.01)
    return Target(ref.time + 2.0, ref.q.T, ("elbow",), "synthetic")  # need not start at 0


# ---------------------------------------------------------------- targets

def test_builtin_curl_is_model_md_min_jerk():
    target = min_jerk_curl()
    assert np.degrees(target.angle[[0, 150, -1]]) == pytest.approx([10, 135, 10])
    assert target.duration == pytest.approx(3.0)
    assert np.max(np.abs(target.angular_velocity())) == pytest.approx(2.727, abs=2e-3)
    assert load_target("builtin:curl").time.size == target.time.size


def _write(path, text):
    path.write_text(text, encoding="utf-8")
    return str(path)


def test_csv_target_in_degrees_and_radians(tmp_path):
    rows = "\n".join(f"{0.01 * i},{10 + i},{math.radians(10 + i)}" for i in range(6))
    path = _write(tmp_path / "t.csv", "time,elbow_deg,elbow_rad\n" + rows + "\n")
    deg = load_target(path, columns="elbow_deg", units="deg")
    rad = load_target(path, columns="elbow_rad", units="rad")
    assert deg.angle == pytest.approx(rad.angle)
    assert math.degrees(deg.angle[2]) == pytest.approx(12.0)


def test_csv_target_with_semicolons_and_comments(tmp_path):
    rows = "\n".join(f"{0.01 * i};{10 + i}" for i in range(6))
    path = _write(tmp_path / "t.csv", "# exported by a lab system\ntime;elbow\n" + rows + "\n")
    target = load_target(path)
    assert target.time.size == 6 and math.degrees(target.angle[-1]) == pytest.approx(15.0)


@pytest.mark.parametrize("flag, scale", [("yes", 1.0), ("no", math.pi / 180)])
def test_mot_target_honours_in_degrees(tmp_path, flag, scale):
    body = "\n".join(f"{0.01 * i}\t{(30 + i) * scale}\t0.0" for i in range(6))
    path = _write(tmp_path / "t.mot", f"trial\nversion=1\nnRows=6\nnColumns=3\n"
                  f"inDegrees={flag}\nendheader\ntime\tr_elbow_flex\tpro_sup\n{body}\n")
    target = load_target(path)  # picks the one column whose name has 'elbow'
    assert math.degrees(target.angle[1]) == pytest.approx(31.0)
    assert "r_elbow_flex" in target.source


@pytest.mark.parametrize("text, suffix, column, match", [
    ("time,a\n0,1\n0.01,nan\n0.02,3\n0.03,4\n0.04,5\n", ".csv", "a", r"line 3, column 'a'.*NaN"),
    ("time,a\n0,1\n0.01,x\n0.02,3\n0.03,4\n0.04,5\n", ".csv", "a", r"line 3.*'x' is not a number"),
    ("time,a\n0,1\n0.01,2\n0.02,3\n0.03,4\n0.04,5\n", ".csv", "b", r"no column 'b'"),
    ("time,a\n0,1\n0.02,2\n0.01,3\n0.03,4\n0.04,5\n", ".csv", "a", r"line 4.*does not increase"),
    ("time,a\n0,1\n0.01,2\n", ".csv", "a", r"2 samples; allowed at least 5"),
    ("time,a,b\n0,1,1\n0.01,2,2\n", ".csv", None, r"no column matches a joint"),
    ("a,b\n0,1\n", ".csv", None, r"no 'time' column"),
    ("time\ta\n0\t1\n", ".mot", "a", r"no 'endheader'"),
    ("inDegrees=yes\nendheader\ntime\ta\n0\t1\n0.1\t2\t3\n", ".mot", "a", r"line 5: 3 cells"),
    ("nRows=9\ninDegrees=yes\nendheader\ntime\ta\n" + "".join(
        f"{0.01 * i}\t{i}\n" for i in range(6)), ".mot", "a", r"nRows=9 but the file has 6"),
    ("nColumns=3\ninDegrees=yes\nendheader\ntime\ta\n" + "".join(
        f"{0.01 * i}\t{i}\n" for i in range(6)), ".mot", "a", r"nColumns=3 but the data has 2"),
    ("inDegrees=maybe\nendheader\ntime\ta\n0\t1\n", ".mot", "a",
     r"line 1: inDegrees='maybe'; allowed yes or no"),
    ("time,a\n" + "".join(f"{0.01 * i},{100 * i}\n" for i in range(6)), ".csv", "a",
     r"column 'a': 500° is more than a full turn"),
])
def test_bad_target_files_name_file_line_and_column(tmp_path, text, suffix, column, match):
    path = _write(tmp_path / f"bad{suffix}", text)
    with pytest.raises(ts.ModelError, match=match) as info:
        load_target(path, columns=column)
    assert info.value.field == "target" and f"bad{suffix}" in str(info.value)


def test_bad_target_via_cli_is_one_line_exit_2(tmp_path, capsys):
    path = _write(tmp_path / "bad.csv", "time,a\n0,1\n0.01,oops\n")
    assert main(["fit", "--target", path, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "line 3" in err and "'a'" in err
    assert not (tmp_path / "o").exists()


# ---------------------------------------------------------------- objective

def test_hermite_sampling_is_exact_for_a_cubic_motion():
    step = 0.1
    t = np.arange(11) * step
    states = np.zeros((11, 4))
    states[:, 0] = 1 + t - 2 * t**2 + 0.5 * t**3
    states[:, 1] = 1 - 4 * t + 1.5 * t**2
    times = np.array([0.0, 0.037, 0.55, 0.999, 1.0])
    theta, omega = np.empty(5), np.empty(5)
    sample_joint(states, step, times, 0, 1, theta, omega)
    assert theta == pytest.approx(1 + times - 2 * times**2 + 0.5 * times**3, abs=1e-12)


def test_score_is_rms_in_degrees_plus_weighted_terms(synthetic_target):
    """‖r‖² = MSE + w_ω²·MSE_ω + w_end²·(end errors²) (objective module docstring)."""
    plain = FitProblem(synthetic_target, step=2.5e-3)
    both = FitProblem(synthetic_target, step=2.5e-3, weight_velocity=0.5, weight_end=2.0)
    r0, _ = plain.residuals(TRUE_X)
    r1, _ = both.residuals(TRUE_X)
    run = ts.simulate(plain.model_for(TRUE_X), "imex", plain.step)
    q, qd = np.empty_like(plain.times), np.empty_like(plain.times)
    sample_joint(run.states, run.step, plain.times, 0, 1, q, qd)
    e = np.degrees(q - synthetic_target.angle)
    ew = np.degrees(qd - plain.target_omega[0])
    assert r0[0] @ r0[0] == pytest.approx(np.mean(e**2), rel=1e-9)
    expected = np.mean(e**2) + 0.25 * np.mean(ew**2) + 4.0 * (e[-1] ** 2 + ew[-1] ** 2)
    assert r1[0] @ r1[0] == pytest.approx(expected, rel=1e-9)


def test_effort_term_is_the_mean_squared_activation_above_rest(synthetic_target):
    """w_a·Σ_u mean (a_u − rest_u)₊²: the flexor (from equilibrium) counts from 0, the
    extensor from its rest level 0.1, and only above it."""
    plain = FitProblem(synthetic_target, step=2.5e-3)
    effort = FitProblem(synthetic_target, step=2.5e-3, weight_effort=10.0)
    r0, _ = plain.residuals(TRUE_X)
    r1, _ = effort.residuals(TRUE_X)
    from torquesim.model.activation import activation

    packed = plain.model_for(TRUE_X).pack(plain.levels).activations
    a = np.array([[activation(t, packed[u]) for t in plain.times] for u in range(2)])
    above = np.maximum(a - np.array([[0.0], [0.1]]), 0.0)
    assert r1[0] @ r1[0] - r0[0] @ r0[0] == pytest.approx(10.0 * np.sum(np.mean(above**2, 1)),
                                                          rel=1e-9)


def test_fit_problem_reproduces_the_simulator(synthetic_target):
    """The compiled objective of TRUE_X equals the RMS of an ordinary simulate() run."""
    problem = FitProblem(synthetic_target, step=2.5e-3)
    score, failed = problem.evaluate(TRUE_X)
    run = ts.simulate(problem.model_for(TRUE_X), "imex", problem.step)
    assert not failed[0]
    assert score[0] == pytest.approx(problem.errors_deg(run)["elbow"][0], rel=1e-9)
    assert score[0] < 0.05  # IMEX at 2.5 ms vs the reference-made target


def test_explicit_rk4_past_its_limit_scores_as_failed():
    """docs/model.md §5 inside the fit: monolithic RK4 at 5 ms breaks the stability limit on
    the curl, so every candidate fails instead of fitting a numerical artefact; IMEX does
    not."""
    model = ts.load_model("builtin:elbow-curl")
    x = vector([u.activation for u in model.units])
    bad = FitProblem(min_jerk_curl(), method="monolithic", step=5e-3)
    scores, failed = bad.evaluate(x)
    assert failed[0] and scores[0] == pytest.approx(FAILED_SCORE)
    good = FitProblem(min_jerk_curl(), method="imex", step=5e-3)
    assert not good.evaluate(x)[1][0]


def test_fit_with_explicit_rk4_past_its_limit_stops_with_advice(capsys, tmp_path):
    args = ["fit", "--method", "monolithic", "--step", "5ms", "--out", str(tmp_path / "o")]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert "step" in err and "stability limit" in err and "--method imex" in err
    assert not (tmp_path / "o").exists()


def test_step_is_shrunk_to_divide_the_target_span(synthetic_target):
    problem = FitProblem(synthetic_target, step=4e-3)
    assert problem.step <= 4e-3 and problem.n_steps * problem.step == pytest.approx(1.5)


def test_jacobian_agrees_with_central_differences_of_the_simulator(synthetic_target):
    """The least-squares Jacobian (forward differences of the parallel compiled population,
    step 1e-6) against central differences of ordinary simulate() runs at step 1e-4: within
    2e-5 relative (Frobenius; the forward difference's own error is ~h·|r''|/2, measured
    2.4e-6), and the same whether r(x) is passed in or simulated with the columns."""
    problem = FitProblem(synthetic_target, step=2.5e-3)
    x = TRUE_X + 0.01
    run = _Run(problem, SearchSettings(), None, lambda _m: None, None, lambda: False)
    run.state = {"initial_x": x}
    jac = run.jacobian(x.copy())

    def residual(v):
        result = ts.simulate(problem.model_for(v), "imex", problem.step)
        q, qd = np.empty_like(problem.times), np.empty_like(problem.times)
        sample_joint(result.states, result.step, problem.times, 0, 1, q, qd)
        return np.degrees(q - synthetic_target.angle) / math.sqrt(q.size)

    h = 1e-4
    reference = np.array([(residual(x + h * e) - residual(x - h * e)) / (2 * h)
                          for e in np.eye(x.size)]).T
    assert np.linalg.norm(jac - reference) <= 2e-5 * np.linalg.norm(reference)
    at, _ = problem.residuals(x)
    np.testing.assert_array_equal(run.jacobian(x.copy(), at[0]), jac)
    central = _Run(problem, SearchSettings(jacobian="central"), None, lambda _m: None, None,
                   lambda: False)
    central.state = {"initial_x": x}
    # second order: closer to the reference than the forward differences' 2.4e-6
    assert np.linalg.norm(central.jacobian(x.copy()) - reference) <= 1e-6 * np.linalg.norm(
        reference)
    # all but the ramps that start after the 1.5 s target ends move the motion
    assert np.count_nonzero(np.linalg.norm(reference, axis=0)) >= 15


def test_a_model_field_is_a_fit_parameter_with_its_own_start(synthetic_target):
    """A model field given bounds (the flexor's SE stiffness) is fitted beside the ramps. At
    the model's own value a candidate scores exactly as with the ramps alone; at another
    value exactly as the ramps alone on a model made with that value (its own static
    equilibrium and packed arrays); and its Jacobian column (a difference step of 1e-6 of
    its range) agrees with central differences of ordinary simulate() runs."""
    path = "elbow_flexor.se_stiffness"
    base = ts.load_model("builtin:elbow-curl")
    plain = FitProblem(synthetic_target, step=2.5e-3)
    space = ParameterSpace.for_model(base).with_bounds(path, 200.0, 900.0, base)
    problem = FitProblem(synthetic_target, space, step=2.5e-3)
    assert problem.space.names[-1] == path and problem.space.size == TRUE_X.size + 1
    x = TRUE_X + 0.01
    np.testing.assert_array_equal(problem.residuals(np.append(x, 600.0))[0],
                                  plain.residuals(x)[0])
    soft = FitProblem(synthetic_target, base_model=set_parameter(base, path, 400.0),
                      step=2.5e-3)
    at_400 = problem.residuals(np.append(x, 400.0))[0]
    np.testing.assert_array_equal(at_400, soft.residuals(x)[0])
    assert np.abs(at_400 - plain.residuals(x)[0]).max() > 1e-3  # the tendon moves the motion
    run = _Run(problem, SearchSettings(), None, lambda _m: None, None, lambda: False)
    run.state = {"initial_x": np.append(x, 400.0)}
    column = run.jacobian(np.append(x, 400.0))[:, -1]

    def residual(k):
        result = ts.simulate(problem.model_for(np.append(x, k)), "imex", problem.step)
        q, qd = np.empty_like(problem.times), np.empty_like(problem.times)
        sample_joint(result.states, result.step, problem.times, 0, 1, q, qd)
        return np.degrees(q - synthetic_target.angle) / math.sqrt(q.size)

    reference = (residual(401.0) - residual(399.0)) / 2.0
    assert np.linalg.norm(column - reference) <= 1e-4 * np.linalg.norm(reference)


def test_a_fit_recovers_a_tendon_stiffness():
    """Targets made with a softer flexor tendon (450 and 300 N·m/rad; the model's is 600) by
    the fit's own technique and step, so that the truth scores 0: fitted from the model's
    value with the stiffness bounded to [200, 900], the fit finds the ramps and the
    stiffness together, the stiffness to 1e-6. (Against a reference-solver target the
    integration error, ~1e-3°, outweighs what a 25 % softer tendon changes once the ramps
    have adapted: the fit then lands within about 1 %.)"""
    path = "elbow_flexor.se_stiffness"
    base = ts.load_model("builtin:elbow-curl")
    space = ParameterSpace.for_model(base).with_bounds(path, 200.0, 900.0, base)
    for stiffness in (450.0, 300.0):
        made = set_parameter(_elbow_with(TRUE_X, 1.5, 20.0), path, stiffness)
        run = ts.simulate(made, "imex", 2.5e-3)
        target = Target(run.time[::4], run.q.T[:, ::4], ("elbow",), "soft tendon")
        problem = FitProblem(target, space, base, step=2.5e-3)
        outcome = run_fit(problem, SearchSettings(starts=2, iterations=150))
        fitted = problem.space.table(outcome.x)[path]
        assert fitted == pytest.approx(stiffness, rel=1e-6)
        assert outcome.score < 1e-6 < outcome.initial_score
        assert problem.model_for(outcome.x).units[0].parameters.se_stiffness == fitted


def test_the_command_fits_a_model_field_and_says_so(tmp_path, capsys):
    """``fit --bound`` with a model field: the printed summary, fit_summary.json's
    ``fitted_fields`` and the fitted model file hold the value found (the target made by the
    fit's technique and step with a 450 N·m/rad tendon); a field that ends at its bound is
    warned about."""
    path = "elbow_flexor.se_stiffness"
    run = ts.simulate(set_parameter(_elbow_with(TRUE_X, 1.5, 20.0), path, 450.0), "imex",
                      2.5e-3)
    target = tmp_path / "soft.csv"
    target.write_text("time,elbow\n" + "".join(f"{float(t)!r},{math.degrees(q)!r}\n" for t, q in
                                              zip(run.time[::4], run.q[::4, 0], strict=True)))
    out = tmp_path / "fit"
    argv = ["fit", "--target", str(target), "--step", "2.5ms", "--starts", "2",
            "--iterations", "150", "--out", str(out), "--quiet", "--overwrite"]
    assert main([*argv, "--bound", f"{path}=200,900"]) == 0
    said = next(line for line in capsys.readouterr().out.splitlines()
                if line.startswith("fitted"))
    summary = json.loads((out / "fit_summary.json").read_text())
    fitted = summary["fitted_fields"][path]
    assert fitted["value"] == pytest.approx(450.0, rel=1e-6) and fitted["start"] == 600.0
    assert said == f"fitted        {path} {fitted['value']:.6g} N·m/rad (from 600; bounds 200 " \
                   "to 900)"
    assert ts.load_model(str(out / "fitted_model.toml")).units[0].parameters.se_stiffness \
        == fitted["value"]
    assert main([*argv, "--bound", f"{path}=500,900"]) == 0
    assert f"warning: {path} ended at its bound 500" in capsys.readouterr().out
    # held (--freeze) instead: the fit runs on the model with that value, which it writes
    assert main([*argv, "--freeze", f"{path}=450"]) == 0
    summary = json.loads((out / "fit_summary.json").read_text())
    assert summary["fitted_fields"] == {} and summary["objective_deg"] < 1e-6
    assert ts.load_model(str(out / "fitted_model.toml")).units[0].parameters.se_stiffness \
        == 450.0


# ---------------------------------------------------------------- the fit

@pytest.mark.parametrize("settings", [QUICK, GLOBAL], ids=["least-squares", "global"])
def test_fit_recovers_a_known_motion(synthetic_target, settings):
    problem = FitProblem(synthetic_target)
    outcome = run_fit(problem, settings)
    reference = ts.simulate(problem.model_for(outcome.x), "reference", output_step=0.005)
    rms, _ = problem.errors_deg(reference)["elbow"]
    assert rms <= 0.5
    assert outcome.score < outcome.initial_score
    assert outcome.simulations == problem.simulations > 500


@pytest.fixture(scope="module")
def arm_target():
    """1.5 s of the arm raise (shoulder and elbow) made by its own preset, reference solver."""
    model = ts.load_model("builtin:arm-raise").replace(duration=1.5)
    ref = ts.simulate(model, "reference", output_step=0.01)
    return model, Target(ref.time, ref.q.T, ("shoulder", "elbow"), "arm preset")


def test_fit_recovers_a_two_joint_motion_per_joint(arm_target):
    """Recovery on a 2-joint preset: ≤ 0.5° RMS per joint with the reference solver."""
    model, target = arm_target
    problem = FitProblem(target, base_model=model)
    assert problem.space.size == 36
    outcome = run_fit(problem, SearchSettings(starts=2, iterations=80))
    reference = ts.simulate(problem.model_for(outcome.x), "reference", output_step=0.005)
    errors = problem.errors_deg(reference)
    assert errors["shoulder"][0] <= 0.5 and errors["elbow"][0] <= 0.5, errors


def test_unscored_joints_are_simulated_not_scored(arm_target):
    model, target = arm_target
    shoulder_only = Target(target.time, target.angles[:1], ("shoulder",), "shoulder")
    problem = FitProblem(shoulder_only, base_model=model)
    assert list(problem.scored) == [0] and problem.residual_size == target.time.size
    weighted = FitProblem(target, base_model=model, joint_weights={"elbow": 3.0})
    assert weighted.weights == pytest.approx([0.25, 0.75])
    with pytest.raises(ts.ModelError, match="not a scored joint"):
        FitProblem(shoulder_only, base_model=model, joint_weights={"elbow": 1.0})


def test_fit_is_reproducible_with_the_same_seed(synthetic_target):
    for small in (SearchSettings(starts=3, iterations=10),
                  SearchSettings(search="global", generations=5, population_per_parameter=4,
                                 polish_simulations=50)):
        a = run_fit(FitProblem(synthetic_target), small)
        b = run_fit(FitProblem(synthetic_target), small)
        assert np.array_equal(a.x, b.x) and a.score == b.score


def test_frozen_parameters_stay_frozen(synthetic_target):
    frozen = {"extensor.ramp1.level": 0.15, "elbow.flexor.ramp2.duration": 0.4}
    space = ParameterSpace(frozen=frozen)
    for settings in (SearchSettings(starts=2, iterations=15),
                     SearchSettings(search="global", generations=8, population_per_parameter=4,
                                    polish_simulations=200)):
        outcome = run_fit(FitProblem(synthetic_target, space), settings)
        assert outcome.x[space.index("elbow_extensor.ramp1.level")] == 0.15
        assert outcome.x[space.index("elbow_flexor.ramp2.duration")] == 0.4
        assert np.all(outcome.x >= space.lower) and np.all(outcome.x <= space.upper)


def _stop_after(n):
    calls = []

    def stop():
        calls.append(1)
        return len(calls) >= n

    return stop


def test_least_squares_resumed_gives_the_uninterrupted_result(synthetic_target, tmp_path):
    settings = SearchSettings(starts=3, iterations=20)
    whole = run_fit(FitProblem(synthetic_target), settings)
    checkpoint = tmp_path / "ck.npz"
    first = run_fit(FitProblem(synthetic_target), settings, checkpoint=checkpoint,
                    should_stop=_stop_after(20))
    assert first.interrupted and first.generations_done < 3
    state = load_checkpoint(checkpoint, FitProblem(synthetic_target), settings)
    resumed = run_fit(FitProblem(synthetic_target), settings, checkpoint=checkpoint,
                      resume=state)
    assert not resumed.interrupted and resumed.generations_done == 3
    assert resumed.x == pytest.approx(whole.x, rel=1e-12, abs=1e-15)
    assert resumed.simulations > first.simulations


def test_global_resume_after_interruption_is_at_least_as_good(synthetic_target, tmp_path):
    checkpoint = tmp_path / "ck.npz"
    problem = FitProblem(synthetic_target)
    first = run_fit(problem, GLOBAL, checkpoint=checkpoint, should_stop=_stop_after(5))
    assert first.interrupted and first.generations_done == 5
    state = load_checkpoint(checkpoint, FitProblem(synthetic_target), GLOBAL)
    assert float(state["best_score"]) == first.score
    resumed = run_fit(FitProblem(synthetic_target), GLOBAL, checkpoint=checkpoint, resume=state)
    assert not resumed.interrupted and resumed.generations_done == GLOBAL.generations
    assert resumed.score <= first.score
    assert resumed.simulations > first.simulations


TINY = SearchSettings(starts=1, iterations=2)


def test_checkpoint_of_another_fit_is_refused(synthetic_target, tmp_path):
    checkpoint = tmp_path / "ck.npz"
    run_fit(FitProblem(synthetic_target), TINY, checkpoint=checkpoint)
    with pytest.raises(ts.ModelError, match="another fit"):
        load_checkpoint(checkpoint, FitProblem(synthetic_target, step=2e-3), TINY)
    with pytest.raises(ts.ModelError, match="another fit"):
        load_checkpoint(checkpoint, FitProblem(synthetic_target, weight_effort=1.0), TINY)
    with pytest.raises(ts.ModelError, match="seed = 1, not 2"):
        load_checkpoint(checkpoint, FitProblem(synthetic_target),
                        SearchSettings(seed=2, starts=1, iterations=2))
    with pytest.raises(ts.ModelError, match="search"):
        load_checkpoint(checkpoint, FitProblem(synthetic_target),
                        SearchSettings(search="global"))
    longer = SearchSettings(starts=1, iterations=50)
    assert load_checkpoint(checkpoint, FitProblem(synthetic_target), longer)["seed"] == 1


def test_a_checkpoint_fingerprints_every_scored_joint(arm_target, tmp_path):
    """A checkpoint of a two-joint fit is refused for a target whose second joint differs."""
    model, target = arm_target
    checkpoint = tmp_path / "ck.npz"
    run_fit(FitProblem(target, base_model=model), TINY, checkpoint=checkpoint)
    other = Target(target.time, np.vstack([target.angles[0], target.angles[1] + 0.01]),
                   target.joints, "other elbow")
    with pytest.raises(ts.ModelError, match="another fit"):
        load_checkpoint(checkpoint, FitProblem(other, base_model=model), TINY)
    assert load_checkpoint(checkpoint, FitProblem(target, base_model=model), TINY)


def test_a_fit_reports_the_error_of_the_model_it_writes(synthetic_target):
    """At a 50 ms IMEX step the fit's own error is not the fitted model's: the fit continues at
    half the step until the reference re-simulation agrees with it per joint (10 % or
    0.02°), and says so."""
    from torquesim.fitting.fit import integration_gap
    from torquesim.fitting.outputs import summarise, summary_lines

    coarse = FitProblem(synthetic_target, step=50e-3)
    settings = SearchSettings(starts=1, iterations=30)
    first = run_fit(coarse, settings)
    own, ref = integration_gap(coarse, first.x)["elbow"]
    assert abs(ref - own) > max(0.1 * own, 0.02)  # the coarse fit alone would mislead
    problem, outcome, refinements = fit_to_accuracy(FitProblem(synthetic_target, step=50e-3),
                                                    settings)
    assert len(refinements) > 1 and refinements[-1]["agree"]
    assert not any(r["agree"] for r in refinements[:-1])
    assert problem.step == pytest.approx(refinements[-1]["step_s"]) and problem.step < 50e-3
    summary = summarise(problem, outcome, settings, refinements)
    joint = summary["joints"]["elbow"]
    assert abs(joint["reference_rms_error_deg"] - joint["rms_error_deg"]) <= max(
        0.1 * joint["rms_error_deg"], 0.02)
    # no warning of a disagreement (30 iterations may end on the cap: that one is said apart)
    assert not [w for w in summary["warnings"] if "stopped on" not in w]
    assert any(line.startswith("step          refined 50 ms") for line in summary_lines(summary))


@pytest.mark.parametrize("damage, message", [
    (lambda data: b"", "empty: not a torquesim checkpoint"),
    (lambda data: data[: len(data) // 2], "corrupt"),
    (lambda data: b"time,angle\n0,1\n", "not a zip file"),
    (lambda data: None, "not a torquesim checkpoint"),  # a valid .npz of something else
])
def test_damaged_or_foreign_checkpoints_are_one_line_errors(synthetic_target, tmp_path,
                                                            damage, message):
    checkpoint = tmp_path / "ck.npz"
    run_fit(FitProblem(synthetic_target), TINY, checkpoint=checkpoint)
    data = damage(checkpoint.read_bytes())
    if data is None:
        np.savez(checkpoint, meta=np.array('{"version": 1}'), weights=np.zeros(3))
    else:
        checkpoint.write_bytes(data)
    with pytest.raises(ts.ModelError) as info:
        load_checkpoint(checkpoint, FitProblem(synthetic_target), TINY)
    assert message in str(info.value) and "\n" not in str(info.value)
    assert info.value.field == "resume"


@pytest.mark.parametrize("space_args, field", [
    (dict(frozen={"flexor.ramp9.level": 0.1}), "freeze"),
    (dict(frozen={"flexor.ramp1.level": 1.5}), "freeze.flexor.ramp1.level"),
    (dict(frozen={"shoulder.flexor.ramp1.level": 0.5}), "freeze"),
    (dict(rest_level=-0.1), "rest_level"),
])
def test_bad_parameter_space(space_args, field):
    with pytest.raises(ts.ModelError) as info:
        ParameterSpace(**space_args)
    assert info.value.field == field


def test_parameter_names_and_aliases_on_a_chain():
    space = ParameterSpace.for_model(ts.load_model("builtin:arm-raise"))
    assert space.names[0] == "shoulder_flexor.ramp1.delay" and space.size == 36
    assert space.resolve("elbow.extensor.ramp3.level") == "elbow_extensor.ramp3.level"
    with pytest.raises(ts.ModelError, match="shoulder_flexor"):
        space.resolve("flexor.ramp1.delay")  # ambiguous on two joints: not an alias


def test_bad_bounds_name_the_parameter():
    with pytest.raises(ts.ModelError, match="lower 0.5 ≥ upper 0.2") as info:
        ParameterSpace().with_bounds("flexor.ramp1.delay", 0.5, 0.2)
    assert info.value.field == "bounds.elbow_flexor.ramp1.delay"


# ---------------------------------------------------------------- CLI

def test_fit_cli_writes_loadable_outputs_and_resumes(tmp_path, capsys):
    target = tmp_path / "target.csv"
    t = np.arange(0, 1.0001, 0.01)
    angle = 20 + 30 * (10 * t**3 - 15 * t**4 + 6 * t**5)
    target.write_text("time,elbow\n" + "".join(f"{a},{b}\n" for a, b in zip(t, angle, strict=True)))
    out = tmp_path / "fit"
    args = ["fit", "--target", str(target), "--out", str(out), "--starts", "2",
            "--iterations", "8", "--freeze", "extensor.ramp3.level=0.1",
            "--bound", "flexor.ramp1.delay=0,0.3"]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "reference RMS" in printed and "mean elbow_flexor" in printed
    summary = json.loads((out / "fit_summary.json").read_text())
    assert summary["parameters"]["elbow_extensor.ramp3.level"] == 0.1
    assert 0 <= summary["parameters"]["elbow_flexor.ramp1.delay"] <= 0.3
    assert summary["simulations"] > 0 and summary["joints"]["elbow"]["reference_rms_error_deg"] < 20
    assert 0.0 <= summary["mean_activation"]["elbow_extensor"] <= 1.0
    fitted = ts.load_model(out / "fitted_model.toml")
    assert fitted.duration == pytest.approx(1.0)
    assert math.degrees(fitted.joints[0].initial_angle) == pytest.approx(20.0)
    # the model file records the fit that made it (target, errors, settings), then the
    # starting model's sources
    assert fitted.notes[0].startswith("Activation ramps fitted by torquesim")
    assert str(target) in fitted.notes[0]
    rms = summary["joints"]["elbow"]["reference_rms_error_deg"]
    assert f"elbow RMS {rms:.3f} deg (reference)" in fitted.notes[0]
    assert "seed 1" in fitted.notes[1] and len(fitted.notes) > 2
    table = ts.read_table(out / "fit_motion.csv")
    assert list(table)[:4] == ["time", "elbow_target_deg", "elbow_fitted_deg",
                               "elbow_reference_deg"]
    storage = ts.read_table(out / "fit_motion.sto")  # OpenSim storage, radians
    assert storage["elbow_target"] == pytest.approx(np.radians(table["elbow_target_deg"]))
    assert (out / "fit.png").stat().st_size > 0
    assert main(args[:-4] + ["--resume"]) == 2  # settings differ (no freeze, no bound)
    assert "another fit" in capsys.readouterr().err
    assert main([*args[:6], "3", *args[7:], "--resume"]) == 0
    assert json.loads((out / "fit_summary.json").read_text())["generations"] == 3


def test_fit_cli_on_a_two_joint_mot_maps_columns_by_name(tmp_path, capsys):
    """An OpenSim IK file: columns named after the coordinates are matched automatically;
    --column maps one by hand; a column that is not there is one line, exit 2."""
    t = np.arange(0, 0.8001, 0.01)
    shoulder = 5 + 20 * (10 * (t / 0.8) ** 3 - 15 * (t / 0.8) ** 4 + 6 * (t / 0.8) ** 5)
    elbow = 10 + 15 * (10 * (t / 0.8) ** 3 - 15 * (t / 0.8) ** 4 + 6 * (t / 0.8) ** 5)
    rows = "".join(f"{a}\t{b}\t{c}\t0.0\n" for a, b, c in zip(t, shoulder, elbow, strict=True))
    path = tmp_path / "ik.mot"
    path.write_text(f"ik\nversion=1\nnRows={t.size}\nnColumns=4\ninDegrees=yes\nendheader\n"
                    f"time\tshoulder_flexion\tr_elbow_flex\tpelvis_tilt\n{rows}")
    out = tmp_path / "fit"
    base = ["fit", "--model", "builtin:arm-raise", "--target", str(path), "--starts", "1",
            "--iterations", "3", "--quiet"]
    assert main([*base, "--out", str(out)]) == 0
    summary = json.loads((out / "fit_summary.json").read_text())
    assert summary["target"]["joints"] == ["shoulder", "elbow"]
    assert "elbow=r_elbow_flex" in summary["target"]["source"]
    capsys.readouterr()
    assert main([*base, "--out", str(tmp_path / "f2"), "--column", "elbow=pelvis_tilt"]) == 0
    summary = json.loads((tmp_path / "f2" / "fit_summary.json").read_text())
    assert "elbow=pelvis_tilt" in summary["target"]["source"]
    assert main([*base, "--out", str(tmp_path / "f3"), "--column", "elbow=wrist"]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "no column 'wrist'" in err
    assert main([*base, "--out", str(tmp_path / "f4"), "--column", "knee=x"]) == 2
    assert "not a joint of the model" in capsys.readouterr().err


def test_target_columns_are_matched_to_joints(tmp_path):
    arm = ts.load_model("builtin:arm-raise")
    rows = "".join(f"{0.01 * i},{10 + i},{20 + i},{i}\n" for i in range(6))
    path = tmp_path / "t.csv"
    path.write_text("time,Shoulder,elbow_flexion,other\n" + rows)
    target = load_target(str(path), arm)
    assert target.joints == ("shoulder", "elbow")
    assert np.degrees(target.angles[:, 1]) == pytest.approx([11, 21])
    only = tmp_path / "o.csv"
    only.write_text("time,hip\n" + "".join(f"{0.01 * i},{i}\n" for i in range(6)))
    with pytest.raises(ts.ModelError, match="no column matches a joint"):
        load_target(str(only), arm)
    with pytest.raises(ts.ModelError, match="JOINT=COLUMN"):
        load_target(str(path), arm, "other")
    assert load_target("builtin:arm-raise", arm).joints == ("shoulder", "elbow")
    with pytest.raises(ts.ModelError, match="does not have"):
        load_target("builtin:knee-extension", arm)


@pytest.mark.parametrize("extra, field", [
    (["--bound", "flexor.ramp1.delay=0"], "--bound"),
    (["--freeze", "nonsense=1"], "--freeze"),
    (["--freeze", "elbow_flexor.ramp1.level=7"], "--freeze elbow_flexor.ramp1.level: 7"),
    (["--step", "0"], "step"),
    (["--resume"], "--resume"),
    (["--target", "builtin:walk"], "target"),
])
def test_fit_cli_bad_input_is_one_line_exit_2(tmp_path, capsys, extra, field):
    assert main(["fit", "--out", str(tmp_path / "o"), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and field in err


def _tiny_fit_args(tmp_path):
    target = tmp_path / "target.csv"
    t = np.arange(0, 0.6001, 0.01)
    angle = 20 + 20 * (10 * t**3 - 15 * t**4 + 6 * t**5)
    target.write_text("time,elbow\n" + "".join(f"{a},{b}\n" for a, b in zip(t, angle,
                                                                          strict=True)))
    return ["fit", "--target", str(target), "--out", str(tmp_path / "fit"), "--starts", "1",
            "--iterations", "2"]


def test_a_new_fit_into_a_fit_directory_needs_resume_or_overwrite(tmp_path, capsys):
    args = _tiny_fit_args(tmp_path)
    assert main(args) == 0
    first = (tmp_path / "fit" / "fit_summary.json").read_text()
    capsys.readouterr()
    assert main(args) == 2
    err = capsys.readouterr().err
    assert "--resume" in err and "--overwrite" in err and err.count("\n") == 1
    assert (tmp_path / "fit" / "fit_summary.json").read_text() == first  # untouched
    assert main([*args, "--overwrite"]) == 0
    assert not (tmp_path / "fit" / ".torquesim-fit.lock").exists()


def test_a_second_fit_into_a_locked_directory_is_refused(tmp_path, capsys):
    import os

    args = _tiny_fit_args(tmp_path)
    (tmp_path / "fit").mkdir()
    (tmp_path / "fit" / ".torquesim-fit.lock").write_text(str(os.getppid()))  # alive
    assert main(args) == 2
    assert "another torquesim fit" in capsys.readouterr().err
    (tmp_path / "fit" / ".torquesim-fit.lock").write_text("999999999")  # gone: stale
    assert main(args) == 0


def test_sigterm_while_the_outputs_are_written_leaves_one_consistent_set(tmp_path, capsys,
                                                                         monkeypatch):
    """The signal arrives from inside the writing (injected, not timed): the run finishes
    writing every file from the same parameters; the fit itself had finished, so it says so
    and exits 0 (0.2 reported "interrupted", 130)."""
    import os
    import signal

    import torquesim.fitting.outputs as outputs

    real_save = outputs.save_model

    def save_then_signal(*a, **k):
        path = real_save(*a, **k)
        os.kill(os.getpid(), signal.SIGTERM)  # between the model file and the others
        return path

    monkeypatch.setattr(outputs, "save_model", save_then_signal)
    args = _tiny_fit_args(tmp_path)
    assert main(args) == 0
    assert "the fit had finished" in capsys.readouterr().err
    out = tmp_path / "fit"
    summary = json.loads((out / "fit_summary.json").read_text())
    fitted = ts.load_model(out / "fitted_model.toml")
    flexor = fitted.units[0].activation.ramps
    assert flexor[0].delay == pytest.approx(
        summary["parameters"]["elbow_flexor.ramp1.delay"], rel=1e-12)
    for name in ("fit_motion.csv", "fit_motion.sto", "fit.png", "fit_checkpoint.npz"):
        assert (out / name).stat().st_size > 0
    assert signal.getsignal(signal.SIGTERM) is not None


def test_fit_quiet_prints_no_progress_and_lines_otherwise(tmp_path, capsys):
    """Not a terminal here: no bar either way; the progress lines unless --quiet."""
    args = _tiny_fit_args(tmp_path)
    assert main([*args, "--quiet"]) == 0
    assert capsys.readouterr().err == ""
    assert main([*args, "--overwrite"]) == 0
    err = capsys.readouterr().err
    assert "initial guess" in err and "\r" not in err  # lines, no bar


def test_a_fit_that_stops_on_its_cap_says_so(synthetic_target, tmp_path):
    """A least-squares refinement that runs out of --iterations before its tolerance is
    named in the summary with what to change (before: only the search's own log said it)."""
    from torquesim.fitting.outputs import fit_and_write, summarise, summary_lines

    problem = FitProblem(synthetic_target)
    _, outcome, summary, _ = fit_and_write(problem, SearchSettings(starts=1, iterations=3),
                                           tmp_path)
    assert outcome.capped and "--iterations" in outcome.capped
    lines = [line for line in summary_lines(summary) if "stopped on" in line]
    assert len(lines) == 1 and "larger --iterations" in lines[0]
    enough = SearchSettings(starts=1, iterations=400)
    generous = run_fit(problem, enough)
    summary = summarise(problem, generous, enough)
    assert not generous.capped and not any("stopped on" in w for w in summary["warnings"])


def test_a_recording_that_begins_in_motion_starts_the_fit_moving(tmp_path):
    """A curl cut from 0.6 s (the elbow flexing at tens of °/s): the fit's model starts at the
    target's speed there (its spline's derivative, within 1 % of the run's), the written
    model keeps it, and the reference re-simulation from it follows the first 50 ms better
    than a start at rest. A target that starts still starts at rest."""
    from torquesim.fitting import FitProblem, Target

    model = ts.load_model("builtin:elbow-curl")
    run = ts.simulate(model, "reference", output_step=0.01)
    cut = (run.time >= 0.6 - 1e-9) & (run.time <= 1.6 + 1e-9)
    target = Target(run.time[cut], run.q[cut].T, ("elbow",), "cut curl")
    true_speed = float(run.qd[cut][0, 0])
    assert abs(math.degrees(true_speed)) > 20.0
    problem = FitProblem(target, base_model=model)
    assert problem.start_speeds["elbow"] == pytest.approx(true_speed, rel=0.01)
    y0 = problem.model.initial_state().state
    assert y0[problem.model.layout.speeds][0] == pytest.approx(true_speed, rel=0.01)
    speed = problem.model.joints[0].initial_speed
    assert speed == pytest.approx(true_speed, rel=0.01)
    from dataclasses import replace

    from torquesim.io.model_file import load_model, model_to_toml, save_model

    assert "initial_speed" in model_to_toml(problem.model)
    save_model(problem.model, tmp_path / "m.toml")
    assert load_model(str(tmp_path / "m.toml")).joints[0].initial_speed == speed
    early = target.elapsed <= 0.05
    moving = ts.simulate(problem.model, "reference", output_step=0.01)
    still = ts.simulate(problem.model.replace(joints=(replace(problem.model.joints[0],
                                                              initial_speed=0.0),)),
                        "reference", output_step=0.01)
    goal = target.angles[0][early]
    assert np.max(np.abs(moving.q[: goal.size, 0] - goal)) < 0.5 * np.max(
        np.abs(still.q[: goal.size, 0] - goal))
    rest = Target(run.time[run.time <= 1.0], run.q[run.time <= 1.0].T, ("elbow",), "start")
    assert np.all(rest.start_speeds() == 0.0)


def test_a_simulated_target_that_starts_still_and_accelerates_at_once_starts_at_rest():
    """A noise-free target that starts at rest with a large acceleration (q = q0 + a·t²/2,
    a = 2000°/s², as a motion made by another simulator whose muscles are not in equilibrium
    at t0): its start speed is 0, where a natural smoothing spline (q̈ = 0 at t0) read
    more than 5°/s."""
    from torquesim.fitting import Target
    from torquesim.fitting.target import STILL

    t = np.arange(0.0, 1.0, 0.01)
    q = np.radians(10.0 + 0.5 * 2000.0 * t**2 / (1.0 + 20.0 * t**2))
    exact = Target(t, q[None, :], ("elbow",), "accelerating")
    assert not exact.noisy()[0]
    from scipy.interpolate import make_smoothing_spline

    natural = make_smoothing_spline(t[:40], q[:40]).derivative()(0.0)
    assert abs(natural) > STILL  # what the earlier estimate read
    assert np.all(exact.start_speeds() == 0.0)


def test_a_free_body_started_moving_keeps_its_loaded_contacts_still():
    """The squat jump with its knee and hip moving at the start: the base moves so that the
    loaded toe and heel start at (least-squares) zero velocity; at rest nothing moves."""
    jump = ts.load_model("builtin:squat-jump")
    from dataclasses import replace

    joints = list(jump.joints)
    joints[2] = replace(joints[2], initial_speed=-1.0)
    joints[3] = replace(joints[3], initial_speed=1.0)
    moving = jump.replace(joints=tuple(joints))
    state = moving.initial_state().state
    layout = moving.layout
    where = moving.kinematics(state[layout.coordinates], state[layout.coordinate_speeds])
    velocities = where["point_velocities"][:2]  # toe and heel
    assert np.all(np.abs(velocities) < 1e-12)  # the foot does not turn: both held exactly
    assert state[layout.speeds][2:] == pytest.approx([-1.0, 1.0])
    assert not np.any(jump.initial_state().state[layout.coordinate_speeds])


def test_an_initial_speed_out_of_range_in_a_model_file_is_one_line(tmp_path, capsys):
    from torquesim.io.model_file import model_to_toml

    text = model_to_toml(ts.load_model("builtin:knee-extension"))
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('name = "knee"\n', 'name = "knee"\ninitial_speed = 500.0\n', 1))
    assert main(["simulate", "--model", str(bad), "--out", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: joints[0].initial_speed: 500 is out of range; allowed "
                          "[-100, 100] rad/s"), err
    assert not (tmp_path / "x.csv").exists()


@pytest.mark.parametrize("preset", ["squat-jump", "countermovement-jump"])
def test_a_model_s_own_ramps_as_the_fit_s_start_leave_its_activation_unchanged(preset):
    """The fit's start from a free body's own ramps (padded to 3 with held ramps) is the
    model's activation exactly, also for a unit whose profile has no ramps and starts at its
    static level (before, its padding ramped it to 0)."""
    from dataclasses import replace

    from torquesim.fitting.parameters import own_vector
    from torquesim.model.activation import ActivationProfile

    model = ts.load_model(f"builtin:{preset}")
    first = model.units[0]
    model = model.replace(units=(replace(first, activation=ActivationProfile(None, ())),
                                 *model.units[1:]))
    again = with_ramps(model, own_vector(model), [None] * model.n_units)
    levels = model.initial_state().levels
    t = np.linspace(0.0, model.duration, 301)
    for unit, same, level in zip(model.units, again.units, levels, strict=True):
        assert np.array_equal(unit.activation(t, level), same.activation(t, level)), unit.name


@pytest.mark.parametrize("samples", [10_001, 60_001])
def test_a_target_of_very_many_exact_samples_is_smoothed_through_fewer(samples):
    """SciPy's cross-validation fails on very many samples: on 10 001 exact ones of a smooth
    3 s motion its spline is 0.7 rad off, on 60 001 it stops ("ill-posed"; the arm raise's
    own 30 001 at 0.1 ms: a traceback from `fit`; SciPy 1.17). The target's spline, through
    at most 4 000 of them, follows the motion and its speed."""
    from torquesim.fitting.target import Target

    t = np.linspace(0.0, 3.0, samples)
    angle = 0.5 * np.sin(2 * np.pi * t / 3) + 0.2 * t**2
    speed = np.pi / 3 * np.cos(2 * np.pi * t / 3) + 0.4 * t
    spline = Target(t, angle[None, :], ("elbow",)).smoothed()
    inner = (t > 0.2) & (t < 2.8)  # the natural ends (q̈ = 0) are not the motion's
    assert np.max(np.abs(spline(t) - angle)) < 1e-4
    assert np.max(np.abs(spline.derivative(1)(t[inner]) - speed[inner])) < 1e-3
