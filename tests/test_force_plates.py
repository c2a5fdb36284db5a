"""Force-plate files into a fit's target: plates summed, zero-lag filtered, resampled
(torquesim.io.force_plates; fit --forces)."""

import numpy as np
import pytest
from scipy.integrate import trapezoid

import torquesim as ts
from torquesim.fitting.target import Target, with_forces
from torquesim.io.force_plates import (
    check_zero_offset,
    grf_channels,
    low_pass,
    read_plates,
    standing_body_mass,
)

WEIGHT = 70.0 * 9.81


def _jump_force(time):
    """A squat jump's vertical force: standing until 0.3 s, a push to 2.2 body weights and
    back to 0 at take-off (0.6 s), flight to the end."""
    push = (time >= 0.3) & (time < 0.6)
    shape = np.sin(np.pi * (time - 0.3) / 0.3) ** 2
    fy = np.where(time < 0.3, WEIGHT, 0.0)
    fy = np.where(push, WEIGHT * (1 - (time - 0.3) / 0.3) + 1.2 * WEIGHT * shape, fy)
    fx = np.where(push, 40.0 * shape, 0.0)
    return fx, fy


def _write_plates(path, time, fx, fy, share, *, header=True, cop=(0.15, -0.05), noise=0.0,
                  offset=0.0, seed=1):
    """A two-plate OpenSim external-loads file: plate 1 (no prefix) carries ``share`` of the
    force at x = cop[0], plate 2 (``1_``) the rest at cop[1]."""
    rng = np.random.default_rng(seed)
    cols = {"time": time}
    for prefix, part, x in (("", share, cop[0]), ("1_", 1 - share, cop[1])):
        cols[f"{prefix}ground_force_vx"] = fx * part
        cols[f"{prefix}ground_force_vy"] = fy * part + rng.normal(0, noise, time.size) + offset
        cols[f"{prefix}ground_force_vz"] = np.zeros_like(time)
        cols[f"{prefix}ground_force_px"] = np.full_like(time, x)
        cols[f"{prefix}ground_force_py"] = np.zeros_like(time)
        cols[f"{prefix}ground_force_pz"] = np.zeros_like(time)
    lines = ["grf", "version=1", f"nRows={time.size}", f"nColumns={len(cols)}",
             "inDegrees=yes", "endheader"] if header else []
    lines.append("\t".join(cols))
    lines += ["\t".join(f"{v:.9g}" for v in row) for row in np.column_stack(list(cols.values()))]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_summed_plates_give_the_total_force_and_centre_of_pressure(tmp_path):
    time = np.arange(0.0, 1.0, 0.001)
    fx, fy = _jump_force(time)
    share = 0.5 + 0.3 * np.sin(5 * time)
    totals = read_plates(_write_plates(tmp_path / "grf.mot", time, fx, fy, share))
    assert totals.plates == ("", "1_") and totals.rate == pytest.approx(1000.0)
    assert totals.force_y == pytest.approx(fy, abs=1e-5)
    assert totals.force_x == pytest.approx(fx, abs=1e-5)
    loaded = fy > 20.0
    expected = (0.15 * share + -0.05 * (1 - share))[loaded]
    assert totals.cop_x[loaded] == pytest.approx(expected, abs=1e-8)
    assert np.all(np.isnan(totals.cop_x[~loaded]))


def test_the_zero_lag_filter_keeps_the_impulse_and_the_timing(tmp_path):
    """Low-pass at 50 Hz: the impulse over the record is the raw one within 0.01 %, the peak
    stays where it was (no phase lag), and 3 N of noise is cut to under 1 N away from the
    record's ends."""
    time = np.arange(0.0, 1.0, 0.001)
    _, fy = _jump_force(time)
    noisy = fy + np.random.default_rng(3).normal(0.0, 3.0, time.size)
    filtered = low_pass(noisy, 1000.0, 50.0)
    assert trapezoid(filtered, time) == pytest.approx(trapezoid(noisy, time), rel=1e-4)
    assert abs(time[np.argmax(filtered)] - time[np.argmax(fy)]) < 0.005
    assert np.std((filtered - fy)[(time > 0.7) & (time < 0.95)]) < 1.0
    with pytest.raises(ts.ModelError, match="--grf-cutoff: 600 is out of range"):
        low_pass(noisy, 1000.0, 600.0)


def test_body_mass_from_quiet_standing_and_the_zero_offset(tmp_path):
    time = np.arange(0.0, 1.0, 0.001)
    fx, fy = _jump_force(time)
    totals = read_plates(_write_plates(tmp_path / "a.mot", time, fx, fy, 0.5, noise=2.0))
    assert standing_body_mass(totals) == pytest.approx(70.0, abs=0.1)
    drifting = read_plates(_write_plates(tmp_path / "b.mot", time, fx, fy, 0.5, offset=15.0))
    with pytest.raises(ts.ModelError,
                       match=r"rows [56]\d\d-1000 .* in flight the plates read 30.0"):
        check_zero_offset(drifting, WEIGHT, rezero=False)
    fixed, said = check_zero_offset(drifting, WEIGHT, rezero=True)
    assert "subtracted (--rezero)" in said
    assert fixed.force_y == pytest.approx(fy, abs=0.01)  # the flight's mean: 30 N ± 0.01


def test_other_rates_and_start_times_line_up(tmp_path):
    """A 960 Hz force file starting 0.5 s before a 120 Hz target: the channels at the
    target's times are the force there (filtered: within 1 % of body weight)."""
    time = np.arange(-0.5, 1.2, 1 / 960)
    fx, fy = _jump_force(time + 0.0)
    totals = read_plates(_write_plates(tmp_path / "grf.mot", time, fx, fy, 0.5))
    target_time = np.arange(0.0, 1.0, 1 / 120)
    channels = grf_channels(totals, target_time, 50.0)
    assert channels["grf_y"] == pytest.approx(_jump_force(target_time)[1], abs=0.01 * WEIGHT)
    with pytest.raises(ts.ModelError, match="allowed: a force recording spanning the target"):
        grf_channels(totals, np.arange(0.0, 2.0, 0.01), 50.0)


@pytest.mark.parametrize("edit, words", [
    (lambda rows: rows[10].__setitem__(2, "abc"), ["line", "ground_force_vy", "not a number"]),
    (lambda rows: rows[20].__setitem__(0, rows[19][0]), ["time", "does not increase"]),
    (lambda rows: [r.__setitem__(0, str(float(r[0]) + 0.1)) for r in rows[500:]],
     ["row 501", "gap"]),
])
def test_bad_force_files_are_one_line_errors(edit, words, tmp_path):
    time = np.arange(0.0, 1.0, 0.001)
    fx, fy = _jump_force(time)
    path = _write_plates(tmp_path / "grf.csv", time, fx, fy, 0.5, header=False)
    lines = path.read_text().splitlines()
    rows = [line.split("\t") for line in lines[1:]]
    edit(rows)
    path.write_text("\n".join([lines[0].replace("\t", ",")]
                              + [",".join(r) for r in rows]) + "\n")
    with pytest.raises(ts.ModelError) as caught:
        read_plates(path)
    message = str(caught.value)
    assert message.startswith("--forces: grf.csv:") and "\n" not in message
    for word in words:
        assert word in message, message


def test_fit_takes_forces_onto_its_target(tmp_path, monkeypatch, capsys):
    """fit --target angles.csv --forces plates.mot --grf-components xy: the fit's target
    carries grf_x and grf_y at the angles' times; the quiet standing's mass is reported beside
    the model's."""
    from .conftest import fit_target, write_angle_csv

    model = ts.load_model("builtin:squat-jump")
    run = ts.simulate(model, "imex", step=1e-4, output_step=1 / 120)
    cols = run.columns()
    angles = write_angle_csv(tmp_path / "angles.csv", run.time, model,
                             [np.degrees(run.angle(j.name)) for j in model.joints])
    fine = np.arange(-0.3, 0.6, 1 / 960)
    fy = np.interp(fine, run.time, cols["grf_y"], left=cols["grf_y"][0])
    fx = np.interp(fine, run.time, cols["grf_x"], left=cols["grf_x"][0])
    forces = _write_plates(tmp_path / "plates.mot", fine, fx, fy, 0.55)
    target = fit_target(["--model", "builtin:squat-jump", "--target", str(angles), "--forces",
                         str(forces), "--grf-components", "xy", "--quiet", "--out",
                         str(tmp_path / "fit")], monkeypatch)
    assert set(target.channels) == {"grf_x", "grf_y"}
    inside = target.time < 0.2  # the push, away from the take-off the filter rounds
    assert target.channels["grf_y"][inside] == pytest.approx(
        np.interp(target.time[inside], run.time, cols["grf_y"]), abs=0.02 * model.weight)
    out = capsys.readouterr().out
    assert "2 plate(s) summed" in out and "from the quiet standing; the model 73.0 kg" in out


def test_forces_need_a_body_on_the_ground(tmp_path):
    target = Target(np.arange(0, 1, 0.01), np.zeros((1, 100)), ("elbow",), "t")
    with pytest.raises(ts.ModelError, match="does not stand on the ground"):
        with_forces(ts.load_model("builtin:elbow-curl"), target, tmp_path / "x.mot", 50.0)


def test_torquesim_s_own_ground_force_file_reads_back_once(tmp_path):
    """`simulate --grf` writes the total beside each contact's part; read back as --forces it
    is the run's ground force once (summing every plate counted it twice: 2 body weights
    standing), and a file whose plates are three real ones is still summed."""
    from torquesim.io.tables import save_ground_reactions

    jump = ts.load_model("builtin:squat-jump")
    run = ts.simulate(jump, "imex", 2.5e-4, duration=0.3, tolerance=None)
    totals = read_plates(save_ground_reactions(run, tmp_path / "grf.mot"))
    c = run.columns()
    assert totals.plates == ("",) and "toe_, heel_" in totals.note
    assert totals.force_y == pytest.approx(c["grf_y"], abs=1e-6)
    assert totals.force_x == pytest.approx(c["grf_x"], abs=1e-6)
    time = np.arange(0.0, 1.0, 0.001)
    fx, fy = _jump_force(time)
    three = tmp_path / "three.mot"
    _write_plates(three, time, fx, fy, 0.5)
    lines = three.read_text().splitlines()
    head = lines.index("endheader") + 1
    names = lines[head].split("\t")
    rows = [r.split("\t") for r in lines[head + 1:]]
    extra = [n.replace("1_", "2_") for n in names if n.startswith("1_")]
    out = lines[:head] + ["\t".join(names + extra)] + [
        "\t".join(r + [r[names.index(n.replace("2_", "1_"))] for n in extra]) for r in rows]
    three.write_text("\n".join(out).replace(f"nColumns={len(names)}",
                                            f"nColumns={len(names) + len(extra)}") + "\n")
    summed = read_plates(three)
    assert summed.plates == ("", "1_", "2_") and summed.note == ""
    assert summed.force_y == pytest.approx(1.5 * fy, abs=1e-5)
