"""Batch fits and sweeps on a real Dask cluster (LocalCluster, 2 worker processes): a bad
target fails its own row, reruns do no finished work twice, a sweep with a known answer,
the same seed gives the same table whatever the number of workers."""


import re

import numpy as np
import pytest

import torquesim as ts
from torquesim.batch import fit_many, sweep
from torquesim.batch.sweep import parse_vary, sample_matrix
from torquesim.cli import main
from torquesim.model.paths import set_parameter

distributed = pytest.importorskip("distributed")

FAST_FIT = dict(starts=1, iterations=3)


@pytest.fixture(scope="module")
def client():
    """Compile (or load from cache) the kernels here first, so the workers only load them."""
    from torquesim.fitting import FitProblem, Target

    ts.simulate(ts.load_model("builtin:elbow-curl").replace(duration=0.1), "imex", 5e-3)
    t = np.linspace(0, 0.2, 21)
    FitProblem(Target(t, np.full((1, 21), 0.3), ("elbow",))).residuals(
        np.full(18, 0.2))
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as c:
        yield c


def _target(path, peak=40.0):
    t = np.arange(0, 0.6001, 0.01)
    angle = 20 + (peak - 20) * (10 * (t / 0.6) ** 3 - 15 * (t / 0.6) ** 4 + 6 * (t / 0.6) ** 5)
    path.write_text("time,elbow\n" + "".join(f"{a},{b}\n" for a, b in zip(t, angle,
                                                                          strict=True)))
    return str(path)


def test_a_bad_target_fails_its_row_and_the_batch_goes_on(client, tmp_path):
    good = _target(tmp_path / "good.csv")
    bad = tmp_path / "bad.csv"
    bad.write_text("time,elbow\n0,1\n0.01,oops\n")
    table = fit_many([good, str(bad)], out=tmp_path / "out", client=client, **FAST_FIT)
    rows = table.set_index("name")
    assert rows.loc["good", "status"] == "done" and rows.loc["bad", "status"] == "failed"
    assert "line 3" in rows.loc["bad", "error"] and "\n" not in rows.loc["bad", "error"]
    assert rows.loc["good", "reference_rms_deg"] < 5
    assert (tmp_path / "out" / "good" / "fitted_model.toml").is_file()
    assert (tmp_path / "out" / "batch.csv").read_text().count("\n") == 3
    assert "data:image/png;base64," in (tmp_path / "out" / "batch.html").read_text()


def test_a_rerun_does_no_finished_work_twice(client, tmp_path):
    targets = [_target(tmp_path / "a.csv", 40.0), _target(tmp_path / "b.csv", 50.0)]
    out = tmp_path / "out"
    first = fit_many(targets, out=out, client=client, **FAST_FIT).set_index("name")
    assert set(first["status"]) == {"done"}
    # b is "interrupted": its fit never finished (no summary, no fingerprint)
    (out / "b" / "batch_fingerprint.txt").unlink()
    (out / "b" / "fit_summary.json").unlink()
    a_model = (out / "a" / "fitted_model.toml").stat().st_mtime_ns
    second = fit_many(targets, out=out, client=client, **FAST_FIT).set_index("name")
    assert second.loc["a", "status"] == "done earlier" and second.loc["a", "worker"] == ""
    assert (out / "a" / "fitted_model.toml").stat().st_mtime_ns == a_model
    assert second.loc["b", "status"] == "done"
    # other settings: the finished fit does not count
    third = fit_many(targets[:1], out=out, client=client, starts=1,
                     iterations=4).set_index("name")
    assert third.loc["a", "status"] == "done"


def test_sweeping_the_dumbbell_mass_lowers_the_peak_monotonically(client, tmp_path):
    """A heavier dumbbell with the same activations: a lower peak, every time (ρ = −1), and
    percentile bands in order."""
    table, histories = sweep("builtin:elbow-curl", ["forearm_hand.dumbbell.mass=grid(3,7,9)"],
                             out=tmp_path, chunk=4, client=client, step=2e-3)
    assert list(table["accuracy"]) == ["ok"] * 9
    assert table["estimated_error_deg"].max() < 0.5
    peaks = table.sort_values("forearm_hand.dumbbell.mass")["peak_elbow_deg"].to_numpy()
    assert np.all(np.diff(peaks) < 0)
    rho = (tmp_path / "rank_correlations.csv").read_text().splitlines()[1].split(",")
    assert float(rho[1]) == pytest.approx(-1.0)
    bands = ts.read_table(tmp_path / "sweep_percentiles.csv")
    assert np.all(bands["elbow_p5_deg"] <= bands["elbow_p50_deg"] + 1e-9)
    assert np.all(bands["elbow_p50_deg"] <= bands["elbow_p95_deg"] + 1e-9)
    assert histories.shape == (9, 1, 101)
    assert (tmp_path / "sweep.png").stat().st_size > 0


def test_the_same_seed_gives_the_same_table_whatever_the_workers(client, tmp_path):
    vary = ["flexor.se_stiffness=normal(600,60)", "elbow_extensor.isometric_torque=uniform(30,50)"]
    two, _ = sweep("builtin:elbow-curl", vary, samples=12, seed=7, chunk=5, client=client)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=":0") as cluster, \
            distributed.Client(cluster) as one_worker:
        one, _ = sweep("builtin:elbow-curl", vary, samples=12, seed=7, chunk=12,
                       client=one_worker)
    columns = [c for c in two.columns if c != "worker"]
    assert two[columns].equals(one[columns])
    other, _ = sweep("builtin:elbow-curl", vary, samples=12, seed=8, chunk=12, client=client)
    assert not other[vary[0].split("=")[0]].equals(two[vary[0].split("=")[0]])


def test_finished_chunks_are_not_simulated_again(client, tmp_path, monkeypatch):
    vary = ["forearm_hand.dumbbell.mass=uniform(4,6)"]
    first, _ = sweep("builtin:elbow-curl", vary, samples=6, chunk=3, out=tmp_path,
                     client=client)
    import torquesim.batch.engine as engine

    def no_cluster(*a, **k):
        raise AssertionError("a finished sweep asked for workers")

    monkeypatch.setattr(engine, "connect", no_cluster)
    again, _ = sweep("builtin:elbow-curl", vary, samples=6, chunk=3, out=tmp_path)
    assert again.equals(first)


def test_a_failing_sample_fails_its_own_row(client):
    """An SE stiffness the model refuses (≤ 0, in a normal distribution's tail) fails its row
    with the one-line error."""
    table, _ = sweep("builtin:elbow-curl", ["flexor.se_stiffness=normal(200,300)"],
                     samples=8, seed=3, chunk=8, client=client, step=2e-3)
    bad = table[table["flexor.se_stiffness"] <= 0]
    assert len(bad) > 0 and set(bad["accuracy"]) == {"failed"}
    assert all("se_stiffness" in e for e in bad["error"])
    assert set(table.loc[table["flexor.se_stiffness"] > 50, "accuracy"]) == {"ok"}


def test_a_sample_whose_run_diverges_is_run_again_at_half_the_step(client):
    """imex-ros2 at 10 ms: the jump goes non-finite (before, its row failed); halved until
    its estimated error meets the tolerance, each row ends accurate at a step that divides
    10 ms by a power of 2, within the tolerance of the reference's peak knee angle."""
    table, _ = sweep("builtin:squat-jump", ["knee_extensors.isometric_torque=uniform(540,560)"],
                     samples=2, seed=1, chunk=2, client=client, method="imex-ros2",
                     step=10e-3)
    assert set(table["accuracy"]) == {"ok"}, table["error"].tolist()
    halvings = np.log2(10e-3 / table["step_s"])
    assert (halvings >= 2).all() and np.allclose(halvings, np.round(halvings))
    row = table.iloc[0]
    model = set_parameter(ts.load_model("builtin:squat-jump"), "knee_extensors.isometric_torque",
                          float(row["knee_extensors.isometric_torque"]))
    peak = np.degrees(ts.simulate(model, "reference").angle("knee").max())
    assert row["peak_knee_deg"] == pytest.approx(peak, abs=0.5)


def test_the_default_technique_of_a_sweep_is_chosen_by_accuracy(client):
    """No --method, no --step: on the jump the choice (imex-ros2, its contacts implicit)
    within half the tolerance, named in the table's attributes; every row accurate."""
    table, _ = sweep("builtin:squat-jump", ["knee_extensors.isometric_torque=uniform(540,560)"],
                     samples=2, seed=1, chunk=2, client=client)
    assert table.attrs["method"] == "imex-ros2"
    assert "chosen for 0.25°" in table.attrs["choice"]
    assert set(table["accuracy"]) == {"ok"}


def test_every_sweep_row_carries_an_accuracy_verdict(client):
    """At a 20 ms step the arm raise is radians off (IMEX, reference peak 72°): every row is
    run again at half the step until its estimated error meets the tolerance (0.5°), and says
    at which step, instead of reporting the wrong peak as fine (0.2) or failing (0.3)."""
    from functools import cache

    from torquesim.study.compare import reference_solution

    @cache
    def reference_peak_deg(stiffness):
        model = set_parameter(ts.load_model("builtin:arm-raise"),
                              "shoulder.flexor.se_stiffness", stiffness)
        return np.degrees(reference_solution(model).angle("shoulder").max())

    table, _ = sweep("builtin:arm-raise", ["shoulder.flexor.se_stiffness=uniform(400,500)"],
                     samples=3, seed=1, chunk=3, client=client, step=20e-3)
    assert set(table["accuracy"]) == {"ok"}
    assert (table["estimated_error_deg"] <= 0.5).all()
    halvings = np.log2(20e-3 / table["step_s"])
    assert (halvings >= 1).all() and np.allclose(halvings, np.round(halvings))
    row = table.iloc[int(np.argmin(table["step_s"]))]  # the most refined sample
    peak = reference_peak_deg(float(row["shoulder.flexor.se_stiffness"]))
    assert row["peak_shoulder_deg"] == pytest.approx(peak, abs=0.5)
    # and at a small step the same rows are accurate and agree with the reference
    fine, _ = sweep("builtin:arm-raise", ["shoulder.flexor.se_stiffness=uniform(400,500)"],
                    samples=1, seed=1, chunk=1, client=client, step=1e-3)
    assert list(fine["accuracy"]) == ["ok"]
    peak = reference_peak_deg(float(fine.iloc[0]["shoulder.flexor.se_stiffness"]))
    assert fine.iloc[0]["peak_shoulder_deg"] == pytest.approx(peak, abs=0.5)


def test_sample_matrix_crosses_grids_with_random_draws():
    d = [parse_vary("a=normal(1,0.1)"), parse_vary("b=grid(0,1,3)")]
    values = sample_matrix(d, 4, seed=1)
    assert values.shape == (12, 2)
    assert sorted(set(values[:, 1])) == [0.0, 0.5, 1.0]
    assert np.allclose(values[:, 0], np.repeat(values[::3, 0], 3))
    lognormal = sample_matrix([parse_vary("c=lognormal(600,0.1)")], 4000, seed=2)[:, 0]
    assert np.median(lognormal) == pytest.approx(600, rel=0.02)
    sobol = sample_matrix([parse_vary("u=uniform(0,1)")], 64, seed=1, sobol=True)[:, 0]
    assert np.histogram(sobol, bins=8, range=(0, 1))[0].tolist() == [8] * 8


@pytest.mark.parametrize("text", ["se_stiffness", "a=normal(1)", "a=weibull(1,2)",
                                  "a=uniform(2,1)", "a=normal(1,-1)", "a=grid(0,1,0.5)"])
def test_bad_distributions_are_refused(text):
    with pytest.raises(ts.ModelError):
        parse_vary(text)


@pytest.mark.parametrize("vary, reaches", [
    ("flexor.ramp1.level=uniform(0,2)", "reaches 2; allowed [0, 1]"),
    ("flexor.se_stiffness=grid(0,600,3)", "reaches 0; allowed (0, 1e+06]"),
    ("elbow.initial_angle=uniform(-4,1)", "reaches -4; allowed [-3.14159, 3.14159]")])
def test_a_distribution_beyond_its_field_s_range_is_refused_before_any_run(vary, reaches):
    """A uniform or grid distribution whose end lies outside the field's range (half or all
    of its samples would fail) is one error naming the end and the range; an open end a
    uniform cannot reach (a stiffness's 0) is allowed."""
    with pytest.raises(ts.ModelError, match=r"--vary: .*" + re.escape(reaches)):
        sweep("builtin:elbow-curl", [vary], samples=4, method="imex", step=1e-3)
    table, _ = sweep("builtin:elbow-curl", ["flexor.se_stiffness=uniform(0,600)"], samples=2,
                     method="imex", step=1e-3)
    assert set(table["accuracy"]) == {"ok"}


def test_batch_cli_bad_input_is_one_line_exit_2(tmp_path, capsys):
    assert main(["batch", "sweep", "--vary", "nonsense", "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "--vary" in err
    assert main(["batch", "fit", str(tmp_path / "none*.csv"), "--out", str(tmp_path / "f")]) \
        == 2
    assert "matches no file" in capsys.readouterr().err


def _die_once(marker: str) -> str:
    """Kill this worker process the first time (as a crash would), succeed the second."""
    import os
    from pathlib import Path

    if not Path(marker).exists():
        Path(marker).write_text("died")
        os._exit(1)
    return "finished"


def test_a_task_whose_worker_dies_is_run_again_elsewhere(client, tmp_path):
    from torquesim.batch.engine import run_tasks

    results = {}
    run_tasks(client, [(_die_once, (str(tmp_path / "marker"),))],
              lambda i, r: results.__setitem__(i, r))
    assert results == {0: "finished"} and (tmp_path / "marker").read_text() == "died"


@pytest.mark.parametrize("preset, step", [("arm-raise", 5e-3), ("squat-jump", 2.5e-4)])
def test_max_unit_torque_matches_the_output_columns(preset, step):
    """On a free base too, whose coordinates come before the joints' (the jump's sweep
    read the wrong columns and gave 10 104 N·m where the largest unit torque is 430)."""
    from torquesim.batch.sweep import max_unit_torque

    model = ts.load_model(f"builtin:{preset}")
    result = ts.simulate(model, "imex", step)
    columns = result.columns()
    expected = max(np.max(np.abs(columns[f"torque_{u.name}"])) for u in model.units)
    assert max_unit_torque(model, result.states) == pytest.approx(expected, rel=1e-12)


def test_ctrl_c_keeps_what_finished_and_the_rerun_completes_the_rest(client, tmp_path):
    """Ctrl-C (KeyboardInterrupt, raised here as the first fit is reported) stops the batch
    with the finished fit in batch.csv; the same call again fits only the other target."""
    targets = [_target(tmp_path / "a.csv", 40.0), _target(tmp_path / "b.csv", 50.0)]
    out = tmp_path / "out"

    def interrupt(done, total):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        fit_many(targets, out=out, client=client, progress=interrupt, **FAST_FIT)
    # nothing keeps writing into the folder once the call has returned: running fits were
    # asked to stop and were waited for
    import time

    def snapshot():
        return {p: p.stat().st_mtime_ns for p in out.rglob("*") if p.is_file()}

    before = snapshot()
    time.sleep(2.0)
    assert snapshot() == before
    rows = (out / "batch.csv").read_text().splitlines()[1:]
    # the fits run at once on the cluster's workers: either may be the one that finished
    # first (its report raised the Ctrl-C)
    finished = [row for row in rows if ",done," in row]
    assert len(rows) == 2 and finished
    # the other fit: never started ("not run") or stopped with its best so far written
    other = rows[1] if rows[0] == finished[0] else rows[0]
    assert ",not run," in other or ",interrupted," in other or ",done," in other
    first = finished[0].split(",")[0]
    again = fit_many(targets, out=out, client=client, **FAST_FIT).set_index("name")
    assert again.loc[first, "status"] == "done earlier"
    # the other fit was cancelled (or, if its worker had started it, finished on its own)
    assert set(again["status"]) <= {"done", "done earlier"} and len(again) == 2
