"""The default technique and step of optimise and batch sweep (`torquesim.solvers.choice`):
the cheapest by counted work among the candidates whose run meets the accuracy, checked
against the reference solver, and its bad inputs."""

import math

import numpy as np
import pytest

import torquesim as ts
from torquesim.cli import main
from torquesim.solvers.choice import candidates, choose_technique

ACCURACY = math.radians(0.1)


def true_error(model, method, step) -> float:
    """Max angle error (rad) of a run against the reference on the run's own grid."""
    run = ts.simulate(model, method, step, tolerance=None, advise=False)
    reference = ts.simulate(model, "reference", output_step=step)
    return float(np.max(np.abs(run.q - reference.q)))


@pytest.mark.parametrize("name, expected", [("elbow-curl", "imex"),
                                            ("squat-jump", "imex-ros2")])
def test_the_choice_is_the_least_work_that_meets_the_accuracy(name, expected):
    """On the curl only IMEX is a candidate (no contacts); on the jump the contacts' implicit
    treatment pays (docs/study.md: imex-ros2 the cheapest at 0.1°). The chosen run is within
    the accuracy against the reference (the estimate is 0.5-1.4× the true error: allow 1.5×),
    no candidate's run that met the accuracy did less work, and the chosen technique's next
    coarser step, where tried, did not meet it."""
    model = ts.load_model(f"builtin:{name}")
    assert ("imex-ros2" in candidates(model)) == bool(model.contacts)
    choice = choose_technique(model, ACCURACY)
    assert choice.method == expected
    assert choice.error <= ACCURACY
    assert true_error(model, choice.method, choice.step) <= 1.5 * ACCURACY
    met = [(m, h, w) for m, h, e, w in choice.tried if e is not None and e <= ACCURACY]
    assert min(w for _, _, w in met) == choice.work
    coarser = [e for m, h, e, _ in choice.tried if m == choice.method and h > choice.step]
    assert all(e is None or e > ACCURACY for e in coarser)
    assert coarser  # the ladder started above the chosen step


def test_a_finer_accuracy_takes_more_work():
    model = ts.load_model("builtin:elbow-curl")
    coarse = choose_technique(model, math.radians(0.5))
    fine = choose_technique(model, math.radians(0.01))
    assert fine.step < coarse.step and fine.work > coarse.work
    assert fine.error <= math.radians(0.01)


def test_bad_accuracies_name_the_field(tmp_path, capsys):
    with pytest.raises(ts.ModelError, match=r"accuracy.*\(0, 3.14"):
        choose_technique(ts.load_model("builtin:elbow-curl"), 0.0)
    out = tmp_path / "never-written"
    code = main(["optimise", "--minimise", "time_to:elbow=90deg", "--accuracy", "0",
                 "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--accuracy" in err[0], err
    assert not out.exists()


def test_optimise_says_which_technique_it_chose(tmp_path, capsys):
    assert main(["optimise", "--minimise", "time_to:elbow=90deg", "--generations", "2",
                 "--quiet", "--out", str(tmp_path / "opt")]) == 0
    out = capsys.readouterr().out
    assert "imex at 5 ms (chosen: the least work within 0.05°" in out
