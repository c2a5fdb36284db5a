"""The comparison study: verdict logic, stability limits, report, work counts."""

import csv
import math

import numpy as np
import pytest

import torquesim as ts
from torquesim.solvers.coupling import IMEX
from torquesim.study.compare import (
    COLUMNS,
    FIXED_STEP_WORK,
    Technique,
    calibrate,
    observed_order,
    run_study,
    stability_limit,
    verdict,
    verdict_sentences,
    verdict_table,
)


def row(tech, h, err_deg, wall, exceeded=False, tol=None):
    r = {c: None for c in COLUMNS}
    r.update(technique=tech, h_s=h, tolerance=tol, max_error_deg=err_deg,
             max_error_rad=math.radians(err_deg), stable=err_deg <= 1.0,
             guard_exceeded=exceeded, wall_time_s=wall, modelled_cost_s=wall,
             status="success", rhs_body=1, rhs_muscle=1, wall_times_s=(wall, 1.5 * wall))
    return r


SYNTHETIC = [
    row("A", 1e-3, 5.0, 1.0, exceeded=True), row("A", 5e-4, 0.5, 2.0), row("A", 2.5e-4, 0.005, 4.0),
    row("B", 1e-3, 0.05, 3.0), row("B", 5e-4, 0.0125, 6.0), row("B", 2.5e-4, 0.003125, 12.0),
    row("C", None, 0.0001, 30.0, tol=1e-8),
]


def test_verdict_picks_the_cheapest_run_meeting_each_target():
    v = {e["target_deg"]: e for e in verdict(SYNTHETIC)}
    assert v[1.0]["winner"]["technique"] == "A" and v[1.0]["winner"]["wall_time_s"] == 2.0
    assert v[1.0]["ratios"] == {"B": 1.5, "C": 15.0}
    assert v[0.01]["winner"]["technique"] == "A" and v[0.01]["ratios"] == {"B": 3.0, "C": 7.5}
    assert v[0.001]["winner"]["technique"] == "C" and v[0.001]["ratios"] == {}
    text = verdict_sentences(verdict(SYNTHETIC), ["A", "B", "C"])
    assert text[3].startswith("0.001°: cheapest is C") and "never reached by A, B" in text[3]


def test_verdict_calls_runs_within_the_tie_ratio_a_tie_and_names_the_first_listed():
    rows = [row("A", 1e-3, 0.5, 1.1), row("B", 1e-3, 0.5, 1.0), row("C", 1e-3, 0.5, 2.0)]
    v = verdict(rows, targets=(1.0,))[0]
    assert v["winner"]["technique"] == "A" and v["tie"]  # B is cheaper, but within 1.2x
    assert v["runner_up"]["technique"] == "B" and v["ratios"]["B"] == pytest.approx(1 / 1.1)
    assert v["wall_ratio"] == pytest.approx(1.0 / 1.1)
    assert v["wall_ratio_range"] == pytest.approx((1.0 / 1.1, 1.0 / 1.1))
    rows[1] = row("B", 1e-3, 0.5, 0.5)  # now clearly cheaper
    v = verdict(rows, targets=(1.0,))[0]
    assert v["winner"]["technique"] == "B" and not v["tie"] and v["ratios"]["A"] == 2.2
    table = verdict_table([v])[0]
    assert table["cheapest"] == "B" and table["cheapest_setting"] == "h = 1 ms"
    assert table["runner_up"] == "A" and table["cost_ratio"] == 2.2


def test_stability_limit_and_order_on_synthetic_rows():
    assert stability_limit(SYNTHETIC, "A") == 5e-4
    assert stability_limit(SYNTHETIC, "B") == 1e-3
    assert observed_order(SYNTHETIC, "B") == pytest.approx(2.0)
    assert observed_order(SYNTHETIC, "C") is None


def test_study_on_a_short_curl_measures_what_model_md_says(tmp_path, monkeypatch):
    from torquesim.study.outputs import write_study

    monkeypatch.setattr("torquesim.study.compare.CALIBRATION_REPEATS", 1)  # nothing timed

    model = ts.default_model().replace(duration=0.6)
    rows, _, smooth = write_study(tmp_path, model, steps=(1e-3, 5e-4, 2e-4, 1e-4), repeats=1,
                                  tolerances=(1e-5, 1e-8))
    by = {(r["technique"], r["h_s"]): r for r in rows}
    # monolithic: unstable at 1 ms (bounded, wrong) and flagged; accurate below 0.25 ms
    assert by[("monolithic", 1e-3)]["guard_exceeded"]
    assert by[("monolithic", 1e-4)]["max_error_rad"] < 1e-7
    # exact work counts: RK4 makes 4 evaluations per part per step
    assert by[("monolithic", 1e-4)]["rhs_body"] == 4 * 6000
    assert by[("partitioned[m=4]", 1e-4)]["rhs_muscle"] == 6000 * (1 + 4 * 4 - 1)
    assert by[("partitioned[iter=3]", 1e-4)]["rhs_body"] == 3 * 4 * 6000
    assert smooth["monolithic"] == pytest.approx(4.0, abs=0.5)
    assert smooth["partitioned"] == pytest.approx(1.0, abs=0.2)
    assert smooth["partitioned[linear]"] == pytest.approx(2.0, abs=0.2)
    assert smooth["imex"] == pytest.approx(2.0, abs=0.2)
    assert by[("imex", 1e-3)]["stable"] and by[("imex", 1e-3)]["max_error_rad"] < 1e-4
    # the report and the table agree
    with open(tmp_path / "results.csv") as fh:
        table = list(csv.DictReader(fh))
    assert len(table) == len(rows)
    assert list(table[0]) == [*COLUMNS, "max_error_deg_elbow"]  # the per-joint error
    report = (tmp_path / "report.html").read_text()
    for sentence in verdict_sentences(verdict(rows), list(dict.fromkeys(
            r["technique"] for r in rows))):
        assert sentence.replace("'", "&#x27;") in report
    first = table[0]
    assert f"{float(first['max_error_deg']):.4g}" in report
    assert report.count("data:image/png;base64,") == 3
    # modelled cost: on readings made from known unit times (not the clock, which moves with
    # the machine's load), the calibration reproduces every calibration run's time
    unit_time = {"step.monolithic": 3e-8, "step.partitioned": 5e-8, "body": 2e-8,
                 "muscle": 4e-8, "newton": 6e-8, "jacobian": 9e-8}
    synthetic = [dict(r) for r in rows]
    for r in synthetic:
        if r["h_s"] is not None:
            r["wall_time_s"] = sum(unit_time[name] * count(r) for name, count in FIXED_STEP_WORK)
    calibrate(synthetic)
    assert sum(r["calibration_run"] for r in synthetic) >= 3
    for r in synthetic:
        if r["calibration_run"]:
            assert r["modelled_cost_s"] == pytest.approx(r["wall_time_s"], rel=1e-6)
    with open(tmp_path / "verdict.csv") as fh:
        verdicts = list(csv.DictReader(fh))
    assert [float(v["target_deg"]) for v in verdicts] == [1.0, 0.1, 0.01, 0.001]
    for name in ("convergence.png", "work_precision.png", "time_constants.png",
                 "manifest.json"):
        assert (tmp_path / name).stat().st_size > 0


def test_partitioned_work_counts_are_exact():
    model = ts.default_model().replace(duration=0.01)
    for coupling, body, muscle in [(ts.Coupling(), 4, 4), (ts.Coupling(muscle_substeps=3), 4, 12),
                                   (ts.Coupling(iterations=2), 8, 7)]:
        r = ts.simulate(model, "partitioned", 1e-4, coupling=coupling)
        assert (r.cost.rhs_body, r.cost.rhs_muscle) == (100 * body, 100 * muscle)


def test_run_study_rejects_a_step_that_does_not_divide():
    with pytest.raises(ts.ModelError):
        run_study(ts.default_model(), steps=(7e-4,), repeats=1)


def test_compare_cli_rejects_bad_steps(capsys):
    from torquesim.cli import main

    assert main(["compare", "--steps", "1,abc"]) == 2
    assert "--steps" in capsys.readouterr().err


@pytest.fixture(scope="module")
def sensitivity_study(tmp_path_factory):
    from torquesim.study.sensitivity import write_sensitivity

    out = tmp_path_factory.mktemp("vary")
    model = ts.default_model().replace(duration=0.6)
    with pytest.MonkeyPatch.context() as patch:  # no extra timing rounds: nothing here is timed
        patch.setattr("torquesim.study.compare.CALIBRATION_REPEATS", 1)
        summary = write_sensitivity(out, model, "se_stiffness", (150.0, 3000.0),
                                    steps=(2e-3, 5e-4, 2e-4, 1e-4), repeats=1,
                                    tolerances=(1e-4, 1e-7))  # none asserted on: two suffice
    return out, summary


def test_sensitivity_to_se_stiffness_moves_tau_and_the_rk4_limit(sensitivity_study):
    """τ = a·T_θ·|h'|/k: a stiffer SE shortens every time constant, so explicit RK4's
    stability limit falls, while IMEX (implicit muscles) stays stable at the largest step."""
    tmp_path, summary = sensitivity_study
    by = {(r["value"], r["technique"]): r for r in summary}
    soft, stiff = by[(150.0, "monolithic")], by[(3000.0, "monolithic")]
    assert soft["min_tau_unit"] == stiff["min_tau_unit"] == "elbow_extensor"
    assert 5 < soft["min_tau_s"] / stiff["min_tau_s"] < 40
    assert (stiff["stability_limit_s"] or 0.0) < soft["stability_limit_s"]
    assert by[(3000.0, "imex")]["stability_limit_s"] == 2e-3
    with open(tmp_path / "sensitivity.csv") as fh:
        assert len(list(csv.DictReader(fh))) == len(summary)
    html_text = (tmp_path / "sensitivity.html").read_text()
    assert html_text.count("data:image/png;base64,") == 3
    assert (tmp_path / "se_stiffness=3000" / "report.html").is_file()
    assert "value (N·m/rad)" in html_text and "stability limit (ms)" in html_text


def test_study_pages_fit_the_window_in_headless_chromium(sensitivity_study, tmp_path):
    """The report and the sensitivity page, opened in Chromium at 1280 and 800 px: no part
    wider than the window, every figure decodes (scripts/check_pages.py); a screenshot at
    the first width (one Chromium run more per page) renders."""
    import importlib.util
    from pathlib import Path

    spec = importlib.util.spec_from_file_location(
        "check_pages", Path(__file__).parents[1] / "scripts" / "check_pages.py")
    check_pages = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(check_pages)
    browser = check_pages.chromium()
    if browser is None:
        pytest.skip("no Chromium on this machine (scripts/check_pages.py needs one)")
    out, _ = sensitivity_study
    for page in (out / "sensitivity.html", out / "se_stiffness=3000" / "report.html"):
        for k, width in enumerate(check_pages.WIDTHS):
            shot = tmp_path / f"{page.stem}-{width}.png" if k == 0 else None
            assert check_pages.check_page(page, browser, width, shot) == "OK", (page, width)
            assert shot is None or shot.stat().st_size > 10_000


def test_no_slope_is_claimed_where_the_error_sits_at_a_floor():
    """Monolithic RK4 on the curl below its stability limit: errors 7e-10, 5e-9, 3e-9 rad
    at 0.05, 0.1, 0.2 ms do not fall with h. No order, and the figure says so."""
    from torquesim.study.report import order_label

    floor = [row("M", 5e-5, math.degrees(6.8e-10), 1.0), row("M", 1e-4, math.degrees(4.6e-9), 1.0),
             row("M", 2e-4, math.degrees(2.7e-9), 1.0), row("M", 5e-4, 4.3, 1.0)]
    assert observed_order(floor, "M") is None
    assert order_label(floor, "M") == "M (no asymptotic range; within 1° up to 0.2 ms)"
    noisy = [row("N", h, e, 1.0) for h, e in [(1e-4, 1e-3), (2e-4, 1.1e-3), (4e-4, 8e-3),
                                               (8e-4, 9e-3)]]
    assert observed_order(noisy, "N") is None  # rising, but not a power law (R² < 0.98)
    assert order_label(SYNTHETIC, "B") == "B (slope 2.00; within 1° up to ≥ 1 ms)"
    assert order_label(SYNTHETIC, "A").endswith("within 1° up to 0.5 ms)")


@pytest.mark.parametrize("text", ["se_stiffness=", "dumbbell_mass=-1", "=1,2",
                                  "extensor_level=0.1,2", "se_stiffness=a,b"])
def test_vary_rejects_bad_specs(text):
    from torquesim.study.sensitivity import parse_vary

    with pytest.raises(ts.ModelError) as info:
        parse_vary(text)
    assert info.value.field == "--vary"


def test_vary_takes_any_model_path_and_rejects_unknown_ones():
    """``compare --vary`` shares the model's parameter paths with ``batch sweep --vary`` and
    ``fit --bound``."""
    from torquesim.study.sensitivity import parse_vary, vary_model

    base = ts.load_model("builtin:arm-raise")
    name, values = parse_vary("elbow.extensor.ramp1.level=0.2,0.3")
    assert name == "elbow.extensor.ramp1.level" and values == (0.2, 0.3)
    changed = vary_model(base, name, 0.3)
    assert changed.units[3].activation.ramps[0].level == 0.3
    assert changed.units[:3] == base.units[:3]
    with pytest.raises(ts.ModelError) as info:
        vary_model(base, "tendon_slack", 0.1)
    assert info.value.field == "--vary" and "UNIT.FIELD" in info.value.reason


def test_vary_model_changes_only_the_named_parameter():
    from torquesim.study.sensitivity import vary_model

    base = ts.default_model().to_chain()
    m = vary_model(base, "extensor_level", 0.3)
    flexor, extensor = m.units
    assert extensor.activation(np.array([0.0, 1.0, 2.9])) == pytest.approx([0.3] * 3)
    assert flexor == base.units[0]
    assert vary_model(base, "dumbbell_mass", 2.0).segments[0].loads[0].mass == 2.0
    stiff = vary_model(base, "se_stiffness", 900.0)
    assert [u.parameters.se_stiffness for u in stiff.units] == [900.0, 900.0]
    with pytest.raises(ts.ModelError, match="extensor_level=1"):
        vary_model(base, "extensor_level", 1.0)  # the flexor cannot hold the start
    arm = ts.load_model("builtin:arm-raise")
    heavy = vary_model(arm, "extensor_level", 0.2)
    assert [u.activation.initial_level for u in heavy.units if u.direction == -1] == [0.2, 0.2]


def test_run_study_reports_progress_after_every_run():
    seen = []
    model = ts.default_model().replace(duration=0.01)
    techniques = (Technique("monolithic", "monolithic"), Technique("imex", "imex", IMEX))
    rows, _ = run_study(model, steps=(1e-3, 5e-4), tolerances=(), techniques=techniques,
                        repeats=1, progress=lambda done, total, label: seen.append(
                            (done, total, label)))
    assert [s[:2] for s in seen[:4]] == [(1, 4), (2, 4), (3, 4), (4, 4)]
    assert seen[0][2] == "monolithic h 1 ms" and len(rows) == 4
    # then the calibration runs (one per technique), round-robin up to 15 readings each
    assert [s[:2] for s in seen[4:]] == [(k, 28) for k in range(1, 29)]
    assert seen[4][2] == "calibration monolithic"
    assert sum(r["calibration_run"] for r in rows) == 2


@pytest.mark.slow
def test_the_verdict_does_not_move_with_noise_in_the_clock(monkeypatch):
    """±50 % random noise on every wall-time reading of one study (a loaded, shared machine)
    moves the verdict only between near-equal runs: at every accuracy target the technique and
    step chosen under noise cost at most 1.5× the quiet choice in the quiet calibration (the
    tie band, 1.2×, times the error noise leaves in a minimum of 5 readings), and where the
    quiet choice wins by more than 2× it stays. The ranking is by modelled cost, calibrated on
    the minimum of interleaved readings; a ranking by raw wall time does not hold this. The
    quiet readings are made from each run's work counts and fixed unit times (not the clock,
    so the test does not depend on the load of the machine running it), then perturbed."""
    unit_time = {"step.monolithic": 3e-8, "step.partitioned": 5e-8, "body": 2e-8,
                 "muscle": 4e-8, "newton": 6e-8, "jacobian": 9e-8}
    adaptive = {"step": 4e-6, "call": 2e-6, "lu": 2e-5}

    def modelled_clock(result):
        cost = result.cost
        if result.step:
            row = {"steps": cost.steps, "rhs_body": cost.rhs_body,
                   "rhs_muscle": cost.rhs_muscle, "newton_iterations": cost.newton_iterations,
                   "jacobians": cost.jacobians, "method": result.method}
            return sum(unit_time[name] * count(row) for name, count in FIXED_STEP_WORK)
        return (adaptive["step"] * cost.steps + adaptive["call"] * cost.rhs_body
                + adaptive["lu"] * cost.lu_decompositions)

    monkeypatch.setattr("torquesim.study.compare.CALIBRATION_REPEATS", 1)
    model = ts.default_model()
    rows, _ = run_study(model, steps=(5e-3, 1e-3, 5e-4, 2e-4, 1e-4), tolerances=(1e-5,),
                        repeats=1, timer=modelled_clock)
    for r in rows:  # the quiet clock reads the same every time: 5 readings of each run
        r["wall_times_s"] = r["wall_times_s"] * 5
    quiet_cost = {(r["technique"], r["h_s"]): r["modelled_cost_s"] for r in rows}
    quiet = verdict(rows)
    for seed in (1, 2):
        rng = np.random.default_rng(seed)
        noisy = [dict(r) for r in rows]
        for r in noisy:
            if r.get("wall_times_s"):
                readings = tuple(t * rng.uniform(0.5, 1.5) for t in r["wall_times_s"])
                r.update(wall_times_s=readings, wall_time_s=min(readings))
        calibrate(noisy)
        for before, after in zip(quiet, verdict(noisy), strict=True):
            chosen = (after["winner"]["technique"], after["winner"]["h_s"])
            best = (before["winner"]["technique"], before["winner"]["h_s"])
            assert quiet_cost[chosen] <= 1.5 * quiet_cost[best], (before["target_deg"], chosen)
            margin = min((x for t, x in before["ratios"].items() if t != best[0]),
                         default=math.inf)
            if margin > 2.0:
                assert chosen == best, (before["target_deg"], chosen, best)
