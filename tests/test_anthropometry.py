"""Built-in models made for a subject (de Leva 1996; torquesim.model.anthropometry)."""

import math

import pytest

import torquesim as ts
from torquesim.cli import main
from torquesim.io.model_file import model_to_toml
from torquesim.model.anthropometry import (
    DE_LEVA,
    REFERENCE,
    STATURE,
    Subject,
    for_subject,
    mass_fractions,
    segment_values,
    strength_ratio,
)
from torquesim.model.preset_names import PRESET_NAMES


def _numbers(model):
    """Every number a model file holds, in order."""
    import re

    text = model_to_toml(model.replace(notes=()))
    return [float(x) for x in re.findall(r"(?<![\w.])-?\d+\.?\d*(?:e-?\d+)?", text)]


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_the_reference_man_gets_the_preset_back(name):
    model = ts.load_model(f"builtin:{name}")
    again = for_subject(model, REFERENCE)
    assert _numbers(again) == pytest.approx(_numbers(model), rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("name", ["squat-jump", "drop-landing"])
def test_a_body_on_the_ground_stands_for_subjects_far_from_the_reference(name):
    """The whole-body presets made for small, large, young and old women and men still
    stand at their start (the drop landing with its antagonists at given levels, the
    dorsiflexors at 0.25, left 42 of 100 such subjects unable to hold the ankle: its units
    now start at equilibrium)."""
    model = ts.load_model(f"builtin:{name}")
    for mass, height in ((50.0, 1.55), (110.0, 1.55), (50.0, 1.95), (110.0, 1.95)):
        for sex in ("male", "female"):
            for age in (25, 65):
                made = for_subject(model, Subject(mass, height, sex, age))
                assert made.initial_state().levels.max() <= 1.0


@pytest.mark.parametrize("sex", ["male", "female"])
def test_de_leva_mass_fractions_sum_to_one(sex):
    """The table's fractions (paired segments twice) sum to 1 (the female table to 0.9999, as
    published), and the whole-body model's segments sum to the subject's body mass."""
    assert mass_fractions(sex) == pytest.approx(1.0, abs=2e-4)
    jump = for_subject(ts.load_model("builtin:squat-jump"), Subject(64.5, 1.69, sex))
    assert sum(s.mass for s in jump.segments) == pytest.approx(64.5, rel=1e-12)


def test_segment_values_follow_de_leva():
    """A thigh of a 60 kg, 1.70 m woman: mass 14.78 %, length 0.3685 m × 1.70/1.735, CoM
    36.12 % from the hip, inertia m·((0.369 L)² + (0.3612 L)²) about the hip."""
    mass, length, com, inertia = segment_values(("thigh",), Subject(60.0, 1.70, "female"))
    expected_length = 0.3685 * 1.70 / STATURE["female"]
    assert mass == pytest.approx(0.1478 * 60.0)
    assert length == pytest.approx(expected_length)
    assert com == pytest.approx(0.3612 * expected_length)
    assert inertia == pytest.approx(mass * expected_length**2 * (0.369**2 + 0.3612**2))
    # two segments end to end: the hand's centre of mass lies beyond the forearm
    m, length, com, _ = segment_values(("forearm", "hand"), REFERENCE)
    f, h = DE_LEVA["male"]["forearm"], DE_LEVA["male"]["hand"]
    assert length == pytest.approx(f[0] + h[0])
    assert com * m == pytest.approx(73 * (f[1] * f[2] * f[0] + h[1] * (f[0] + h[2] * h[0])))


def test_mass_and_height_scale_as_they_should():
    """Twice the body mass at the same height: every body segment's mass and inertia twice,
    lengths the same, strengths twice; 10 % taller: lengths 1.1×, inertias 1.1²× the mass
    ratio, strengths 1.1×. External loads (the dumbbell) unchanged."""
    base = ts.load_model("builtin:arm-raise")
    light = for_subject(base, Subject(50.0, 1.70))
    heavy = for_subject(base, Subject(100.0, 1.70))
    tall = for_subject(base, Subject(50.0, 1.87))
    for a, b, c in zip(light.segments, heavy.segments, tall.segments, strict=True):
        assert b.mass == pytest.approx(2 * a.mass)
        assert b.inertia_about_joint == pytest.approx(2 * a.inertia_about_joint)
        assert b.length == pytest.approx(a.length)
        assert c.length == pytest.approx(1.1 * a.length)
        assert c.inertia_about_joint == pytest.approx(1.21 * a.inertia_about_joint)
        assert [ld.mass for ld in b.loads] == [ld.mass for ld in a.loads]
    for a, b, c in zip(light.units, heavy.units, tall.units, strict=True):
        assert b.parameters.isometric_torque == pytest.approx(2 * a.parameters.isometric_torque)
        assert c.parameters.isometric_torque == pytest.approx(1.1 * a.parameters.isometric_torque)


def test_women_get_de_leva_s_female_proportions():
    """Same mass and height: the woman's thigh is 14.78/14.16 as heavy and
    (0.3685/1.735)/(0.4222/1.741) as long as the man's."""
    jump = ts.load_model("builtin:squat-jump")
    man = for_subject(jump, Subject(70.0, 1.75, "male"))
    woman = for_subject(jump, Subject(70.0, 1.75, "female"))
    thigh = {m.name: m for m in man.segments}["thigh"], {w.name: w for w in woman.segments}[
        "thigh"]
    assert thigh[1].mass / thigh[0].mass == pytest.approx(0.1478 / 0.1416)
    assert thigh[1].length / thigh[0].length == pytest.approx(
        (0.3685 / 1.735) / (0.4222 / 1.741))


def _t0(model, unit):
    return {u.name: u for u in model.units}[unit].parameters.isometric_torque


def test_strengths_follow_anderson_by_sex_and_age():
    """Same size: a young woman's knee extensors are 0.159/0.163 of a young man's, her
    dorsiflexors 0.027/0.033 (Anderson et al. 2007, Table 3, C1 per body weight × height); a
    man's plantarflexors at 60 are 0.114/0.095 of his at 21.5, at 40 linearly between, and
    from 70 on the over-65 group's; the SE stiffness moves with T0 (its strain at T0 stays);
    the elbow, with no table, takes the mean of the six lower-limb ratios."""
    jump = ts.load_model("builtin:squat-jump")
    man = for_subject(jump, Subject(70.0, 1.75, "male"))
    woman = for_subject(jump, Subject(70.0, 1.75, "female"))
    assert _t0(woman, "knee_extensors") / _t0(man, "knee_extensors") == pytest.approx(
        0.159 / 0.163, rel=1e-12)
    assert _t0(woman, "dorsiflexors") / _t0(man, "dorsiflexors") == pytest.approx(
        0.027 / 0.033, rel=1e-12)
    aged = {age: _t0(for_subject(jump, Subject(70.0, 1.75, "male", age)), "plantarflexors")
            for age in (18, 21.5, 40, 60, 70, 90)}
    assert aged[18] == aged[21.5] == pytest.approx(_t0(man, "plantarflexors"), rel=1e-12)
    assert aged[60] / aged[21.5] == pytest.approx(0.114 / 0.095, rel=1e-12)
    assert aged[40] == pytest.approx(aged[21.5] + (aged[60] - aged[21.5]) * 18.5 / 38.5,
                                     rel=1e-12)
    assert aged[90] == aged[70] == pytest.approx(aged[21.5] * 0.106 / 0.095, rel=1e-12)
    for unit in jump.units:
        tm, tw = ({u.name: u for u in m.units}[unit.name].parameters for m in (man, woman))
        assert tw.se_stiffness / tm.se_stiffness == pytest.approx(
            tw.isometric_torque / tm.isometric_torque, rel=1e-12)
    curl = ts.load_model("builtin:elbow-curl")
    ratios = [0.181 / 0.161, 0.127 / 0.113, 0.159 / 0.163, 0.080 / 0.087, 0.104 / 0.095,
              0.027 / 0.033]
    assert strength_ratio(None, "female", None) == pytest.approx(sum(ratios) / 6, rel=1e-12)
    w = for_subject(curl, Subject(70.0, 1.75, "female"))
    m = for_subject(curl, Subject(70.0, 1.75, "male"))
    assert _t0(w, "elbow_flexor") / _t0(m, "elbow_flexor") == pytest.approx(
        sum(ratios) / 6, rel=1e-12)
    assert "mean lower-limb ratio, est." in w.notes[0] and "Anderson" in w.notes[0]


def test_a_subject_s_jump_runs_and_jumps(tmp_path):
    """The command of issue 31: the model file loads, simulates, leaves the ground."""
    out = tmp_path / "me.toml"
    assert main(["model", "squat-jump", "--body-mass", "72", "--height", "1.78", "--sex",
                 "female", "--out", str(out)]) == 0
    model = ts.load_model(str(out))
    assert "female subject of 72 kg and 1.78 m" in model.notes[0]
    columns = ts.simulate(model, "imex", step=1e-4).columns()
    assert math.isfinite(columns["com_y"][-1])
    assert columns["com_speed_y"].max() > 1.0  # m/s upwards: it jumps
    assert columns["grf_y"][-1] == 0.0  # and is in the air at the end


@pytest.mark.parametrize("options, message", [
    (["--body-mass", "500", "--height", "1.8"],
     "--body-mass: 500 is out of range; allowed [20, 250] kg"),
    (["--body-mass", "70"], "--height: required"),
    (["--height", "3", "--body-mass", "70"], "--height: 3 is out of range; allowed [1, 2.5] m"),
    (["--body-mass", "70", "--height", "1.7", "--age", "12"],
     "--age: 12 is out of range; allowed [18, 100] years"),
    (["--age", "30"], "--body-mass: required"),
    # a value given is judged before the one missing (it asked for --height first)
    (["--body-mass", "0"], "--body-mass: 0 is out of range; allowed [20, 250] kg"),
    (["--age", "5"], "--age: 5 is out of range; allowed [18, 100] years"),
])
def test_bad_subjects_are_one_line_errors(options, message, tmp_path, capsys):
    assert main(["model", "squat-jump", *options, "--out", str(tmp_path / "x.toml")]) == 2
    assert capsys.readouterr().err.strip().startswith(f"error: {message}")
    assert not (tmp_path / "x.toml").exists()


def test_a_model_file_is_not_made_for_a_subject(tmp_path, capsys):
    path = tmp_path / "m.toml"
    assert main(["model", "elbow-curl", "--out", str(path)]) == 0
    assert main(["model", str(path), "--body-mass", "70", "--height", "1.7", "--out",
                 str(tmp_path / "n.toml")]) == 2
    assert "is a model file; allowed: a built-in model" in capsys.readouterr().err
